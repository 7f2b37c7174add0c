//! The laser: a collimated beam with a pencil, flat-top disk or Gaussian profile, a vacuum
//! wavelength, and an optional linear frequency chirp (FMCW).

use glam::DVec3;

use crate::sampling::{PathRng, warp};

/// Transverse intensity profile of the collimated beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Profile {
    /// Every path starts at the source position.
    Pencil,
    /// Uniform over a disk of the given radius (m), perpendicular to the beam.
    Disk { radius: f64 },
    /// Gaussian with the given 1/e² intensity radius (m).
    Gaussian { waist: f64 },
}

/// A linear chirp: bandwidth `B` (Hz) swept in `T` (s); slope `α = B/T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chirp {
    pub bandwidth: f64,
    pub duration: f64,
}

impl Chirp {
    pub fn slope(&self) -> f64 {
        self.bandwidth / self.duration
    }
}

/// A beam pointing by angles, in the frame x = east, y = north, z = up (an atmosphere's height,
/// the stack's depth axis).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pointing {
    /// Degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Degrees above the horizontal.
    pub elevation_deg: f64,
    /// `(cos e·sin a, cos e·cos a, sin e)`.
    pub direction: DVec3,
}

impl Pointing {
    pub fn new(azimuth_deg: f64, elevation_deg: f64) -> Self {
        let (sa, ca) = azimuth_deg.to_radians().sin_cos();
        let (se, ce) = elevation_deg.to_radians().sin_cos();
        Pointing { azimuth_deg, elevation_deg, direction: DVec3::new(ce * sa, ce * ca, se) }
    }
}

/// A laser beam: collimated, or with a Gaussian far-field divergence.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Vacuum wavelength λ0, m.
    pub wavelength: f64,
    pub profile: Profile,
    /// Centre of the beam's emission plane, m (above or on the top surface: `z ≤ 0`).
    pub position: DVec3,
    /// Unit propagation direction, with `z > 0` (into the stack).
    pub direction: DVec3,
    pub chirp: Option<Chirp>,
    /// Far-field 1/e² intensity half-angle θ_d of a Gaussian beam, rad (0: collimated). Each
    /// path leaves at a small angle whose two components are normal with standard deviation θ_d/2
    /// (the far field of a Gaussian beam, `I ∝ exp(−2θ²/θ_d²)`).
    pub divergence: f64,
    /// A scan: the pointings to run in turn (empty: just `direction`). `direction` is the first.
    pub pointings: Vec<Pointing>,
    /// Precomputed basis of the emission plane.
    basis: (DVec3, DVec3),
}

impl Source {
    pub fn new(wavelength: f64, profile: Profile, position: DVec3, direction: DVec3, chirp: Option<Chirp>) -> Self {
        let direction = direction.normalize();
        Source {
            wavelength,
            profile,
            position,
            direction,
            chirp,
            divergence: 0.0,
            pointings: Vec::new(),
            basis: warp::orthonormal_basis(direction),
        }
    }

    /// The same source pointing along `direction` (a unit vector).
    pub fn pointed(&self, direction: DVec3) -> Self {
        let direction = direction.normalize();
        Source { direction, basis: warp::orthonormal_basis(direction), ..self.clone() }
    }

    /// The direction of one path: [`Source::direction`], tilted by the beam's divergence.
    #[inline(always)]
    pub fn emit_direction(&self, rng: &mut PathRng) -> DVec3 {
        if self.divergence == 0.0 {
            return self.direction;
        }
        let sd = 0.5 * self.divergence;
        let (a, b) = (sd * rng.normal(), sd * rng.normal());
        (self.direction + a * self.basis.0 + b * self.basis.1).normalize()
    }

    /// Emission point of one path (the direction is always [`Source::direction`]).
    ///
    /// The pencil beam is inlined into the walk; the spread profiles (with their `sin_cos`) are
    /// an outlined call, which otherwise kept the whole function out of line and cost a call
    /// with six register saves per pencil path (measured: 25 → 3 instructions per path). The
    /// uniforms are drawn here, so that the generator is never handed to an outlined function
    /// (see [`PathRng`]).
    #[inline(always)]
    pub fn emit(&self, rng: &mut PathRng) -> DVec3 {
        match self.profile {
            Profile::Pencil => self.position,
            _ => self.emit_spread(rng.uniform(), rng.uniform()),
        }
    }

    /// Whether the beam has a footprint (a camera path can meet it): a disk or a Gaussian. A
    /// pencil lights a line, which a path reaches with probability zero.
    pub fn has_footprint(&self) -> bool {
        !matches!(self.profile, Profile::Pencil)
    }

    /// Irradiance (W/m² per watt emitted) of the beam's light travelling along `dir` through the
    /// point `s` of the ambient medium above the stack, on a plane perpendicular to `dir`, before
    /// any interface: the profile's density where the ray back from `s` along `−dir` meets the
    /// emission plane, times `dir · direction` (the emission plane's area seen along `dir`).
    /// `dir` is [`Source::direction`] for a collimated beam; with a divergence it is a direction
    /// drawn by [`emit_direction`](Self::emit_direction), which makes this an unbiased estimate.
    /// 0 for a pencil beam and behind the emission plane.
    pub fn irradiance_along(&self, s: DVec3, dir: DVec3) -> f64 {
        let cos = dir.dot(self.direction);
        let back = (s - self.position).dot(self.direction) / cos;
        if !(cos > 0.0 && back >= 0.0) {
            return 0.0;
        }
        let y = s - back * dir - self.position;
        let (u, v) = (y.dot(self.basis.0), y.dot(self.basis.1));
        let r2 = u * u + v * v;
        let density = match self.profile {
            Profile::Pencil => 0.0,
            Profile::Disk { radius } => {
                if r2 <= radius * radius {
                    1.0 / (std::f64::consts::PI * radius * radius)
                } else {
                    0.0
                }
            }
            // The density of `warp::gaussian_beam`: I(r) = 2/(πw²)·exp(−2r²/w²).
            Profile::Gaussian { waist } => {
                2.0 / (std::f64::consts::PI * waist * waist) * (-2.0 * r2 / (waist * waist)).exp()
            }
        };
        density / cos
    }

    #[inline(never)]
    fn emit_spread(&self, u1: f64, u2: f64) -> DVec3 {
        let (x, y) = self.plane_point(u1, u2);
        self.position + x * self.basis.0 + y * self.basis.1
    }
}

/// Where a beam's paths enter the top surface `z = 0`: the profile laid flat about `center`.
/// Defined for a beam at normal incidence without divergence ([`Source::footprint`]), where the
/// entry points have the profile's own density; the layered control variate integrates it over
/// rectangles ([`Footprint::mass_in_rect`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    pub center: (f64, f64),
    pub profile: Profile,
}

impl Source {
    /// The beam's footprint on the top surface, if its entry points have the profile's density
    /// there: a collimated beam at normal incidence (a tilted one's is an ellipse, a diverging
    /// one's a blurred profile; neither is integrated).
    pub fn footprint(&self) -> Option<Footprint> {
        let normal = self.direction.x == 0.0 && self.direction.y == 0.0 && self.direction.z > 0.0;
        (normal && self.divergence == 0.0)
            .then_some(Footprint { center: (self.position.x, self.position.y), profile: self.profile })
    }
}

impl Footprint {
    /// The fraction of the paths entering within `[x0, x1) × [y0, y1)` (m): exact for every
    /// profile (the disk's area of intersection in closed form, the Gaussian's as a product of
    /// error functions, the pencil's point with the half-open convention of the image's pixels).
    pub fn mass_in_rect(&self, (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> f64 {
        let (cx, cy) = self.center;
        let (x0, x1, y0, y1) = (x0 - cx, x1 - cx, y0 - cy, y1 - cy);
        if !(x1 > x0 && y1 > y0) {
            return 0.0;
        }
        match self.profile {
            Profile::Pencil => f64::from(u8::from(x0 <= 0.0 && 0.0 < x1 && y0 <= 0.0 && 0.0 < y1)),
            Profile::Gaussian { waist } => {
                // Each axis normal with σ = w/2: Φ(b) − Φ(a) = ½[erf(b/(σ√2)) − erf(a/(σ√2))].
                let k = std::f64::consts::SQRT_2 / waist;
                let axis = |a: f64, b: f64| 0.5 * (erf_difference(a * k, b * k));
                axis(x0, x1) * axis(y0, y1)
            }
            Profile::Disk { radius } => {
                let r2 = radius * radius;
                // Inside (its farthest corner is) or outside (its nearest point is): the common cases
                // without the closed form's arcsines.
                let (fx, fy) = (x0.abs().max(x1.abs()), y0.abs().max(y1.abs()));
                if fx * fx + fy * fy <= r2 {
                    return (x1 - x0) * (y1 - y0) / (std::f64::consts::PI * r2);
                }
                let near = |a: f64, b: f64| if a <= 0.0 && 0.0 <= b { 0.0 } else { a.abs().min(b.abs()) };
                let (nx, ny) = (near(x0, x1), near(y0, y1));
                if nx * nx + ny * ny >= r2 {
                    return 0.0;
                }
                let q = |x: f64, y: f64| disk_quadrant_area(radius, x, y);
                let area = q(x1, y1) - q(x0, y1) - q(x1, y0) + q(x0, y0);
                (area / (std::f64::consts::PI * radius * radius)).clamp(0.0, 1.0)
            }
        }
    }
}

/// `erf(b) − erf(a)`, for `a ≤ b`, without cancelling where both lie in the same tail (there
/// the complementary functions of the same sign are subtracted).
fn erf_difference(a: f64, b: f64) -> f64 {
    if a >= 0.0 {
        libm::erfc(a) - libm::erfc(b)
    } else if b <= 0.0 {
        libm::erfc(-b) - libm::erfc(-a)
    } else {
        libm::erf(b) - libm::erf(a)
    }
}

/// The area of the disk of radius `r` about the origin with `X ≤ x` and `Y ≤ y`:
/// `∫_{−r}^{min(x, r)} max(0, min(y, s) + s) dX` with `s = √(r² − X²)`, in closed form over the
/// pieces where `s` lies above or below `|y|`.
fn disk_quadrant_area(r: f64, x: f64, y: f64) -> f64 {
    let x = x.clamp(-r, r);
    if y <= -r || x <= -r {
        return 0.0;
    }
    // ∫ s dX = P(X) = ½(X s + r² asin(X/r)).
    let p = |t: f64| {
        let t = t.clamp(-r, r);
        0.5 * (t * (r * r - t * t).max(0.0).sqrt() + r * r * (t / r).clamp(-1.0, 1.0).asin())
    };
    // The integrand over [lo, hi] ∩ [−r, x].
    let piece = |lo: f64, hi: f64, f: &dyn Fn(f64, f64) -> f64| {
        let hi = hi.min(x);
        if hi > lo { f(lo, hi) } else { 0.0 }
    };
    let two_s = |lo: f64, hi: f64| 2.0 * (p(hi) - p(lo));
    let y_plus_s = |lo: f64, hi: f64| y * (hi - lo) + p(hi) - p(lo);
    if y >= r {
        return piece(-r, r, &two_s);
    }
    // Where s = |y|: X = ±a.
    let a = (r * r - y * y).max(0.0).sqrt();
    if y >= 0.0 {
        // |X| > a: s < y, the whole chord; |X| ≤ a: the chord up to y.
        piece(-r, -a, &two_s) + piece(-a, a, &y_plus_s) + piece(a, r, &two_s)
    } else {
        // |X| > a: the chord lies above y; |X| ≤ a: from −s up to y.
        piece(-a, a, &y_plus_s)
    }
}

/// Launches where the regions are (`run.launches = "near_regions"`): a share of the paths start
/// from the profile as configured, the rest from the profile restricted to the cells of the
/// emission plane whose surface point lies within a margin of a region (seen straight down), each
/// path weighted by the profile's density over the mixture's. Unbiased for every output; it spends
/// the paths where the regions' rare contributions come from.
///
/// The near cells are a grid over the emission plane (pitch half the margin), so that their share
/// of the profile `P` is exact ([`Footprint::mass_in_rect`] in the plane): with the profile's
/// share `α`, a path starts near with density `(α + (1 − α)/P)·S` and elsewhere `α·S`.
#[derive(Debug, Clone, PartialEq)]
pub struct Launches {
    profile_share: f64,
    /// The grid's lower corner in the emission plane's coordinates, its pitch and size.
    origin: (f64, f64),
    pitch: f64,
    size: (usize, usize),
    near: Vec<bool>,
    /// The profile's share of the near cells, and the weights of a path starting near and
    /// elsewhere.
    pub p_near: f64,
    w_near: f64,
    w_far: f64,
}

impl Launches {
    /// The launches of `source` near the `regions` (their shapes, and the depth ranges of their
    /// layers), `margin` m around them, the profile keeping `profile_share` of the paths. `None`
    /// for a pencil beam, or when the near cells hold none or all of the profile.
    pub fn new(
        source: &Source,
        regions: &[(crate::medium::Shape, (f64, f64))],
        margin: f64,
        profile_share: f64,
    ) -> Option<Self> {
        let reach = match source.profile {
            Profile::Pencil => return None,
            Profile::Disk { radius } => radius,
            Profile::Gaussian { waist } => 4.55 * waist,
        };
        let pitch = 0.5 * margin;
        let n = ((2.0 * reach / pitch).ceil() as usize).clamp(1, 1024);
        let pitch = 2.0 * reach / n as f64;
        let origin = (-reach, -reach);
        let plane = Footprint { center: (0.0, 0.0), profile: source.profile };
        let (mut near, mut p_near) = (vec![false; n * n], 0.0);
        for j in 0..n {
            for i in 0..n {
                let (u, v) = (origin.0 + (i as f64 + 0.5) * pitch, origin.1 + (j as f64 + 0.5) * pitch);
                let p = source.surface_point(u, v);
                // The vertical line through the surface point meets a region grown by the margin
                // within its layer's depth (plus the cell's half-diagonal: the whole cell counts).
                let grow = margin + std::f64::consts::FRAC_1_SQRT_2 * pitch;
                let hit = regions.iter().any(|(shape, (z0, z1))| {
                    shape
                        .grown(grow)
                        .intersect(glam::DVec3::new(p.x, p.y, *z0), glam::DVec3::Z)
                        .is_some_and(|(a, b)| b > a.max(0.0) && a < (z1 - z0))
                });
                if hit {
                    near[j * n + i] = true;
                    let (x0, y0) = (origin.0 + i as f64 * pitch, origin.1 + j as f64 * pitch);
                    p_near += plane.mass_in_rect((x0, x0 + pitch), (y0, y0 + pitch));
                }
            }
        }
        if !(p_near > 1e-6 && p_near < 1.0 - 1e-6) {
            return None;
        }
        let a = profile_share;
        Some(Launches {
            profile_share: a,
            origin,
            pitch,
            size: (n, n),
            near,
            p_near,
            w_near: 1.0 / (a + (1.0 - a) / p_near),
            w_far: 1.0 / a,
        })
    }

    /// Whether the emission-plane point `(u, v)` lies in a near cell.
    #[inline]
    fn is_near(&self, u: f64, v: f64) -> bool {
        let i = ((u - self.origin.0) / self.pitch).floor();
        let j = ((v - self.origin.1) / self.pitch).floor();
        (0.0..self.size.0 as f64).contains(&i)
            && (0.0..self.size.1 as f64).contains(&j)
            && self.near[j as usize * self.size.0 + i as usize]
    }

    /// A path's emission point and its weight: from the profile with probability `α`, else from
    /// the profile until the point is near (rejection: `1/P` draws on average).
    pub fn emit(&self, source: &Source, rng: &mut PathRng) -> (DVec3, f64) {
        let from_profile = rng.uniform() < self.profile_share;
        loop {
            let (u, v) = source.plane_point(rng.uniform(), rng.uniform());
            let near = self.is_near(u, v);
            if from_profile || near {
                let w = if near { self.w_near } else { self.w_far };
                return (source.position + u * source.basis.0 + v * source.basis.1, w);
            }
        }
    }
}

impl Source {
    /// The point of the emission plane's coordinates `(u, v)` on the top surface, along the beam.
    pub fn surface_point(&self, u: f64, v: f64) -> DVec3 {
        let p = self.position + u * self.basis.0 + v * self.basis.1;
        p + (-p.z / self.direction.z) * self.direction
    }

    /// A point of the profile in the emission plane's coordinates, from two uniforms (as
    /// [`Source::emit`] draws it).
    fn plane_point(&self, u1: f64, u2: f64) -> (f64, f64) {
        match self.profile {
            Profile::Pencil => (0.0, 0.0),
            Profile::Disk { radius } => {
                let (x, y) = warp::uniform_disk(u1, u2);
                (x * radius, y * radius)
            }
            Profile::Gaussian { waist } => warp::gaussian_beam(waist, u1, u2),
        }
    }
}
