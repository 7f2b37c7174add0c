//! Velocity–azimuth display (VAD): the wind vector from radial velocities along several pointings
//! (Browning & Wexler 1968, J. Appl. Meteor. 7:105, in its least-squares form).
//!
//! **Frame.** [`pointing`] uses `x` = east, `y` = north, `z` = up, azimuth clockwise from north
//! (0 = north, 90° = east) and elevation above the horizontal. [`vad_fit`] takes any unit vectors
//! and returns the wind in their frame; its horizontal speed and direction read `x` as east and `y`
//! as north.
//!
//! **Model.** A uniform wind `V` seen along the unit pointing `d̂_i` (away from the lidar) gives
//! the radial velocity `v_i = d̂_i·V` (positive receding, the crate's Doppler sign). `V` minimises
//! `χ² = Σ_i ((v_i − d̂_i·V)/σ_i)²`: with `N = Σ_i d̂_i d̂_iᵀ/σ_i²` (the normal matrix),
//! `V = N⁻¹·Σ_i v_i d̂_i/σ_i²`, and `Cov V = N⁻¹` for known `σ_i`. Without standard errors every
//! `σ_i = 1` and `Cov V = N⁻¹·χ²/(n − 3)` (the noise level estimated from the residuals).

use super::linalg::{condition_number, spd_inverse};
use super::{RetrievalError, check_finite, check_len, check_stderr};
use glam::{DMat3, DVec3};

/// Beyond this condition number of the normal matrix (10 of 16 significant digits lost in the
/// solve) the pointings are treated as degenerate: they lie in, or too near, one plane through
/// the origin and leave one wind component undetermined.
pub const MAX_CONDITION: f64 = 1e10;

const COPLANAR: &str =
    "the pointings lie in (or near) one plane through the origin; one wind component is undetermined";

/// Tolerance on `|d̂| = 1` for a pointing.
const UNIT_TOL: f64 = 1e-9;

/// The unit pointing vector at `azimuth_rad` (clockwise from north) and `elevation_rad` (above
/// the horizontal) in the frame `x` = east, `y` = north, `z` = up:
/// `(cos e·sin a, cos e·cos a, sin e)`.
pub fn pointing(azimuth_rad: f64, elevation_rad: f64) -> DVec3 {
    let (sa, ca) = azimuth_rad.sin_cos();
    let (se, ce) = elevation_rad.sin_cos();
    DVec3::new(ce * sa, ce * ca, se)
}

/// A VAD retrieval.
#[derive(Debug, Clone, PartialEq)]
pub struct VadFit {
    /// `(V_x, V_y, V_z)`, m/s, in the frame of the pointings (east, north, up for [`pointing`]).
    pub wind: DVec3,
    /// `Cov V` (m²/s²); `None` without standard errors and with exactly 3 pointings (no residual
    /// to estimate the noise from).
    pub covariance: Option<DMat3>,
    /// Whether the covariance was scaled by `χ²/dof` (no standard errors given).
    pub covariance_scaled: bool,
    /// `Σ ((v_i − d̂_i·V)/σ_i)²` (`σ_i = 1` without standard errors).
    pub chi2: f64,
    /// Pointings minus 3.
    pub dof: usize,
    /// `v_i − d̂_i·V`, m/s.
    pub residuals: Vec<f64>,
    /// `λ_max/λ_min` of the unit-weight normal matrix `Σ d̂_i d̂_iᵀ`: the conditioning of the
    /// geometry (6 for a full ring at 60° elevation).
    pub condition_number: f64,
    /// `√(V_x² + V_y²)`, m/s.
    pub horizontal_speed: f64,
    /// First-order standard error: `σ² = (u²C_uu + 2uv·C_uv + v²C_vv)/(u² + v²)`; for a calm
    /// (speed exactly 0, where that is undefined) `√max(C_uu, C_vv)`.
    pub horizontal_speed_stderr: Option<f64>,
    /// Meteorological direction: where the wind blows *from*, degrees clockwise from north in
    /// `[0, 360)`: `atan2(−u, −v)` (a wind from the west, `u > 0`, is 270°). 0 for a calm.
    pub direction_from_deg: f64,
    /// First-order standard error (degrees): `σ² = (v²C_uu − 2uv·C_uv + u²C_vv)/(u² + v²)²` rad²;
    /// infinite for a calm.
    pub direction_stderr_deg: Option<f64>,
}

impl VadFit {
    /// `√diag(Cov V)`, m/s.
    pub fn wind_stderr(&self) -> Option<DVec3> {
        self.covariance.map(|c| DVec3::new(c.x_axis.x.sqrt(), c.y_axis.y.sqrt(), c.z_axis.z.sqrt()))
    }
}

/// Least-squares wind from radial velocities `radial_velocities[i]` (m/s, positive receding)
/// along unit vectors `pointings[i]`, weighted by `stderr` (m/s) when given (see the module docs).
///
/// Errors: mismatched lengths; fewer than 3 pointings ([`RetrievalError::TooFewPoints`]); a
/// non-finite value; a pointing that is not a unit vector; a non-positive standard error;
/// pointings in (or within round-off of) one plane through the origin
/// ([`RetrievalError::Degenerate`]: the condition number of `Σ d̂_i d̂_iᵀ` exceeds
/// [`MAX_CONDITION`]).
pub fn vad_fit(
    pointings: &[DVec3],
    radial_velocities: &[f64],
    stderr: Option<&[f64]>,
) -> Result<VadFit, RetrievalError> {
    let n = pointings.len();
    check_len("radial_velocities", radial_velocities, n)?;
    if n < 3 {
        return Err(RetrievalError::TooFewPoints { needed: 3, found: n });
    }
    check_finite("radial_velocities", radial_velocities)?;
    if let Some(se) = stderr {
        check_len("stderr", se, n)?;
        check_stderr(se)?;
    }
    for (index, d) in pointings.iter().enumerate() {
        if !d.is_finite() {
            return Err(RetrievalError::NonFinite { what: "pointings", index });
        }
        if (d.length() - 1.0).abs() > UNIT_TOL {
            return Err(RetrievalError::InvalidParameter {
                name: "pointing",
                value: d.length(),
                expected: "unit vectors (|d̂| = 1 within 1e-9)",
            });
        }
    }
    let weight = |i: usize| stderr.map_or(1.0, |se| 1.0 / (se[i] * se[i]));
    // Σ w_i d̂_i d̂_iᵀ as a row-major 3×3.
    let normal_matrix = |w: &dyn Fn(usize) -> f64| {
        let mut m = [0.0; 9];
        for (i, d) in pointings.iter().enumerate() {
            let d = d.to_array();
            for a in 0..3 {
                for b in 0..3 {
                    m[a * 3 + b] += w(i) * d[a] * d[b];
                }
            }
        }
        m
    };
    // The geometry alone decides degeneracy (unequal weights would inflate the condition number
    // of the weighted matrix without any plane in sight).
    let condition = condition_number(&normal_matrix(&|_| 1.0), 3);
    if condition > MAX_CONDITION {
        return Err(RetrievalError::Degenerate { what: COPLANAR, condition });
    }
    let normal = normal_matrix(&weight);
    let rhs: DVec3 = pointings.iter().zip(radial_velocities).enumerate().map(|(i, (d, v))| weight(i) * v * *d).sum();
    let inv = spd_inverse(&normal, 3).ok_or_else(|| RetrievalError::Degenerate {
        what: "the weighted normal matrix is singular (standard errors spanning too many decades)",
        condition: condition_number(&normal, 3),
    })?;
    // Row-major 3×3 → glam's column-major DMat3 (symmetric, so the same either way).
    let n_inv = DMat3::from_cols_slice(&inv);
    let wind = n_inv * rhs;
    let residuals: Vec<f64> = pointings.iter().zip(radial_velocities).map(|(d, v)| v - d.dot(wind)).collect();
    let chi2: f64 = residuals.iter().enumerate().map(|(i, r)| weight(i) * r * r).sum();
    let dof = n - 3;
    let covariance = match (stderr, dof) {
        (Some(_), _) => Some(n_inv),
        (None, 0) => None,
        (None, _) => Some(n_inv * (chi2 / dof as f64)),
    };
    let (horizontal_speed, horizontal_speed_stderr, direction_from_deg, direction_stderr_deg) =
        horizontal(wind, covariance.as_ref());
    Ok(VadFit {
        wind,
        covariance,
        covariance_scaled: stderr.is_none(),
        chi2,
        dof,
        residuals,
        condition_number: condition,
        horizontal_speed,
        horizontal_speed_stderr,
        direction_from_deg,
        direction_stderr_deg,
    })
}

/// Horizontal speed and meteorological direction (degrees, from where the wind blows) of `wind`
/// (`x` east, `y` north), with first-order standard errors from `cov`.
///
/// With `u = V_x`, `v = V_y`, `s = √(u² + v²)` and `θ = atan2(−u, −v)`:
/// `ds = (u·du + v·dv)/s` and `dθ = (v·du − u·dv)/s²`.
fn horizontal(wind: DVec3, cov: Option<&DMat3>) -> (f64, Option<f64>, f64, Option<f64>) {
    let (u, v) = (wind.x, wind.y);
    let speed = u.hypot(v);
    let direction = if speed > 0.0 { (-u).atan2(-v).to_degrees().rem_euclid(360.0) } else { 0.0 };
    // `rem_euclid` can return 360.0 for a tiny negative angle.
    let direction = if direction >= 360.0 { 0.0 } else { direction };
    let Some(c) = cov else { return (speed, None, direction, None) };
    let (cuu, cvv, cuv) = (c.x_axis.x, c.y_axis.y, c.x_axis.y);
    if speed == 0.0 {
        return (speed, Some(cuu.max(cvv).sqrt()), direction, Some(f64::INFINITY));
    }
    let s2 = speed * speed;
    let var_speed = (u * u * cuu + 2.0 * u * v * cuv + v * v * cvv) / s2;
    let var_dir = (v * v * cuu - 2.0 * u * v * cuv + u * u * cvv) / (s2 * s2);
    (speed, Some(var_speed.max(0.0).sqrt()), direction, Some(var_dir.max(0.0).sqrt().to_degrees()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn ring(count: usize, elevation_deg: f64) -> Vec<DVec3> {
        (0..count).map(|i| pointing(2.0 * PI * i as f64 / count as f64, elevation_deg.to_radians())).collect()
    }

    #[test]
    fn pointing_frame() {
        let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-15;
        assert!(close(pointing(0.0, 0.0), DVec3::Y)); // north
        assert!(close(pointing(0.5 * PI, 0.0), DVec3::X)); // east: clockwise from north
        assert!(close(pointing(1.234, 0.5 * PI), DVec3::Z)); // up
        let d = pointing(0.3, 1.0);
        assert!((d.length() - 1.0).abs() < 1e-15);
        // A wind blowing towards the pointing's azimuth recedes: positive radial velocity.
        assert!(d.dot(DVec3::new(0.3f64.sin(), 0.3f64.cos(), 0.0)) > 0.0);
    }

    #[test]
    fn exact_wind_from_4_and_12_azimuths() {
        let wind = DVec3::new(6.5, -3.25, 0.4);
        for count in [4, 12] {
            let dirs = ring(count, 60.0);
            let v: Vec<f64> = dirs.iter().map(|d| d.dot(wind)).collect();
            let fit = vad_fit(&dirs, &v, None).unwrap();
            assert!((fit.wind - wind).abs().max_element() < 1e-12, "{count}: {:?}", fit.wind);
            assert!(fit.chi2 < 1e-24);
            assert_eq!(fit.dof, count - 3);
            // A full ring at 60°: N = diag(n cos²e/2, n cos²e/2, n sin²e), condition 6.
            assert!((fit.condition_number - 6.0).abs() < 1e-9, "{}", fit.condition_number);
            assert!((fit.horizontal_speed - 6.5f64.hypot(3.25)).abs() < 1e-12);
        }
    }

    #[test]
    fn weighted_solution_is_the_weighted_normal_equations() {
        // Three pointings determine V exactly whatever the weights; with a fourth, inconsistent
        // one, a huge weight on it pulls the solution onto it.
        let dirs = vec![DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(1.0, 1.0, 0.0).normalize()];
        let v = [1.0, 2.0, 3.0, 0.0];
        let fit = vad_fit(&dirs, &v, Some(&[1.0, 1.0, 1.0, 1e-6])).unwrap();
        assert!(fit.residuals[3].abs() < 1e-9);
        // Unit weights: the normal equations are (I + e·eᵀ)·V = (1, 2, 3) = b, so by
        // Sherman–Morrison V = b − e·(e·b)/2.
        let fit = vad_fit(&dirs, &v, None).unwrap();
        let e = DVec3::new(1.0, 1.0, 0.0).normalize();
        let b = DVec3::new(1.0, 2.0, 3.0);
        let expect = b - e * (e.dot(b) / 2.0);
        assert!((fit.wind - expect).abs().max_element() < 1e-14, "{:?}", fit.wind);
        assert_eq!(fit.dof, 1);
        assert!(fit.covariance_scaled);
    }

    #[test]
    fn direction_is_where_the_wind_comes_from() {
        let dir = |u: f64, v: f64| horizontal(DVec3::new(u, v, 0.0), None).2;
        assert!((dir(5.0, 0.0) - 270.0).abs() < 1e-12); // from the west, blowing east
        assert!((dir(-5.0, 0.0) - 90.0).abs() < 1e-12); // from the east
        assert!(dir(0.0, -5.0).abs() < 1e-12); // from the north, blowing south
        assert!((dir(0.0, 5.0) - 180.0).abs() < 1e-12); // from the south
        assert!((dir(3.0, 3.0) - 225.0).abs() < 1e-12); // from the south-west
        assert_eq!(dir(0.0, 0.0), 0.0);
        // The same through the whole retrieval.
        let dirs = ring(8, 60.0);
        let v: Vec<f64> = dirs.iter().map(|d| d.dot(DVec3::new(5.0, 0.0, 0.0))).collect();
        assert!((vad_fit(&dirs, &v, None).unwrap().direction_from_deg - 270.0).abs() < 1e-9);
    }

    #[test]
    fn propagated_horizontal_errors_by_hand() {
        // u = 3, v = 4, s = 5, C_uu = 0.04, C_vv = 0.09, C_uv = 0.01.
        let c = DMat3::from_cols_array(&[0.04, 0.01, 0.0, 0.01, 0.09, 0.0, 0.0, 0.0, 1.0]);
        let (s, ss, _, sd) = horizontal(DVec3::new(3.0, 4.0, 7.0), Some(&c));
        assert!((s - 5.0).abs() < 1e-15);
        let var_s: f64 = (9.0 * 0.04 + 2.0 * 12.0 * 0.01 + 16.0 * 0.09) / 25.0;
        let var_d: f64 = (16.0 * 0.04 - 2.0 * 12.0 * 0.01 + 9.0 * 0.09) / 625.0;
        assert!((ss.unwrap() - var_s.sqrt()).abs() < 1e-15);
        assert!((sd.unwrap() - var_d.sqrt().to_degrees()).abs() < 1e-12);
    }

    #[test]
    fn degenerate_geometry_is_named() {
        let wind = DVec3::new(1.0, 2.0, 0.5);
        // Two pointings.
        let two = ring(2, 60.0);
        let v: Vec<f64> = two.iter().map(|d| d.dot(wind)).collect();
        assert_eq!(vad_fit(&two, &v, None), Err(RetrievalError::TooFewPoints { needed: 3, found: 2 }));
        // One azimuth, many elevations: all in the vertical plane through north.
        let plane: Vec<DVec3> = (0..6).map(|i| pointing(0.0, (10.0 * i as f64).to_radians())).collect();
        let v: Vec<f64> = plane.iter().map(|d| d.dot(wind)).collect();
        match vad_fit(&plane, &v, None) {
            Err(RetrievalError::Degenerate { condition, .. }) => assert!(condition > MAX_CONDITION),
            other => panic!("{other:?}"),
        }
        // All horizontal: the vertical wind is undetermined.
        let flat = ring(8, 0.0);
        let v: Vec<f64> = flat.iter().map(|d| d.dot(wind)).collect();
        assert!(matches!(vad_fit(&flat, &v, None), Err(RetrievalError::Degenerate { .. })));
        // A tilted plane through the origin.
        let n = DVec3::new(1.0, -2.0, 0.7).normalize();
        let tilted: Vec<DVec3> = ring(7, 30.0).iter().map(|d| (*d - n * n.dot(*d)).normalize()).collect();
        let v: Vec<f64> = tilted.iter().map(|d| d.dot(wind)).collect();
        assert!(matches!(vad_fit(&tilted, &v, None), Err(RetrievalError::Degenerate { .. })));
    }

    #[test]
    fn bad_input_is_an_error() {
        let dirs = ring(4, 60.0);
        assert!(matches!(vad_fit(&dirs, &[1.0; 3], None), Err(RetrievalError::LengthMismatch { .. })));
        assert!(matches!(
            vad_fit(&dirs, &[1.0, 1.0, f64::NAN, 1.0], None),
            Err(RetrievalError::NonFinite { index: 2, .. })
        ));
        let mut long = dirs.clone();
        long[1] *= 1.01;
        assert!(matches!(
            vad_fit(&long, &[1.0; 4], None),
            Err(RetrievalError::InvalidParameter { name: "pointing", .. })
        ));
        assert!(vad_fit(&dirs, &[1.0; 4], Some(&[1.0, 0.0, 1.0, 1.0])).is_err());
        // Three pointings without standard errors: a solution but no covariance.
        let fit = vad_fit(&dirs[..3], &[1.0, 2.0, 3.0], None).unwrap();
        assert_eq!((fit.dof, fit.covariance), (0, None));
        assert_eq!(fit.horizontal_speed_stderr, None);
    }
}
