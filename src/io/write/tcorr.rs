//! A surface detector's time-resolved and correlation outputs ([`crate::detect::time`],
//! [`crate::detect::correlation`]): their axes, arrays, manifest entries and figures — the TPSF
//! on a log y axis with ±σ, a few gates of a time-gated image, g1 and g2 against τ on a log axis
//! with ±σ, K against the exposure time, and the speckle-contrast image with its colour bar.

use std::collections::BTreeMap;

use serde_json::{Value, json};

use super::figures::{image_panel, stem};
use super::{Entry, Writer, estimate};
use crate::detect::{CorrelationLayout, CorrelationSpec, TimeLayout, TimeSpec};
use crate::error::Result;
use crate::io::figures::image::ImageFigure;
use crate::io::figures::lines::{Curve, LinePlot, Mark, PALETTE};
use crate::output::{Kind, Output};

/// Panels drawn of an image stack (evenly spread over its layers).
const STACK_PANELS: usize = 4;

/// The TPSF (and time-gated image) of detector `name`, its time axis and out-of-range tallies
/// (into `de`); returns the manifest entry.
pub fn write_time(
    w: &mut Writer,
    name: &str,
    spec: &TimeSpec,
    lay: &TimeLayout,
    de: &mut BTreeMap<String, Entry>,
) -> Result<Value> {
    let bins = spec.axis.bins;
    let centres: Vec<f64> = (0..bins).map(|k| spec.axis.center(k)).collect();
    let time_file = format!("{name}_time_s.npy");
    w.axis_file(time_file.clone(), "time_s", "s", &centres)?;
    let o = w.registry.at(lay.tpsf);
    let (v, e) = w.array(o)?;
    let ((below, above), (below_se, above_se)) = (o.tails(w.mean, 0), o.tails(w.stderr, 0));
    let tails = [("below", estimate(below, below_se)), ("above", estimate(above, above_se))];
    de.insert("tpsf_out_of_range".into(), Entry::Group(tails.map(|(k, e)| (k.to_string(), Entry::Estimate(e))).into()));
    if w.figures {
        // Picoseconds below 100 ns of axis: whole numbers label the ticks exactly.
        let (scale, unit) = if spec.axis.f_max < 100e-9 { (1e12, "ps") } else { (1e9, "ns") };
        let x: Vec<f64> = centres.iter().map(|t| t * scale).collect();
        let mut plot = LinePlot::new(
            format!("{name}: temporal point-spread function"),
            format!("time of flight ({unit})"),
            "power per time bin (fraction of emitted)",
        );
        plot.log_y = true;
        plot.curves.push(band_curve("TPSF", x, &v, &e, PALETTE[0]));
        // Six decades below the peak: a band reaching zero would stretch the log axis to nothing.
        let peak = v.iter().fold(0.0_f64, |m, &x| m.max(x));
        if peak > 0.0 {
            plot.y_range = Some((peak * 1e-6, peak * 2.0));
        }
        plot.note = format!(
            "band: ±σ; y: 6 decades below the peak; bin {} {unit}; power out of the axis: {} before, {} after",
            crate::describe::num(spec.axis.bin_width() * scale),
            crate::describe::num(below),
            crate::describe::num(above)
        );
        w.figure(&stem(o), &plot)?;
    }
    let mut entry = json!({
        "t_min_s": spec.axis.f_min,
        "t_max_s": spec.axis.f_max,
        "bins": bins,
        "bin_width_s": spec.axis.bin_width(),
        "time_file": time_file,
        "time_of_flight": "optical path length / c, from emission to the detector plane",
        "units": "fraction of emitted power per time bin",
    });
    if let Some(o) = lay.image.map(|s| w.registry.at(s)) {
        let (v, _) = w.array(o)?;
        let labels: Vec<String> = centres.iter().map(|t| format!("t = {:.3} ns", t * 1e9)).collect();
        stack_figure(w, o, &v, &labels, "fraction of emitted power")?;
        entry["image_file"] = json!(o.file);
        entry["image_layout"] = json!("[time bin][row][col], row 0 = largest y");
    }
    Ok(entry)
}

/// g1, g2 and the speckle contrast of detector `name`, with their τ and exposure axes; returns
/// the manifest entry.
pub fn write_correlation(w: &mut Writer, name: &str, spec: &CorrelationSpec, lay: &CorrelationLayout) -> Result<Value> {
    let n = spec.tau.len();
    let tau_file = format!("{name}_tau_s.npy");
    w.axis_file(tau_file.clone(), "tau_s", "s", &spec.tau)?;
    curves(w, name, spec, (lay.g1, lay.g2, lay.contrast))?;
    let mut entry = json!({
        "tau_file": tau_file,
        "points": n,
        "beta": spec.beta,
        "g1_layout": "[0] real part, [1] imaginary part, per delay",
        "normalisation": "over the run: ratios of the run's means, |g1|² unbiased in numerator and denominator; σ: jackknife over 16 groups of batches",
    });
    if !spec.exposures.is_empty() {
        let exposure_file = format!("{name}_exposure_s.npy");
        w.axis_file(exposure_file.clone(), "exposure_s", "s", &spec.exposures)?;
        entry["exposure_file"] = json!(exposure_file);
        if let Some(o) = lay.pixel_contrast.map(|s| w.registry.at(s)) {
            contrast_image_figure(w, o, spec)?;
            entry["image_file"] = json!(o.file);
            entry["image_layout"] = json!("[exposure][row][col], row 0 = largest y; NaN: too few paths");
        }
    }
    if !spec.rois.is_empty() {
        let mut rois = serde_json::Map::new();
        let (n, nt) = (spec.tau.len(), spec.exposures.len());
        for (r, roi) in spec.rois.iter().enumerate() {
            let key = format!("{name}.roi_{}", roi.name);
            // Each ROI's g1, g2 and K, in the order CorrelationSpec::declare lays them out.
            let base = lay.roi_outputs + r * (3 * n + nt);
            curves(w, &key, spec, (base, base + 2 * n, base + 3 * n))?;
            let file = |what: &str| json!(format!("{name}_roi_{}_{what}.npy", roi.name));
            let mut e = json!({ "g1_file": file("g1"), "g2_file": file("g2") });
            if !spec.exposures.is_empty() {
                e["speckle_contrast_file"] = file("speckle_contrast");
            }
            rois.insert(roi.name.clone(), e);
        }
        entry["rois"] = Value::Object(rois);
    }
    Ok(entry)
}

/// g1, g2 and K (a detector's or an ROI's, `key` in their titles) as files and figures, from
/// the outputs at their slots `(g1, g2, K)`.
fn curves(w: &mut Writer, key: &str, spec: &CorrelationSpec, (g1, g2, k): (usize, usize, usize)) -> Result<()> {
    let (n, name) = (spec.tau.len(), key.replace('.', " "));
    let (o1, o2, ok) = (w.registry.at(g1), w.registry.at(g2), k);
    let (g1, g1e) = w.array(o1)?;
    let (g2, g2e) = w.array(o2)?;
    if w.figures {
        let mut plot =
            LinePlot::new(format!("{name}: field and intensity autocorrelation"), "delay τ (s)", "g1, g2 − 1");
        plot.log_x = true;
        plot.curves.push(band_curve("Re g1", spec.tau.clone(), &g1[..n], &g1e[..n], PALETTE[0]));
        if g1[n..].iter().any(|x| x.abs() > 1e-12) {
            plot.curves.push(band_curve("Im g1", spec.tau.clone(), &g1[n..], &g1e[n..], PALETTE[2]));
        }
        let g2m1: Vec<f64> = g2.iter().map(|g| g - 1.0).collect();
        plot.curves.push(band_curve(&format!("g2 − 1 (β = {})", spec.beta), spec.tau.clone(), &g2m1, &g2e, PALETTE[1]));
        plot.note = "band: ±σ (jackknife over groups of batches)".into();
        w.figure(&stem(o2), &plot)?;
    }
    if !spec.exposures.is_empty() {
        let nt = spec.exposures.len();
        let ok = w.registry.at(ok);
        let (k, ke) = w.array(ok)?;
        if w.figures {
            let mut plot = LinePlot::new(format!("{name}: speckle contrast"), "exposure time T (s)", "K");
            // K lies in [0, √β], often within one decade: a linear y axis labels it (a log axis
            // showed a single tick).
            plot.log_x = true;
            let mut c = Curve::line("K(T)", spec.exposures.clone(), k.clone(), PALETTE[0]);
            c.y_err = Some(ke.clone());
            c.mark = Mark::LineMarkers;
            plot.curves.push(c);
            // The long-exposure law K ∝ T^−½, through the longest exposure, for comparison.
            let (t_last, k_last) = (spec.exposures[nt - 1], k[nt - 1]);
            if nt > 1 && k_last > 0.0 {
                let law: Vec<f64> = spec.exposures.iter().map(|t| k_last * (t_last / t).sqrt()).collect();
                let mut c = Curve::line("∝ T^−½", spec.exposures.clone(), law, PALETTE[6]);
                c.mark = Mark::Dashed;
                plot.curves.push(c);
            }
            let top = k.iter().zip(&ke).map(|(k, e)| k + e).filter(|x| x.is_finite()).fold(spec.beta.sqrt(), f64::max);
            plot.y_range = Some((0.0, 1.05 * top));
            plot.note = format!("error bars: ±σ; β = {} (K → √β as T → 0)", spec.beta);
            w.figure(&stem(ok), &plot)?;
        }
    }
    Ok(())
}

/// The speckle contrast image `o` at the middle exposure, with its σ beside it (NaN pixels —
/// too few paths for a defined |g1|² or σ — grey in both).
fn contrast_image_figure(w: &mut Writer, o: &Output, spec: &CorrelationSpec) -> Result<()> {
    let Kind::ImageStack { layers, nx, ny, min, max } = o.kind else { return Ok(()) };
    let (v, e) = w.array(o)?;
    if !w.figures || layers == 0 {
        return Ok(());
    }
    let j = layers / 2;
    let layer = Output { kind: Kind::Image { nx, ny, min, max }, ..o.clone() };
    let (k, ke) = (&v[j * nx * ny..(j + 1) * nx * ny], &e[j * nx * ny..(j + 1) * nx * ny]);
    let undefined = k.iter().filter(|x| !x.is_finite()).count();
    let title = format!("K at T = {:.3} ms", spec.exposures[j] * 1e3);
    let mut kp = image_panel(&layer, k, &title, "speckle contrast K", false);
    kp.caption = format!("0 to the 99.5th percentile; grey: too few paths ({undefined})");
    let mut ep = image_panel(&layer, ke, "σ(K), jackknife", "σ(K)", false);
    ep.caption = format!("0 to the 99.5th percentile; grey: undefined ({undefined})");
    w.figure(&stem(o), &ImageFigure { panels: vec![kp, ep] })
}

/// A curve with a ±σ band.
fn band_curve(label: &str, x: Vec<f64>, v: &[f64], e: &[f64], color: [u8; 3]) -> Curve {
    let mut c = Curve::line(label, x, v.to_vec(), color);
    c.band = Some((v.iter().zip(e).map(|(a, s)| a - s).collect(), v.iter().zip(e).map(|(a, s)| a + s).collect()));
    c
}

/// Up to [`STACK_PANELS`] layers of an image stack `o` (values `v` as written), each with its
/// colour bar in `unit`, titled by `labels`.
fn stack_figure(w: &mut Writer, o: &Output, v: &[f64], labels: &[String], unit: &str) -> Result<()> {
    let Kind::ImageStack { layers, nx, ny, min, max } = o.kind else { return Ok(()) };
    if !w.figures || layers == 0 {
        return Ok(());
    }
    let layer = Output { kind: Kind::Image { nx, ny, min, max }, ..o.clone() };
    let picks: Vec<usize> = if layers <= STACK_PANELS {
        (0..layers).collect()
    } else {
        (0..STACK_PANELS).map(|j| j * (layers - 1) / (STACK_PANELS - 1)).collect()
    };
    let panels = picks
        .into_iter()
        .map(|j| {
            let values = &v[j * nx * ny..(j + 1) * nx * ny];
            image_panel(&layer, values, &labels[j], unit, false)
        })
        .collect();
    w.figure(&stem(o), &ImageFigure { panels })
}
