//! Colour maps, robust colour ranges (percentiles, so that a few bright "firefly" pixels do not
//! set the scale) and the scaling of a unit's numbers to readable tick labels.

/// A colour map from `[0, 1]` to RGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Colormap {
    /// Perceptually ordered dark blue → green → yellow (anchors sampled from viridis).
    Viridis,
    /// Blue (−) → white (0) → red (+), for signed values on a symmetric range.
    Diverging,
    /// Black → white.
    Grey,
}

const VIRIDIS: [[u8; 3]; 9] = [
    [68, 1, 84],
    [71, 44, 122],
    [59, 81, 139],
    [44, 113, 142],
    [33, 144, 141],
    [39, 173, 129],
    [92, 200, 99],
    [170, 220, 50],
    [253, 231, 37],
];
const DIVERGING: [[u8; 3]; 5] = [[33, 102, 172], [146, 197, 222], [247, 247, 247], [244, 165, 130], [178, 24, 43]];

/// Non-finite cells.
pub const NO_DATA: [u8; 3] = [190, 190, 190];

fn interpolate(anchors: &[[u8; 3]], t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (anchors.len() - 1) as f64;
    let i = (x.floor() as usize).min(anchors.len() - 2);
    let f = x - i as f64;
    let (a, b) = (anchors[i], anchors[i + 1]);
    [0, 1, 2].map(|k| (a[k] as f64 + f * (b[k] as f64 - a[k] as f64)).round() as u8)
}

impl Colormap {
    /// The colour at `t` (clamped to `[0, 1]`; NaN as 0).
    pub fn color(self, t: f64) -> [u8; 3] {
        match self {
            Colormap::Viridis => interpolate(&VIRIDIS, t),
            Colormap::Diverging => interpolate(&DIVERGING, t),
            Colormap::Grey => interpolate(&[[0; 3], [255; 3]], t),
        }
    }

    /// `values` as colours on `range` (clamped beyond it; non-finite values as [`NO_DATA`]).
    pub fn colors(self, values: &[f64], (lo, hi): (f64, f64)) -> Vec<[u8; 3]> {
        let span = if hi > lo { hi - lo } else { 1.0 };
        values.iter().map(|&v| if v.is_finite() { self.color((v - lo) / span) } else { NO_DATA }).collect()
    }
}

/// The `q`-quantile (0–1) of the finite values (nearest rank), `None` if there are none.
pub fn quantile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let k = ((q.clamp(0.0, 1.0) * (v.len() - 1) as f64).round() as usize).min(v.len() - 1);
    let (_, x, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    Some(*x)
}

/// The percentile that sets the top of a colour scale: the brightest 0.5 % of the pixels (a
/// few fireflies in a 128² image) saturate instead of darkening the rest.
pub const TOP_QUANTILE: f64 = 0.995;

/// A colour range for values ≥ 0 (or mostly so): from 0 (or the 0.5 % quantile if below 0) to the
/// [`TOP_QUANTILE`] quantile; widened to the largest value when that quantile is 0 (a sparse
/// image whose few non-zero pixels are its content), and to `(0, 1)` without any non-zero value.
pub fn sequential_range(values: &[f64]) -> (f64, f64) {
    let lo = quantile(values, 1.0 - TOP_QUANTILE).unwrap_or(0.0).min(0.0);
    let mut hi = quantile(values, TOP_QUANTILE).unwrap_or(0.0);
    if hi <= lo {
        hi = values.iter().copied().filter(|x| x.is_finite()).fold(lo, f64::max);
    }
    if hi > lo { (lo, hi) } else { (lo, lo + 1.0) }
}

/// A symmetric range `(−m, m)` for signed values: `m` the [`TOP_QUANTILE`] quantile of `|v|`
/// (the largest `|v|` when that is 0; 1 without any non-zero value).
pub fn symmetric_range(values: &[f64]) -> (f64, f64) {
    let abs: Vec<f64> = values.iter().map(|v| v.abs()).collect();
    let mut m = quantile(&abs, TOP_QUANTILE).unwrap_or(0.0);
    if m <= 0.0 {
        m = abs.iter().copied().filter(|x| x.is_finite()).fold(0.0, f64::max);
    }
    if m > 0.0 { (-m, m) } else { (-1.0, 1.0) }
}

/// The power of ten that brings `|x|` into [1, 10), for scaled tick labels: `(factor, suffix)`
/// with values to be multiplied by `factor` and the suffix (`"×10⁻⁷"`) for the label; `(1, "")`
/// for 0.01 ≤ |x| < 10⁴ and for 0 or non-finite. (Powers of 1000 left ticks in the hundreds
/// under a `×10⁻¹²`, issue 37.)
pub fn engineering(x: f64) -> (f64, String) {
    let a = x.abs();
    if !(a.is_finite() && a > 0.0) || (1e-2..1e4).contains(&a) {
        return (1.0, String::new());
    }
    let e = a.log10().floor() as i32;
    // (log10 of a power of ten may round below it: keep the mantissa in [1, 10).)
    let e = if a * 10f64.powi(-e) >= 10.0 { e + 1 } else { e };
    (10f64.powi(-e), format!("×10{}", superscript(e)))
}

/// `e` in superscript digits.
pub fn superscript(e: i32) -> String {
    let digits = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let mut s = String::new();
    if e < 0 {
        s.push('⁻');
    }
    for c in e.unsigned_abs().to_string().chars() {
        s.push(digits[c.to_digit(10).unwrap_or(0) as usize]);
    }
    s
}

/// A tick label for `v` on an axis whose ticks are `step` apart: as few decimals as the step
/// needs, scientific for very large or small numbers.
pub fn tick_label(v: f64, step: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    // A tick meant to be 0 can come out as a rounding residue of the axis range (−5.6e-17 on
    // an axis from −0.6 to 0.6): far below the step, it is 0.
    let a = v.abs();
    if v == 0.0 || (step > 0.0 && step.is_finite() && a < 1e-9 * step) {
        return "0".into();
    }
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.1e}");
        return s.replace(".0e", "e");
    }
    let step = if step > 0.0 && step.is_finite() { step } else { a };
    let decimals = (-(step.log10().floor()) as i32).clamp(0, 6) as usize;
    format!("{v:.decimals$}")
}

/// Power in dB (10 log10); NaN (a gap in a line) for values ≤ 0.
pub fn db(v: f64) -> f64 {
    if v > 0.0 { 10.0 * v.log10() } else { f64::NAN }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rounding_residue_at_zero_is_labelled_zero() {
        assert_eq!(tick_label(-5.551115123125783e-17, 0.2), "0");
        assert_eq!(tick_label(0.0, 0.2), "0");
        assert_eq!(tick_label(0.2, 0.2), "0.2");
        assert_eq!(tick_label(3e-9, 1e-9), "3e-9");
    }

    #[test]
    fn fireflies_do_not_set_the_scale() {
        // 128² pixels ~1, a dozen fireflies at 1000.
        let mut v = vec![1.0; 128 * 128];
        for k in 0..12 {
            v[k * 1000] = 1000.0;
        }
        let (lo, hi) = sequential_range(&v);
        assert_eq!((lo, hi), (0.0, 1.0));
        // A single non-zero pixel is the content: it sets the scale.
        let mut one = vec![0.0; 256];
        one[17] = 3e-9;
        assert_eq!(sequential_range(&one), (0.0, 3e-9));
        assert_eq!(sequential_range(&[0.0; 4]), (0.0, 1.0));
        assert_eq!(sequential_range(&[]), (0.0, 1.0));
        assert_eq!(symmetric_range(&[0.0, -2.0, 1.0]), (-2.0, 2.0));
        assert_eq!(symmetric_range(&[f64::NAN]), (-1.0, 1.0));
    }

    #[test]
    fn labels_and_units() {
        assert_eq!(engineering(3.2e-7), (1e7, "×10⁻⁷".into()));
        assert_eq!(engineering(0.5).0, 1.0);
        assert_eq!(engineering(2.5e5).1, "×10⁵");
        assert_eq!(engineering(3.6e-10).1, "×10⁻¹⁰");
        for x in [1e-7, 9.99e-7, 1e5, 4.2e-12] {
            let m = x * engineering(x).0;
            assert!((1.0..10.0).contains(&m), "{x}: {m}");
        }
        assert_eq!(tick_label(0.25, 0.05), "0.25");
        assert_eq!(tick_label(-30.0, 10.0), "-30");
        assert_eq!(tick_label(2e-6, 1e-6), "2e-6");
        assert!(db(0.0).is_nan() && db(-1.0).is_nan() && (db(1e-3) + 30.0).abs() < 1e-12);
        assert_eq!(Colormap::Viridis.colors(&[f64::NAN, 0.0, 2.0], (0.0, 1.0)), [NO_DATA, VIRIDIS[0], VIRIDIS[8]]);
    }
}
