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
        let (x, y) = match self.profile {
            Profile::Pencil => return self.position,
            Profile::Disk { radius } => {
                let (x, y) = warp::uniform_disk(u1, u2);
                (x * radius, y * radius)
            }
            Profile::Gaussian { waist } => warp::gaussian_beam(waist, u1, u2),
        };
        self.position + x * self.basis.0 + y * self.basis.1
    }
}
