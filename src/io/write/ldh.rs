//! Outputs of an LDH camera: M0± (and M1, per-class) images as `.npy` and `.exr` with their
//! standard errors, PNG previews, ROI spectra (`.npy` and a dB plot), per-pixel spectra when asked,
//! and the ROIs' single-window speckle spectra. The sign flag of the set-up is applied here, and
//! only here (M0− and M1 keep their meaning, spectra are mirrored).

use std::collections::BTreeMap;

use serde_json::{Map, Value, json};

use super::figures::{Channel, directional, frequency_unit, mark_band, spectrum_plot, stem};
use super::{Entry, IMAGE_LAYOUT, OutputEntry, Writer, estimate};
use crate::detect::ImageSpec;
use crate::detect::ldh::{CLASS_NAMES, LdhLayout, LdhSpec, M1_UNITS, SPECTRUM_UNITS};
use crate::error::Result;
use crate::io::figures::image::ImageFigure;
use crate::output::{Axis, Output, rows_reversed};
use crate::post::{Finished, PixelSpeckle, RoiSpeckle, band_sums};

/// Mirror a periodogram in fftshift order: `ν_k = (k − N/2)Δ` goes to `−ν_k`, bin `N − k`; the
/// unpaired `−f_s/2` bin (k = 0) is its own alias.
fn mirror_fftshift(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    (0..n).map(|k| if k == 0 { v[0] } else { v[n - k] }).collect()
}

/// Write the outputs of the LDH camera `name` (over the image `im`, its tallies laid out as `lay`,
/// its speckle in `f`) as the registry declares them; returns its manifest entry. The ROI
/// estimates go to the top level of `estimates` (`m0_plus_roi_NAME`, `m0_minus_roi_NAME`).
pub fn write_ldh(
    w: &mut Writer,
    name: &str,
    im: &ImageSpec,
    spec: &LdhSpec,
    lay: &LdhLayout,
    f: &Finished,
    estimates: &mut BTreeMap<String, Entry>,
) -> Result<Value> {
    let (speckle, pixel_speckle) = (&f.speckle, f.pixel_speckle.as_ref());
    let registry = w.registry;
    let out = |slot: usize| registry.at(slot);
    // Each image's EXR channel is named after what it holds (`m0_plus`, `m0_minus_static`, …).
    let (f1, f2) = (spec.band.0 / 1e3, spec.band.1 / 1e3);
    let band = format!("{f1}–{f2} kHz");
    const M0: &str = "fraction of emitted power";
    let image = |w: &mut Writer, slot: usize, what: &str, title: String, unit: &str| -> Result<Vec<f64>> {
        let o = out(slot);
        let (v, e) = w.image(o, what)?;
        w.image_figure(o, &v, &e, &format!("{name}: {title}"), unit)?;
        Ok(v)
    };
    let m0p = image(w, lay.m0_plus, "m0_plus", format!("M0+ ({band})"), M0)?;
    let m0m = image(w, lay.m0_minus, "m0_minus", format!("M0− ({band}, + receding)"), M0)?;
    if let Some(slot) = lay.m1 {
        image(w, slot, "m1", format!("M1 ({band})"), "Hz × fraction of emitted power")?;
    }
    if let Some(classes) = lay.classes {
        // `[class][M0+, M0−][pixel]`, as LdhSpec::declare lays them out.
        for (c, cname) in CLASS_NAMES.iter().enumerate() {
            for (k, (what, sign)) in [("m0_plus", "+"), ("m0_minus", "−")].into_iter().enumerate() {
                let title = format!("M0{sign}, {} ({band})", super::figures::channel_label(cname));
                image(w, classes + (2 * c + k) * lay.pixels, &format!("{what}_{cname}"), title, M0)?;
            }
        }
    }
    let title = format!("{name}: directional M0 ({band})");
    w.figure(&format!("{name}_m0_directional"), &directional(out(lay.m0_plus), &m0p, &m0m, &title))?;

    // ROI spectra.
    let axis = spec.spectrum_axis;
    let bins = axis.bins;
    let (f_lo, f_hi) = if spec.flip_sign { (-axis.f_max, -axis.f_min) } else { (axis.f_min, axis.f_max) };
    let width = axis.bin_width();
    let centres: Vec<f64> = (0..bins).map(|k| f_lo + (k as f64 + 0.5) * width).collect();
    let frequency_file = format!("{name}_roi_frequency_hz.npy");
    if !spec.rois.is_empty() || spec.pixel_spectra {
        w.axis_file(frequency_file.clone(), "frequency_hz", "Hz", &centres)?;
    }
    let channel_names: Vec<String> =
        std::iter::once("total".to_string()).chain(CLASS_NAMES.iter().map(|c| c.to_string())).collect();
    let mut rois = Map::new();
    for (r, (roi, rl)) in spec.rois.iter().zip(&lay.rois).enumerate() {
        for (what, slot) in [("m0_plus", rl.m0_plus), ("m0_minus", rl.m0_minus)] {
            let e = w.estimate(out(slot));
            estimates.insert(format!("{what}_roi_{}", roi.name), Entry::Estimate(e));
        }
        // On the written axis: mirrored with the set-up's sign flipped.
        let o = out(rl.spectrum);
        let (v, e) = w.array(o)?;
        let mut out_of_range = Map::new();
        for (ch, chname) in channel_names.iter().enumerate() {
            let ((below, above), (below_se, above_se)) = (o.tails(w.mean, ch), o.tails(w.stderr, ch));
            out_of_range.insert(
                chname.clone(),
                json!({ "below": estimate(below, below_se), "above": estimate(above, above_se) }),
            );
        }
        let channels: Vec<Channel> = channel_names
            .iter()
            .zip(v.chunks_exact(bins).zip(e.chunks_exact(bins)))
            .map(|(n, (values, stderr))| Channel { name: n, values, stderr })
            .collect();
        let title = format!("{name}: ROI \"{}\" spectrum by path class", roi.name);
        let mut plot = spectrum_plot(&title, &centres, &channels, "power per bin (dB re emitted)");
        let (div, _) = frequency_unit(centres.iter().fold(0.0_f64, |m, f| m.max(f.abs())));
        mark_band(&mut plot, spec.band, div, "M0 band (both signs)");
        w.figure(&stem(o), &plot)?;
        let mut info = Map::new();
        info.insert("x_range_m".into(), json!([roi.min[0], roi.max[0]]));
        info.insert("y_range_m".into(), json!([roi.min[1], roi.max[1]]));
        info.insert("spectrum_file".into(), json!(o.file));
        info.insert("out_of_range".into(), Value::Object(out_of_range));
        if let Some(s) = speckle.get(r) {
            // The windows' frequency axis is the same for every ROI: one file.
            info.insert("speckle".into(), write_speckle(w, spec, name, &roi.name, s, r == 0)?);
        }
        rois.insert(roi.name.clone(), Value::Object(info));
    }
    if let (Some(acq), Some(wl)) = (&spec.acquisition, &lay.windows) {
        for (roi, rw) in spec.rois.iter().zip(&wl.rois) {
            waveform_figure(w, name, &roi.name, acq, out(rw.m0_plus), &band)?;
        }
    }
    if let Some(slot) = lay.pixel_spectra {
        let o = out(slot);
        let (v, _) = w.array(o)?;
        w.figure(&stem(o), &pixel_spectra_plot(name, &centres, &v, bins, spec.band))?;
    }
    let pixel_speckle = match pixel_speckle {
        Some(s) => write_pixel_speckle(w, name, spec, out(lay.m0_plus), s, &m0p, &m0m)?,
        None => Value::Null,
    };

    let total = |v: &[f64]| v.iter().sum::<f64>();
    estimates.insert("m0_plus_image_total".into(), Entry::Number(total(&m0p)));
    estimates.insert("m0_minus_image_total".into(), Entry::Number(total(&m0m)));
    Ok(json!({
        "frame_rate_hz": spec.stft.sample_rate(),
        "window_samples": spec.stft.samples(),
        "window": spec.stft.window().name(),
        "bin_width_hz": spec.stft.bin_width(),
        "band_hz": [spec.band.0, spec.band.1],
        "flip_sign": spec.flip_sign,
        "sign_convention": if spec.flip_sign {
            "flipped: positive = optical path shortening (approaching)"
        } else {
            "positive = optical path lengthening (receding)"
        },
        "images": {
            "pixels": [im.nx, im.ny],
            "x_range_m": [im.min[0], im.max[0]],
            "y_range_m": [im.min[1], im.max[1]],
            "layout": IMAGE_LAYOUT,
            "m0_units": out(lay.m0_plus).units,
            "m1_units": M1_UNITS,
            "classes": CLASS_NAMES,
        },
        "spectrum": {
            "f_min_hz": f_lo,
            "f_max_hz": f_hi,
            "bins": bins,
            "bin_width_hz": width,
            "frequency_file": frequency_file,
            "channels": channel_names,
            "units": SPECTRUM_UNITS,
        },
        "rois": Value::Object(rois),
        "pixel_speckle": pixel_speckle,
    }))
}

/// Median of the finite values (NaN if none).
fn median(v: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = v.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 { v[m] } else { 0.5 * (v[m - 1] + v[m]) }
}

/// The per-pixel speckle files of the camera `name` and their summary: window 0 as the frame
/// (`NAME_m0_{plus,minus}_speckle` `.npy` and `.png`, as the M0± images), all windows
/// (`_windows.npy`, windows × ny × nx), the expectation `NAME_m0_plus_speckle_expected.npy` (band
/// sums of `S`), and how `S`'s binning approximation compares with the exact images `m0p`, `m0m`
/// (as written: M0− with the set-up's sign).
fn write_pixel_speckle(
    w: &mut Writer,
    name: &str,
    spec: &LdhSpec,
    grid: &Output,
    s: &PixelSpeckle,
    m0p: &[f64],
    m0m: &[f64],
) -> Result<Value> {
    let (nx, ny, windows) = (s.nx, s.ny, s.windows);
    let pixels = nx * ny;
    let sign = if spec.flip_sign { -1.0 } else { 1.0 };
    // Drawn per tally pixel (row 0 = the lowest y); written, and compared with the images `m0p`
    // and `m0m`, with row 0 = the largest y, window by window.
    let top_first = |v: &[f64]| -> Vec<f64> { v.chunks(pixels.max(1)).flat_map(|im| rows_reversed(im, nx)).collect() };
    let signed = |v: &[f64]| -> Vec<f64> { v.iter().map(|x| sign * x).collect() };
    let (all_plus, all_minus) = (top_first(&s.m0_plus), signed(&top_first(&s.m0_minus)));
    let (expected_plus, contrast) = (top_first(&s.expected_m0_plus), top_first(&s.contrast));
    let plus = &all_plus[..pixels];
    let minus = &all_minus[..pixels];
    let file = |what: &str| format!("{name}_{what}");
    let image = |units| OutputEntry::made("speckle_image", &[ny, nx], units, grid.axes.clone());
    let windows_axis = Axis::linear("window", "", 0.0, 1.0, windows);
    let stack = |units| {
        let axes = std::iter::once(windows_axis.clone()).chain(grid.axes.iter().cloned()).collect();
        OutputEntry::made("speckle_windows", &[windows, ny, nx], units, axes)
    };
    const P: &str = "fraction of emitted power";
    w.npy(file("m0_plus_speckle.npy"), plus, image(P))?;
    w.npy(file("m0_minus_speckle.npy"), minus, image(P))?;
    w.npy(file("m0_plus_speckle_windows.npy"), &all_plus, stack(P))?;
    w.npy(file("m0_minus_speckle_windows.npy"), &all_minus, stack(P))?;
    w.npy(file("m0_plus_speckle_expected.npy"), &expected_plus, image(P))?;
    let band = format!("{}–{} kHz", spec.band.0 / 1e3, spec.band.1 / 1e3);
    for (what, values, sign) in [("m0_plus", plus, "+"), ("m0_minus", minus, "−")] {
        let title = format!("{name}: M0{sign}, single window ({band})");
        let p = super::figures::image_panel(grid, values, &title, "fraction of emitted power", sign == "−");
        w.figure(&file(&format!("{what}_speckle")), &ImageFigure { panels: vec![p] })?;
    }
    // The binning approximation: E M0± = band sums of S against the exact images.
    let total = |v: &[f64]| v.iter().sum::<f64>();
    let ratio = |a: f64, b: f64| if b != 0.0 { a / b } else { f64::NAN };
    let relative = |a: f64, b: f64| ratio(a, b) - 1.0;
    let mean_plus: Vec<f64> =
        (0..pixels).map(|p| (0..windows).map(|j| all_plus[j * pixels + p]).sum::<f64>() / windows as f64).collect();
    let per_pixel = median((0..pixels).filter(|&p| m0p[p] > 0.0).map(|p| (expected_plus[p] / m0p[p] - 1.0).abs()));
    // Measured single-window contrast of M0+ per pixel (over the windows) against the closed form.
    let measured = (windows > 1).then(|| {
        median((0..pixels).filter(|&p| contrast[p].is_finite()).map(|p| {
            let v: Vec<f64> = (0..windows).map(|j| all_plus[j * pixels + p]).collect();
            let m = total(&v) / windows as f64;
            let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (windows - 1) as f64;
            var.sqrt() / m
        }))
    });
    let power = s.in_range + s.out_of_range;
    Ok(json!({
        "algorithm": "1 (expected single-window periodogram of each pixel's spectrum × Exp(1) per bin)",
        "windows": windows,
        "frame_window": 0,
        "seconds": s.seconds,
        "pixel_spectra_bytes": s.spectra_bytes,
        "axis_on_stft_grid": s.on_stft_grid,
        "stream": "(seed, Speckle, 2^63 | pixel, window)",
        "binning": {
            "note": "each pixel's spectrum counts a path at its bin centre; power outside the spectrum axis is left out",
            "expected_m0_plus_total_relative_difference": relative(total(&s.expected_m0_plus), total(m0p)),
            "expected_m0_minus_total_relative_difference":
                relative(sign * total(&s.expected_m0_minus), total(m0m)),
            "expected_m0_plus_median_pixel_relative_difference": per_pixel,
            "expected_m0_plus_pixel_absolute_difference_over_total":
                ratio(expected_plus.iter().zip(m0p).map(|(e, m)| (e - m).abs()).sum::<f64>(), total(m0p)),
            "mean_over_windows_m0_plus_total_relative_difference": relative(total(&mean_plus), total(m0p)),
            "out_of_axis_fraction": if power > 0.0 { s.out_of_range / power } else { f64::NAN },
        },
        "contrast": {
            "median_closed_form": median(s.contrast.iter().copied()),
            "median_measured": measured,
        },
        "files": {
            "m0_plus": file("m0_plus_speckle.npy"),
            "m0_minus": file("m0_minus_speckle.npy"),
            "m0_plus_windows": file("m0_plus_speckle_windows.npy"),
            "m0_minus_windows": file("m0_minus_speckle_windows.npy"),
            "m0_plus_expected": file("m0_plus_speckle_expected.npy"),
        },
    }))
}

/// Speckle files of the ROI `roi` of the camera `name` and their summary: the expected
/// periodogram and single windows of both algorithms (`.npy`), and the single-window M0±
/// statistics; the windows' frequency axis too when `axis`.
fn write_speckle(w: &mut Writer, spec: &LdhSpec, name: &str, roi: &str, s: &RoiSpeckle, axis: bool) -> Result<Value> {
    let n = spec.stft.samples();
    let prep = |v: &[f64]| -> Vec<f64> {
        if spec.flip_sign { v.chunks_exact(n).flat_map(mirror_fftshift).collect() } else { v.to_vec() }
    };
    let windows = s.algorithm1.len() / n.max(1);
    let freqs: Vec<f64> = (0..n).map(|k| spec.stft.bin_frequency(k)).collect();
    let file = |what: &str| format!("{name}_roi_{roi}_{what}.npy");
    let frequency_file = format!("{name}_stft_frequency_hz.npy");
    if axis {
        w.axis_file(frequency_file.clone(), "frequency_hz", "Hz", &freqs)?;
    }
    const P: &str = "fraction of emitted power per STFT bin";
    let f = Axis::file("frequency_hz", "Hz", frequency_file.clone());
    let window = Axis::linear("window", "", 0.0, 1.0, windows);
    let one = OutputEntry::made("periodogram", &[n], P, vec![f.clone()]);
    let draws = OutputEntry::made("speckle_windows", &[windows, n], P, vec![window, f]);
    let (expected, algorithm1, algorithm2) = (prep(&s.expected), prep(&s.algorithm1), prep(&s.algorithm2));
    w.npy(file("periodogram"), &expected, one)?;
    w.npy(file("speckle_algorithm1"), &algorithm1, draws.clone())?;
    w.npy(file("speckle_algorithm2"), &algorithm2, draws)?;
    // Their figures: the expected periodogram with one window of each algorithm over it, and
    // every window of each algorithm as an image (issue 37: the speckle outputs had none).
    // (Mirrored or not, row entry k is at the axis file's frequency ν_k.)
    let f_axis = freqs;
    let stem_of = |what: &str| file(what).trim_end_matches(".npy").to_string();
    let title = format!("{name}, ROI {roi}: expected single-window periodogram");
    let first = |rows: &[f64]| rows.get(..n).map(<[f64]>::to_vec).unwrap_or_default();
    let (one1, one2) = (first(&algorithm1), first(&algorithm2));
    let zero = vec![0.0; n];
    // The expected periodogram last, over the windows' speckle.
    let channels = [
        Channel { name: "one window, algorithm 1", values: &one1, stderr: &zero },
        Channel { name: "one window, algorithm 2", values: &one2, stderr: &zero },
        Channel { name: "expected", values: &expected, stderr: &zero },
    ];
    let mut plot = spectrum_plot(&title, &f_axis, &channels, "power per STFT bin (dB re emitted)");
    let (div, _) = frequency_unit(f_axis.iter().fold(0.0_f64, |m, f| m.max(f.abs())));
    mark_band(&mut plot, spec.band, div, "M0 band");
    w.figure(&stem_of("periodogram"), &plot)?;
    for (what, rows, how) in [
        ("speckle_algorithm1", &algorithm1, "algorithm 1 (expected × Exp(1) per bin)"),
        ("speckle_algorithm2", &algorithm2, "algorithm 2 (random phases per path)"),
    ] {
        let fig = speckle_windows_figure(&format!("{name}, ROI {roi}: {how}"), &f_axis, rows, windows);
        w.figure(&stem_of(what), &fig)?;
    }
    let sign = if spec.flip_sign { -1.0 } else { 1.0 };
    let summary = |rows: &[f64]| -> Value {
        let m0: Vec<(f64, f64)> = rows
            .chunks_exact(n)
            .map(|w| {
                let b = band_sums(&spec.stft, spec.band, w);
                (b.m0_plus, sign * b.m0_minus)
            })
            .collect();
        let k = m0.len() as f64;
        let mean = |f: &dyn Fn(&(f64, f64)) -> f64| m0.iter().map(f).sum::<f64>() / k;
        let mp = mean(&|x| x.0);
        let mm = mean(&|x| x.1);
        let sd =
            if m0.len() > 1 { (m0.iter().map(|x| (x.0 - mp).powi(2)).sum::<f64>() / (k - 1.0)).sqrt() } else { 0.0 };
        json!({
            "m0_plus_mean": mp,
            "m0_minus_mean": mm,
            "m0_plus_std": sd,
            "m0_plus_relative_std": if mp > 0.0 { sd / mp } else { f64::NAN },
        })
    };
    let b = band_sums(&spec.stft, spec.band, &s.expected);
    Ok(json!({
        "paths": s.lines,
        "windows": windows,
        "expected_m0_plus": b.m0_plus,
        "expected_m0_minus": sign * b.m0_minus,
        "algorithm1": summary(&s.algorithm1),
        "algorithm2": summary(&s.algorithm2),
        "seconds_expected": s.seconds_expected,
        "seconds_algorithm1": s.seconds_algorithm1,
        "seconds_algorithm2": s.seconds_algorithm2,
        "files": {
            "frequency": frequency_file,
            "expected": file("periodogram"),
            "algorithm1": file("speckle_algorithm1"),
            "algorithm2": file("speckle_algorithm2"),
        },
    }))
}

/// The single windows of a speckle algorithm as an image: one row per window (the first at the
/// top), frequency across, in dB re the largest bin, 40 dB deep (grey: no power).
fn speckle_windows_figure(title: &str, freq_hz: &[f64], rows: &[f64], windows: usize) -> ImageFigure {
    use crate::io::figures::image::Panel;
    use crate::io::figures::scale::{Colormap, db};
    let n = freq_hz.len().max(1);
    let peak = rows.iter().fold(0.0_f64, |m, &v| m.max(v));
    let values: Vec<f64> = rows.iter().map(|&v| if v > 0.0 && peak > 0.0 { db(v / peak) } else { f64::NAN }).collect();
    let (div, unit) = frequency_unit(freq_hz.iter().fold(0.0_f64, |m, f| m.max(f.abs())));
    let half = if n > 1 { 0.5 * (freq_hz[n - 1] - freq_hz[0]) / (n - 1) as f64 } else { 0.5 };
    let x = ((freq_hz[0] - half) / div, (freq_hz[n - 1] + half) / div);
    let mut p = Panel::new(
        title,
        values,
        (n, windows),
        x,
        (windows as f64, 0.0),
        Colormap::Viridis,
        (-40.0, 0.0),
        "dB re the largest bin",
    );
    p.x_label = format!("frequency ({unit})");
    p.y_label = "window".into();
    p.equal = false;
    p.caption = "each row one window's periodogram; grey: no power; 40 dB below the largest bin".into();
    ImageFigure { panels: vec![p] }
}

/// The spectra of every pixel summed (the image's spectrum) and of its brightest pixel, in dB,
/// with the M0 band shaded.
fn pixel_spectra_plot(
    name: &str,
    centres: &[f64],
    v: &[f64],
    bins: usize,
    band: (f64, f64),
) -> crate::io::figures::lines::LinePlot {
    let bins = bins.max(1);
    let mut sum = vec![0.0; bins];
    let mut best = (0.0, 0);
    for (p, px) in v.chunks_exact(bins).enumerate() {
        sum.iter_mut().zip(px).for_each(|(s, x)| *s += x);
        let t: f64 = px.iter().sum();
        if t > best.0 {
            best = (t, p);
        }
    }
    let bright = v.chunks_exact(bins).nth(best.1).map_or(vec![0.0; bins], |c| c.to_vec());
    let zero = vec![0.0; bins];
    let channels = [
        Channel { name: "all pixels (sum)", values: &sum, stderr: &zero },
        Channel { name: "brightest pixel", values: &bright, stderr: &zero },
    ];
    let mut plot =
        spectrum_plot(&format!("{name}: pixel spectra"), centres, &channels, "power per bin (dB re emitted)");
    plot.note = plot.note.replace("band: ±σ; ", "");
    let (div, _) = frequency_unit(centres.iter().fold(0.0_f64, |m, f| m.max(f.abs())));
    mark_band(&mut plot, band, div, "M0 band (both signs)");
    plot
}

/// An ROI's M0+ over an acquisition's windows (`o`, its per-window output) relative to its mean
/// over them, ±σ, with the scene's pulsing waveforms (relative to their cycle means) beside it;
/// its resistivity index in the title.
fn waveform_figure(
    w: &mut Writer,
    name: &str,
    roi: &str,
    acq: &crate::detect::ldh::Acquisition,
    o: &Output,
    band: &str,
) -> Result<()> {
    use crate::io::figures::lines::{Curve, LinePlot, PALETTE};
    if !w.figures {
        return Ok(());
    }
    let (v, e) = o.values(w.mean, w.stderr);
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    if mean.is_nan() || mean <= 0.0 {
        return Ok(());
    }
    let x: Vec<f64> = acq.times.iter().map(|t| 1e3 * t).collect();
    let (hi, lo) = v.iter().fold((f64::NEG_INFINITY, f64::INFINITY), |(h, l), &a| (h.max(a), l.min(a)));
    let mut plot = LinePlot::new(
        format!("{name}: ROI \"{roi}\" M0+ ({band}) over the cycle, RI {:.3}", (hi - lo) / hi),
        "time in the cycle (ms)",
        "relative to the cycle mean",
    );
    let mut m0 = Curve::line("M0+ / mean, ±σ", x.clone(), v.iter().map(|a| a / mean).collect(), PALETTE[0]);
    m0.band = Some((
        v.iter().zip(&e).map(|(a, s)| (a - s) / mean).collect(),
        v.iter().zip(&e).map(|(a, s)| (a + s) / mean).collect(),
    ));
    plot.curves.push(m0);
    for (k, (label, s)) in acq.waveforms.iter().enumerate() {
        plot.curves.push(Curve::line(
            format!("{label} (input)"),
            x.clone(),
            s.clone(),
            PALETTE[(k + 1) % PALETTE.len()],
        ));
    }
    plot.note = "σ of each window; the windows share their paths, so their differences are known better".into();
    w.figure(&format!("{name}_roi_{roi}_waveform"), &plot)
}
