//! Outputs of a pulsed lidar receiver: the range–Doppler spectra (gates × bins; total, single and
//! multiple scattering) as `.npy` with standard errors, their axes, a range–Doppler map and a plot
//! of a few gates' spectra as PNG, and per gate (CSV and the manifest) the energies by class, the
//! shot-noise SNR, the spectral moments and the one- or two-component fit of the total spectrum
//! ([`crate::retrieval::retrieve_gate`]).

use serde_json::{Value, json};

use super::{Writer, estimate};
use crate::detect::lidar::LIDAR_CHANNELS;
use crate::detect::{LidarLayout, LidarSpec};
use crate::error::Result;
use crate::io::figures::image::{ImageFigure, Panel};
use crate::io::figures::lines::{Curve, LinePlot, PALETTE, VLine, db_range};
use crate::io::figures::scale::{Colormap, db};
use crate::retrieval::{FIT_SELECTION_LEVEL, GateRetrieval, RetrievalError, radial_velocity};

/// Gates drawn in the gate-spectra figure (fewer if the receiver has fewer).
const PLOTTED_GATES: usize = 4;
/// Dynamic range of the range–Doppler map below its peak, dB.
const MAP_RANGE_DB: f64 = super::figures::DB_DEPTH;

/// Write the receiver's outputs (its tallies laid out as `lay`), with `retrievals` its gates'
/// ([`crate::post::retrieve_gates`]); returns the manifest entry (axes, files, noise model,
/// per-gate energies and estimates).
pub fn write_lidar(
    w: &mut Writer,
    name: &str,
    spec: &LidarSpec,
    lay: &LidarLayout,
    retrievals: &[GateRetrieval],
) -> Result<Value> {
    let (reg, mean, se) = (w.registry, w.mean, w.stderr);
    let (gates, bins, m) = (spec.gates, spec.fft_points, spec.gate_points);
    let range: Vec<f64> = (0..gates).map(|g| spec.gate_range(g)).collect();
    let freq: Vec<f64> = (0..bins).map(|k| spec.bin_frequency(k)).collect();
    let velocity: Vec<f64> = freq.iter().map(|&f| radial_velocity(f, spec.wavelength)).collect();
    let file = |what: &str| format!("{name}_{what}");
    w.axis_file(file("range_m.npy"), "range_m", "m", &range)?;
    w.axis_file(file("frequency_hz.npy"), "frequency_hz", "Hz", &freq)?;
    let mut files = serde_json::Map::new();
    // Each channel's range–Doppler map, `[gate][bin]` from its first slot.
    let mut maps = Vec::with_capacity(LIDAR_CHANNELS.len());
    for (c, channel) in LIDAR_CHANNELS.iter().enumerate() {
        // Channel c's map, `[gate][bin]`, as LidarSpec::declare lays them out.
        let o = reg.at(lay.spectra + c * gates * bins);
        w.array(o)?;
        files.insert((*channel).into(), json!(o.file));
        maps.push(o.slots.start);
    }
    let spectrum = |c: usize, g: usize| {
        let o = maps[c] + g * bins;
        (&mean[o..o + bins], &se[o..o + bins])
    };
    let total = &mean[reg.at(lay.spectra).range()];
    let who = receiver_label(name, spec.axis);
    w.figure(&format!("{name}_range_doppler"), &range_doppler_figure(spec, &who, &range, total))?;
    let plot = gate_spectra_plot(spec, &who, &range, &velocity, retrievals, |c, g| spectrum(c, g).0);
    w.figure(&format!("{name}_gate_spectra"), &plot)?;

    // Per-gate energies (the lag sum D_0: pulse energy in the gate window, summed over paths),
    // the SNR D_0/(Mσ²) and the retrievals from the total spectrum.
    let lags = lay.lags;
    let energy = |c: usize, g: usize| {
        let o = lags + spec.lag_slot(c, g, 0);
        (mean[o], se[o])
    };
    let noise_energy = m as f64 * spec.noise_variance_per_sample();
    let mut csv = String::from("gate,range_m");
    for name in LIDAR_CHANNELS {
        csv.push_str(&format!(",energy_{name},energy_{name}_stderr"));
    }
    csv.push_str(",snr,snr_stderr,snr_db");
    csv.push_str(",peak_velocity_m_per_s,centroid_velocity_m_per_s,width_m_per_s,fwhm_m_per_s,moments_status");
    csv.push_str(",fit_components,fit_p_value,fit_line_shape");
    for j in 1..=2 {
        csv.push_str(&format!(
            ",fit{j}_velocity_m_per_s,fit{j}_velocity_stderr_m_per_s,fit{j}_width_m_per_s,\
             fit{j}_width_stderr_m_per_s,fit{j}_power,fit{j}_power_stderr"
        ));
    }
    csv.push_str(",fit_status\n");
    let mut table = Vec::with_capacity(gates);
    for (g, r) in range.iter().enumerate() {
        csv.push_str(&format!("{g},{r}"));
        let mut row = serde_json::Map::new();
        row.insert("range_m".into(), json!(r));
        for (c, name) in LIDAR_CHANNELS.iter().enumerate() {
            let (v, e) = energy(c, g);
            csv.push_str(&format!(",{v:e},{e:e}"));
            row.insert(format!("energy_{name}"), json!(estimate(v, e)));
        }
        let (d0, d0_se) = energy(0, g);
        let (snr, snr_se) = (d0 / noise_energy, d0_se / noise_energy);
        let snr_db = 10.0 * snr.log10();
        csv.push_str(&format!(",{snr:e},{snr_se:e},{snr_db:.3}"));
        row.insert("snr".into(), json!(estimate(snr, snr_se)));
        row.insert("snr_db".into(), json!(snr_db));
        gate_columns(&mut csv, &mut row, &retrievals[g], spec.wavelength);
        csv.push('\n');
        table.push(Value::Object(row));
    }
    w.put(file("gates.csv"), csv.into_bytes())?;
    Ok(json!({
        "range_m": range,
        "frequency_hz": freq,
        "range_file": file("range_m.npy"),
        "frequency_file": file("frequency_hz.npy"),
        "gates_file": file("gates.csv"),
        "spectra": Value::Object(files),
        "plots": if w.figures {
            json!([file("range_doppler.png"), file("gate_spectra.png")])
        } else {
            json!([])
        },
        "layout": "gates × bins, bins in fftshift order (ν_k = (k − K/2)·f_s/K)",
        "units": "fraction of the pulse energy per bin (expected periodogram, |X_k|²/K), without noise",
        "gate_points": m,
        "sample_rate_hz": spec.sample_rate,
        "pulse_fwhm_s": spec.pulse_fwhm,
        "aperture_radius_m": spec.aperture_radius,
        "field_of_view_rad": spec.cos_fov.acos(),
        "wavelength_m": spec.wavelength,
        "noise": {
            "model": "shot-noise-limited heterodyne: hν/(η E_p) per complex sample, white",
            "pulse_energy_j": spec.pulse_energy,
            "quantum_efficiency": spec.quantum_efficiency,
            "heterodyne_efficiency": spec.heterodyne_efficiency,
            "photon_energy_j": spec.photon_energy(),
            "variance_per_sample": spec.noise_variance_per_sample(),
            "floor_per_bin": spec.noise_floor_per_bin(),
        },
        "gate_estimates": {
            "spectrum": "total, plus the shot-noise floor (known, fixed in the fits)",
            "velocity_sign": "positive = receding (v = λ0·f/2)",
            "snr": "gate energy D_0 over the gate's noise energy M·σ² (wideband CNR averaged over the gate)",
            "fit_selection_level": FIT_SELECTION_LEVEL,
            "fit_weights": "batch standard errors; a zero one replaced by the gate's smallest positive one",
        },
        "gates": table,
    }))
}

/// A CSV field holding free text (quoted, quotes doubled).
fn csv_text(s: &str) -> String {
    format!("\"{}\"", s.replace('"', "\"\""))
}

/// "ok", or the error's message.
fn status<T>(r: &std::result::Result<T, RetrievalError>) -> String {
    match r {
        Ok(_) => "ok".to_string(),
        Err(e) => e.to_string(),
    }
}

/// Append one gate's moment and fit columns to `csv` and fields to `row` (NaN in the CSV and
/// null in the manifest for what could not be estimated, with the reason in the status).
fn gate_columns(csv: &mut String, row: &mut serde_json::Map<String, Value>, gate: &GateRetrieval, wavelength: f64) {
    let v = |f: f64| radial_velocity(f, wavelength);
    match &gate.moments {
        Ok(e) => {
            let fwhm = e.fwhm_hz.map_or(f64::NAN, v);
            csv.push_str(&format!(
                ",{:e},{:e},{:e},{fwhm:e}",
                e.peak_velocity_m_per_s, e.centroid_velocity_m_per_s, e.width_m_per_s
            ));
            row.insert("peak_velocity_m_per_s".into(), json!(e.peak_velocity_m_per_s));
            row.insert("centroid_velocity_m_per_s".into(), json!(e.centroid_velocity_m_per_s));
            row.insert("width_m_per_s".into(), json!(e.width_m_per_s));
            row.insert("fwhm_m_per_s".into(), json!(e.fwhm_hz.map(v)));
        }
        Err(_) => {
            csv.push_str(",NaN,NaN,NaN,NaN");
            for key in ["peak_velocity_m_per_s", "centroid_velocity_m_per_s", "width_m_per_s", "fwhm_m_per_s"] {
                row.insert(key.into(), Value::Null);
            }
        }
    }
    let moments_status = status(&gate.moments);
    csv.push_str(&format!(",{}", csv_text(&moments_status)));
    row.insert("moments_status".into(), json!(moments_status));

    let mut fit_status = status(&gate.fit);
    match &gate.fit {
        Ok(choice) => {
            let fit = choice.chosen();
            csv.push_str(&format!(",{},{:e},{}", choice.components, choice.p_value, gate.line_shape.name()));
            let mut list = Vec::new();
            for j in 0..2 {
                match fit.components.get(j) {
                    Some(c) => {
                        let (vel, vel_se) = (v(c.mean_hz), v(c.mean_hz_stderr));
                        let (wid, wid_se) = (v(c.sigma_hz), v(c.sigma_hz_stderr));
                        csv.push_str(&format!(
                            ",{vel:e},{vel_se:e},{wid:e},{wid_se:e},{:e},{:e}",
                            c.power, c.power_stderr
                        ));
                        list.push(json!({
                            "velocity_m_per_s": estimate(vel, vel_se),
                            "width_m_per_s": estimate(wid, wid_se),
                            "power": estimate(c.power, c.power_stderr),
                        }));
                    }
                    None => csv.push_str(",NaN,NaN,NaN,NaN,NaN,NaN"),
                }
            }
            if let Err(e) = &choice.two {
                fit_status = format!("ok (one component kept: the two-component fit failed: {e})");
            }
            row.insert(
                "fit".into(),
                json!({
                    "components": choice.components,
                    "p_value": choice.p_value,
                    "line_shape": gate.line_shape.name(),
                    "f_statistic": choice.f_statistic,
                    "chi2": fit.chi2,
                    "dof": fit.dof,
                    "list": list,
                }),
            );
        }
        Err(_) => {
            csv.push_str(",NaN,NaN,NaN");
            csv.push_str(&",NaN".repeat(12));
            row.insert("fit".into(), Value::Null);
        }
    }
    csv.push_str(&format!(",{}", csv_text(&fit_status)));
    row.insert("fit_status".into(), json!(fit_status));
    row.insert("stderr_substituted".into(), json!(gate.stderr_substituted));
}

/// The total range–Doppler map in dB re its peak: x = radial velocity, y = range (the farthest
/// gate at the top), with the height of each range on the right (`z0 + range · sin(elevation)`).
/// `receiver, azimuth 90°, elevation 60°`: which detector a lidar figure shows, and where it
/// points (`axis`: x east, y north, z up; azimuth clockwise from north), so that the figures of a
/// scan's pointings tell themselves apart.
pub fn receiver_label(name: &str, axis: glam::DVec3) -> String {
    let elevation = axis.z.clamp(-1.0, 1.0).asin().to_degrees();
    let azimuth = axis.x.atan2(axis.y).to_degrees().rem_euclid(360.0);
    // A vertical beam has no azimuth.
    if axis.x.hypot(axis.y) < 1e-9 {
        return format!("{name}, elevation {elevation:.0}°");
    }
    // Whole degrees unless the pointing needs a decimal (0.5° steps of a fine scan).
    let deg = |v: f64| if (v - v.round()).abs() < 0.05 { format!("{v:.0}") } else { format!("{v:.1}") };
    format!("{name}, azimuth {}°, elevation {}°", deg(azimuth % 360.0), deg(elevation))
}

fn range_doppler_figure(spec: &LidarSpec, who: &str, range: &[f64], total: &[f64]) -> ImageFigure {
    let (gates, bins) = (spec.gates, spec.fft_points);
    let peak = total.iter().cloned().fold(0.0, f64::max);
    // Row 0 of the figure is the top: the last gate.
    let db_map: Vec<f64> = (0..gates)
        .rev()
        .flat_map(|g| total[g * bins..(g + 1) * bins].iter())
        .map(|&v| if v > 0.0 && peak > 0.0 { db(v / peak) } else { f64::NAN })
        .collect();
    let half_bin = 0.5 * spec.sample_rate / bins as f64;
    let v = |f: f64| radial_velocity(f, spec.wavelength);
    let x = (v(spec.bin_frequency(0) - half_bin), v(spec.bin_frequency(bins - 1) + half_bin));
    // Each row spans its gate: M samples of c/(2 f_s) each, centred on the gate's range.
    let half_gate = 0.25 * crate::SPEED_OF_LIGHT * spec.gate_points as f64 / spec.sample_rate;
    let y = (range[0] - half_gate, range[gates - 1] + half_gate);
    let height = |r: f64| spec.position.z + r * spec.axis.z;
    let title = format!("{who}: range–Doppler spectrum");
    let mut p =
        Panel::new(title, db_map, (bins, gates), x, y, Colormap::Viridis, (-MAP_RANGE_DB, 0.0), "power (dB re peak)");
    p.x_label = "radial velocity (m/s), + receding".into();
    p.y_label = "range (m)".into();
    p.equal = false;
    p.right_axis = Some(("height (m)".into(), (height(y.0), height(y.1))));
    p.caption =
        format!("all light; {gates} gates × {bins} bins; grey: no power, or {MAP_RANGE_DB:.0} dB below the peak");
    ImageFigure { panels: vec![p] }
}

/// A colour halfway to white.
fn tint(c: [u8; 3]) -> [u8; 3] {
    c.map(|v| v + (255 - v) / 2)
}

/// A few evenly spaced gates' total and multiple-scattering spectra (dB re the pulse energy per
/// bin) against radial velocity, with the shot-noise floor; 60 dB below the peak (the floor too
/// when it lies within 80 dB of the peak). The legend lists only curves with power in range.
/// `spectrum(c, g)`: channel `c`'s spectrum in gate `g`.
fn gate_spectra_plot<'a>(
    spec: &LidarSpec,
    who: &str,
    range: &[f64],
    velocity: &[f64],
    retrievals: &[GateRetrieval],
    spectrum: impl Fn(usize, usize) -> &'a [f64],
) -> LinePlot {
    let gates = spec.gates;
    let n = PLOTTED_GATES.min(gates);
    let mut chosen: Vec<usize> =
        (0..n).map(|i| if n == 1 { 0 } else { (i * (gates - 1) + (n - 1) / 2) / (n - 1) }).collect();
    chosen.dedup();
    let to_db = |p: &[f64]| -> Vec<f64> { p.iter().map(|&v| db(v)).collect() };
    let title = format!("{who}: gate spectra");
    let mut plot = LinePlot::new(title, "radial velocity (m/s), + receding", "dB re pulse energy per bin");
    plot.note = format!(
        "all light; lighter: the same gate's multiple scattering; pulse energy {}, efficiency η = {:.2}",
        crate::describe::energy(spec.pulse_energy),
        spec.efficiency()
    );
    for (i, &g) in chosen.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        plot.curves.push(Curve::line(
            format!("gate at {:.0} m", range[g]),
            velocity.to_vec(),
            to_db(spectrum(0, g)),
            color,
        ));
        // The same gate's multiply scattered light, in its lighter colour (said in the note; its
        // own legend entries made the legend cover the spectra).
        plot.curves.push(Curve::line("", velocity.to_vec(), to_db(spectrum(2, g)), tint(color)));
    }
    // The first plotted gate's fitted components (aerosol and rain: issue 37, the rain's
    // component could not be seen), dashed at their mean radial velocities.
    if let Some(Ok(choice)) = chosen.first().and_then(|&g| retrievals.get(g)).map(|r| &r.fit) {
        let means: Vec<f64> =
            choice.chosen().components.iter().map(|c| radial_velocity(c.mean_hz, spec.wavelength)).collect();
        let listed: Vec<String> = means.iter().map(|v| format!("{v:+.2}")).collect();
        for (i, &v) in means.iter().enumerate() {
            let label = if i == 0 {
                format!("fit, gate at {:.0} m: {} m/s", range[chosen[0]], listed.join(", "))
            } else {
                String::new()
            };
            plot.vlines.push(VLine { x: v, label, color: PALETTE[6] });
        }
    }
    let floor_db = db(spec.noise_floor_per_bin());
    plot.y_range = db_range(plot.curves.iter().flat_map(|c| &c.y), MAP_RANGE_DB).map(|(lo, hi)| {
        if floor_db.is_finite() && floor_db > lo - 20.0 { (lo.min(floor_db - 5.0), hi) } else { (lo, hi) }
    });
    let mut floor = Curve::line("shot-noise floor", velocity.to_vec(), vec![floor_db; velocity.len()], [90, 90, 90]);
    floor.mark = crate::io::figures::lines::Mark::Dashed;
    plot.curves.push(floor);
    let (lo, _) = plot.y_range.unwrap_or((f64::NEG_INFINITY, 0.0));
    // (A multiple-scattering curve is named after its gate's total, the curve before it.)
    let hidden: Vec<String> = plot
        .curves
        .iter()
        .enumerate()
        .filter(|(_, c)| !c.y.iter().any(|&y| y.is_finite() && y >= lo))
        .map(|(i, c)| match c.label.as_str() {
            "" => format!("{}, multiple", plot.curves[i - 1].label),
            label => label.to_string(),
        })
        .collect();
    if !hidden.is_empty() {
        plot.note = format!("{}; not drawn (below the range or no power): {}", plot.note, hidden.join(", "));
    }
    plot
}
