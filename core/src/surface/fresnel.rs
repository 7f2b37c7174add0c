//! Fresnel reflection and refraction of unpolarised light at a smooth planar interface whose
//! normal is the z axis (every smooth interface of the layer stack; `transport::fresnel`).

use glam::DVec3;

/// Unpolarised Fresnel reflectance for light going from index `n1` into `n2` at incidence
/// `cos_i ∈ [0, 1]`, and the cosine of the refracted angle. Total internal reflection gives
/// `(1, 0)`; a matched interface `(0, cos_i)`.
#[inline]
pub fn reflectance(n1: f64, n2: f64, cos_i: f64) -> (f64, f64) {
    if n1 == n2 {
        return (0.0, cos_i);
    }
    let eta = n1 / n2;
    let sin_t2 = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin_t2 >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin_t2).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    (0.5 * (rs * rs + rp * rp), cos_t)
}

/// Direction refracted through a z-normal interface from `n1` into `n2`, given the refracted
/// cosine from [`reflectance`]: tangential components scale by `n1/n2` (Snell), the normal
/// component keeps its sign.
#[inline]
pub fn refract(dir: DVec3, n1: f64, n2: f64, cos_t: f64) -> DVec3 {
    if n1 == n2 {
        return dir;
    }
    let eta = n1 / n2;
    DVec3::new(eta * dir.x, eta * dir.y, cos_t.copysign(dir.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_and_energy() {
        // R = ((n1 − n2)/(n1 + n2))² at normal incidence: air → glass 1.5 gives 0.04.
        let (r, ct) = reflectance(1.0, 1.5, 1.0);
        assert!((r - 0.04).abs() < 1e-15 && (ct - 1.0).abs() < 1e-15);
        // Reciprocity: R is the same from both sides for the Snell-paired angles.
        let cos_i: f64 = 0.6;
        let (r12, cos_t) = reflectance(1.0, 1.4, cos_i);
        let (r21, back) = reflectance(1.4, 1.0, cos_t);
        assert!((r12 - r21).abs() < 1e-14 && (back - cos_i).abs() < 1e-14);
    }

    #[test]
    fn oblique_incidence_matches_textbook_values() {
        // Air → glass n = 1.5 at 45°: Rs = 0.0920, Rp = 0.0085, R = (Rs + Rp)/2 = 0.05024.
        let cos45 = std::f64::consts::FRAC_1_SQRT_2;
        let (r, cos_t) = reflectance(1.0, 1.5, cos45);
        assert!((r - 0.050_240).abs() < 5e-6, "R(45°) = {r}");
        assert!((cos_t - (1.0f64 - 0.5 / 2.25).sqrt()).abs() < 1e-15);
        // At Brewster's angle (tan θB = n2/n1) the p-polarised part vanishes: R = Rs/2, with
        // Rs = ((cos θi − n cos θt)/(cos θi + n cos θt))².
        let theta_b = 1.5f64.atan();
        let (ci, si) = (theta_b.cos(), theta_b.sin());
        let ct = (1.0 - si * si / 2.25).sqrt();
        let rs = ((ci - 1.5 * ct) / (ci + 1.5 * ct)).powi(2);
        let (rb, _) = reflectance(1.0, 1.5, ci);
        assert!((rb - 0.5 * rs).abs() < 1e-12, "R(Brewster) = {rb}, Rs/2 = {}", 0.5 * rs);
    }

    #[test]
    fn total_internal_reflection() {
        // Critical angle from 1.5 into 1.0: sin θc = 1/1.5.
        let sin_c: f64 = 1.0 / 1.5;
        let cos_c = (1.0 - sin_c * sin_c).sqrt();
        assert_eq!(reflectance(1.5, 1.0, cos_c - 1e-9), (1.0, 0.0));
        let (r, _) = reflectance(1.5, 1.0, cos_c + 1e-6);
        assert!(r < 1.0 && r > 0.9);
        // Grazing incidence reflects everything.
        assert!((reflectance(1.0, 1.5, 0.0).0 - 1.0).abs() < 1e-15);
    }

    #[test]
    fn refracted_direction_is_unit_and_obeys_snell() {
        let d = DVec3::new(0.6, 0.0, 0.8);
        let (_, cos_t) = reflectance(1.0, 1.33, d.z);
        let t = refract(d, 1.0, 1.33, cos_t);
        assert!((t.length() - 1.0).abs() < 1e-14);
        assert!((1.0 * 0.6 - 1.33 * t.x).abs() < 1e-14 && t.z > 0.0);
    }
}
