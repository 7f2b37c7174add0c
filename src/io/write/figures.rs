//! What each output is drawn as (issue 22: a figure for every output): the figures are built here
//! from the values the writers hold, and written by [`Writer::figure`] as `<stem>.png` and
//! `<stem>.svg` (`<detector>_<output>`), listed in the manifest like every file, unless the run
//! asked for none (`--no-figures`).
//!
//! - images: axes in mm, colour bar in the output's unit, 0 to the 99.5th percentile (signed
//!   images: ± the 99.5th percentile of |value|), a main image with its per-pixel relative error
//!   as a second panel;
//! - spectra: dB of the power per bin with a ±σ band, every channel with power drawn (the others
//!   named under the plot), 60 dB below the peak, and an LDH camera's M0 band shaded.

use super::Writer;
use crate::error::{Error, Result};
use crate::io::figures::image::{ImageFigure, Panel, hsv};
use crate::io::figures::lines::{Curve, LinePlot, Mark, PALETTE, Span, VLine, db_range};
use crate::io::figures::scale::{Colormap, TOP_QUANTILE, db, quantile, sequential_range, symmetric_range};
use crate::io::figures::{Draw, Figure, render};
use crate::output::{Kind, Output, PixelErrors, Style};

/// Dynamic range of spectra and maps below their peak, dB.
pub const DB_DEPTH: f64 = 60.0;

/// `camera.m0_plus` → `camera_m0_plus`: the stem of an output's figure.
pub fn stem(o: &Output) -> String {
    o.name.replace('.', "_")
}

/// `d` drawn; a failure is an error writing `path` (the PNG's).
pub fn drawn(d: &impl Draw, path: std::path::PathBuf) -> Result<Figure> {
    render(d).map_err(|m| Error::Write { path, source: std::io::Error::other(m) })
}

impl Writer<'_, '_> {
    /// Write `d` as `<stem>.png` and `<stem>.svg`, unless figures are off.
    pub fn figure(&mut self, stem: &str, d: &impl Draw) -> Result<()> {
        if !self.figures {
            return Ok(());
        }
        let f = drawn(d, format!("{stem}.png").into())?;
        self.put(format!("{stem}.png"), f.png)?;
        self.put(format!("{stem}.svg"), f.svg.into_bytes())
    }

    /// The figure of the image output `o` (values `v`, row 0 at the top, standard errors `e`):
    /// a main output with its relative-error map beside it, on a diverging map over a symmetric
    /// range where its declaration says so ([`Style::Diverging`]).
    pub fn image_figure(&mut self, o: &Output, v: &[f64], e: &[f64], title: &str, unit: &str) -> Result<()> {
        if !self.figures {
            return Ok(());
        }
        let mut panels = vec![match o.style {
            Style::Spread => spread_panel(o, v, title, unit),
            style => image_panel(o, v, title, unit, style == Style::Diverging),
        }];
        if o.primary {
            panels.push(error_panel(o, v, e));
        }
        self.figure(&stem(o), &ImageFigure { panels })
    }
}

/// The extent of an image output in mm: ((left, right), (bottom, top)).
fn extent_mm(o: &Output) -> ((f64, f64), (f64, f64), (usize, usize)) {
    match o.kind {
        Kind::Image { nx, ny, min, max } => ((1e3 * min[0], 1e3 * max[0]), (1e3 * min[1], 1e3 * max[1]), (nx, ny)),
        _ => ((0.0, 1.0), (0.0, 1.0), (1, 1)),
    }
}

/// How many values lie above `hi` (saturated).
fn above(v: &[f64], hi: f64) -> usize {
    v.iter().filter(|&&x| x > hi).count()
}

/// The caption of an image zero at every pixel, drawn grey without a colour scale
/// ([`crate::io::figures::image::ZERO_EVERYWHERE`]).
const ZERO_CAPTION: &str = "every pixel is exactly 0: drawn grey, without a colour scale";

/// An image panel of `v` on the grid of `o`: sequential from 0, or diverging if `signed`.
pub fn image_panel(o: &Output, v: &[f64], title: &str, unit: &str, signed: bool) -> Panel {
    let (x, y, n) = extent_mm(o);
    let (cmap, range) =
        if signed { (Colormap::Diverging, symmetric_range(v)) } else { (Colormap::Viridis, sequential_range(v)) };
    let mut p = Panel::new(title, v.to_vec(), n, x, y, cmap, range, unit);
    if v.iter().all(|x| *x == 0.0) {
        p.caption = ZERO_CAPTION.into();
        return p;
    }
    let sat = if signed { v.iter().filter(|x| x.abs() > range.1).count() } else { above(v, range.1) };
    p.caption = format!(
        "colour scale: {} the {:.1}th percentile{}; {} pixels saturate",
        if signed { "± " } else { "0 to" },
        100.0 * TOP_QUANTILE,
        if signed { " of |value|" } else { "" },
        sat
    );
    p
}

/// An image panel of `v` on the grid of `o`, sequential between the 0.5th and the 99.5th
/// percentiles of its values ([`Style::Spread`]).
fn spread_panel(o: &Output, v: &[f64], title: &str, unit: &str) -> Panel {
    let (x, y, n) = extent_mm(o);
    let lo = quantile(v, 1.0 - TOP_QUANTILE).unwrap_or(0.0);
    let hi = quantile(v, TOP_QUANTILE).unwrap_or(1.0);
    let range = if hi > lo { (lo, hi) } else { (lo, lo + 1.0) };
    let mut p = Panel::new(title, v.to_vec(), n, x, y, Colormap::Viridis, range, unit);
    let outside = v.iter().filter(|&&x| x < range.0 || x > range.1).count();
    // Short enough for the panel's width (grey pixels: no signal, as in every image).
    p.caption = format!(
        "colour scale: {:.1}th–{:.1}th percentile; {outside} pixels outside",
        100.0 * (1.0 - TOP_QUANTILE),
        100.0 * TOP_QUANTILE
    );
    p
}

/// The per-pixel relative error `σ/|value|` of `o` in %, grey where the value is 0.
fn error_panel(o: &Output, v: &[f64], e: &[f64]) -> Panel {
    let (x, y, n) = extent_mm(o);
    let pe = PixelErrors::of(v, e);
    // Of an output zero everywhere, no error either: a blank panel.
    let zero = v.iter().all(|x| *x == 0.0);
    let pct: Vec<f64> = if zero { vec![0.0; v.len()] } else { pe.map.iter().map(|r| 100.0 * r).collect() };
    // Up to 100 %: beyond that a pixel has no meaningful value; a map of small errors keeps detail.
    let hi = quantile(&pct, TOP_QUANTILE).unwrap_or(100.0).clamp(1e-6, 100.0);
    let mut p = Panel::new(
        format!("relative error (median {:.1} %)", 100.0 * pe.median),
        pct,
        n,
        x,
        y,
        Colormap::Viridis,
        (0.0, hi),
        "σ / |value| (%)",
    );
    p.caption =
        format!("grey: no signal ({} pixels); 0 to the {:.1}th percentile", pe.without_signal, 100.0 * TOP_QUANTILE);
    p
}

/// The directional composite of an LDH camera's M0± images (on the grid of `o`): hue red where
/// M0− > 0 (receding), blue where < 0, saturation the asymmetry |M0−|/M0+, brightness M0+ up to
/// its 99.5th percentile (so fireflies do not darken the image).
pub fn directional(o: &Output, m0p: &[f64], m0m: &[f64], title: &str) -> ImageFigure {
    let (x, y, n) = extent_mm(o);
    let (_, top) = sequential_range(m0p);
    let asym: Vec<f64> =
        m0p.iter().zip(m0m).map(|(&p, &m)| if p > 0.0 { (m / p).clamp(-1.0, 1.0) } else { 0.0 }).collect();
    let colors = m0p
        .iter()
        .zip(&asym)
        .map(|(&p, &a)| if p.is_finite() { hsv(if a >= 0.0 { 0.0 } else { 240.0 }, a.abs(), p / top) } else { [0; 3] })
        .collect();
    let mut p = Panel::new(
        title,
        asym,
        n,
        x,
        y,
        Colormap::Diverging,
        (-1.0, 1.0),
        "M0− / M0+ (blue approaching, red receding)",
    );
    p.colors = Some(colors);
    p.caption =
        format!("brightness: M0+, 0 to its {:.1}th percentile; hue and saturation: M0− / M0+", 100.0 * TOP_QUANTILE);
    ImageFigure { panels: vec![p] }
}

/// A frequency axis unit for values up to `max_abs` Hz: (divisor, name).
pub fn frequency_unit(max_abs: f64) -> (f64, &'static str) {
    match max_abs {
        m if m >= 1e9 => (1e9, "GHz"),
        m if m >= 1e6 => (1e6, "MHz"),
        m if m >= 1e3 => (1e3, "kHz"),
        _ => (1.0, "Hz"),
    }
}

/// A spectrum channel to draw: name, values and standard errors per bin.
pub struct Channel<'a> {
    pub name: &'a str,
    pub values: &'a [f64],
    pub stderr: &'a [f64],
}

/// A channel's name as a figure shows it: the names of the outputs' channels
/// (`single_doppler`, `order>=3`, `doppler_events=0`) in words (issue 37: legends showed code
/// identifiers). Unknown names are shown as they are.
pub fn channel_label(name: &str) -> String {
    let plural = |n: &str, what: &str| if n == "1" { format!("{n} {what}") } else { format!("{n} {what}s") };
    match name {
        "static" => "static (no Doppler event)".into(),
        "single_doppler" => "one Doppler event".into(),
        "multiple_doppler" => "several Doppler events".into(),
        _ => {
            for (key, what) in [("order", "scattering event"), ("doppler_events", "Doppler event")] {
                if let Some(n) = name.strip_prefix(key).and_then(|r| r.strip_prefix(">=")) {
                    return format!("{} or more", plural(n, what));
                }
                if let Some(n) = name.strip_prefix(key).and_then(|r| r.strip_prefix('=')) {
                    return plural(n, what);
                }
            }
            name.replace('_', " ")
        }
    }
}

/// Spectra in dB with ±σ bands against frequency (`freq_hz`, bin centres): channels without any
/// power are named in the note instead of drawn; the y range is [`DB_DEPTH`] below the peak.
pub fn spectrum_plot(title: &str, freq_hz: &[f64], channels: &[Channel], y_label: &str) -> LinePlot {
    let (div, unit) = frequency_unit(freq_hz.iter().fold(0.0_f64, |m, f| m.max(f.abs())));
    let x: Vec<f64> = freq_hz.iter().map(|f| f / div).collect();
    let mut plot = LinePlot::new(title, format!("frequency ({unit})"), y_label);
    let mut empty = Vec::new();
    for (i, c) in channels.iter().enumerate() {
        let finite = c.values.iter().filter(|v| **v > 0.0).count();
        if finite == 0 {
            empty.push(channel_label(c.name));
            continue;
        }
        let y: Vec<f64> = c.values.iter().map(|&v| db(v)).collect();
        let lo: Vec<f64> = c.values.iter().zip(c.stderr).map(|(&v, &s)| db(v - s)).collect();
        let hi: Vec<f64> = c.values.iter().zip(c.stderr).map(|(&v, &s)| db(v + s)).collect();
        let mut curve = Curve::line(channel_label(c.name), x.clone(), y, PALETTE[i % PALETTE.len()]);
        curve.band = Some((lo, hi));
        // A channel in a few bins (the static light at 0 Hz, an FMCW target's beat lines) would
        // be dots: drawn as lines on stems.
        if finite <= 3 {
            curve.mark = Mark::Stems;
        }
        plot.curves.push(curve);
    }
    plot.y_range = db_range(plot.curves.iter().flat_map(|c| &c.y), DB_DEPTH);
    let mut notes = vec![format!("band: ±σ; y: {DB_DEPTH:.0} dB below the peak")];
    // Lines narrower than a tenth of the axis (an FMCW target's beat lines: a bin or two each)
    // are zoomed onto, with their surroundings (issue 37: two dots in an empty box).
    if let Some((lo, _)) = plot.y_range {
        let lit: Vec<f64> = plot
            .curves
            .iter()
            .flat_map(|c| c.x.iter().zip(&c.y).filter(|(_, y)| y.is_finite() && **y >= lo).map(|(x, _)| *x))
            .collect();
        let (first, last) = lit.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        let (axis_lo, axis_hi) = (x.first().copied().unwrap_or(0.0), x.last().copied().unwrap_or(0.0));
        let bin = if x.len() > 1 { (axis_hi - axis_lo) / (x.len() - 1) as f64 } else { 0.0 };
        // Narrow: lit within a tenth of the axis, or in at most 2 % of its bins (a few lines).
        let sparse = lit.len() * 50 <= x.len() * plot.curves.len().max(1);
        if first.is_finite() && bin > 0.0 && (last - first < 0.1 * (axis_hi - axis_lo) || sparse) {
            let margin = (0.5 * (last - first)).max(8.0 * bin);
            plot.x_range = Some(((first - margin).max(axis_lo), (last + margin).min(axis_hi)));
            notes.push("x: zoomed onto the lines".into());
        }
    }
    if !empty.is_empty() {
        notes.push(format!("no power (not drawn): {}", empty.join(", ")));
    }
    plot.note = notes.join("; ");
    plot
}

/// Shade the band `[f1, f2]` Hz and its mirror `[−f2, −f1]` (M0 sums both sides) on a plot whose
/// x axis is in units of `div` Hz.
pub fn mark_band(plot: &mut LinePlot, (f1, f2): (f64, f64), div: f64, label: &str) {
    for (lo, hi) in [(f1, f2), (-f2, -f1)] {
        plot.spans.push(Span { lo: lo / div, hi: hi / div, label: label.into(), color: [0, 150, 80] });
    }
}

/// A vertical marker at `f` Hz on a plot in units of `div` Hz.
pub fn mark_frequency(plot: &mut LinePlot, f: f64, div: f64, label: String, color: [u8; 3]) {
    plot.vlines.push(VLine { x: f / div, label, color });
}

/// The spectrum figures of surface detector `i` (`name`): each spectrum output (total and its
/// splits) with all its channels; a chirped detector's up- and down-chirp totals in one figure
/// instead, with the beat frequencies read off (`fmcw`) marked and the range and velocity they
/// give in the title. `roles`: each output's chirp and split
/// ([`crate::detect::SpectrumLayout::role`]).
pub fn spectra_figures(
    w: &mut Writer,
    name: &str,
    outputs: &[&Output],
    roles: &[(&str, Option<&str>)],
    fmcw: Option<&crate::retrieval::FmcwEstimate>,
) -> Result<()> {
    if !w.figures {
        return Ok(());
    }
    let total = |chirp: &str| outputs.iter().zip(roles).find(|(_, r)| **r == (chirp, None)).map(|(o, _)| *o);
    let chirped = total("up").is_some();
    let axis_of = |o: &Output| -> Vec<f64> {
        match &o.kind {
            Kind::Spectrum { axis, mirrored, .. } => {
                let c: Vec<f64> = (0..axis.bins).map(|k| axis.center(k)).collect();
                if *mirrored { c.iter().rev().map(|f| -f).collect() } else { c }
            }
            _ => vec![],
        }
    };
    let names_of = |o: &Output| -> Vec<String> {
        match &o.kind {
            Kind::Spectrum { channels, .. } => channels.clone(),
            _ => vec![],
        }
    };
    if chirped {
        let mut totals = Vec::new();
        for chirp in ["up", "down"] {
            if let Some(o) = total(chirp) {
                let (v, e) = o.values(w.mean, w.stderr);
                let bins = axis_of(o).len().max(1);
                totals.push((
                    format!("{chirp}-chirp total"),
                    axis_of(o),
                    v[..bins.min(v.len())].to_vec(),
                    e[..bins.min(e.len())].to_vec(),
                ));
            }
        }
        let Some(freq) = totals.first().map(|t| t.1.clone()) else { return Ok(()) };
        let channels: Vec<Channel> =
            totals.iter().map(|t| Channel { name: &t.0, values: &t.2, stderr: &t.3 }).collect();
        let title = match fmcw {
            Some(f) => format!(
                "{name}: FMCW spectra, range {:.3} m, radial velocity {:.3} m/s",
                f.range_m, f.radial_velocity_m_per_s
            ),
            None => format!("{name}: FMCW spectra (no read-off)"),
        };
        let mut plot = spectrum_plot(&title, &freq, &channels, "power per bin (dB re emitted)");
        if let Some(f) = fmcw {
            let (div, unit) = frequency_unit(freq.iter().fold(0.0_f64, |m, f| m.max(f.abs())));
            mark_frequency(&mut plot, f.f_up_hz, div, format!("f_up = {:.4} {unit}", f.f_up_hz / div), PALETTE[0]);
            mark_frequency(
                &mut plot,
                f.f_down_hz,
                div,
                format!("f_down = {:.4} {unit}", f.f_down_hz / div),
                PALETTE[1],
            );
        }
        return w.figure(&format!("{name}_spectra"), &plot);
    }
    for (o, (chirp, split)) in outputs.iter().zip(roles) {
        let (v, e) = o.values(w.mean, w.stderr);
        let freq = axis_of(o);
        let bins = freq.len().max(1);
        let names = names_of(o);
        let channels: Vec<Channel> = names
            .iter()
            .zip(v.chunks_exact(bins).zip(e.chunks_exact(bins)))
            .map(|(n, (values, stderr))| Channel { name: n, values, stderr })
            .collect();
        let what = [*chirp, split.unwrap_or("")].into_iter().filter(|w| !w.is_empty()).collect::<Vec<_>>().join(" ");
        let what = what.replace('_', " ");
        let title = if what.is_empty() { format!("{name}: spectrum") } else { format!("{name}: spectrum {what}") };
        w.figure(&stem(o), &spectrum_plot(&title, &freq, &channels, "power per bin (dB re emitted)"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::channel_label;

    /// Legends and titles name channels in words, never by their code identifiers.
    #[test]
    fn channels_are_named_in_words() {
        for (name, label) in [
            ("single_doppler", "one Doppler event"),
            ("multiple_doppler", "several Doppler events"),
            ("static", "static (no Doppler event)"),
            ("order=1", "1 scattering event"),
            ("order=2", "2 scattering events"),
            ("order>=5", "5 scattering events or more"),
            ("doppler_events=0", "0 Doppler events"),
            ("doppler_events>=3", "3 Doppler events or more"),
            ("total", "total"),
        ] {
            assert_eq!(channel_label(name), label);
            assert!(!channel_label(name).contains(['_', '=']), "{name}");
        }
    }
}
