//! Surface scattering (issue 38): the BSDFs of opaque surfaces and of rough interfaces between
//! media.
//!
//! Every function here works in the surface's local frame ([`Frame`]): the macroscopic normal is
//! `+z` on the side the light arrives from, and `wi` is the direction back towards where the light
//! came from (`wi = −dir_in`, `wi.z > 0`); `wo` is the direction it leaves in. The walk carries
//! power (a path's weight is a fraction of the emitted power), so a sampled direction comes with
//! the weight `f(wi, wo) |wo.z| / pdf(wo)` by which the path's weight is multiplied, and
//! [`Bsdf::eval`] gives `f(wi, wo) |wo.z|` (per steradian of `wo`): the density of scattered power
//! a shadow ray needs, as a phase function's `p` is for a particle.
//!
//! Models: the Lambertian reflector; the rough conductor of Walter et al. (2007) with GGX normals
//! and the exact Fresnel reflectance of a complex index (`α = 0`: a smooth mirror); a mixture of
//! those; the rough dielectric interface ([`RoughDielectric`]). Masking–shadowing is Smith's
//! separable form, `G = G1(wi) G1(wo)`, as Mitsuba 3's `roughconductor` and `roughdielectric`
//! (the peers the validation compares with): single scattering among the microfacets, so a rough
//! surface loses the energy of the light that would scatter twice among them (Heitz et al. 2016).

pub mod fresnel;
pub mod metals;
pub mod microfacet;

use glam::DVec3;
use num_complex::Complex64;

pub use microfacet::Ggx;

use crate::sampling::warp;

/// An orthonormal frame about a surface normal: local `+z` is `n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub n: DVec3,
    pub t: DVec3,
    pub b: DVec3,
}

impl Frame {
    pub fn new(n: DVec3) -> Self {
        let (t, b) = warp::orthonormal_basis(n);
        Frame { n, t, b }
    }

    #[inline]
    pub fn to_local(&self, w: DVec3) -> DVec3 {
        DVec3::new(w.dot(self.t), w.dot(self.b), w.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, w: DVec3) -> DVec3 {
        w.x * self.t + w.y * self.b + w.z * self.n
    }
}

/// Unpolarised Fresnel reflectance of a conductor of complex index `eta = n + ik` relative to
/// the medium the light arrives from, at incidence `cos_i ∈ [0, 1]`: the mean of `|r_s|²` and
/// `|r_p|²` with `cos θ_t = √(1 − sin²θ_i/η²)` (complex; Born & Wolf §14.2). With `k = 0` it is
/// the dielectric's reflectance ([`fresnel::reflectance`] for `n > 1`).
#[inline]
pub fn conductor_reflectance(eta: Complex64, cos_i: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    if cos_i == 0.0 {
        // Grazing incidence reflects everything (and `η = 1` would give 0/0 below).
        return 1.0;
    }
    let sin2 = 1.0 - cos_i * cos_i;
    let cos_t = (Complex64::new(1.0, 0.0) - sin2 / (eta * eta)).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    // (Where the reflection is total, |r|² may round an ulp above 1.)
    (0.5 * (rs.norm_sqr() + rp.norm_sqr())).min(1.0)
}

/// What an opaque surface does to the light arriving at it: it reflects a share back (into the
/// medium above it) and absorbs the rest.
#[derive(Debug, Clone, PartialEq)]
pub enum Bsdf {
    /// The ideal diffuse reflector: `f = albedo/π`.
    Lambertian { albedo: f64 },
    /// A metal: GGX microfacets of roughness `alpha` (0: a smooth mirror) with the Fresnel
    /// reflectance of the complex index `eta` relative to the medium above.
    Conductor { alpha: f64, eta: Complex64 },
    /// A weighted sum of the others (weights > 0, summing to 1): each reflection is one of them,
    /// drawn by weight.
    Mixture(Vec<(f64, Bsdf)>),
}

/// A direction drawn from a BSDF and the factor on the path's weight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampled {
    /// The local direction the light leaves in.
    pub wo: DVec3,
    /// `f |wo.z| / pdf`: the share of the power carried on.
    pub weight: f64,
    /// Whether the direction was drawn from a Dirac lobe (a smooth mirror), which a shadow ray
    /// cannot reach.
    pub delta: bool,
}

impl Bsdf {
    /// A direction for light arriving from `wi` (`wi.z > 0`) from three uniforms; `None` when the
    /// drawn direction is below the surface (a rough surface's masked share: the energy its
    /// single-scattering model loses).
    pub fn sample(&self, wi: DVec3, u: [f64; 3]) -> Option<Sampled> {
        let s = self.draw(wi, u);
        debug_assert!(
            s.is_none_or(|s| s.weight >= 0.0
                && s.weight <= self.albedo_bound()
                && (s.wo.length_squared() - 1.0).abs() < 1e-9),
            "a BSDF's draw {s:?} from {wi} outside its bound {} or not unit",
            self.albedo_bound()
        );
        s
    }

    /// The largest share of the power a reflection can carry on: a Lambertian's albedo, a
    /// conductor's 1 (Fresnel times masking), a mixture's largest part's.
    pub fn albedo_bound(&self) -> f64 {
        match self {
            Bsdf::Lambertian { albedo } => *albedo,
            Bsdf::Conductor { .. } => 1.0,
            Bsdf::Mixture(parts) => parts.iter().map(|(_, p)| p.albedo_bound()).fold(0.0, f64::max),
        }
    }

    /// [`Bsdf::sample`] without its checks.
    fn draw(&self, wi: DVec3, u: [f64; 3]) -> Option<Sampled> {
        match self {
            Bsdf::Lambertian { albedo } => {
                let wo = cosine_hemisphere(u[0], u[1]);
                (wo.z > 0.0).then_some(Sampled { wo, weight: *albedo, delta: false })
            }
            &Bsdf::Conductor { alpha, eta } => {
                if alpha == 0.0 {
                    let wo = DVec3::new(-wi.x, -wi.y, wi.z);
                    return Some(Sampled { wo, weight: conductor_reflectance(eta, wi.z), delta: true });
                }
                let g = Ggx { alpha };
                let m = g.sample_visible(wi, u[0], u[1]);
                let wo = microfacet::reflect(wi, m);
                if wo.z <= 0.0 {
                    return None;
                }
                let weight = conductor_reflectance(eta, wi.dot(m)) * g.g1(wo, m);
                Some(Sampled { wo, weight, delta: false })
            }
            Bsdf::Mixture(parts) => {
                // The first uniform picks the part and is stretched back to [0, 1) for it.
                let mut acc = 0.0;
                for (k, (w, part)) in parts.iter().enumerate() {
                    if u[0] < acc + w || k + 1 == parts.len() {
                        let v = ((u[0] - acc) / w).clamp(0.0, 1.0 - f64::EPSILON);
                        return part.sample(wi, [v, u[1], u[2]]);
                    }
                    acc += w;
                }
                None
            }
        }
    }

    /// `f(wi, wo) |wo.z|`: the reflected power per steradian of `wo` (0 below the surface and
    /// for a smooth mirror's Dirac lobe).
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match self {
            Bsdf::Lambertian { albedo } => albedo * std::f64::consts::FRAC_1_PI * wo.z,
            &Bsdf::Conductor { alpha, eta } => {
                if alpha == 0.0 {
                    return 0.0;
                }
                let g = Ggx { alpha };
                let m = (wi + wo).normalize();
                let f =
                    conductor_reflectance(eta, wi.dot(m)) * g.d(m) * g.g1(wi, m) * g.g1(wo, m) / (4.0 * wi.z * wo.z);
                f * wo.z
            }
            Bsdf::Mixture(parts) => parts.iter().map(|(w, p)| w * p.eval(wi, wo)).sum(),
        }
    }

    /// The density of [`Bsdf::sample`]'s direction per steradian of `wo` (its continuous part).
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        match self {
            Bsdf::Lambertian { .. } => wo.z * std::f64::consts::FRAC_1_PI,
            &Bsdf::Conductor { alpha, .. } => {
                if alpha == 0.0 {
                    return 0.0;
                }
                let m = (wi + wo).normalize();
                // The reflection's Jacobian dω_m/dω_o = 1/(4 wo·m).
                Ggx { alpha }.pdf_visible(wi, m) / (4.0 * wo.dot(m))
            }
            Bsdf::Mixture(parts) => parts.iter().map(|(w, p)| w * p.pdf(wi, wo)).sum(),
        }
    }

    /// Whether it has a Dirac lobe (a smooth mirror, alone or in a mixture), which turns a
    /// collimated beam into another one.
    pub fn has_delta_part(&self) -> bool {
        match self {
            Bsdf::Lambertian { .. } => false,
            Bsdf::Conductor { alpha, .. } => *alpha == 0.0,
            Bsdf::Mixture(parts) => parts.iter().any(|(_, p)| p.has_delta_part()),
        }
    }

    /// The narrowest microfacet lobe (the smallest GGX α > 0 of its rough conductors), if any.
    pub fn narrowest_lobe(&self) -> Option<f64> {
        match self {
            Bsdf::Lambertian { .. } => None,
            Bsdf::Conductor { alpha, .. } => (*alpha > 0.0).then_some(*alpha),
            Bsdf::Mixture(parts) => parts.iter().filter_map(|(_, p)| p.narrowest_lobe()).reduce(f64::min),
        }
    }

    /// Whether a shadow ray can reach any of its lobes (not a smooth mirror alone).
    pub fn has_continuous_part(&self) -> bool {
        match self {
            Bsdf::Lambertian { .. } => true,
            Bsdf::Conductor { alpha, .. } => *alpha > 0.0,
            Bsdf::Mixture(parts) => parts.iter().any(|(_, p)| p.has_continuous_part()),
        }
    }
}

/// A cosine-weighted direction on the upper hemisphere (Malley's method).
#[inline]
pub fn cosine_hemisphere(u1: f64, u2: f64) -> DVec3 {
    let (x, y) = warp::uniform_disk(u1, u2);
    DVec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

/// The top face of a layer, between its medium and the one above: how light crosses it. A smooth
/// face is Fresnel's, which the walk takes inline; a rough one is a surface model the walk draws
/// its crossing from. A new model is a variant here.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Interface {
    #[default]
    Smooth,
    Rough(RoughDielectric),
}

impl Interface {
    /// The face of GGX roughness `alpha` (0: smooth).
    pub fn with_roughness(alpha: f64) -> Self {
        if alpha > 0.0 { Interface::Rough(RoughDielectric { alpha }) } else { Interface::Smooth }
    }

    /// Its GGX roughness α (0 for a smooth face).
    pub fn roughness(&self) -> f64 {
        match self {
            Interface::Smooth => 0.0,
            Interface::Rough(r) => r.alpha,
        }
    }

    /// Whether it scatters (is not Fresnel's smooth face).
    pub fn is_rough(&self) -> bool {
        matches!(self, Interface::Rough(_))
    }

    /// [`RoughDielectric::sample`] of a rough face; a smooth face draws nothing here (the walk
    /// crosses it).
    pub fn sample(&self, wi: DVec3, n_i: f64, n_t: f64, u: [f64; 3]) -> Option<Crossed> {
        match self {
            Interface::Smooth => None,
            Interface::Rough(r) => r.sample(wi, n_i, n_t, u),
        }
    }

    /// [`RoughDielectric::eval`] (0 for a smooth face, whose lobes are Dirac's).
    pub fn eval(&self, wi: DVec3, wo: DVec3, n_i: f64, n_t: f64) -> f64 {
        match self {
            Interface::Smooth => 0.0,
            Interface::Rough(r) => r.eval(wi, wo, n_i, n_t),
        }
    }

    /// [`RoughDielectric::pdf`] (0 for a smooth face).
    pub fn pdf(&self, wi: DVec3, wo: DVec3, n_i: f64, n_t: f64) -> f64 {
        match self {
            Interface::Smooth => 0.0,
            Interface::Rough(r) => r.pdf(wi, wo, n_i, n_t),
        }
    }
}

/// A rough interface between two dielectrics (GGX normals of roughness `alpha > 0`; Walter et
/// al. 2007, §5): each microfacet reflects with the unpolarised Fresnel reflectance of its own
/// incidence and refracts the rest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoughDielectric {
    pub alpha: f64,
}

/// A direction drawn at a rough interface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossed {
    pub wo: DVec3,
    /// The factor on the path's (power) weight: `G1(wo)`.
    pub weight: f64,
    /// Whether it went through (into the medium of index `n_t`).
    pub transmitted: bool,
}

impl RoughDielectric {
    /// Light arriving from `wi` (`wi.z > 0`, in the medium of index `n_i`) at the interface with
    /// `n_t` below: a visible normal, then reflection with its Fresnel reflectance or refraction,
    /// from three uniforms. `None` when the direction drawn is on the wrong side of the
    /// macroscopic surface (the masked share).
    pub fn sample(&self, wi: DVec3, n_i: f64, n_t: f64, u: [f64; 3]) -> Option<Crossed> {
        let g = Ggx { alpha: self.alpha };
        let m = g.sample_visible(wi, u[0], u[1]);
        let (r, cos_t) = fresnel::reflectance(n_i, n_t, wi.dot(m));
        if u[2] < r {
            let wo = microfacet::reflect(wi, m);
            return (wo.z > 0.0).then(|| Crossed { wo, weight: g.g1(wo, m), transmitted: false });
        }
        let wo = microfacet::refract(wi, m, n_i, n_t, cos_t);
        (wo.z < 0.0).then(|| Crossed { wo, weight: g.g1(wo, m), transmitted: true })
    }

    /// `f(wi, wo) |wo.z|` for power crossing from `n_i` (the side of `wi`, `wi.z > 0`): reflection
    /// for `wo.z > 0`, transmission into `n_t` for `wo.z < 0` (Walter et al. 2007, Eqs. 20–21,
    /// with the generalised half vector `h = −(n_i wi + n_t wo)` of a refraction).
    pub fn eval(&self, wi: DVec3, wo: DVec3, n_i: f64, n_t: f64) -> f64 {
        let g = Ggx { alpha: self.alpha };
        match self.lobe(wi, wo, n_i, n_t) {
            None => 0.0,
            Some((m, r, None)) => r * g.d(m) * g.g1(wi, m) * g.g1(wo, m) / (4.0 * wi.z),
            Some((m, r, Some(denom))) => {
                let (ci, co) = (wi.dot(m), wo.dot(m));
                (1.0 - r) * g.d(m) * g.g1(wi, m) * g.g1(wo, m) * ci * co.abs() * n_t * n_t / (wi.z * denom * denom)
            }
        }
    }

    /// The density of [`RoughDielectric::sample`]'s direction per steradian of `wo`.
    pub fn pdf(&self, wi: DVec3, wo: DVec3, n_i: f64, n_t: f64) -> f64 {
        let g = Ggx { alpha: self.alpha };
        match self.lobe(wi, wo, n_i, n_t) {
            None => 0.0,
            // The reflection's Jacobian dω_m/dω_o = 1/(4 wo·m).
            Some((m, r, None)) => r * g.pdf_visible(wi, m) / (4.0 * wo.dot(m)),
            // The refraction's, n_t² |wo·m| / (n_i wi·m + n_t wo·m)².
            Some((m, r, Some(denom))) => {
                (1.0 - r) * g.pdf_visible(wi, m) * n_t * n_t * wo.dot(m).abs() / (denom * denom)
            }
        }
    }

    /// The microfacet normal that takes `wi` to `wo` and its Fresnel reflectance; for a refraction
    /// also `n_i wi·m + n_t wo·m` (its Jacobian's denominator). `None` where no microfacet does.
    fn lobe(&self, wi: DVec3, wo: DVec3, n_i: f64, n_t: f64) -> Option<(DVec3, f64, Option<f64>)> {
        if wi.z <= 0.0 || wo.z == 0.0 {
            return None;
        }
        if wo.z > 0.0 {
            let m = (wi + wo).normalize();
            return Some((m, fresnel::reflectance(n_i, n_t, wi.dot(m)).0, None));
        }
        let m = refraction_half_vector(wi, wo, n_i, n_t)?;
        let r = fresnel::reflectance(n_i, n_t, wi.dot(m)).0;
        Some((m, r, Some(n_i * wi.dot(m) + n_t * wo.dot(m))))
    }
}

/// The microfacet normal that refracts `wi` (index `n_i`) into `wo` (index `n_t`, `wo.z < 0`),
/// oriented to `+z`, if it does so physically (`wi` on its front, `wo` on its back).
#[inline]
fn refraction_half_vector(wi: DVec3, wo: DVec3, n_i: f64, n_t: f64) -> Option<DVec3> {
    if n_i == n_t {
        return None;
    }
    let h = -(n_i * wi + n_t * wo);
    let len = h.length();
    if len == 0.0 {
        return None;
    }
    let m = if h.z < 0.0 { -h / len } else { h / len };
    (wi.dot(m) > 0.0 && wo.dot(m) < 0.0).then_some(m)
}

#[cfg(test)]
mod tests;
