//! Images on physical axes ([`ImageFigure`]: one or more [`Panel`]s side by side): cells drawn
//! as stored (row 0 at the top), axes in the data's units (mm for a camera, m/s and m for a
//! range–Doppler map, optionally a second y axis on the right: a lidar's height), equal scales
//! on both axes where asked (a camera's pixels stay square), and a colour bar in the output's
//! unit, its numbers scaled by a power of 1000 named in its label. Colour ranges are set by the
//! caller (percentiles, [`super::scale`]); what lies beyond them saturates, and a caption under
//! the panel says how the range was chosen.

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::scale::{Colormap, NO_DATA, engineering, tick_label};
use super::{Draw, DrawResult, FAMILY, Raster};

/// One image panel.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    /// `ny × nx` values, row 0 = the top row (largest y), columns x ascending.
    pub values: Vec<f64>,
    pub nx: usize,
    pub ny: usize,
    /// The axis values of the left and right edges, and of the bottom and top edges.
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub x_label: String,
    pub y_label: String,
    /// Equal scales on x and y (square camera pixels).
    pub equal: bool,
    /// A second y axis on the right: its label and its values at the bottom and top edges.
    pub right_axis: Option<(String, (f64, f64))>,
    pub cmap: Colormap,
    /// Values at the bottom and top of the colour bar.
    pub range: (f64, f64),
    /// The colour bar's label (the unit).
    pub unit: String,
    /// Cell colours given directly (a directional composite), else from `cmap` and `range`.
    pub colors: Option<Vec<[u8; 3]>>,
    /// A line under the panel: how the colour range was chosen, what is grey.
    pub caption: String,
}

/// What a panel whose every value is exactly 0 says in place of its colour bar: the cells are
/// grey ([`NO_DATA`]), with no colour scale, so that an output zero by construction (a class of
/// paths that never reaches the band) is not drawn as data.
pub const ZERO_EVERYWHERE: &str = "0 at every cell: nothing to scale";

impl Panel {
    /// A panel with the defaults: no second axis, colours from `cmap`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        title: impl Into<String>,
        values: Vec<f64>,
        (nx, ny): (usize, usize),
        x: (f64, f64),
        y: (f64, f64),
        cmap: Colormap,
        range: (f64, f64),
        unit: impl Into<String>,
    ) -> Panel {
        Panel {
            title: title.into(),
            values,
            nx,
            ny,
            x,
            y,
            x_label: "x (mm)".into(),
            y_label: "y (mm)".into(),
            equal: true,
            right_axis: None,
            cmap,
            range,
            unit: unit.into(),
            colors: None,
            caption: String::new(),
        }
    }
}

/// Panels side by side, each `PANEL` pixels.
#[derive(Debug, Clone)]
pub struct ImageFigure {
    pub panels: Vec<Panel>,
}

/// The size of one panel, pixels.
pub const PANEL: (u32, u32) = (640, 560);

const TITLE_H: i32 = 40;
const CAPTION_H: i32 = 26;
const LEFT: i32 = 78;
const BOTTOM: i32 = 54;
const RIGHT_AXIS: i32 = 74;
const BAR_W: i32 = 120;
const PAD: i32 = 12;

/// A usable axis range: finite (within ±1e250) and non-empty, else `(0, n)` (cell indices).
fn usable((a, b): (f64, f64), n: usize) -> (f64, f64) {
    // Plotters' tick search does not end on spans near the largest float.
    if a.abs() < 1e250 && b.abs() < 1e250 && a != b { (a, b) } else { (0.0, n.max(1) as f64) }
}

impl Draw for ImageFigure {
    fn size(&self) -> (u32, u32) {
        (PANEL.0 * self.panels.len().max(1) as u32, PANEL.1)
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Vec<Raster>, DB> {
        let areas = root.split_evenly((1, self.panels.len().max(1)));
        let mut rasters = Vec::new();
        for (p, area) in self.panels.iter().zip(&areas) {
            rasters.push(draw_panel(p, area)?);
        }
        Ok(rasters)
    }
}

/// Title text that fits `width` pixels at 18 px (about 9.5 px a character), cut with "…".
fn fit(title: &str, width: i32) -> String {
    let max = (width / 10).max(4) as usize;
    if title.chars().count() <= max { title.to_string() } else { title.chars().take(max - 1).chain(['…']).collect() }
}

fn draw_panel<DB: DrawingBackend>(p: &Panel, area: &DrawingArea<DB, Shift>) -> DrawResult<Raster, DB> {
    let (w, h) = (PANEL.0 as i32, PANEL.1 as i32);
    let (ox, oy) = (area.get_base_pixel().0, area.get_base_pixel().1);
    area.draw(&Text::new(
        fit(&p.title, w - 2 * PAD),
        (w / 2, TITLE_H / 2),
        (FAMILY, 18).into_font().color(&BLACK).pos(Pos::new(HPos::Center, VPos::Center)),
    ))?;
    let xr = usable(p.x, p.nx);
    let yr = usable(p.y, p.ny);
    let right = if p.right_axis.is_some() { RIGHT_AXIS } else { PAD };
    // The plot box: what is left of the panel, shrunk to equal scales if asked.
    let (aw, ah) = (w - LEFT - right - BAR_W - PAD, h - TITLE_H - BOTTOM - CAPTION_H - PAD);
    let (mut pw, mut ph) = (aw.max(10), ah.max(10));
    if p.equal {
        let (dx, dy) = ((xr.1 - xr.0).abs(), (yr.1 - yr.0).abs());
        let s = (pw as f64 / dx).min(ph as f64 / dy);
        if s.is_finite() && s > 0.0 {
            pw = ((dx * s).round() as i32).clamp(10, pw);
            ph = ((dy * s).round() as i32).clamp(10, ph);
        }
    }
    let (x0, y0) = (LEFT + (aw - pw) / 2, TITLE_H + (ah - ph) / 2);
    let sub = area.margin(y0 as u32, (h - y0 - ph - BOTTOM).max(0) as u32, (x0 - LEFT).max(0) as u32, 0);
    let chart_w = LEFT + pw + right;
    let (chart_area, _) = sub.split_horizontally(chart_w);
    let mut builder = ChartBuilder::on(&chart_area);
    // The axis description is drawn at the label area's outer edge: keep it off the panel edge.
    builder.margin_left(16).x_label_area_size(BOTTOM).y_label_area_size(LEFT - 16);
    if p.right_axis.is_some() {
        builder.right_y_label_area_size(right);
    }
    let chart = builder.build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
    let (x_step, y_step) = (step(xr), step(yr));
    let mut chart = match &p.right_axis {
        Some((_, r2)) => {
            let r2 = usable(*r2, p.ny);
            let mut dual = chart.set_secondary_coord(xr.0..xr.1, r2.0..r2.1);
            draw_mesh(&mut dual, p, x_step, y_step)?;
            let s2 = step(r2);
            dual.configure_secondary_axes()
                .y_desc(p.right_axis.as_ref().map_or("", |a| a.0.as_str()))
                .axis_desc_style((FAMILY, 16))
                .label_style((FAMILY, 14))
                .y_labels(8)
                .y_label_formatter(&|v| tick_label(*v, s2))
                .draw()?;
            let (px, py) = dual.plotting_area().get_pixel_range();
            return finish(p, area, (ox, oy), px, py);
        }
        None => chart,
    };
    draw_mesh(&mut chart, p, x_step, y_step)?;
    let (px, py) = chart.plotting_area().get_pixel_range();
    finish(p, area, (ox, oy), px, py)
}

/// Axes, tick labels and descriptions of an image's chart (no grid: it would cover cells).
fn draw_mesh<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    p: &Panel,
    x_step: f64,
    y_step: f64,
) -> DrawResult<(), DB> {
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(&p.x_label)
        .y_desc(&p.y_label)
        .axis_desc_style((FAMILY, 16))
        .label_style((FAMILY, 14))
        .x_labels(8)
        .y_labels(8)
        .x_label_formatter(&|v| tick_label(*v, x_step))
        .y_label_formatter(&|v| tick_label(*v, y_step))
        .draw()
}

/// The colour bar, the caption and the raster of the cells in the plot box `px × py`.
fn finish<DB: DrawingBackend>(
    p: &Panel,
    area: &DrawingArea<DB, Shift>,
    (ox, oy): (i32, i32),
    px: std::ops::Range<i32>,
    py: std::ops::Range<i32>,
) -> DrawResult<Raster, DB> {
    let w = PANEL.0 as i32;
    let shape_ok = p.nx.checked_mul(p.ny).is_some_and(|n| n == p.values.len() && n > 0);
    let zero = p.colors.is_none() && shape_ok && p.values.iter().all(|v| *v == 0.0);
    let cells = match &p.colors {
        Some(c) if shape_ok && c.len() == p.values.len() => c.clone(),
        _ if zero => vec![NO_DATA; p.values.len()],
        _ if shape_ok => p.cmap.colors(&p.values, p.range),
        _ => vec![NO_DATA],
    };
    let (nx, ny) = if shape_ok { (p.nx, p.ny) } else { (1, 1) };
    // Frame around the cells (drawn before them in the SVG order; the cells fill its inside).
    let frame =
        Rectangle::new([(px.start - ox - 1, py.start - oy - 1), (px.end - ox, py.end - oy)], BLACK.stroke_width(1));
    area.draw(&frame)?;
    // The colour bar beside the plot box, as tall.
    let bx = w - BAR_W - PAD + 14;
    let (top, bottom) = (py.start - oy, py.end - oy);
    if zero {
        vertical(area, ZERO_EVERYWHERE.into(), (bx + 9, (top + bottom) / 2))?;
        caption(p, area)?;
        return Ok(Raster { x0: px.start, y0: py.start, x1: px.end, y1: py.end, nx, ny, rgb: cells });
    }
    let (lo, hi) = p.range;
    let (factor, suffix) = engineering(lo.abs().max(hi.abs()));
    let steps = 128;
    for k in 0..steps {
        let t = (k as f64 + 0.5) / steps as f64;
        let y1 = bottom - ((bottom - top) as f64 * k as f64 / steps as f64).round() as i32;
        let y0 = bottom - ((bottom - top) as f64 * (k + 1) as f64 / steps as f64).round() as i32;
        let c = p.cmap.color(t);
        area.draw(&Rectangle::new([(bx, y0), (bx + 18, y1)], RGBColor(c[0], c[1], c[2]).filled()))?;
    }
    area.draw(&Rectangle::new([(bx, top), (bx + 18, bottom)], BLACK.stroke_width(1)))?;
    let ticks = bar_ticks((lo * factor, hi * factor));
    let span = hi * factor - lo * factor;
    for (v, label) in ticks {
        let y = bottom - (((v - lo * factor) / span) * (bottom - top) as f64).round() as i32;
        area.draw(&PathElement::new(vec![(bx + 18, y), (bx + 23, y)], BLACK))?;
        area.draw(&Text::new(
            label,
            (bx + 26, y),
            (FAMILY, 13).into_font().color(&BLACK).pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
    }
    let unit = if suffix.is_empty() { p.unit.clone() } else { format!("{} ({suffix})", p.unit) };
    vertical(area, fit(&unit, bottom - top + 40), (bx + 92, (top + bottom) / 2))?;
    caption(p, area)?;
    Ok(Raster { x0: px.start, y0: py.start, x1: px.end, y1: py.end, nx, ny, rgb: cells })
}

/// `text` read bottom to top, centred on `at` (beside a colour bar).
fn vertical<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: String, at: (i32, i32)) -> DrawResult<(), DB> {
    let font = (FAMILY, 15).into_font().transform(FontTransform::Rotate270);
    area.draw(&Text::new(text, at, font.color(&BLACK).pos(Pos::new(HPos::Center, VPos::Center))))
}

/// The panel's caption under it, if any.
fn caption<DB: DrawingBackend>(p: &Panel, area: &DrawingArea<DB, Shift>) -> DrawResult<(), DB> {
    let (w, h) = (PANEL.0 as i32, PANEL.1 as i32);
    if !p.caption.is_empty() {
        area.draw(&Text::new(
            fit(&p.caption, (w - 2 * PAD) * 10 / 8),
            (PAD, h - CAPTION_H / 2 - 2),
            (FAMILY, 13).into_font().color(&RGBColor(70, 70, 70)).pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
    }
    Ok(())
}

/// About 6 nice ticks inside `(lo, hi)` with their labels.
fn bar_ticks((lo, hi): (f64, f64)) -> Vec<(f64, String)> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return vec![];
    }
    let s = step_n((lo, hi), 6.0);
    let first = (lo / s).ceil() as i64;
    let last = (hi / s).floor() as i64;
    (first..=last)
        .take(20)
        .map(|k| k as f64 * s)
        .map(|v| (v, tick_label(if v.abs() < 1e-9 * s { 0.0 } else { v }, s)))
        .collect()
}

fn step_n((lo, hi): (f64, f64), n: f64) -> f64 {
    let raw = (hi - lo).abs() / n;
    if !(raw > 0.0 && raw.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * p).find(|s| *s >= raw).unwrap_or(10.0 * p)
}

fn step(r: (f64, f64)) -> f64 {
    step_n(r, 8.0)
}

/// HSV (hue in degrees, saturation and value in [0, 1]) to RGB.
pub fn hsv(h: f64, s: f64, v: f64) -> [u8; 3] {
    let (s, v) = (s.clamp(0.0, 1.0), v.clamp(0.0, 1.0));
    let c = v * s;
    let hp = (h.rem_euclid(360.0)) / 60.0;
    let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r, g, b].map(|u| ((u + m) * 255.0).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::super::render;
    use super::super::tests::check_figure;
    use super::*;

    fn panel(values: Vec<f64>, nx: usize, ny: usize) -> Panel {
        let range = super::super::scale::sequential_range(&values);
        Panel::new("M0+ (6–18.3 kHz)", values, (nx, ny), (-1.2, 1.2), (-1.2, 1.2), Colormap::Viridis, range, "W/W")
    }

    /// Row 0 is drawn at the top: a bright top row shows in the upper half of the plot box.
    #[test]
    fn row_zero_is_the_top_and_sizes_are_kept() {
        let (nx, ny) = (4, 4);
        let mut v = vec![0.0; nx * ny];
        v[..nx].fill(1.0);
        let fig = ImageFigure { panels: vec![panel(v, nx, ny)] };
        let (w, _, rgb) = check_figure(&render(&fig).unwrap(), PANEL);
        let bright = Colormap::Viridis.color(1.0);
        let rows: Vec<usize> = (0..PANEL.1 as usize)
            .filter(|&y| (0..w).filter(|&x| rgb[3 * (y * w + x)..3 * (y * w + x) + 3] == bright).count() > 50)
            .collect();
        assert!(!rows.is_empty());
        let mid = (TITLE_H + (PANEL.1 as i32 - TITLE_H - BOTTOM - CAPTION_H) / 2) as usize;
        assert!(rows.iter().all(|&y| y < mid), "{rows:?}");
    }

    /// An image zero at every pixel (an LDH camera's static-class M0±) is not drawn as data: grey
    /// cells, and no colour bar — none of the colour map's colours anywhere in the figure.
    #[test]
    fn a_zero_image_is_not_drawn_as_data() {
        let fig = ImageFigure { panels: vec![panel(vec![0.0; 32 * 32], 32, 32)] };
        let figure = render(&fig).unwrap();
        let (_, _, rgb) = check_figure(&figure, PANEL);
        let viridis: Vec<[u8; 3]> = (0..=16).map(|k| Colormap::Viridis.color(k as f64 / 16.0)).collect();
        let colored = rgb.chunks(3).filter(|c| viridis.iter().any(|v| v == c)).count();
        assert_eq!(colored, 0, "colour-map pixels in a zero image");
        assert!(rgb.chunks(3).filter(|c| *c == NO_DATA).count() > 100_000, "the plot box is grey");
        assert!(figure.svg.contains(ZERO_EVERYWHERE));
        // One non-zero pixel and it is data again, with its colour bar.
        let mut v = vec![0.0; 32 * 32];
        v[7] = 1e-21;
        let figure = render(&ImageFigure { panels: vec![panel(v, 32, 32)] }).unwrap();
        assert!(!figure.svg.contains(ZERO_EVERYWHERE));
    }

    #[test]
    fn degenerate_images_draw() {
        let mut one = vec![0.0; 128 * 128];
        one[5000] = 2e-9;
        let cases = [
            panel(vec![0.0; 256 * 256], 256, 256),
            panel(one, 128, 128),
            panel(vec![3.0], 1, 1),
            panel(vec![], 0, 0),
            panel(vec![1.0; 5], 2, 3),
            Panel { x: (f64::NAN, 1.0), y: (2.0, 2.0), range: (1.0, 1.0), ..panel(vec![1.0; 4], 2, 2) },
        ];
        for p in cases {
            let two = ImageFigure { panels: vec![p.clone(), p] };
            check_figure(&render(&two).unwrap(), (2 * PANEL.0, PANEL.1));
        }
        // A long title is cut to the panel, not drawn across its neighbour.
        assert!(fit(&"x".repeat(500), 600).chars().count() <= 60);
    }

    #[test]
    fn hsv_primaries() {
        assert_eq!(hsv(0.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv(240.0, 1.0, 1.0), [0, 0, 255]);
        assert_eq!(hsv(120.0, 0.0, 0.5), [128, 128, 128]);
    }
}
