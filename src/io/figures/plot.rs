//! Simple line plots as PNG (spectra, profiles), and images on labelled axes (range–Doppler
//! maps, [`image_with_axes`]), drawn on a [`Canvas`].
//!
//! [`line_plot_png`] draws one or more [`Series`] on linear axes: a frame with "nice" ticks
//! (1, 2, 5 × 10^k steps, [`nice_ticks`]), light grid lines, numeric tick labels on both axes
//! ([`tick_label`]), the x-axis label under the axis, the y-axis label rotated on the left, a title
//! above and a legend box (in the corner of the plot area that the lines cover least).
//!
//! Orientation is the usual one for plots: x grows to the right and **y grows upwards** (the
//! canvas itself has row 0 at the top; the mapping flips it). Points with a non-finite `x` or `y`
//! (e.g. `−inf` dB) break a series' line; lines are clipped to the plot area.

use super::raster::{Canvas, ColorBar, Colormap, NO_DATA, clip_segment, text_width};
use super::ticks::{nice_ticks, tick_label};

/// One line of a plot: `y` against `x` (the longer slice is truncated to the shorter).
#[derive(Clone, Copy, Debug)]
pub struct Series<'a> {
    pub label: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub color: [u8; 3],
}

/// A fixed palette of 8 distinguishable colours for series (readable on white, colour-blind
/// friendly in its first six).
pub const PALETTE: [[u8; 3]; 8] = [
    [0, 114, 178],   // blue
    [213, 94, 0],    // vermilion
    [0, 158, 115],   // bluish green
    [204, 121, 167], // reddish purple
    [230, 159, 0],   // orange
    [86, 180, 233],  // sky blue
    [90, 90, 90],    // dark grey
    [140, 100, 20],  // brown
];

const WIDTH: usize = 900;
const HEIGHT: usize = 560;
const MARGIN: usize = 16;
const TITLE_SCALE: usize = 2;
const AXIS_LABEL_SCALE: usize = 2;
const TICK_SCALE: usize = 1;
const LEGEND_SCALE: usize = 1;
const TICK_LEN: i64 = 5;
const WHITE: [u8; 3] = [255, 255, 255];
const TEXT: [u8; 3] = [20, 20, 20];
const AXIS: [u8; 3] = [40, 40, 40];
const GRID: [u8; 3] = [228, 228, 228];

/// A finite axis range from data limits: widened if empty, with `margin` (a fraction of the span)
/// added on each side.
fn axis_range(lo: f64, hi: f64, margin: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
        return (0.0, 1.0);
    }
    if hi - lo == 0.0 {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - d, hi + d);
    }
    let pad = margin * (hi - lo);
    if (hi - lo + 2.0 * pad).is_finite() { (lo - pad, hi + pad) } else { (lo, hi) }
}

/// Ticks inside `[lo, hi]` such that neighbouring ticks are at least `min_px(labels)` pixels apart
/// on an axis `len_px` long: the most ticks (up to 9) that fit, with their labels.
fn fitting_ticks(lo: f64, hi: f64, len_px: f64, min_px: impl Fn(&[String]) -> f64) -> (Vec<f64>, Vec<String>) {
    let eps = 1e-9 * (hi - lo);
    let mut fallback = (vec![], vec![]);
    for target in (2..=9).rev() {
        let all = nice_ticks(lo, hi, target);
        let step = if all.len() >= 2 { all[1] - all[0] } else { hi - lo };
        let ticks: Vec<f64> = all.into_iter().filter(|&v| v >= lo - eps && v <= hi + eps).collect();
        let labels: Vec<String> = ticks.iter().map(|&v| tick_label(v, step)).collect();
        let spacing = step / (hi - lo) * len_px;
        if ticks.len() <= 1 || spacing >= min_px(&labels) {
            return (ticks, labels);
        }
        fallback = (ticks, labels);
    }
    // Even 2 targets do not fit: keep every other tick of the coarsest set.
    let (t, l) = fallback;
    (t.into_iter().step_by(2).collect(), l.into_iter().step_by(2).collect())
}

/// A line plot (900 × 560 px) of `series`: axes with nice ticks and numeric tick labels, `x_label`
/// under the x axis, `y_label` rotated on the left, `title` above, a legend box with each series'
/// colour and label (series with an empty label are left out of it). Non-finite points break the
/// lines. `y_range`: `None` = from the finite data with a 5% margin; `Some((lo, hi))` = fixed,
/// lines clipped to it (a non-finite or empty range counts as `None`). The x range is that of the
/// finite data. Never panics; with no finite point the axes say "no data".
pub fn line_plot_png(
    series: &[Series],
    title: &str,
    x_label: &str,
    y_label: &str,
    y_range: Option<(f64, f64)>,
) -> Vec<u8> {
    line_plot_canvas(series, title, x_label, y_label, y_range).to_png()
}

/// The points of a series that count (x and y truncated to the shorter).
fn points<'a>(s: &'a Series) -> impl Iterator<Item = (f64, f64)> + 'a {
    s.x.iter().zip(s.y).map(|(&x, &y)| (x, y))
}

/// [`line_plot_png`] before encoding.
pub fn line_plot_canvas(
    series: &[Series],
    title: &str,
    x_label: &str,
    y_label: &str,
    y_range: Option<(f64, f64)>,
) -> Canvas {
    let finite = |&(x, y): &(f64, f64)| x.is_finite() && y.is_finite();
    let limits = |vals: &mut dyn Iterator<Item = f64>| {
        vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
    };
    let all_x = &mut series.iter().flat_map(points).map(|p| p.0).filter(|x| x.is_finite());
    let (x_lo, x_hi) = limits(all_x);
    let (x_lo, x_hi) = axis_range(x_lo, x_hi, 0.0);
    let fixed_y = y_range
        .map(|(a, b)| (a.min(b), a.max(b)))
        .filter(|&(a, b)| a.is_finite() && b.is_finite() && b > a && (b - a).is_finite());
    let any_data = series.iter().flat_map(points).any(|p| finite(&p));
    let (y_lo, y_hi) = fixed_y.unwrap_or_else(|| {
        let (lo, hi) = limits(&mut series.iter().flat_map(points).filter(finite).map(|p| p.1));
        axis_range(lo, hi, 0.05)
    });

    let axes = Axes::layout(WIDTH, HEIGHT, 8, (x_lo, x_hi), (y_lo, y_hi));
    let mut c = Canvas::new(WIDTH, HEIGHT, WHITE);
    axes.draw(&mut c, true, title, x_label, y_label);
    let (px, py) = (|x| axes.px(x), |y| axes.py(y));
    let (li, ri, ti, bi) = (axes.left as i64, axes.right as i64, axes.top as i64, axes.bottom as i64);

    // The lines, clipped to the data range; isolated points as small squares.
    let rect = (x_lo, x_hi, y_lo, y_hi);
    for s in series {
        let pts: Vec<(f64, f64)> = points(s).collect();
        for (i, &p) in pts.iter().enumerate() {
            if !finite(&p) {
                continue;
            }
            let next_ok = pts.get(i + 1).is_some_and(finite);
            let prev_ok = i > 0 && finite(&pts[i - 1]);
            if next_ok {
                if let Some([x0, y0, x1, y1]) = clip_segment(p, pts[i + 1], rect) {
                    c.line_width(px(x0), py(y0), px(x1), py(y1), s.color, 2);
                }
            } else if !prev_ok && p.0 >= x_lo && p.0 <= x_hi && p.1 >= y_lo && p.1 <= y_hi {
                let (xi, yi) = (px(p.0).round() as i64, py(p.1).round() as i64);
                c.fill_rect(xi - 1, yi - 1, xi + 1, yi + 1, s.color);
            }
        }
    }
    if !any_data {
        let msg = "no data";
        let w = text_width(msg, AXIS_LABEL_SCALE) as i64;
        c.text((li + ri) / 2 - w / 2, (ti + bi) / 2 - 8, msg, TEXT, AXIS_LABEL_SCALE);
    }
    draw_legend(&mut c, series, (li, ri, ti, bi));
    c
}

/// The frame of a plot: the plot area in pixels, the data ranges it shows, ticks and labels.
struct Axes {
    left: usize,
    right: usize,
    top: usize,
    bottom: usize,
    x: (f64, f64),
    y: (f64, f64),
    x_ticks: Vec<f64>,
    x_labels: Vec<String>,
    y_ticks: Vec<f64>,
    y_labels: Vec<String>,
}

impl Axes {
    /// Lay out, from the outside in, a `width × height` canvas: the title on top; the x label and
    /// x tick labels at the bottom; the y label and y tick labels on the left; `right_reserve`
    /// pixels (beyond the margin) free on the right. `x` and `y` are finite, non-empty ranges.
    fn layout(width: usize, height: usize, right_reserve: usize, x: (f64, f64), y: (f64, f64)) -> Axes {
        let tick_h = 8 * TICK_SCALE;
        let top = MARGIN + 8 * TITLE_SCALE + 16;
        let bottom = height - (MARGIN + 8 * AXIS_LABEL_SCALE + 10 + tick_h + 6 + TICK_LEN as usize);
        let (y_ticks, y_labels) = fitting_ticks(y.0, y.1, (bottom - top) as f64, |_| 2.5 * tick_h as f64);
        let y_label_w = y_labels.iter().map(|s| text_width(s, TICK_SCALE)).max().unwrap_or(0);
        let left = MARGIN + 8 * AXIS_LABEL_SCALE + 12 + y_label_w + 6 + TICK_LEN as usize;
        let right = width.saturating_sub(MARGIN + right_reserve).max(left + 1);
        let (x_ticks, x_labels) = fitting_ticks(x.0, x.1, (right - left) as f64, |labels| {
            (labels.iter().map(|s| text_width(s, TICK_SCALE)).max().unwrap_or(0) + 3 * 8 * TICK_SCALE) as f64
        });
        Axes { left, right, top, bottom, x, y, x_ticks, x_labels, y_ticks, y_labels }
    }

    /// Canvas column of data `x`.
    fn px(&self, x: f64) -> f64 {
        let (l, r) = (self.left as f64, self.right as f64);
        l + (x - self.x.0) / (self.x.1 - self.x.0) * (r - l)
    }

    /// Canvas row of data `y` (y grows upwards).
    fn py(&self, y: f64) -> f64 {
        let (t, b) = (self.top as f64, self.bottom as f64);
        b - (y - self.y.0) / (self.y.1 - self.y.0) * (b - t)
    }

    /// Grid lines (if `grid`), the frame, ticks and tick labels, the axis labels and the title.
    fn draw(&self, c: &mut Canvas, grid: bool, title: &str, x_label: &str, y_label: &str) {
        let tick_h = 8 * TICK_SCALE;
        let (li, ri, ti, bi) = (self.left as i64, self.right as i64, self.top as i64, self.bottom as i64);
        if grid {
            for &x in &self.x_ticks {
                let xi = self.px(x).round() as i64;
                c.fill_rect(xi, ti, xi, bi, GRID);
            }
            for &y in &self.y_ticks {
                let yi = self.py(y).round() as i64;
                c.fill_rect(li, yi, ri, yi, GRID);
            }
        }
        c.rect_outline(li - 1, ti - 1, ri + 1, bi + 1, AXIS);
        for (&x, label) in self.x_ticks.iter().zip(&self.x_labels) {
            let xi = self.px(x).round() as i64;
            c.fill_rect(xi, bi + 1, xi, bi + TICK_LEN, AXIS);
            let w = text_width(label, TICK_SCALE) as i64;
            c.text(xi - w / 2, bi + TICK_LEN + 5, label, TEXT, TICK_SCALE);
        }
        for (&y, label) in self.y_ticks.iter().zip(&self.y_labels) {
            let yi = self.py(y).round() as i64;
            c.fill_rect(li - TICK_LEN - 1, yi, li - 2, yi, AXIS);
            let w = text_width(label, TICK_SCALE) as i64;
            c.text(li - TICK_LEN - 6 - w, yi - tick_h as i64 / 2, label, TEXT, TICK_SCALE);
        }
        let width = c.width as i64;
        let height = c.height as i64;
        let xw = text_width(x_label, AXIS_LABEL_SCALE) as i64;
        let x_label_y = height - (MARGIN + 8 * AXIS_LABEL_SCALE) as i64;
        c.text(((li + ri) / 2 - xw / 2).max(MARGIN as i64), x_label_y, x_label, TEXT, AXIS_LABEL_SCALE);
        let yh = text_width(y_label, AXIS_LABEL_SCALE) as i64;
        c.text_vertical(MARGIN as i64, ((ti + bi) / 2 - yh / 2).max(0), y_label, TEXT, AXIS_LABEL_SCALE);
        let tw = text_width(title, TITLE_SCALE) as i64;
        let title_x = ((li + ri) / 2 - tw / 2).min(width - MARGIN as i64 - tw).max(MARGIN as i64);
        c.text(title_x, MARGIN as i64, title, TEXT, TITLE_SCALE);
    }
}

/// A false-colour image on labelled axes ([`image_with_axes`]).
#[derive(Clone, Copy, Debug)]
pub struct AxesImage<'a> {
    /// `ny × nx` values, row-major, row 0 = the smallest `y` (drawn at the bottom), column 0 the
    /// smallest `x`.
    pub values: &'a [f64],
    pub nx: usize,
    pub ny: usize,
    /// Data coordinates of the left edge of column 0 and the right edge of column `nx − 1`.
    pub x_range: (f64, f64),
    /// Data coordinates of the bottom edge of row 0 and the top edge of row `ny − 1`.
    pub y_range: (f64, f64),
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub title: &'a str,
    pub cmap: Colormap,
    /// Values mapped to the bottom and top of the colour bar (clamped beyond).
    pub value_range: (f64, f64),
    pub colorbar_label: &'a str,
}

/// An image (900 × 560 px) on axes in data coordinates: the cells stretched over the plot area
/// (nearest cell per pixel, y up), a frame with nice ticks and numeric tick labels on both axes,
/// the axis labels, the title above and a colour bar with its unit label on the right. Non-finite
/// values (and a `values.len()` that is not `nx · ny`) are drawn in [`NO_DATA`], listed under the
/// colour bar. Ranges that are not finite or empty fall back to the cell indices. Never panics.
pub fn image_with_axes(im: &AxesImage) -> Canvas {
    let usable = |(a, b): (f64, f64), n: usize| {
        if a.is_finite() && b.is_finite() && b > a && (b - a).is_finite() { (a, b) } else { (0.0, n.max(1) as f64) }
    };
    let (x_range, y_range) = (usable(im.x_range, im.nx), usable(im.y_range, im.ny));
    const BAR_GAP: usize = 20;
    let shape_ok = im.nx.checked_mul(im.ny).is_some_and(|n| n == im.values.len() && n > 0);
    // The bar spans the plot area: lay out once for its height, then with its width reserved.
    let probe = Axes::layout(WIDTH, HEIGHT, 8, x_range, y_range);
    let bar = ColorBar::new(im.cmap, im.value_range, im.colorbar_label, probe.bottom - probe.top + 1);
    let axes = Axes::layout(WIDTH, HEIGHT, BAR_GAP + bar.width(), x_range, y_range);
    let mut c = Canvas::new(WIDTH, HEIGHT, WHITE);
    let (lo, hi) = (bar.lo(), bar.hi());
    let mut any_missing = !shape_ok;
    let (w, h) = (axes.right - axes.left + 1, axes.bottom - axes.top + 1);
    for py in 0..h {
        // Pixel rows from the top: the top row shows the largest y.
        let iy = im.ny.saturating_sub(1).saturating_sub(py * im.ny.max(1) / h);
        for px in 0..w {
            let ix = (px * im.nx.max(1) / w).min(im.nx.saturating_sub(1));
            let v = if shape_ok { im.values[iy * im.nx + ix] } else { f64::NAN };
            let color = if v.is_finite() {
                im.cmap.color((v - lo) / (hi - lo))
            } else {
                any_missing = true;
                NO_DATA
            };
            c.set((axes.left + px) as i64, (axes.top + py) as i64, color);
        }
    }
    axes.draw(&mut c, false, im.title, im.x_label, im.y_label);
    let bar_x = axes.right + BAR_GAP;
    bar.draw(&mut c, bar_x, axes.top);
    if any_missing {
        ColorBar::draw_no_data(&mut c, bar_x, (axes.bottom + 12).min(HEIGHT - 12));
    }
    c
}

/// The legend box, in the corner of the plot area with the fewest series-coloured pixels.
fn draw_legend(c: &mut Canvas, series: &[Series], (l, r, t, b): (i64, i64, i64, i64)) {
    let entries: Vec<&Series> = series.iter().filter(|s| !s.label.is_empty()).collect();
    if entries.is_empty() {
        return;
    }
    const SWATCH: i64 = 24;
    const PAD: i64 = 8;
    let row = (8 * LEGEND_SCALE) as i64 + 8;
    let text_w = entries.iter().map(|s| text_width(s.label, LEGEND_SCALE)).max().unwrap_or(0) as i64;
    let (w, h) = (PAD + SWATCH + 8 + text_w + PAD, 2 * PAD + row * entries.len() as i64 - 8);
    let inset = 10;
    let corners = [
        (r - inset - w, t + inset),
        (l + inset, t + inset),
        (r - inset - w, b - inset - h),
        (l + inset, b - inset - h),
    ];
    let colors: Vec<[u8; 3]> = entries.iter().map(|s| s.color).collect();
    let covered = |&(x0, y0): &(i64, i64)| {
        let mut n = 0usize;
        for y in y0.max(0)..(y0 + h) {
            for x in x0.max(0)..(x0 + w) {
                if c.get(x as usize, y as usize).is_some_and(|p| colors.contains(&p)) {
                    n += 1;
                }
            }
        }
        n
    };
    let (x0, y0) = corners.iter().copied().min_by_key(|p| covered(p)).unwrap_or(corners[0]);
    c.fill_rect(x0, y0, x0 + w - 1, y0 + h - 1, WHITE);
    c.rect_outline(x0, y0, x0 + w - 1, y0 + h - 1, [150, 150, 150]);
    for (k, s) in entries.iter().enumerate() {
        let y = y0 + PAD + k as i64 * row;
        let mid = y + (4 * LEGEND_SCALE) as i64;
        c.fill_rect(x0 + PAD, mid - 1, x0 + PAD + SWATCH - 1, mid + 1, s.color);
        c.text(x0 + PAD + SWATCH + 8, y, s.label, TEXT, LEGEND_SCALE);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(bytes: &[u8]) -> (usize, usize, Vec<u8>) {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("PNG header");
        let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
        let info = reader.next_frame(&mut buf).expect("PNG frame");
        buf.truncate(info.buffer_size());
        (info.width as usize, info.height as usize, buf)
    }

    fn count_color(rgb: &[u8], c: [u8; 3]) -> usize {
        rgb.chunks_exact(3).filter(|p| *p == c).count()
    }

    #[test]
    fn line_plot_has_every_series_colour() {
        let x: Vec<f64> = (0..200).map(|i| i as f64 * 0.05 - 5.0).collect();
        let y1: Vec<f64> = x.iter().map(|x| -30.0 + 10.0 * x.sin()).collect();
        let y2: Vec<f64> = x.iter().map(|x| if x.abs() < 1.0 { f64::NEG_INFINITY } else { -x * x }).collect();
        let y3: Vec<f64> = x.iter().map(|x| 0.5 * x).collect();
        let series = [
            Series { label: "sin", x: &x, y: &y1, color: PALETTE[0] },
            Series { label: "parabola with a gap", x: &x, y: &y2, color: PALETTE[1] },
            Series { label: "", x: &x[..50], y: &y3, color: PALETTE[2] },
        ];
        let (w, h, rgb) = decode(&line_plot_png(&series, "test plot", "frequency (kHz)", "power (dB)", None));
        assert_eq!((w, h), (WIDTH, HEIGHT));
        for s in &series {
            assert!(count_color(&rgb, s.color) > 100, "{:?}", s.color);
        }
        // The gap: the parabola's colour is missing from the columns of |x| < 1 inside the plot.
        let c = line_plot_canvas(&series, "test plot", "frequency (kHz)", "power (dB)", Some((-40.0, 10.0)));
        let col = (c.width as f64 * 0.5) as usize;
        let hits = (0..c.height).filter(|&y| c.get(col, y) == Some(PALETTE[1])).count();
        assert_eq!(hits, 0);
    }

    #[test]
    fn fixed_range_clips_lines_to_the_plot_area() {
        let x = [0.0, 1.0, 2.0];
        let y = [0.0, 1e6, 0.0];
        let s = [Series { label: "spike", x: &x, y: &y, color: [255, 0, 255] }];
        let c = line_plot_canvas(&s, "clip", "x", "y", Some((0.0, 1.0)));
        // Nothing magenta in the title band above the plot.
        for y in 0..(MARGIN + 8 * TITLE_SCALE + 14) {
            for x in 0..c.width {
                assert_ne!(c.get(x, y), Some([255, 0, 255]), "({x}, {y})");
            }
        }
        assert!(count_color(&c.rgb, [255, 0, 255]) > 10);
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let nan = [f64::NAN; 4];
        let one = [1.0];
        let x4 = [0.0, 1.0, 2.0, 3.0];
        let inf = [f64::INFINITY, f64::NEG_INFINITY, 1.0, 2.0];
        let big = [-f64::MAX, f64::MAX, 0.0, 1.0];
        let cases: Vec<Vec<Series>> = vec![
            vec![],
            vec![Series { label: "empty", x: &[], y: &[], color: PALETTE[0] }],
            vec![Series { label: "nan", x: &x4, y: &nan, color: PALETTE[1] }],
            vec![Series { label: "one point", x: &one, y: &one, color: PALETTE[2] }],
            vec![Series { label: "mismatch", x: &x4, y: &one, color: PALETTE[3] }],
            vec![Series { label: "flat", x: &x4, y: &[2.0; 4], color: PALETTE[4] }],
            vec![Series { label: "inf", x: &inf, y: &x4, color: PALETTE[5] }],
            vec![Series { label: "huge", x: &x4, y: &big, color: PALETTE[6] }],
            vec![Series { label: "same x", x: &[5.0; 4], y: &x4, color: PALETTE[7] }],
        ];
        for s in &cases {
            for range in [None, Some((1.0, 1.0)), Some((f64::NAN, 0.0)), Some((5.0, -5.0))] {
                let (w, h, _) = decode(&line_plot_png(s, "degenerate", "", "", range));
                assert_eq!((w, h), (WIDTH, HEIGHT));
            }
        }
        let label = "x".repeat(500);
        let s = [Series { label: &label, x: &x4, y: &x4, color: PALETTE[0] }];
        decode(&line_plot_png(&s, &label, &label, &label, None));
        // An isolated finite point between breaks is still drawn.
        let y = [f64::NAN, 1.0, f64::NAN, 2.0];
        let s = [Series { label: "dots", x: &x4, y: &y, color: [1, 2, 3] }];
        assert!(count_color(&line_plot_canvas(&s, "", "", "", None).rgb, [1, 2, 3]) >= 18);
    }

    #[test]
    fn image_with_axes_puts_row_zero_at_the_bottom_and_marks_missing_values() {
        // 2 × 3 cells: row 0 = 0 (bottom, dark), row 2 = 10 (top, bright); one NaN cell.
        let values = vec![0.0, 0.0, 5.0, 5.0, 10.0, 10.0];
        let mut holed = values.clone();
        holed[3] = f64::NAN;
        let base = AxesImage {
            values: &values,
            nx: 2,
            ny: 3,
            x_range: (-20.0, 20.0),
            y_range: (90.0, 690.0),
            x_label: "radial velocity (m/s)",
            y_label: "range (m)",
            title: "test",
            cmap: Colormap::Grey,
            value_range: (0.0, 10.0),
            colorbar_label: "dB",
        };
        let c = image_with_axes(&base);
        assert_eq!((c.width, c.height), (WIDTH, HEIGHT));
        let axes = Axes::layout(WIDTH, HEIGHT, 8, (-20.0, 20.0), (90.0, 690.0));
        let x = axes.left + 40;
        let (top, bottom) = (c.get(x, axes.top + 5).unwrap(), c.get(x, axes.bottom - 5).unwrap());
        assert_eq!(top, Colormap::Grey.color(1.0));
        assert_eq!(bottom, Colormap::Grey.color(0.0));
        assert_eq!(count_color(&c.rgb, NO_DATA), 0);
        let c = image_with_axes(&AxesImage { values: &holed, ..base });
        assert!(count_color(&c.rgb, NO_DATA) > 1000);
        // Degenerate inputs draw something and never panic.
        for (v, nx, ny, xr) in [
            (&[][..], 0, 0, (0.0, 1.0)),
            (&values[..5], 2, 3, (f64::NAN, 1.0)),
            (&values[..], usize::MAX, 2, (1.0, 1.0)),
            (&values[..], 6, 1, (5.0, -5.0)),
        ] {
            let c = image_with_axes(&AxesImage { values: v, nx, ny, x_range: xr, value_range: (1.0, 1.0), ..base });
            assert_eq!((c.width, c.height), (WIDTH, HEIGHT));
        }
    }

    /// Renders an example plot to `$OHD_PNG_DIR` (for looking at it), when set.
    #[test]
    fn render_example_when_asked() {
        let Ok(dir) = std::env::var("OHD_PNG_DIR") else { return };
        let f: Vec<f64> = (0..=400).map(|i| -30.0 + 60.0 * i as f64 / 400.0).collect();
        let lorentz = |f0: f64, w: f64, a: f64| -> Vec<f64> {
            f.iter().map(|&f| 10.0 * (a / (1.0 + ((f - f0) / w).powi(2)) + 1e-6).log10()).collect()
        };
        let s1 = lorentz(0.0, 1.5, 1e-3);
        let s2 = lorentz(6.0, 4.0, 2e-4);
        let mut s3 = lorentz(-9.0, 6.0, 5e-5);
        for v in s3.iter_mut().skip(180).take(40) {
            *v = f64::NEG_INFINITY;
        }
        let series = [
            Series { label: "static tissue (DC)", x: &f, y: &s1, color: PALETTE[0] },
            Series { label: "vessel, receding", x: &f, y: &s2, color: PALETTE[1] },
            Series { label: "vessel, approaching (gap = -inf dB)", x: &f, y: &s3, color: PALETTE[2] },
        ];
        let png = line_plot_png(&series, "Doppler power spectrum", "beat frequency (kHz)", "power (dB)", None);
        std::fs::write(std::path::Path::new(&dir).join("ohd_plot_spectrum.png"), png).unwrap();
        let x: Vec<f64> = (0..100).map(|i| i as f64 * 1e-6).collect();
        let y: Vec<f64> = x.iter().map(|x| 2e-5 * (-x / 3e-5).exp()).collect();
        let series = [Series { label: "M0", x: &x, y: &y, color: PALETTE[3] }];
        let png = line_plot_png(&series, "Small numbers", "depth (m)", "M0 (fraction)", None);
        std::fs::write(std::path::Path::new(&dir).join("ohd_plot_small.png"), png).unwrap();
    }
}
