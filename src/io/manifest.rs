//! Writing a finished run: `manifest.json` (version, config as run, seed, samples, threads, wall
//! time, run statistics, every scalar estimate with its standard error) plus, per detector, its
//! spectra (`.npy`, with per-bin standard errors and the frequency axis), FMCW range and velocity
//! estimates with a chirp (`fmcw_estimates.csv`, see [`super::fmcw`]) and image (`.exr`, `.npy`).
//! Data files are written first and the manifest last, each atomically.

use std::path::Path;

use serde_json::{Value, json};

use crate::detect::{Scalar, Side};
use crate::error::{Error, Result};
use crate::experiment::{Experiment, RunOutput};

use super::{exr_bytes, npy, write_atomic};

/// `{"value": v, "stderr": s}`.
pub(super) fn estimate(v: f64, s: f64) -> Value {
    json!({ "value": v, "stderr": s })
}

/// A number, or `null` when it is not finite (JSON has no infinity).
fn finite_or_null(v: f64) -> Value {
    if v.is_finite() { json!(v) } else { Value::Null }
}

/// What the manifest records about how the run was invoked.
#[derive(Debug, Clone, Default)]
pub struct Invocation {
    /// Where the configuration came from (a path, or "built-in default").
    pub config_source: String,
    /// `--set` overrides in the order given.
    pub overrides: Vec<String>,
}

/// Write all outputs of `out` into `dir` (created if needed). Returns the manifest as written.
pub fn write_run(
    dir: &Path,
    exp: &Experiment,
    out: &RunOutput,
    config: &toml::Table,
    inv: &Invocation,
) -> Result<Value> {
    std::fs::create_dir_all(dir).map_err(|source| Error::Write { path: dir.to_path_buf(), source })?;
    let mean = out.estimates.mean();
    let se = out.estimates.stderr();
    // Post-processing that the outputs need: the LDH ROIs' speckle, from the recorded lines.
    let t = std::time::Instant::now();
    let speckle = crate::post::speckle_of(exp, out);
    let speckle_seconds = t.elapsed().as_secs_f64();
    let mut files: Vec<String> = Vec::new();
    let mut put = |name: String, bytes: Vec<u8>| -> Result<()> {
        write_atomic(&dir.join(&name), &bytes)?;
        files.push(name);
        Ok(())
    };

    let mut estimates = serde_json::Map::new();
    for s in Scalar::ALL {
        estimates.insert(s.name().to_string(), estimate(mean[s as usize], se[s as usize]));
    }
    let mut det_estimates = serde_json::Map::new();
    let mut det_info = serde_json::Map::new();
    let mut out_of_range_total = 0.0;
    let chirp_names: &[&str] = if out.beat.chirps() == 2 { &["_up", "_down"] } else { &[""] };

    let mut fmcw_rows: Vec<String> = Vec::new();
    let mut fmcw_any = false;
    for (i, (d, lay)) in exp.detectors.iter().zip(&out.layout.detectors).enumerate() {
        let mut de = serde_json::Map::new();
        de.insert("detected_power".into(), estimate(mean[lay.power], se[lay.power]));
        let mut info = serde_json::Map::new();
        info.insert("side".into(), json!(if d.side == Side::Top { "top" } else { "bottom" }));
        if let (Some(spec), Some((start, stride))) = (&d.spectrum, lay.spectra) {
            let bins = spec.axis.bins;
            let centres: Vec<f64> = (0..bins).map(|k| spec.axis.center(k)).collect();
            put(format!("{}_frequency_hz.npy", d.name), npy::to_bytes(&[bins], &centres))?;
            let mut channel_names = vec!["total".to_string()];
            let mut groups: Vec<(&str, usize, usize)> = vec![("", 0, 1)];
            if let Some(k) = spec.by_order {
                groups.push(("_by_order", 1, k as usize + 1));
                channel_names
                    .extend((0..=k).map(|i| if i == k { format!("order>={k}") } else { format!("order={i}") }));
            }
            if let Some(e) = spec.by_doppler_events {
                let first = 1 + spec.by_order.map_or(0, |k| k as usize + 1);
                groups.push(("_by_doppler_events", first, e as usize + 1));
                channel_names.extend(
                    (0..=e)
                        .map(|i| if i == e { format!("doppler_events>={e}") } else { format!("doppler_events={i}") }),
                );
            }
            let mut chirps = serde_json::Map::new();
            for (c, cname) in chirp_names.iter().enumerate() {
                let base = start + c * lay.channels * stride;
                for &(suffix, first, count) in &groups {
                    let mut v = Vec::with_capacity(count * bins);
                    let mut e = Vec::with_capacity(count * bins);
                    for ch in first..first + count {
                        let o = base + ch * stride;
                        v.extend_from_slice(&mean[o..o + bins]);
                        e.extend_from_slice(&se[o..o + bins]);
                    }
                    let shape = if count == 1 && suffix.is_empty() { vec![bins] } else { vec![count, bins] };
                    put(format!("{}{cname}_spectrum{suffix}.npy", d.name), npy::to_bytes(&shape, &v))?;
                    put(format!("{}{cname}_spectrum{suffix}_stderr.npy", d.name), npy::to_bytes(&shape, &e))?;
                }
                let mut oor = serde_json::Map::new();
                for (ch, chname) in channel_names.iter().enumerate() {
                    let o = base + ch * stride + bins;
                    oor.insert(
                        chname.clone(),
                        json!({ "below": estimate(mean[o], se[o]), "above": estimate(mean[o + 1], se[o + 1]) }),
                    );
                }
                out_of_range_total += mean[base + bins] + mean[base + bins + 1];
                let key =
                    if cname.is_empty() { "single".to_string() } else { cname.trim_start_matches('_').to_string() };
                de.insert(format!("out_of_range_{key}"), Value::Object(oor));
                chirps.insert(key, json!(cname));
            }
            info.insert(
                "spectrum".into(),
                json!({
                    "f_min_hz": spec.axis.f_min,
                    "f_max_hz": spec.axis.f_max,
                    "bins": bins,
                    "bin_width_hz": spec.axis.bin_width(),
                    "frequency_file": format!("{}_frequency_hz.npy", d.name),
                    "channels": channel_names,
                    "chirps": Value::Object(chirps),
                    "units": "fraction of emitted power per bin",
                }),
            );
        }
        if let Some(entry) = super::fmcw::detector_entry(exp, out, i, &mut de) {
            fmcw_any = true;
            info.insert("fmcw".into(), entry.info);
            fmcw_rows.extend(entry.row);
        }
        if let (Some(im), Some(start)) = (&d.image, lay.image) {
            let n = im.nx * im.ny;
            let (v, e) = (&mean[start..start + n], &se[start..start + n]);
            put(format!("{}_image.npy", d.name), npy::to_bytes(&[im.ny, im.nx], v))?;
            put(format!("{}_image_stderr.npy", d.name), npy::to_bytes(&[im.ny, im.nx], e))?;
            let exr = exr_bytes(im.nx, im.ny, &[("intensity", v), ("stderr", e)]).map_err(|m| Error::Write {
                path: dir.join(format!("{}_image.exr", d.name)),
                source: std::io::Error::other(m),
            })?;
            put(format!("{}_image.exr", d.name), exr)?;
            info.insert(
                "image".into(),
                json!({
                    "pixels": [im.nx, im.ny],
                    "x_range_m": [im.min[0], im.max[0]],
                    "y_range_m": [im.min[1], im.max[1]],
                    "layout": "rows = y (ascending), columns = x (ascending)",
                    "units": "fraction of emitted power per pixel",
                }),
            );
        }
        if let (Some(spec), Some(ll)) = (&d.ldh, &lay.ldh) {
            let v = super::ldh::write_ldh(&mut put, d, spec, ll, mean, &se, &speckle, &mut estimates)?;
            info.insert("ldh".into(), v);
        }
        if let (Some(spec), Some(ll)) = (&d.lidar, &lay.lidar) {
            info.insert("lidar".into(), super::lidar::write_lidar(&mut put, spec, ll, mean, &se)?);
        }
        det_estimates.insert(d.name.clone(), Value::Object(de));
        det_info.insert(d.name.clone(), Value::Object(info));
    }
    if fmcw_any {
        put(super::fmcw::CSV_FILE.into(), super::fmcw::csv(&fmcw_rows).into_bytes())?;
    }
    if !det_estimates.is_empty() {
        estimates.insert("detectors".into(), Value::Object(det_estimates));
    }

    // Each named medium once (a medium used by several layers appears once per use in the scene).
    let mut media = serde_json::Map::new();
    for m in &exp.scene.media {
        media.entry(m.name.clone()).or_insert_with(|| {
            json!({
                "sigma_a_per_m": m.sigma_a(),
                "sigma_s_per_m": m.sigma_s(),
                "albedo": m.albedo(),
                "optics": serde_json::to_value(&m.info).unwrap_or(Value::Null),
                // A heterogeneous medium: σa and σs above are at density 1.
                "density": m.heterogeneity().map_or(Value::Null, |h| serde_json::to_value(&h.info).unwrap_or(Value::Null)),
            })
        });
    }

    let st = &out.stats;
    let wall = out.wall_seconds.max(1e-9);
    let manifest = json!({
        "ohd_version": env!("CARGO_PKG_VERSION"),
        "name": exp.name,
        "config_source": inv.config_source,
        "overrides": inv.overrides,
        "config": config,
        "config_toml": toml::to_string(config).unwrap_or_default(),
        "seed": exp.plan.seed,
        "samples": out.samples(),
        "samples_requested": exp.plan.requested_samples,
        "batches": out.batches,
        "main_output": { "name": out.main_output.0, "relative_error": finite_or_null(out.main_output.1) },
        "target_error": out.target.as_ref().map_or(Value::Null, |t| json!({
            "output": t.output,
            "target": t.target,
            "reached": finite_or_null(t.reached),
            "met": t.met,
            "rounds": t.rounds,
            "max_samples": t.max_samples,
        })),
        "threads": out.threads,
        "wall_seconds": out.wall_seconds,
        "run_statistics": {
            "paths": st.paths,
            "scattering_events": st.scattering_events,
            "events_per_second": st.scattering_events as f64 / wall,
            "paths_per_second": st.paths as f64 / wall,
            "null_collisions": st.null_collisions,
            "roulette_terminations": st.roulette_terminations,
            "truncated_paths": st.truncated_paths,
            "non_finite": st.non_finite,
            "speckle_seconds": speckle_seconds,
            "out_of_range_weight": out_of_range_total,
            "doppler": exp.needs_doppler(),
            "path_length": exp.needs_length(),
        },
        "media": Value::Object(media),
        "estimates": Value::Object(estimates),
        "detectors": Value::Object(det_info),
        "files": files,
    });
    let text = serde_json::to_string_pretty(&manifest).expect("a JSON value serialises");
    write_atomic(&dir.join("manifest.json"), text.as_bytes())?;
    Ok(manifest)
}
