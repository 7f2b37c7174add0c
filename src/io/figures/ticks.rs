//! Axis ticks: "nice" positions (1, 2, 5 × 10^k steps) and compact labels, for plots and colour
//! bars.

/// "Nice" tick positions covering `[lo, hi]` with about `target` ticks: multiples of a step of
/// 1, 2 or 5 × 10^k, from the largest multiple ≤ `lo` to the smallest ≥ `hi` (so the first and
/// last may lie outside the range). `lo > hi` is swapped; `lo == hi` gives `[lo]`; a non-finite
/// end gives no ticks.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !lo.is_finite() || !hi.is_finite() {
        return Vec::new();
    }
    let (lo, hi) = (lo.min(hi), lo.max(hi));
    let span = hi - lo;
    if span == 0.0 {
        return vec![lo];
    }
    if !span.is_finite() {
        return vec![lo, hi];
    }
    let target = target.clamp(2, 100);
    let raw = span / (target - 1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let count = |step: f64| ((hi / step).ceil() - (lo / step).floor()).clamp(0.0, 1e6) as usize + 1;
    // The candidate step whose tick count is closest to the target (ties: the larger step).
    let mut best: Option<(usize, f64)> = None;
    for m in [0.5, 1.0, 2.0, 5.0, 10.0, 20.0] {
        let step = m * mag;
        if !step.is_finite() || step <= 0.0 {
            continue;
        }
        let miss = count(step).abs_diff(target);
        if best.is_none_or(|(b, _)| miss <= b) {
            best = Some((miss, step));
        }
    }
    let Some((_, step)) = best else {
        return vec![lo, hi];
    };
    let first = (lo / step).floor();
    let n = count(step).min(1000);
    (0..n)
        .map(|k| {
            let v = (first + k as f64) * step;
            // Snap float noise (3 × 0.1 = 0.30000000000000004) to the nearest short decimal.
            if v.abs() < 1e-9 * step { 0.0 } else { v }
        })
        .collect()
}

/// The number of decimals that show multiples of `step` exactly (0 to 9).
fn decimals_for(step: f64) -> usize {
    (0..=9)
        .find(|&d| {
            let s = step * 10f64.powi(d as i32);
            (s - s.round()).abs() <= 1e-6 * s.max(1.0)
        })
        .unwrap_or(9)
}

/// `v` in scientific notation, C style ("1e-06", "2.5e+04"), with enough mantissa digits (0–3)
/// to tell ticks `step` apart, shortened to at most 8 characters.
fn sci_label(v: f64, step: f64) -> String {
    if v == 0.0 {
        return "0".to_string();
    }
    let e0 = v.abs().log10().floor() as i32;
    let step_digits = (e0 - step.abs().log10().floor() as i32).clamp(0, 3) as usize;
    let mantissa = |e: i32| v / 10f64.powi(e);
    let own_digits: usize = (0..=3usize)
        .find(|&d| {
            let m = mantissa(e0) * 10f64.powi(d as i32);
            (m - m.round()).abs() <= 1e-6 * m.abs().max(1.0)
        })
        .unwrap_or(3);
    let mut digits = step_digits.max(own_digits);
    loop {
        let mut e = e0;
        let mut m = format!("{:.*}", digits, mantissa(e));
        if m.trim_start_matches('-').starts_with("10") {
            e += 1;
            m = format!("{:.*}", digits, mantissa(e));
        }
        if m.contains('.') {
            m = m.trim_end_matches('0').trim_end_matches('.').to_string();
        }
        let s = format!("{m}e{}{:02}", if e < 0 { '-' } else { '+' }, e.unsigned_abs());
        if s.len() <= 8 || digits == 0 {
            return s;
        }
        digits -= 1;
    }
}

/// Tick label text: compact, e.g. "-30", "0.5", "1e-06", "2.5e+04" (at most 8 characters).
/// Fixed-point with just enough decimals for `step`, scientific when the step is ≥ 10⁴ or
/// < 10⁻³ or the fixed form would be too long; (near) zero is written as 0 with the step's
/// decimals ("0", "0.0") or "0" in scientific notation.
pub fn tick_label(v: f64, step: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let step = if step.is_finite() && step != 0.0 {
        step.abs()
    } else if v != 0.0 {
        v.abs()
    } else {
        1.0
    };
    // (Near) zero: float noise from `k × step`, or -0.
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    if (1e-3..1e4).contains(&step) {
        let s = format!("{:.*}", decimals_for(step), v);
        if s.len() <= 8 {
            let negative_zero = s.starts_with('-') && s.parse::<f64>() == Ok(0.0);
            return if negative_zero { s[1..].to_string() } else { s };
        }
    }
    sci_label(v, step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_ticks_steps() {
        assert_eq!(nice_ticks(-30.0, 30.0, 7), vec![-30.0, -20.0, -10.0, 0.0, 10.0, 20.0, 30.0]);
        assert_eq!(nice_ticks(30.0, -30.0, 7), nice_ticks(-30.0, 30.0, 7));
        assert_eq!(nice_ticks(0.0, 1.0, 6), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        let t = nice_ticks(0.013, 0.087, 5);
        assert!(t[0] <= 0.013 && *t.last().unwrap() >= 0.087, "{t:?}");
        let step = t[1] - t[0];
        let norm = step / 10f64.powf(step.log10().floor());
        assert!([1.0, 2.0, 5.0].iter().any(|m| (norm - m).abs() < 1e-9), "{step}");
        assert_eq!(nice_ticks(3.0, 3.0, 5), vec![3.0]);
        assert!(nice_ticks(f64::NAN, 1.0, 5).is_empty());
        assert!(nice_ticks(0.0, f64::INFINITY, 5).is_empty());
        assert_eq!(nice_ticks(-f64::MAX, f64::MAX, 5).len(), 2);
        assert!(nice_ticks(0.0, 1.0, 0).len() >= 2);
        assert!(nice_ticks(1e-300, 2e-300, 5).len() >= 3);
    }

    #[test]
    fn tick_labels() {
        assert_eq!(tick_label(-30.0, 10.0), "-30");
        assert_eq!(tick_label(0.5, 0.5), "0.5");
        assert_eq!(tick_label(0.6000000000000001, 0.2), "0.6");
        assert_eq!(tick_label(1e-6, 1e-6), "1e-06");
        assert_eq!(tick_label(2.5e4, 5e4), "2.5e+04");
        assert_eq!(tick_label(1.5e5, 5e4), "1.5e+05");
        assert_eq!(tick_label(25000.0, 5000.0), "25000");
        assert_eq!(tick_label(1e-17, 0.1), "0.0");
        assert_eq!(tick_label(-1e-17, 1.0), "0");
        assert_eq!(tick_label(1e-22, 1e-6), "0");
        assert_eq!(tick_label(-0.0, 1.0), "0");
        assert_eq!(tick_label(-0.01, 1.0), "0");
        assert_eq!(tick_label(0.0, 0.5), "0.0");
        assert_eq!(tick_label(9.99999e5, 1e5), "1e+06");
        assert_eq!(tick_label(f64::NEG_INFINITY, 1.0), "-inf");
        for (v, step) in [(-1.234567e-12, 1e-15), (123456789.0, 0.1), (-9.87e300, 1e299), (3.0, f64::NAN), (0.1, 0.0)] {
            let s = tick_label(v, step);
            assert!(!s.is_empty() && s.len() <= 8, "{v} {step}: {s}");
        }
    }
}
