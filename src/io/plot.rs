//! TEMPORARY stub (replaced by branch `plot`).
#![allow(dead_code, missing_docs, unused_variables)]
pub struct Series<'a> {
    pub label: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: [u8; 3],
}
pub fn line_plot_png(
    series: &[Series],
    title: &str,
    x_label: &str,
    y_label: &str,
    y_range: Option<(f64, f64)>,
) -> Vec<u8> {
    Vec::new()
}
pub const PALETTE: [[u8; 3]; 8] = [[0, 0, 0]; 8];
