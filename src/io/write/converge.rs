//! The files of `ohd converge`: `converge.csv` (one row per output and rung), `converge.json`
//! (per output: the fitted log–log slope of error against seconds, the extrapolated seconds to
//! 1 % and 0.1 % relative error and the agreement of the run's own σ with the measured error) and
//! `converge.png` (relative error against seconds, log–log, with a `1/√t` guide). Also reading a
//! previous run's outputs as the reference.

use std::path::Path;

use serde_json::{Value, json};

use crate::converge::{NamedOutput, Reference, Study};
use crate::error::{Error, Result};

use super::dir::DirWriter;
use crate::io::figures::lines::{Curve, LinePlot, Mark, PALETTE};
use crate::io::formats::npy;
use crate::io::outdir::OutDir;

/// The agreement band of measured to self-reported error (issue 7).
pub const SIGMA_RATIO_BAND: (f64, f64) = (0.5, 2.0);

/// Largest `manifest.json` read as a reference, bytes (it holds the configuration twice, at most
/// [`crate::config::MAX_FILE_BYTES`] each, and the scalar estimates).
pub const MAX_MANIFEST_BYTES: u64 = 256 << 20;

/// Room for an `.npy` file's header besides its values, bytes (a version 1 header is < 64 KiB).
const NPY_HEADER_BYTES: u64 = 1 << 16;

fn num(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

/// Read the reference of every output from the run directory `dir` (written by `ohd run` of the
/// same experiment): arrays from their `.npy` and `_stderr.npy` files, scalars from
/// `manifest.json`. A missing file, a malformed file or an array of the wrong size is an error
/// naming the file.
pub fn read_reference(dir: &Path, outputs: &[NamedOutput]) -> Result<Vec<Option<Reference>>> {
    let read = |name: &str, limit: u64, what: &str| crate::io::read_limited(&dir.join(name), limit, what);
    let bad = |name: &str, why: String| Error::invalid_file(dir.join(name), why);
    if super::dir::is_incomplete(dir) {
        return Err(bad(
            super::dir::MARKER,
            "the run in this directory is incomplete (its writing was interrupted): rerun it".into(),
        ));
    }
    let manifest: Value = serde_json::from_slice(&read("manifest.json", MAX_MANIFEST_BYTES, "a run's manifest")?)
        .map_err(|e| bad("manifest.json", format!("not JSON: {e}")))?;
    let mut refs = Vec::with_capacity(outputs.len());
    for o in outputs {
        let (values, stderr) = if o.is_scalar() {
            let stderr_ptr = o.file.replace("/value", "/stderr");
            match (
                manifest.pointer(&o.file).and_then(Value::as_f64),
                manifest.pointer(&stderr_ptr).and_then(Value::as_f64),
            ) {
                (Some(v), Some(s)) => (vec![v], vec![s]),
                _ => return Err(bad("manifest.json", format!("has no {} (is it a run of this experiment?)", o.file))),
            }
        } else {
            let se_name = o.file.replace(".npy", "_stderr.npy");
            let limit = NPY_HEADER_BYTES + 8 * o.range().len() as u64;
            let load = |name: &str| -> Result<Vec<f64>> {
                let (_, data) = npy::from_bytes(&read(name, limit, &format!("the .npy file of {}", o.name))?)
                    .ok_or_else(|| bad(name, "not an ohd .npy file (little-endian f64)".into()))?;
                if data.len() != o.range().len() {
                    return Err(bad(
                        name,
                        format!(
                            "holds {} values; {} has {} (is it a run of this experiment?)",
                            data.len(),
                            o.name,
                            o.range().len()
                        ),
                    ));
                }
                Ok(data)
            };
            (load(&o.file)?, load(&se_name)?)
        };
        // Back to the tally's convention and order (standard errors carry no sign).
        let stderr = o.to_tally(&stderr).into_iter().map(f64::abs).collect();
        refs.push(Some(Reference { values: o.to_tally(&values), stderr, kind: "directory" }));
    }
    Ok(refs)
}

/// `converge.csv`: `output,samples,seconds,error,stderr` (error and stderr in the output's
/// metric: absolute for scalars, relative RMS for arrays).
pub fn csv(study: &Study) -> String {
    let mut s = String::from("output,samples,seconds,error,stderr\n");
    for o in &study.outputs {
        for (k, r) in study.rungs.iter().enumerate() {
            if let (Some(e), Some(se)) = (o.error.get(k), o.stderr.get(k)) {
                s.push_str(&format!("{},{},{:.6},{:.6e},{:.6e}\n", o.output.name, r.samples, r.seconds, e, se));
            }
        }
    }
    s
}

/// `converge.json`.
pub fn json(study: &Study, config_source: &str) -> Value {
    let mut outputs = serde_json::Map::new();
    for o in &study.outputs {
        let (slope, slope_se) = o.fit.map_or((f64::NAN, f64::NAN), |(b, se, _)| (b, se));
        let ratio = o.sigma_ratio_rms();
        outputs.insert(
            o.output.name.clone(),
            json!({
                "metric": if o.output.is_scalar() { "absolute" } else { "relative_rms" },
                "reference": o.reference_kind,
                "slope": num(slope),
                "slope_stderr": num(slope_se),
                "seconds_to_1_percent": num(o.seconds_to(0.01).unwrap_or(f64::NAN)),
                "seconds_to_0_1_percent": num(o.seconds_to(0.001).unwrap_or(f64::NAN)),
                "stderr_slope": num(o.stderr_fit.map_or(f64::NAN, |f| f.0)),
                "error_scale": num(o.error_scale()),
                "paths_per_second": num(o.paths_per_second),
                "reference_error": num(o.reference_error),
                "relative_error": o.relative.iter().map(|&v| num(v)).collect::<Vec<_>>(),
                "sigma_ratio": o.sigma_ratio.iter().map(|&v| num(v)).collect::<Vec<_>>(),
                "sigma_ratio_rms": num(ratio),
                "sigma_agrees": ratio >= SIGMA_RATIO_BAND.0 && ratio <= SIGMA_RATIO_BAND.1,
            }),
        );
        if !o.pixel_median.is_empty() {
            let entry = outputs.get_mut(&o.output.name).and_then(Value::as_object_mut).expect("just inserted");
            let slope = |f: Option<(f64, f64, f64)>| num(f.map_or(f64::NAN, |f| f.0));
            let list = |v: &[f64]| v.iter().map(|&x| num(x)).collect::<Vec<_>>();
            entry.insert("pixel_median_relative_stderr".into(), json!(list(&o.pixel_median)));
            entry.insert("pixel_median_slope".into(), slope(o.pixel_median_fit));
            if !o.region_median.is_empty() {
                entry.insert("region_median_relative_stderr".into(), json!(list(&o.region_median)));
                entry.insert("region_median_slope".into(), slope(o.region_median_fit));
            }
        }
    }
    let skipped: serde_json::Map<String, Value> =
        study.skipped.iter().map(|(n, why)| (n.clone(), json!(why))).collect();
    json!({
        "ohd_version": env!("CARGO_PKG_VERSION"),
        "config_source": config_source,
        "main_output": study.main_output,
        "rungs": study.rungs.iter().map(|r| json!({ "samples": r.samples, "seconds": r.seconds, "seed": r.seed })).collect::<Vec<_>>(),
        "reference_run": study.reference_run.as_ref().map_or(Value::Null, |r| json!({ "samples": r.samples, "seconds": r.seconds, "seed": r.seed })),
        "sigma_ratio_band": [SIGMA_RATIO_BAND.0, SIGMA_RATIO_BAND.1],
        "notes": "error: |x − r| for scalars, ‖x − r‖₂/‖r‖₂ for spectra and images; stderr: the run's own σ in the same metric; sigma_ratio: error/√(σ² + σ_ref²) per rung; slope: least squares of ln(relative error) against ln(seconds) (−1/2 for Monte Carlo), the rung's error taken as √(error² − reference_error²) with a reference run; stderr_slope: the fit of the run's own relative σ against paths (not seconds); error_scale: √(mean over rungs of (error² − reference_error²)/σ²); seconds_to_*: from the largest rung along 1/√N (its σ times error_scale), at paths_per_second (a single rung's error is one noisy draw and its wall time is noisy; the slopes check the law); images also: pixel_median_relative_stderr, the median over pixels of the run's own σ/|value| per rung, and its slope against paths (−1/2 when every pixel converges as Monte Carlo), and region_median_* the same over the regions' footprints (the pixels whose vertical line meets a region)",
        "outputs": Value::Object(outputs),
        "skipped": Value::Object(skipped),
    })
}

/// The study's figure: relative error against wall time per output (the main output first; at
/// most 7), log–log, with markers, the run's own relative σ as error bars and a `1/√t` line
/// through the main output's points.
pub fn plot(study: &Study) -> LinePlot {
    let mut order: Vec<&_> = study.outputs.iter().collect();
    order.sort_by_key(|o| !study.is_main(&o.output));
    let seconds: Vec<f64> = study.rungs.iter().map(|r| r.seconds).collect();
    let mut plot = LinePlot::new("Error against run time", "wall time (s)", "relative error");
    plot.log_x = true;
    plot.log_y = true;
    for (i, o) in order.iter().take(PALETTE.len() - 1).enumerate() {
        let mut c = Curve::line(o.output.name.clone(), seconds.clone(), o.relative.clone(), PALETTE[i]);
        c.y_err = Some(o.relative_stderr.clone());
        c.mark = Mark::LineMarkers;
        plot.curves.push(c);
    }
    if let Some(main) = order.first() {
        let pts: Vec<(f64, f64)> = seconds
            .iter()
            .zip(&main.relative)
            .filter(|(t, e)| **t > 0.0 && **e > 0.0 && t.is_finite() && e.is_finite())
            .map(|(t, e)| (t.ln(), e.ln()))
            .collect();
        if !pts.is_empty() {
            // ln e = c − ln(t)/2 through the mean point.
            let n = pts.len() as f64;
            let c = pts.iter().map(|(t, e)| e + 0.5 * t).sum::<f64>() / n;
            let (lo, hi) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.0), h.max(p.0)));
            let x = vec![lo.exp(), hi.exp()];
            let y = x.iter().map(|t: &f64| (c - 0.5 * t.ln()).exp()).collect();
            let mut g = Curve::line("1/√t", x, y, PALETTE[PALETTE.len() - 1]);
            g.mark = Mark::Dashed;
            plot.curves.push(g);
        }
    }
    plot.note = "error bars: the runs' own relative σ".into();
    plot
}

/// Write `converge.csv`, the figure `converge.png`/`.svg` (if `figures`) and (last)
/// `converge.json` into `dir`, atomically,
/// through a [`DirWriter`] (an earlier study there is replaced; a run stays).
pub fn write_study(dir: &OutDir, study: &Study, config_source: &str, figures: bool) -> Result<()> {
    let mut out = DirWriter::begin(dir, super::dir::Output::Study, &[])?;
    let [csv_file, png_file, svg_file] = super::dir::CONVERGE_FILES;
    out.put(csv_file, csv(study).as_bytes())?;
    if figures {
        out.figure(png_file, svg_file, &plot(study))?;
    }
    let text = serde_json::to_string_pretty(&json(study, config_source)).expect("a JSON value serialises");
    out.finish(Some((super::dir::CONVERGE, text.as_bytes())))
}
