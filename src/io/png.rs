//! TEMPORARY stub (replaced by branch `plot`).
#![allow(dead_code, missing_docs, unused_variables)]
pub enum Colormap {
    Grey,
    Diverging,
    Viridis,
}
pub fn image_png(
    values: &[f64],
    nx: usize,
    ny: usize,
    cmap: Colormap,
    range: (f64, f64),
    title: &str,
    colorbar_label: &str,
) -> Vec<u8> {
    Vec::new()
}
pub fn directional_png(pos: &[f64], neg: &[f64], nx: usize, ny: usize, title: &str) -> Vec<u8> {
    Vec::new()
}
pub fn symmetric_range(values: &[f64], quantile: f64) -> (f64, f64) {
    (-1.0, 1.0)
}
pub fn sequential_range(values: &[f64], quantile: f64) -> (f64, f64) {
    (0.0, 1.0)
}
