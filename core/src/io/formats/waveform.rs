//! Waveform tables (`[cardiac.waveforms] table = "…csv"`): one closed cardiac cycle as CSV rows
//! `time_s,value` or `phase,value`, read with validation and resampled for the waveform's
//! harmonics ([`crate::flow::pulse::Waveform::from_samples`]).

use std::path::Path;

/// Largest waveform table file read, bytes.
pub const MAX_TABLE_BYTES: u64 = 1 << 20;

/// Samples over the cycle a table is resampled to before its harmonics are taken.
pub const RESAMPLED: usize = 512;

/// A number as a message shows it.
fn num(x: f64) -> String {
    if x == 0.0 || (1e-4..1e9).contains(&x.abs()) { format!("{x}") } else { format!("{x:e}") }
}

/// A CSV table of one closed cycle, resampled to [`RESAMPLED`] equally spaced values (the first at
/// t = 0). Its first column is `time_s` (0 to `period`) or `phase` (0 to 1), as its header says
/// (no header: time in s).
pub fn read_table(file: &Path, period: f64) -> Result<Vec<f64>, String> {
    let text =
        crate::io::read_text_limited(file, MAX_TABLE_BYTES, "a waveform table (CSV)").map_err(|e| e.to_string())?;
    let mut rows: Vec<(f64, f64)> = Vec::new();
    let mut scale = 1.0 / period;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let cols: Vec<&str> = line.split(',').map(str::trim).collect();
        if rows.is_empty() && cols.first().is_some_and(|c| c.parse::<f64>().is_err()) {
            match cols[0] {
                "time_s" => {}
                "phase" => scale = 1.0,
                h => return Err(format!("line {}: header column `{h}`: expected time_s or phase", i + 1)),
            }
            continue;
        }
        let [t, v] = cols[..] else {
            return Err(format!("line {}: expected two columns, time (or phase) and value", i + 1));
        };
        let parse = |s: &str| s.parse::<f64>().ok().filter(|x| x.is_finite());
        let (Some(t), Some(v)) = (parse(t), parse(v)) else {
            return Err(format!("line {}: expected two finite numbers", i + 1));
        };
        rows.push((t * scale, v));
    }
    if rows.len() < 3 {
        return Err(format!("{} rows: expected at least 3 over the cycle", rows.len()));
    }
    if rows[0].0 != 0.0 {
        return Err(format!("starts at phase {}: expected the cycle from 0", rows[0].0));
    }
    if let Some(i) = rows.windows(2).position(|w| w[1].0 <= w[0].0) {
        return Err(format!("row {}: times must increase", i + 2));
    }
    let (last_t, last_v) = rows[rows.len() - 1];
    if (last_t - 1.0).abs() > 1e-6 {
        return Err(format!(
            "ends at {} s: the table must close over the cycle, from 0 to the period {} s (60/heart_rate_bpm)",
            num(last_t / scale),
            num(period)
        ));
    }
    let span = rows.iter().fold(0.0f64, |m, r| m.max(r.1.abs()));
    if (last_v - rows[0].1).abs() > 1e-6 * span {
        return Err(format!(
            "does not close over the cycle: its last value {} differs from its first {}",
            num(last_v),
            num(rows[0].1)
        ));
    }
    let mut j = 0;
    Ok((0..RESAMPLED)
        .map(|i| {
            let x = i as f64 / RESAMPLED as f64;
            while rows[j + 1].0 < x {
                j += 1;
            }
            let ((t0, v0), (t1, v1)) = (rows[j], rows[j + 1]);
            v0 + (v1 - v0) * (x - t0) / (t1 - t0)
        })
        .collect())
}
