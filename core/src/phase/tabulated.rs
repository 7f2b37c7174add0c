//! Tabulated phase functions: values at scattering angles (a Mie table, a measurement), read as a
//! density that is linear in `cos θ` between the given angles.
//!
//! The table is held as a distribution of `m = 1 − cos θ ∈ [0, 2]` (`dΩ = 2π dm`, so the density
//! of `m` is `2π p`). Working in `m` keeps full relative precision for the milliradian deflections
//! of forward-peaked particles (red blood cells, raindrops): a node at θ = 1e-5 rad is
//! `m = 2 sin²(θ/2) = 5e-11`, which `1 − cos θ` would round to 0. Linear in `m` is linear in
//! `cos θ`, so [`eval`](TabulatedPhase::eval) is exactly the density that
//! [`sample`](TabulatedPhase::sample) draws from (see [`crate::sampling::tabulated`]).
//!
//! Whatever the normalisation of the values as given, the table is renormalised to 1 over the
//! sphere; [`source_integral`](TabulatedPhase::source_integral) reports what it was.

use std::f64::consts::PI;
use std::fmt;

use super::Deflection;
use crate::sampling::tabulated::{PiecewiseLinear, TableError};

/// A phase function given by a table of values at scattering angles.
#[derive(Clone, PartialEq)]
pub struct TabulatedPhase {
    /// Distribution of `m = 1 − cos θ` on `[0, 2]`.
    m: PiecewiseLinear,
    mean_cosine: f64,
    /// Where the table came from (a file, a Mie specification), for messages and the manifest.
    origin: String,
}

impl fmt::Debug for TabulatedPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Tabulated({} angles, g = {:.6}, from {})", self.m.nodes().len(), self.mean_cosine, self.origin)
    }
}

/// How far the first and last angle may be from 0 and π (radians) and still count as the ends.
const END_TOLERANCE: f64 = 1e-9;

impl TabulatedPhase {
    /// A table of `values` at scattering angles `theta` (radians, strictly monotone, from 0 to π
    /// in either direction), in any normalisation.
    pub fn from_angles(theta: &[f64], values: &[f64], origin: impl Into<String>) -> Result<Self, TableError> {
        check_monotone(theta)?;
        let (first, last) = (theta[0].min(theta[theta.len() - 1]), theta[0].max(theta[theta.len() - 1]));
        if first.abs() > END_TOLERANCE || (last - PI).abs() > END_TOLERANCE {
            return Err(TableError::Invalid(format!(
                "the angles run from {:.6}° to {:.6}°; a phase table must span 0° to 180°",
                first.to_degrees(),
                last.to_degrees()
            )));
        }
        // 2 sin²(θ/2) is 1 − cos θ without cancellation.
        let m_of = |i: usize| 2.0 * (0.5 * theta[i]).sin().powi(2);
        Self::from_ordered(theta[0] > theta[theta.len() - 1], theta.len(), m_of, values, origin.into())
    }

    /// A table of `values` at `cos θ` (strictly monotone, from −1 to 1 in either direction).
    pub fn from_cosines(cos: &[f64], values: &[f64], origin: impl Into<String>) -> Result<Self, TableError> {
        check_monotone(cos)?;
        let n = cos.len();
        let (lo, hi) = (cos[0].min(cos[n - 1]), cos[0].max(cos[n - 1]));
        if (lo + 1.0).abs() > END_TOLERANCE || (hi - 1.0).abs() > END_TOLERANCE {
            return Err(TableError::Invalid(format!("cos θ runs from {lo} to {hi}; a phase table must span −1 to 1")));
        }
        let m_of = |i: usize| (1.0 - cos[i]).clamp(0.0, 2.0);
        Self::from_ordered(cos[0] < cos[n - 1], n, m_of, values, origin.into())
    }

    /// Build from `m(i)`, reversing both columns when `reversed` so that `m` increases.
    fn from_ordered(
        reversed: bool,
        n: usize,
        m_of: impl Fn(usize) -> f64,
        values: &[f64],
        origin: String,
    ) -> Result<Self, TableError> {
        if values.len() != n {
            return Err(TableError::Invalid(format!(
                "{n} angles but {} values; the two columns must have the same length",
                values.len()
            )));
        }
        let order: Vec<usize> = if reversed { (0..n).rev().collect() } else { (0..n).collect() };
        let mut m: Vec<f64> = order.iter().map(|&i| m_of(i)).collect();
        // The callers checked that the ends are 0 and π (within rounding): pin them exactly.
        m[0] = 0.0;
        m[n - 1] = 2.0;
        let v: Vec<f64> = order.iter().map(|&i| values[i]).collect();
        let unreverse = |i: usize| if reversed { n - 1 - i } else { i };
        let m = PiecewiseLinear::new(&m, &v).map_err(|e| match e {
            TableError::NotFinite(i) => TableError::NotFinite(unreverse(i)),
            TableError::Negative(i) => TableError::Negative(unreverse(i)),
            TableError::NotIncreasing(i) => TableError::NotIncreasing(unreverse(i)),
            e => e,
        })?;
        let mean_cosine = 1.0 - m.mean();
        Ok(TabulatedPhase { m, mean_cosine, origin })
    }

    /// Draw a deflection from one uniform number `u ∈ [0, 1)`.
    #[inline(always)]
    pub fn sample(&self, u: f64) -> Deflection {
        Deflection::from_one_minus_cos(self.m.sample(u))
    }

    /// Density (sr⁻¹) at `cos θ`.
    pub fn eval(&self, cos_theta: f64) -> f64 {
        self.eval_one_minus_cos(1.0 - cos_theta)
    }

    /// Density (sr⁻¹) at `1 − cos θ`, without the rounding of `cos θ` near forward.
    pub fn eval_one_minus_cos(&self, m: f64) -> f64 {
        self.m.pdf(m) / (2.0 * PI)
    }

    /// `P(1 − cos θ ≤ m)`.
    pub fn cdf_one_minus_cos(&self, m: f64) -> f64 {
        self.m.cdf(m)
    }

    /// Mean cosine of the tabulated distribution (exact for the linear interpolation).
    pub fn mean_cosine(&self) -> f64 {
        self.mean_cosine
    }

    /// `∫ p dΩ` of the values as given: 1 for a table in sr⁻¹, 4π for one normalised to 4π.
    pub fn source_integral(&self) -> f64 {
        2.0 * PI * self.m.raw_integral()
    }

    /// Number of angles in the table.
    pub fn len(&self) -> usize {
        self.m.nodes().len()
    }

    /// Whether the table has no angles (never, once built).
    pub fn is_empty(&self) -> bool {
        self.m.nodes().is_empty()
    }

    /// Where the table came from.
    pub fn origin(&self) -> &str {
        &self.origin
    }
}

/// Strictly increasing or strictly decreasing, with the first offending index.
fn check_monotone(x: &[f64]) -> Result<(), TableError> {
    if x.len() < 2 {
        return Err(TableError::Invalid(format!("{} angle(s); a phase table needs at least 2", x.len())));
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Err(TableError::NotFinite(i));
    }
    let up = x[1] > x[0];
    match x.windows(2).position(|w| if up { w[1] <= w[0] } else { w[1] >= w[0] }) {
        Some(i) => Err(TableError::NotIncreasing(i + 1)),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::HenyeyGreenstein;

    fn hg_table(g: f64, n: usize) -> TabulatedPhase {
        let hg = HenyeyGreenstein::new(g).unwrap();
        // Dense near forward: θ = π (i/(n−1))².
        let theta: Vec<f64> = (0..n).map(|i| PI * (i as f64 / (n - 1) as f64).powi(2)).collect();
        let values: Vec<f64> = theta.iter().map(|t| 4.0 * PI * hg.eval(t.cos())).collect();
        TabulatedPhase::from_angles(&theta, &values, "test").unwrap()
    }

    #[test]
    fn renormalises_and_reports_the_source_normalisation() {
        let t = hg_table(0.5, 4000);
        // Values were given normalised to 4π.
        assert!((t.source_integral() / (4.0 * PI) - 1.0).abs() < 1e-4, "{}", t.source_integral());
        assert!((t.mean_cosine() - 0.5).abs() < 1e-4, "{}", t.mean_cosine());
        let hg = HenyeyGreenstein::new(0.5).unwrap();
        for c in [-0.9, 0.0, 0.7, 0.999] {
            assert!((t.eval(c) / hg.eval(c) - 1.0).abs() < 2e-3, "cos {c}");
        }
    }

    #[test]
    fn either_direction_and_degrees_or_cosines_agree() {
        let theta: Vec<f64> = (0..=180).map(|d| (d as f64).to_radians()).collect();
        let v: Vec<f64> = theta.iter().map(|t| 1.0 + t.cos().powi(2)).collect();
        let a = TabulatedPhase::from_angles(&theta, &v, "a").unwrap();
        let rt: Vec<f64> = theta.iter().rev().copied().collect();
        let rv: Vec<f64> = v.iter().rev().copied().collect();
        let b = TabulatedPhase::from_angles(&rt, &rv, "b").unwrap();
        let cos: Vec<f64> = theta.iter().map(|t| t.cos()).collect();
        let c = TabulatedPhase::from_cosines(&cos, &v, "c").unwrap();
        for x in [-1.0, -0.3, 0.2, 0.95, 1.0] {
            assert!((a.eval(x) - b.eval(x)).abs() < 1e-14);
            assert!((a.eval(x) - c.eval(x)).abs() < 1e-12);
        }
        // Rayleigh-like: symmetric, mean cosine 0.
        assert!(a.mean_cosine().abs() < 1e-12);
    }

    #[test]
    fn rejects_tables_that_do_not_span_the_sphere_or_are_not_monotone() {
        let d = |v: &[f64]| v.iter().map(|x: &f64| x.to_radians()).collect::<Vec<_>>();
        let e = TabulatedPhase::from_angles(&d(&[0.0, 90.0, 170.0]), &[1.0, 1.0, 1.0], "t").unwrap_err();
        assert!(e.to_string().contains("must span 0° to 180°"), "{e}");
        let e = TabulatedPhase::from_angles(&d(&[0.0, 90.0, 80.0, 180.0]), &[1.0; 4], "t").unwrap_err();
        assert_eq!(e, TableError::NotIncreasing(2));
        let e = TabulatedPhase::from_angles(&d(&[180.0, 90.0, 0.0]), &[1.0, -1.0, 1.0], "t").unwrap_err();
        assert_eq!(e, TableError::Negative(1));
        let e = TabulatedPhase::from_angles(&d(&[0.0, 180.0]), &[1.0], "t").unwrap_err();
        assert!(matches!(e, TableError::Invalid(_)));
    }

    #[test]
    fn forward_nodes_keep_their_precision() {
        // A node at θ = 1e-6 rad is m = 5e-13: it must not collapse onto θ = 0.
        let theta = [0.0, 1e-6, 2e-6, PI];
        let t = TabulatedPhase::from_angles(&theta, &[1e12, 1e12, 0.0, 0.0], "peak").unwrap();
        for k in 0..1000 {
            let d = t.sample(k as f64 / 1000.0);
            assert!(d.one_minus_cos <= 2.0 * (1e-6f64).powi(2) * (1.0 + 1e-9), "{d:?}");
        }
        assert!(t.mean_cosine() > 1.0 - 1e-11);
    }
}
