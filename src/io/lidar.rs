//! Outputs of a pulsed lidar receiver: the range–Doppler spectra (gates × bins; total, single and
//! multiple scattering) as `.npy` with standard errors, their axes, a dB map, and the per-gate
//! energies as CSV and in the manifest.

use serde_json::{Value, json};

use super::ldh::Put;
use super::manifest::estimate;
use super::npy;
use super::png::{Colormap, image_png};
use crate::detect::lidar::LIDAR_CHANNELS;
use crate::detect::{LidarLayout, LidarSpec};
use crate::error::Result;

/// Write the receiver's outputs; returns the manifest entry (axes, files, per-gate energies).
pub fn write_lidar(put: &mut Put, spec: &LidarSpec, lay: &LidarLayout, mean: &[f64], se: &[f64]) -> Result<Value> {
    let (gates, bins, m) = (spec.gates, spec.fft_points, spec.gate_points);
    let range: Vec<f64> = (0..gates).map(|g| spec.gate_range(g)).collect();
    let freq: Vec<f64> = (0..bins).map(|k| spec.bin_frequency(k)).collect();
    put("range_m.npy".into(), npy::to_bytes(&[gates], &range))?;
    put("frequency_hz.npy".into(), npy::to_bytes(&[bins], &freq))?;
    let mut files = serde_json::Map::new();
    for (c, name) in LIDAR_CHANNELS.iter().enumerate() {
        let stem = if c == 0 { "range_doppler".to_string() } else { format!("range_doppler_{name}") };
        let o = lay.spectra + c * gates * bins;
        put(format!("{stem}.npy"), npy::to_bytes(&[gates, bins], &mean[o..o + gates * bins]))?;
        put(format!("{stem}_stderr.npy"), npy::to_bytes(&[gates, bins], &se[o..o + gates * bins]))?;
        files.insert((*name).into(), json!(format!("{stem}.npy")));
    }
    // The map in dB relative to its peak: rows = gates (the first at the bottom), columns = bins.
    let o = lay.spectra;
    let total = &mean[o..o + gates * bins];
    let peak = total.iter().cloned().fold(0.0, f64::max);
    let db: Vec<f64> =
        total.iter().map(|&v| if v > 0.0 && peak > 0.0 { 10.0 * (v / peak).log10() } else { f64::NAN }).collect();
    let title = format!(
        "range-Doppler: {:.0}-{:.0} m (rows), {:.1} to {:.1} MHz (columns)",
        range[0],
        range[gates - 1],
        freq[0] * 1e-6,
        freq[bins - 1] * 1e-6
    );
    put(
        "range_doppler.png".into(),
        image_png(&db, bins, gates, Colormap::Viridis, (-60.0, 0.0), &title, "dB re peak"),
    )?;

    // Per-gate energies (the lag sum D_0: pulse energy in the gate window, summed over paths).
    let energy = |c: usize, g: usize| {
        let o = lay.lags + ((c * gates + g) * m) * 2;
        (mean[o], se[o])
    };
    let mut csv = String::from("gate,range_m");
    for name in LIDAR_CHANNELS {
        csv.push_str(&format!(",energy_{name},energy_{name}_stderr"));
    }
    csv.push('\n');
    let mut table = Vec::with_capacity(gates);
    for (g, r) in range.iter().enumerate() {
        csv.push_str(&format!("{g},{r}"));
        let mut row = serde_json::Map::new();
        row.insert("range_m".into(), json!(r));
        for (c, name) in LIDAR_CHANNELS.iter().enumerate() {
            let (v, e) = energy(c, g);
            csv.push_str(&format!(",{v:e},{e:e}"));
            row.insert(format!("energy_{name}"), estimate(v, e));
        }
        csv.push('\n');
        table.push(Value::Object(row));
    }
    put("gates.csv".into(), csv.into_bytes())?;
    Ok(json!({
        "range_m": range,
        "frequency_hz": freq,
        "range_file": "range_m.npy",
        "frequency_file": "frequency_hz.npy",
        "spectra": Value::Object(files),
        "layout": "gates × bins, bins in fftshift order (ν_k = (k − K/2)·f_s/K)",
        "units": "fraction of the pulse energy per bin (expected periodogram, |X_k|²/K)",
        "gate_points": m,
        "sample_rate_hz": spec.sample_rate,
        "pulse_fwhm_s": spec.pulse_fwhm,
        "aperture_radius_m": spec.aperture_radius,
        "field_of_view_rad": spec.cos_fov.acos(),
        "gates": table,
    }))
}
