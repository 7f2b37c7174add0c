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

/// A collimated laser.
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
    /// Precomputed basis of the emission plane.
    basis: (DVec3, DVec3),
}

impl Source {
    pub fn new(wavelength: f64, profile: Profile, position: DVec3, direction: DVec3, chirp: Option<Chirp>) -> Self {
        let direction = direction.normalize();
        Source { wavelength, profile, position, direction, chirp, basis: warp::orthonormal_basis(direction) }
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
