//! Line plots ([`LinePlot`]): curves with an optional ±σ band, markers and error bars, shaded
//! x-bands ([`Span`]: an M0 band) and marked x values ([`VLine`]: a recovered frequency), on
//! linear or logarithmic axes. Non-finite points break a line (a zero power in dB); values
//! outside a fixed y range are clipped to it. The legend lists exactly the curves that have a
//! point drawn; a note under the plot can say what was left out and why.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use super::scale::tick_label;
use super::{Draw, DrawResult, FAMILY, Raster};

/// How a curve is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    Line,
    Dashed,
    Markers,
    LineMarkers,
    /// Markers on stems from the bottom of the plot: spectral lines a bin wide.
    Stems,
}

/// One curve: `y` against `x` (the longer truncated to the shorter).
#[derive(Debug, Clone)]
pub struct Curve {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    /// A shaded band `(lower, upper)` per point (e.g. ±σ); non-finite bounds break it.
    pub band: Option<(Vec<f64>, Vec<f64>)>,
    /// Error bars: half-lengths along x or y per point.
    pub x_err: Option<Vec<f64>>,
    pub y_err: Option<Vec<f64>>,
    pub color: [u8; 3],
    pub mark: Mark,
}

impl Curve {
    /// A plain line.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>, color: [u8; 3]) -> Curve {
        Curve { label: label.into(), x, y, band: None, x_err: None, y_err: None, color, mark: Mark::Line }
    }

    fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.x.iter().zip(&self.y).map(|(&x, &y)| (x, y))
    }
}

/// A shaded range of x (a frequency band).
#[derive(Debug, Clone)]
pub struct Span {
    pub lo: f64,
    pub hi: f64,
    /// Listed in the legend unless empty (several spans may share one entry: the first labelled).
    pub label: String,
    pub color: [u8; 3],
}

/// A vertical line at `x`, labelled in the legend.
#[derive(Debug, Clone)]
pub struct VLine {
    pub x: f64,
    pub label: String,
    pub color: [u8; 3],
}

/// A line plot.
#[derive(Debug, Clone)]
pub struct LinePlot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub curves: Vec<Curve>,
    pub spans: Vec<Span>,
    pub vlines: Vec<VLine>,
    pub log_x: bool,
    pub log_y: bool,
    /// Fixed y range (else from the data); non-finite or empty counts as none.
    pub y_range: Option<(f64, f64)>,
    /// Fixed x range (a zoom onto narrow lines; else from the data), likewise.
    pub x_range: Option<(f64, f64)>,
    /// A line of text under the plot (what was left out, how the range was chosen).
    pub note: String,
    pub size: (u32, u32),
}

/// A palette of distinguishable colours, readable on white (the first six colour-blind safe).
pub const PALETTE: [[u8; 3]; 8] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
    [90, 90, 90],
    [140, 100, 20],
];

/// The default size of a line plot, pixels.
pub const SIZE: (u32, u32) = (960, 600);

impl LinePlot {
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> LinePlot {
        LinePlot {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            curves: Vec::new(),
            spans: Vec::new(),
            vlines: Vec::new(),
            log_x: false,
            log_y: false,
            y_range: None,
            x_range: None,
            note: String::new(),
            size: SIZE,
        }
    }

    /// Whether a value can be shown on the x (`y = false`) or y axis.
    fn shown(&self, v: f64, y: bool) -> bool {
        v.is_finite() && !((if y { self.log_y } else { self.log_x }) && v <= 0.0)
    }

    /// The data's x and y ranges (with a margin), finite and non-empty.
    fn ranges(&self) -> ((f64, f64), (f64, f64)) {
        let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
        let mut ys = xs;
        let grow = |r: &mut (f64, f64), v: f64| *r = (r.0.min(v), r.1.max(v));
        for c in &self.curves {
            for (i, (x, y)) in c.points().enumerate() {
                // The whole x axis of a curve shows, where it has power or not (a spectrum's axis).
                if self.shown(x, false) {
                    grow(&mut xs, x);
                }
                if !(self.shown(x, false) && self.shown(y, true)) {
                    continue;
                }
                let ex = c.x_err.as_ref().and_then(|e| e.get(i)).copied().filter(|e| e.is_finite()).unwrap_or(0.0);
                let ey = c.y_err.as_ref().and_then(|e| e.get(i)).copied().filter(|e| e.is_finite()).unwrap_or(0.0);
                for v in [x - ex, x + ex] {
                    if self.shown(v, false) {
                        grow(&mut xs, v);
                    }
                }
                for v in [y - ey, y + ey] {
                    if self.shown(v, true) {
                        grow(&mut ys, v);
                    }
                }
                if let Some((lo, hi)) = &c.band {
                    for v in [lo.get(i), hi.get(i)].into_iter().flatten() {
                        if self.shown(*v, true) {
                            grow(&mut ys, *v);
                        }
                    }
                }
            }
        }
        for v in &self.vlines {
            if self.shown(v.x, false) {
                grow(&mut xs, v.x);
            }
        }
        let fixed = self
            .y_range
            .map(|(a, b)| (a.min(b), a.max(b)))
            .filter(|&(a, b)| self.shown(a, true) && self.shown(b, true) && b > a && (b - a).is_finite());
        let fixed_x = self
            .x_range
            .map(|(a, b)| (a.min(b), a.max(b)))
            .filter(|&(a, b)| self.shown(a, false) && self.shown(b, false) && b > a && (b - a).is_finite());
        // A log axis gets 2 % of its decades each side: a tick on the data's edge (the 1 µs of a
        // DCS K(T)) is otherwise lost to rounding at the boundary (issue 37).
        let xs = fixed_x.unwrap_or_else(|| pad(xs, self.log_x, if self.log_x { 0.02 } else { 0.0 }));
        (bound(xs), bound(fixed.unwrap_or_else(|| pad(ys, self.log_y, 0.05))))
    }
}

/// A finite, non-empty axis range from data limits, with `margin` of the span (of the decades on
/// a log axis) on each side.
fn pad((lo, hi): (f64, f64), log: bool, margin: f64) -> (f64, f64) {
    if log {
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0) {
            return (1.0, 10.0);
        }
        let (a, b) = pad((lo.log10(), hi.log10()), false, margin);
        // Ticks fall on powers of ten: an axis holding fewer than two of them is widened to the
        // decades around its data (issue 37: converge.png had a single tick, or none).
        let (a, b) = if b.floor() - a.ceil() < 1.0 { (a.floor(), b.ceil().max(a.floor() + 1.0)) } else { (a, b) };
        return (10f64.powf(a), 10f64.powf(b));
    }
    if !(lo.is_finite() && hi.is_finite()) || lo > hi {
        return (0.0, 1.0);
    }
    if hi - lo == 0.0 {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        return (lo - d, hi + d);
    }
    let p = margin * (hi - lo);
    if (hi - lo + 2.0 * p).is_finite() { (lo - p, hi + p) } else { (lo, hi) }
}

/// A range plotters can lay ticks on: within ±1e250 (a span near the largest float makes its
/// tick search overflow and never end); an emptied range widened.
fn bound((lo, hi): (f64, f64)) -> (f64, f64) {
    const B: f64 = 1e250;
    let (lo, hi) = (lo.clamp(-B, B), hi.clamp(-B, B));
    if hi > lo { (lo, hi) } else { (lo, lo + lo.abs().max(1.0)) }
}

/// Runs of consecutive points for which `ok` holds.
fn runs<T: Copy>(points: &[T], ok: impl Fn(&T) -> bool) -> Vec<Vec<T>> {
    let mut out: Vec<Vec<T>> = vec![];
    let mut cur = vec![];
    for p in points {
        if ok(p) {
            cur.push(*p);
        } else if !cur.is_empty() {
            out.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

impl Draw for LinePlot {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Vec<Raster>, DB> {
        let (xr, yr) = self.ranges();
        match (self.log_x, self.log_y) {
            (false, false) => self.draw_on(root, xr.0..xr.1, yr.0..yr.1),
            (true, false) => self.draw_on(root, (xr.0..xr.1).log_scale(), yr.0..yr.1),
            (false, true) => self.draw_on(root, xr.0..xr.1, (yr.0..yr.1).log_scale()),
            (true, true) => self.draw_on(root, (xr.0..xr.1).log_scale(), (yr.0..yr.1).log_scale()),
        }?;
        Ok(vec![])
    }
}

impl LinePlot {
    fn draw_on<DB, X, Y>(&self, root: &DrawingArea<DB, Shift>, xs: X, ys: Y) -> DrawResult<(), DB>
    where
        DB: DrawingBackend,
        X: AsRangedCoord<Value = f64>,
        Y: AsRangedCoord<Value = f64>,
        X::CoordDescType: ValueFormatter<f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let (xr, yr) = self.ranges();
        let (body, note_area) = root.split_vertically(self.size.1 as i32 - if self.note.is_empty() { 0 } else { 26 });
        let mut chart = ChartBuilder::on(&body)
            .caption(&self.title, (FAMILY, 22))
            .margin(14)
            .margin_right(24)
            .x_label_area_size(52)
            .y_label_area_size(78)
            .build_cartesian_2d(xs, ys)?;
        let x_step = tick_step(xr, self.log_x);
        let y_step = tick_step(yr, self.log_y);
        let (lx, ly) = (self.log_x, self.log_y);
        chart
            .configure_mesh()
            .light_line_style(RGBColor(240, 240, 240))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .axis_desc_style((FAMILY, 17))
            .label_style((FAMILY, 14))
            .x_labels(9)
            .y_labels(9)
            .x_label_formatter(&|v| tick_label(*v, if lx { *v } else { x_step }))
            .y_label_formatter(&|v| tick_label(*v, if ly { *v } else { y_step }))
            .draw()?;

        // Bands of x first, so that the curves are drawn over them.
        let mut labelled_span = false;
        for s in &self.spans {
            let (lo, hi) = (s.lo.max(xr.0), s.hi.min(xr.1));
            if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
                continue;
            }
            let c = rgb(s.color);
            let rect = Rectangle::new([(lo, yr.0), (hi, yr.1)], c.mix(0.13).filled());
            let a = chart.draw_series(std::iter::once(rect))?;
            if !s.label.is_empty() && !labelled_span {
                labelled_span = true;
                a.label(&s.label)
                    .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 22, y + 6)], c.mix(0.3).filled()));
            }
        }
        let clip_y = |y: f64| y.clamp(yr.0, yr.1);
        let in_x = |x: f64| x >= xr.0 && x <= xr.1;
        // Lines and markers outside the y range are left out (a gap), not drawn along its edge.
        let visible =
            |&(x, y): &(f64, f64)| self.shown(x, false) && self.shown(y, true) && in_x(x) && y >= yr.0 && y <= yr.1;
        for c in &self.curves {
            let color = rgb(c.color);
            if let Some((lo, hi)) = &c.band {
                let pts: Vec<(f64, f64, f64)> =
                    c.x.iter().zip(lo.iter().zip(hi)).map(|(&x, (&l, &h))| (x, l, h)).collect();
                // A lower bound below the axis (or ≤ 0 in dB: NaN) is drawn at the axis bottom.
                let pts: Vec<(f64, f64, f64)> =
                    pts.into_iter().map(|(x, l, h)| (x, if self.shown(l, true) { l } else { yr.0 }, h)).collect();
                for run in runs(&pts, |p| self.shown(p.0, false) && self.shown(p.2, true) && in_x(p.0)) {
                    let mut poly: Vec<(f64, f64)> = run.iter().map(|p| (p.0, clip_y(p.2))).collect();
                    poly.extend(run.iter().rev().map(|p| (p.0, clip_y(p.1))));
                    chart.draw_series(std::iter::once(Polygon::new(poly, color.mix(0.22).filled())))?;
                }
            }
        }
        for c in &self.curves {
            let color = rgb(c.color);
            let pts: Vec<(f64, f64)> = c.points().collect();
            let drawn: Vec<(f64, f64)> = pts.iter().copied().filter(visible).collect();
            if drawn.is_empty() {
                continue;
            }
            let line = matches!(c.mark, Mark::Line | Mark::Dashed | Mark::LineMarkers);
            let markers = matches!(c.mark, Mark::Markers | Mark::LineMarkers | Mark::Stems);
            let style = color.stroke_width(2);
            if c.mark == Mark::Stems {
                for &(x, y) in &drawn {
                    chart.draw_series(std::iter::once(PathElement::new(vec![(x, yr.0), (x, y)], style)))?;
                }
            }
            if line {
                for run in runs(&pts, visible) {
                    // An isolated point has no segment: a small dot shows it.
                    if run.len() == 1 {
                        chart.draw_series(std::iter::once(Circle::new(run[0], 2, color.filled())))?;
                    } else if c.mark == Mark::Dashed {
                        chart.draw_series(DashedLineSeries::new(run, 8, 5, style))?;
                    } else {
                        chart.draw_series(LineSeries::new(run, style))?;
                    }
                }
            }
            for (i, &(x, y)) in pts.iter().enumerate() {
                if !visible(&(x, y)) {
                    continue;
                }
                let bar =
                    |e: Option<&Vec<f64>>| e.and_then(|e| e.get(i)).copied().filter(|e| e.is_finite() && *e > 0.0);
                if let Some(e) = bar(c.y_err.as_ref()) {
                    let (a, b) = (clip_y(if self.shown(y - e, true) { y - e } else { yr.0 }), clip_y(y + e));
                    chart.draw_series(std::iter::once(PathElement::new(vec![(x, a), (x, b)], style)))?;
                }
                if let Some(e) = bar(c.x_err.as_ref()) {
                    let (a, b) = ((x - e).max(xr.0), (x + e).min(xr.1));
                    let a = if self.shown(a, false) { a } else { xr.0 };
                    chart.draw_series(std::iter::once(PathElement::new(vec![(a, y), (b, y)], style)))?;
                }
            }
            if markers {
                chart.draw_series(drawn.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
            }
            if !c.label.is_empty() {
                // An empty series carries the legend entry of what was drawn.
                chart.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?.label(&c.label).legend(
                    move |(x, y)| {
                        EmptyElement::at((x, y))
                            + PathElement::new(vec![(0, 0), (22, 0)], color.stroke_width(2))
                            + Circle::new((11, 0), if markers { 4 } else { 0 }, color.filled())
                    },
                );
            }
        }
        for v in self.vlines.iter().filter(|v| in_x(v.x) && self.shown(v.x, false)) {
            let c = rgb(v.color);
            let a =
                chart.draw_series(DashedLineSeries::new(vec![(v.x, yr.0), (v.x, yr.1)], 6, 4, c.stroke_width(2)))?;
            if !v.label.is_empty() {
                a.label(&v.label).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], c.stroke_width(2)));
            }
        }
        let any = self.curves.iter().any(|c| c.points().any(|(x, y)| self.shown(x, false) && self.shown(y, true)));
        if !any {
            let (w, h) = body.dim_in_pixel();
            body.draw(&Text::new("no data", (w as i32 / 2 - 30, h as i32 / 2), (FAMILY, 20)))?;
        }
        chart
            .configure_series_labels()
            .position(self.legend_corner(xr, yr))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .label_font((FAMILY, 14))
            .draw()?;
        if !self.note.is_empty() {
            note_area.draw(&Text::new(
                self.note.as_str(),
                (16, 2),
                (FAMILY, 14).into_font().color(&RGBColor(70, 70, 70)),
            ))?;
        }
        Ok(())
    }
}

impl LinePlot {
    /// The corner of the plot whose legend covers the fewest drawn points (issue 37: legends over
    /// the data): the legend's box estimated from its entries (27 px each, 8 px a character, in
    /// the plot area of this size), the curves sampled along their segments in the axes' own
    /// (linear or log) coordinates; ties go to the upper right, then upper left, lower right,
    /// lower left.
    fn legend_corner(&self, xr: (f64, f64), yr: (f64, f64)) -> SeriesLabelPosition {
        let labels: Vec<&str> = self
            .curves
            .iter()
            .map(|c| c.label.as_str())
            .chain(self.spans.iter().map(|s| s.label.as_str()))
            .chain(self.vlines.iter().map(|v| v.label.as_str()))
            .filter(|l| !l.is_empty())
            .collect();
        let note = if self.note.is_empty() { 0.0 } else { 26.0 };
        let (pw, ph) = ((self.size.0 as f64 - 130.0).max(100.0), (self.size.1 as f64 - 150.0 - note).max(100.0));
        let widest = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0) as f64;
        // Measured on the drawn figures: about 27 px an entry and 8 px a character.
        let w = ((widest * 8.0 + 60.0) / pw).min(0.6);
        let h = ((labels.len() as f64 * 27.0 + 20.0) / ph).min(0.9);
        let unit = |v: f64, (lo, hi): (f64, f64), log: bool| {
            if log { (v.ln() - lo.ln()) / (hi.ln() - lo.ln()) } else { (v - lo) / (hi - lo) }
        };
        let to_unit = |(x, y): (f64, f64)| (unit(x, xr, self.log_x), unit(y, yr, self.log_y));
        let corners = [
            (SeriesLabelPosition::UpperRight, (1.0 - w, 1.0), (1.0 - h, 1.0)),
            (SeriesLabelPosition::UpperLeft, (0.0, w), (1.0 - h, 1.0)),
            (SeriesLabelPosition::LowerRight, (1.0 - w, 1.0), (0.0, h)),
            (SeriesLabelPosition::LowerLeft, (0.0, w), (0.0, h)),
        ];
        let mut covered = [0usize; 4];
        let shown = |p: &(f64, f64)| self.shown(p.0, false) && self.shown(p.1, true);
        for c in &self.curves {
            let pts: Vec<(f64, f64)> = c.points().filter(shown).map(to_unit).collect();
            // Each segment sampled at 8 points, so that a sparse curve's lines count too.
            let samples = pts.windows(2).flat_map(|s| {
                (0..8).map(move |k| {
                    let t = k as f64 / 8.0;
                    (s[0].0 + t * (s[1].0 - s[0].0), s[0].1 + t * (s[1].1 - s[0].1))
                })
            });
            for (u, v) in samples.chain(pts.last().copied()) {
                for (k, (_, xs, ys)) in corners.iter().enumerate() {
                    if (xs.0..=xs.1).contains(&u) && (ys.0..=ys.1).contains(&v) {
                        covered[k] += 1;
                    }
                }
            }
        }
        let best = (0..4).min_by_key(|&k| (covered[k], k)).unwrap_or(0);
        corners[best].0.clone()
    }
}

/// The spacing of about 9 nice ticks over `r` (for the decimals of the labels).
fn tick_step((lo, hi): (f64, f64), log: bool) -> f64 {
    if log {
        return 0.0;
    }
    let raw = (hi - lo) / 9.0;
    if !(raw > 0.0 && raw.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * p).find(|s| *s >= raw).unwrap_or(10.0 * p)
}

/// The y range for spectra in dB: from `depth` dB below the highest finite value to 3 dB above.
pub fn db_range<'a>(values: impl IntoIterator<Item = &'a f64>, depth: f64) -> Option<(f64, f64)> {
    let top = values.into_iter().copied().filter(|v| v.is_finite()).fold(f64::NEG_INFINITY, f64::max);
    top.is_finite().then_some((top - depth, top + 3.0))
}

#[cfg(test)]
mod tests {
    use super::super::render;
    use super::super::tests::check_figure;
    use super::*;

    fn count(rgb: &[u8], c: [u8; 3]) -> usize {
        rgb.chunks_exact(3).filter(|p| *p == c).count()
    }

    #[test]
    fn every_curve_band_and_marker_is_drawn() {
        let x: Vec<f64> = (0..200).map(|i| i as f64 * 0.05 - 5.0).collect();
        let y: Vec<f64> = x.iter().map(|x| -30.0 + 10.0 * x.sin()).collect();
        let gap: Vec<f64> = x.iter().map(|x| if x.abs() < 1.0 { f64::NAN } else { -x * x }).collect();
        let mut p = LinePlot::new("test", "frequency (kHz)", "power (dB)");
        let mut a = Curve::line("sin", x.clone(), y.clone(), [200, 0, 0]);
        a.band = Some((y.iter().map(|v| v - 3.0).collect(), y.iter().map(|v| v + 3.0).collect()));
        p.curves.push(a);
        p.curves.push(Curve::line("parabola with a gap", x.clone(), gap, [0, 0, 200]));
        p.spans.push(Span { lo: 1.0, hi: 2.0, label: "band".into(), color: [0, 150, 0] });
        p.vlines.push(VLine { x: -2.0, label: "peak".into(), color: [150, 0, 150] });
        p.note = "a note".into();
        let f = render(&p).unwrap();
        let (_, _, rgb) = check_figure(&f, SIZE);
        assert!(count(&rgb, [200, 0, 0]) > 200 && count(&rgb, [0, 0, 200]) > 200 && count(&rgb, [150, 0, 150]) > 50);
        assert!(f.svg.contains("parabola with a gap") && f.svg.contains("a note") && f.svg.contains("band"));
    }

    #[test]
    fn degenerate_data_draws_a_figure() {
        let nan = vec![f64::NAN; 4];
        let x4 = vec![0.0, 1.0, 2.0, 3.0];
        let cases: Vec<Vec<Curve>> = vec![
            vec![],
            vec![Curve::line("empty", vec![], vec![], PALETTE[0])],
            vec![Curve::line("nan", x4.clone(), nan.clone(), PALETTE[1])],
            vec![Curve::line("one", vec![1.0], vec![1.0], PALETTE[2])],
            vec![Curve::line("flat", x4.clone(), vec![2.0; 4], PALETTE[3])],
            vec![Curve::line("huge", x4.clone(), vec![-f64::MAX, f64::MAX, 0.0, 1.0], PALETTE[4])],
            vec![Curve {
                band: Some((vec![], vec![])),
                ..Curve::line("empty band", x4.clone(), x4.clone(), PALETTE[5])
            }],
        ];
        for curves in cases {
            for (log_x, log_y) in [(false, false), (true, true)] {
                for y_range in [None, Some((1.0, 1.0)), Some((f64::NAN, 0.0))] {
                    let p = LinePlot { curves: curves.clone(), log_x, log_y, y_range, ..LinePlot::new("t", "x", "y") };
                    check_figure(&render(&p).unwrap(), SIZE);
                }
            }
        }
        // Error bars on log axes reaching below zero stop at the axis.
        let mut c = Curve::line("err", vec![1.0, 10.0], vec![0.1, 0.01], PALETTE[0]);
        c.y_err = Some(vec![0.5, 0.05]);
        c.mark = Mark::Markers;
        let p = LinePlot { curves: vec![c], log_x: true, log_y: true, ..LinePlot::new("t", "x", "y") };
        check_figure(&render(&p).unwrap(), SIZE);
    }
}
