//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution of Walter et al. (2007),
//! "Microfacet models for refraction through rough surfaces" (EGSR), with Smith's masking
//! function and the sampling of its visible normals of Heitz (2018), "Sampling the GGX
//! distribution of visible normals" (JCGT 7(4)).
//!
//! Directions are in the surface's local frame: the macroscopic normal is `+z` and every
//! direction given here lies on its side (`z > 0`) unless said otherwise. The roughness `α` is
//! GGX's width parameter (Mitsuba 3's `alpha`; `α² ≈ 2/(e + 2)` against a Phong exponent `e`).

use glam::DVec3;

/// The smallest GGX α of a rough face or a rough conductor: a configured roughness `0 < α <
/// ROUGHNESS_MIN` is the smooth face (`α = 0`). The lobe of such a face is narrower than f64 can
/// tell directions apart by their cosines (`1 − cos 10⁻⁸` rounds to 0 against 1, and every test of
/// a direction against a cone or a face compares cosines), and its `D` would leave f64 below
/// `α ≈ 10⁻¹⁵⁴` (`α²` underflows): a face that smooth is the smooth one for every estimator.
pub const ROUGHNESS_MIN: f64 = 1e-8;

/// An isotropic GGX distribution of microfacet normals of roughness `alpha > 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ggx {
    pub alpha: f64,
}

impl Ggx {
    /// The density of microfacet normals `m` per unit projected area and solid angle,
    /// `D(m) = α² / (π ((α² − 1) cos²θ_m + 1)²)` for `m.z > 0` (0 otherwise); `∫ D(m) cos θ_m dω_m = 1`.
    ///
    /// Below `α = 10⁻³` the denominator is written `α² cos²θ_m + sin²θ_m`, with `sin²θ_m` from the
    /// normal's tangential components: the textbook `(α² − 1) cos²θ_m + 1` loses `α²` against 1
    /// (at `α = 10⁻⁹`, `α² − 1` rounds to −1 and a normal of `cos θ_m = 1` gives `D = α²/0 = ∞`) and
    /// `sin²θ_m` to the rounding of `cos θ_m` (`1 − cos θ` is 0 in f64 below `θ ≈ 1.5·10⁻⁸`). Above,
    /// the two forms agree to 10⁻¹⁰ relative; the textbook one is kept there so that the results
    /// of rougher faces stay as they were, bit for bit. The smoothest α a face may have is
    /// [`ROUGHNESS_MIN`], where `D`'s peak, `1/(π α²)`, is 3·10¹⁵.
    #[inline]
    pub fn d(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t =
            if self.alpha >= 1e-3 { (a2 - 1.0) * m.z * m.z + 1.0 } else { a2 * m.z * m.z + (m.x * m.x + m.y * m.y) };
        a2 / (std::f64::consts::PI * t * t)
    }

    /// Smith's `Λ(ω)` of GGX: `(√(1 + α² tan²θ) − 1)/2`, 0 at normal incidence.
    #[inline]
    pub fn lambda(&self, w: DVec3) -> f64 {
        let z2 = w.z * w.z;
        if z2 <= 0.0 {
            return f64::INFINITY;
        }
        let tan2 = ((1.0 - z2) / z2).max(0.0);
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    /// Smith's masking function `G1(ω, m) = 1/(1 + Λ(ω))` where `ω` and `m` are on the same
    /// side of the microfacet (`ω·m` of the sign of `ω.z`), else 0.
    #[inline]
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// A microfacet normal drawn from the distribution of the normals visible from `wi`
    /// (`wi.z > 0`), `D_wi(m) = G1(wi, m) max(0, wi·m) D(m) / wi.z` (Heitz 2018, listing 1: the
    /// hemisphere of the stretched configuration, its projected disk warped by the visible
    /// fraction), from two uniforms in [0, 1).
    #[inline]
    pub fn sample_visible(&self, wi: DVec3, u1: f64, u2: f64) -> DVec3 {
        let a = self.alpha;
        // To the configuration of roughness 1.
        let vh = DVec3::new(a * wi.x, a * wi.y, wi.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { DVec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { DVec3::X };
        let t2 = vh.cross(t1);
        // A point on the unit disk, its lower half squeezed by the visible projected area.
        let r = u1.sqrt();
        let (sin_phi, cos_phi) = (std::f64::consts::TAU * u2).sin_cos();
        let p1 = r * cos_phi;
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin_phi;
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Back to roughness α.
        DVec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
    }

    /// The density of [`Ggx::sample_visible`]: `D_wi(m)` (per steradian of `m`).
    #[inline]
    pub fn pdf_visible(&self, wi: DVec3, m: DVec3) -> f64 {
        let c = wi.dot(m);
        if c <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        self.g1(wi, m) * c * self.d(m) / wi.z
    }
}

/// `wi` mirrored about the microfacet normal `m`: `2(wi·m)m − wi`.
#[inline]
pub fn reflect(wi: DVec3, m: DVec3) -> DVec3 {
    2.0 * wi.dot(m) * m - wi
}

/// `wi` (on the side `m` points to) refracted through the microfacet `m` from index `n_i` into
/// `n_t`, given `cos_t` (the refracted cosine against `m`, from Fresnel's law): the direction
/// on the far side, `−η wi + (η (wi·m) − cos_t) m` with `η = n_i/n_t`.
#[inline]
pub fn refract(wi: DVec3, m: DVec3, n_i: f64, n_t: f64, cos_t: f64) -> DVec3 {
    let eta = n_i / n_t;
    (-eta * wi + (eta * wi.dot(m) - cos_t) * m).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{PathRng, Purpose};

    fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    /// `∫ D(m) cos θ_m dω_m = 1` (projected area), and the visible normals' density integrates
    /// to 1 for every incidence, `∫ G1 (wi·m) D(m) dω_m = wi.z` (Heitz 2014, Eq. 2): by a
    /// midpoint rule in (cos θ, φ).
    #[test]
    fn normals_and_visible_normals_are_normalised() {
        for alpha in [0.05, 0.3, 1.0] {
            let g = Ggx { alpha };
            let (nt, np) = (4000, 256);
            let mut proj = 0.0;
            let mut vis = [0.0; 3];
            let incid = [dir(0.0, 0.0), dir(45.0, 30.0), dir(80.0, 0.0)];
            for i in 0..nt {
                // cos θ on a grid refined towards 1, where D peaks for small α (u² warp).
                let u = (i as f64 + 0.5) / nt as f64;
                let c = 1.0 - u * u;
                let dc = 2.0 * u / nt as f64;
                let s = (1.0 - c * c).sqrt();
                for j in 0..np {
                    let phi = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
                    let m = DVec3::new(s * phi.cos(), s * phi.sin(), c);
                    let dw = dc * std::f64::consts::TAU / np as f64;
                    proj += g.d(m) * c * dw;
                    for (k, wi) in incid.iter().enumerate() {
                        vis[k] += g.pdf_visible(*wi, m) * dw;
                    }
                }
            }
            assert!((proj - 1.0).abs() < 2e-3, "α = {alpha}: ∫D cos = {proj}");
            for (k, v) in vis.iter().enumerate() {
                assert!((v - 1.0).abs() < 3e-3, "α = {alpha}, incidence {k}: ∫D_wi = {v}");
            }
        }
    }

    /// The sampled visible normals follow `D_wi`: χ² of their histogram over bins in
    /// (cos θ_m, φ_m) against the density's integral over each bin.
    #[test]
    fn visible_normals_follow_their_density() {
        let mut rng = PathRng::new(7, Purpose::Test, 0, 0);
        for (alpha, wi) in [(0.2, dir(60.0, 20.0)), (0.6, dir(10.0, 0.0)), (1.0, dir(85.0, 90.0))] {
            let g = Ggx { alpha };
            let (nc, np, n) = (12usize, 8usize, 200_000usize);
            // Bins equal in the density's mass along cos θ_m would be ideal; a u² warp of
            // 1 − cos θ_m spreads the mass enough for these roughnesses.
            let edge = |i: usize| {
                let u = i as f64 / nc as f64;
                1.0 - u * u
            };
            let bin = |m: DVec3| {
                let u = (1.0 - m.z).max(0.0).sqrt().min(1.0 - 1e-12);
                let i = (u * nc as f64) as usize;
                let phi = m.y.atan2(m.x).rem_euclid(std::f64::consts::TAU);
                let j = ((phi / std::f64::consts::TAU) * np as f64) as usize % np;
                i * np + j
            };
            let mut counts = vec![0f64; nc * np];
            for _ in 0..n {
                let m = g.sample_visible(wi, rng.uniform(), rng.uniform());
                assert!((m.length() - 1.0).abs() < 1e-12 && m.z >= 0.0);
                counts[bin(m)] += 1.0;
            }
            // Expected counts: a fine midpoint rule inside each bin.
            let mut chi2 = 0.0;
            let mut dof = 0;
            for i in 0..nc {
                for j in 0..np {
                    let (c0, c1) = (edge(i + 1), edge(i));
                    let (sub_c, sub_p) = (40, 20);
                    let mut p = 0.0;
                    for a in 0..sub_c {
                        let c = c0 + (c1 - c0) * (a as f64 + 0.5) / sub_c as f64;
                        let s = (1.0 - c * c).max(0.0).sqrt();
                        for b in 0..sub_p {
                            let phi = std::f64::consts::TAU * (j as f64 + (b as f64 + 0.5) / sub_p as f64) / np as f64;
                            let m = DVec3::new(s * phi.cos(), s * phi.sin(), c);
                            p += g.pdf_visible(wi, m);
                        }
                    }
                    let expected =
                        n as f64 * p * (c1 - c0) / sub_c as f64 * std::f64::consts::TAU / (np * sub_p) as f64;
                    if expected > 20.0 {
                        chi2 += (counts[i * np + j] - expected).powi(2) / expected;
                        dof += 1;
                    }
                }
            }
            // χ² with `dof` degrees of freedom: mean dof, σ = √(2 dof); 4σ.
            let bound = dof as f64 + 4.0 * (2.0 * dof as f64).sqrt();
            assert!(dof > 30 && chi2 < bound, "α = {alpha}: χ² = {chi2:.1} over {dof} bins (bound {bound:.1})");
        }
    }

    /// Narrow lobes (α down to 10⁻¹², below the smoothest a face may have) evaluate without
    /// cancellation: `D` at the normal is `1/(π α²)`, at the tilt `tan θ = α` a quarter of it
    /// (`1/(π α² cos⁴θ (1 + tan²θ/α²)²)`), and `∫ D cos θ dω = 1` by a quadrature in `tan θ/α`.
    /// (The textbook `(α² − 1) cos²θ + 1` gave `D = ∞` at the normal for α = 10⁻⁹ and 10⁻¹².)
    #[test]
    fn narrow_lobes_evaluate_without_cancellation() {
        for alpha in [1e-5, 1e-8, 1e-9, 1e-12] {
            let g = Ggx { alpha };
            let peak = 1.0 / (std::f64::consts::PI * alpha * alpha);
            let at = |t: f64| {
                // The normal at tan θ = α t, azimuth 30°, from its tangent (no 1 − cos θ).
                let th = (alpha * t).atan();
                let (sin, cos) = th.sin_cos();
                let (sp, cp) = 30f64.to_radians().sin_cos();
                (DVec3::new(sin * cp, sin * sp, cos), cos)
            };
            let d0 = g.d(DVec3::Z);
            assert!((d0 / peak - 1.0).abs() < 1e-12, "α = {alpha}: D(normal) = {d0:e}, 1/(πα²) = {peak:e}");
            let (m, c) = at(1.0);
            let want = peak / (c.powi(4) * 4.0);
            assert!((g.d(m) / want - 1.0).abs() < 1e-9, "α = {alpha}: D(tan θ = α) = {:e}, want {want:e}", g.d(m));
            // ∫ D cos θ dω = 2π ∫ D cos θ sin θ dθ, θ = atan(α t), dθ = α dt/(1 + α²t²), midpoints
            // in ln t over 10⁻⁴ … 10⁴ (outside: 10⁻⁸ of the mass on either side).
            let (lo, hi, n) = ((1e-4f64).ln(), (1e4f64).ln(), 40_000);
            let mut sum = 0.0;
            for i in 0..n {
                let x = lo + (hi - lo) * (i as f64 + 0.5) / n as f64;
                let t = x.exp();
                let (m, c) = at(t);
                let dth = alpha * t / (1.0 + alpha * alpha * t * t) * (hi - lo) / n as f64;
                sum += std::f64::consts::TAU * g.d(m) * c * m.truncate().length() * dth;
            }
            assert!((sum - 1.0).abs() < 1e-4, "α = {alpha}: ∫D cos = {sum}");
        }
    }

    /// Visible normals drawn at narrow lobes are unit normals with finite densities, and a
    /// conductor's and an interface's sampled weights are their `eval/pdf` (finite, in [0, 1]).
    #[test]
    fn narrow_lobes_sample_with_finite_weights() {
        let mut rng = PathRng::new(11, Purpose::Test, 0, 0);
        let eta = num_complex::Complex64::new(0.716, 10.66);
        for alpha in [1e-6, 1e-8, 1e-9, 1e-12] {
            let g = Ggx { alpha };
            let conductor = crate::surface::Bsdf::Conductor { alpha, eta };
            let face = crate::surface::RoughDielectric { alpha };
            for wi in [dir(0.0, 0.0), dir(1e-7, 10.0), dir(40.0, 70.0), dir(85.0, 200.0)] {
                for _ in 0..2000 {
                    let u = [rng.uniform(), rng.uniform(), rng.uniform()];
                    let m = g.sample_visible(wi, u[0], u[1]);
                    assert!(m.is_finite() && (m.length() - 1.0).abs() < 1e-12 && m.z > 0.0, "α = {alpha}: m = {m}");
                    let p = g.pdf_visible(wi, m);
                    assert!(p.is_finite() && p >= 0.0, "α = {alpha}: pdf = {p}");
                    if let Some(smp) = conductor.sample(wi, u) {
                        let (f, pdf) = (conductor.eval(wi, smp.wo), conductor.pdf(wi, smp.wo));
                        assert!(f.is_finite() && pdf.is_finite() && (0.0..=1.0).contains(&smp.weight));
                        assert!(
                            pdf > 0.0 && (f / pdf / smp.weight - 1.0).abs() < 1e-6,
                            "α = {alpha}: {f:e}/{pdf:e} against {}",
                            smp.weight
                        );
                    }
                    for (n_i, n_t) in [(1.0, 1.5), (1.5, 1.0)] {
                        if let Some(c) = face.sample(wi, n_i, n_t, u) {
                            let (f, pdf) = (face.eval(wi, c.wo, n_i, n_t), face.pdf(wi, c.wo, n_i, n_t));
                            assert!(
                                f.is_finite() && pdf.is_finite() && (0.0..=1.0).contains(&c.weight),
                                "α = {alpha}: {f:e} {pdf:e}"
                            );
                            assert!(
                                pdf > 0.0 && (f / pdf / c.weight - 1.0).abs() < 1e-6,
                                "α = {alpha}: {f:e}/{pdf:e} against {}",
                                c.weight
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn reflect_and_refract_obey_the_laws() {
        let m = dir(20.0, 40.0);
        let wi = dir(50.0, 200.0);
        let r = reflect(wi, m);
        assert!((r.length() - 1.0).abs() < 1e-14 && (r.dot(m) - wi.dot(m)).abs() < 1e-14);
        let (ni, nt) = (1.0f64, 1.5f64);
        let ci = wi.dot(m);
        let st2 = (ni / nt).powi(2) * (1.0 - ci * ci);
        let ct = (1.0 - st2).sqrt();
        let t = refract(wi, m, ni, nt, ct);
        // Snell: n_i sin θ_i = n_t sin θ_t about m, the far side, in the plane of wi and m.
        let si = (1.0 - ci * ci).sqrt();
        let st = (1.0 - t.dot(m).powi(2)).sqrt();
        assert!((ni * si - nt * st).abs() < 1e-13 && t.dot(m) < 0.0);
        assert!(wi.cross(m).dot(t).abs() < 1e-13);
    }
}
