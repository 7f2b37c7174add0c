//! FMCW outputs of a chirped run: per spectrum detector, the range and radial velocity read off its
//! total up- and down-chirp spectra ([`crate::retrieval::fmcw`]) — in the manifest's
//! `estimates.detectors.NAME` (plain numbers: they have no standard errors, see the module docs
//! there) with the method in `detectors.NAME.fmcw`, and a row in the detector's
//! `NAME_fmcw_estimates.csv`.

use std::collections::BTreeMap;

use serde_json::{Value, json};

use super::Entry as Estimates;

use crate::experiment::{Experiment, RunOutput};
use crate::retrieval::{FmcwEstimate, RetrievalError};

/// The estimate keys, in the order of the CSV columns (part of the scripting interface).
pub const KEYS: [&str; 10] = [
    "range_m",
    "radial_velocity_m_per_s",
    "f_up_hz",
    "f_down_hz",
    "range_centroid_m",
    "radial_velocity_centroid_m_per_s",
    "f_up_centroid_hz",
    "f_down_centroid_hz",
    "range_bin_m",
    "velocity_bin_m_per_s",
];

/// The output file of the detector `name`.
pub fn csv_file(name: &str) -> String {
    format!("{name}_fmcw_estimates.csv")
}

/// The estimates of `e` in the order of [`KEYS`].
pub fn values(e: &FmcwEstimate) -> [f64; 10] {
    [
        e.range_m,
        e.radial_velocity_m_per_s,
        e.f_up_hz,
        e.f_down_hz,
        e.range_centroid_m,
        e.radial_velocity_centroid_m_per_s,
        e.f_up_centroid_hz,
        e.f_down_centroid_hz,
        e.range_bin_m,
        e.velocity_bin_m_per_s,
    ]
}

/// What one detector contributes: its estimates (into `estimates`), the manifest's description
/// of them, and its CSV row (none without estimates). `None` when the run has no chirp or the
/// detector no spectrum.
pub struct Entry {
    pub info: Value,
    pub row: Option<String>,
}

/// Read detector `i`'s estimates off `out`, insert them into its manifest `estimates` map, and
/// return its description and CSV row. No estimates (and a note saying why) when they cannot be
/// read off.
pub fn detector_entry(
    exp: &Experiment,
    out: &RunOutput,
    i: usize,
    estimates: &mut BTreeMap<String, Estimates>,
) -> Option<Entry> {
    let result = exp.fmcw_estimates(out, i)?;
    let name = &exp.detectors[i].name;
    let mut info = json!({
        "spectra": "total up- and down-chirp spectra",
        "range": "R = c·T·(f_up + f_down)/(4B)",
        "radial_velocity": "v = λ0·(f_up − f_down)/4, positive receding (f_up > f_down)",
        "peak": "range_m, radial_velocity_m_per_s, f_up_hz, f_down_hz: the largest bin, refined by the parabola through the logarithms of it and its two neighbours",
        "centroid": "range_centroid_m, radial_velocity_centroid_m_per_s, f_*_centroid_hz: power-weighted mean frequency over the contiguous bins around the peak above 1 % of the peak bin",
        "range_bin_m": "c·T·Δf/(2B): the range one frequency bin spans",
        "velocity_bin_m_per_s": "λ0·Δf/2: the radial velocity one bin of Doppler shift spans (peaks inside their true bins give errors below one range_bin and one velocity_bin)",
        "standard_errors": "none: the up- and down-chirp spectra are the same paths and their cross-covariance over batches is not kept",
        "file": csv_file(name),
    });
    let row = match &result {
        Ok(e) => {
            let v = values(e);
            for (k, x) in KEYS.iter().zip(v) {
                estimates.insert((*k).into(), Estimates::Number(x));
            }
            Some(std::iter::once(name.clone()).chain(v.iter().map(|x| x.to_string())).collect::<Vec<_>>().join(","))
        }
        Err(_) => None,
    };
    if let Some(n) = note(&result) {
        info["note"] = json!(n);
    }
    Some(Entry { info, row })
}

/// What to note about an FMCW retrieval: why there are no estimates, or that the return reaches
/// an end of the frequency axis; `None` when the estimates stand.
pub fn note(result: &Result<FmcwEstimate, RetrievalError>) -> Option<String> {
    match result {
        Ok(e) if !e.is_finite() => Some(
            "estimates that are not finite numbers (written as null): the range conversions c·T/(2B) of this axis overflow"
                .into(),
        ),
        Ok(e) if e.touches_axis_end => Some(
            "the return reaches an end of the frequency axis: it may extend beyond it and the estimates may be cut off (widen detectors.spectrum)"
                .into(),
        ),
        Ok(_) => None,
        Err(RetrievalError::NoSignal) => Some(
            "no estimates: no signal: the up- or down-chirp spectrum has no power inside the frequency axis (see out_of_range_up/down)"
                .into(),
        ),
        Err(other) => Some(format!("no estimates: {other}")),
    }
}

/// The CSV text: a header and the rows given (a detector's, if it has estimates).
pub fn csv(rows: &[String]) -> String {
    let mut s = format!("detector,{}\n", KEYS.join(","));
    for r in rows {
        s.push_str(r);
        s.push('\n');
    }
    s
}
