//! Velocity fields attached to media: the velocity of the particle a path scatters on.
//!
//! A closed set dispatched by `match`. A medium whose field is [`VelocityField::Static`] never
//! looks a velocity up, and a scene in which nothing moves compiles its random walk without the
//! Doppler term at all (see `transport::walk`).

use glam::DVec3;

use crate::sampling::{PathRng, warp};

/// The velocity (m/s) of the scatterers of a medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VelocityField {
    /// Nothing moves.
    Static,
    /// Every particle moves with the same velocity (rigid translation).
    Uniform(DVec3),
    /// Laminar flow in a circular tube: `v(r) = v_max (1 − r²/R²) ê` at distance `r` from the axis,
    /// zero outside the tube.
    Poiseuille {
        /// A point on the axis.
        origin: DVec3,
        /// Unit vector: the flow direction.
        axis: DVec3,
        radius: f64,
        v_max: f64,
    },
    /// Each scattering event draws a fresh direction, uniform on the sphere, at fixed speed
    /// (an ensemble of particles moving in random directions).
    RandomDirection { speed: f64 },
}

impl VelocityField {
    /// Whether any particle can have a non-zero velocity.
    pub fn is_moving(&self) -> bool {
        match *self {
            VelocityField::Static => false,
            VelocityField::Uniform(v) => v != DVec3::ZERO,
            VelocityField::Poiseuille { v_max, .. } => v_max != 0.0,
            VelocityField::RandomDirection { speed } => speed != 0.0,
        }
    }

    /// The velocity of the particle scattering at `p`. Random fields draw from `rng`.
    #[inline]
    pub fn velocity(&self, p: DVec3, rng: &mut PathRng) -> DVec3 {
        match *self {
            VelocityField::Static => DVec3::ZERO,
            VelocityField::Uniform(v) => v,
            VelocityField::Poiseuille { origin, axis, radius, v_max } => {
                let d = p - origin;
                let radial = d - d.dot(axis) * axis;
                let s = radial.length_squared() / (radius * radius);
                if s < 1.0 { axis * (v_max * (1.0 - s)) } else { DVec3::ZERO }
            }
            VelocityField::RandomDirection { speed } => {
                let (u1, u2) = (rng.uniform(), rng.uniform());
                warp::uniform_sphere(u1, u2) * speed
            }
        }
    }

    /// The same field with every velocity reversed (used by the mirror-symmetry check).
    pub fn reversed(&self) -> Self {
        match *self {
            VelocityField::Static => VelocityField::Static,
            VelocityField::Uniform(v) => VelocityField::Uniform(-v),
            VelocityField::Poiseuille { origin, axis, radius, v_max } => {
                VelocityField::Poiseuille { origin, axis, radius, v_max: -v_max }
            }
            VelocityField::RandomDirection { speed } => VelocityField::RandomDirection { speed: -speed },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Purpose;

    #[test]
    fn poiseuille_profile() {
        let f =
            VelocityField::Poiseuille { origin: DVec3::new(0.0, 0.0, 1.0), axis: DVec3::X, radius: 2.0, v_max: 3.0 };
        let mut r = PathRng::new(0, Purpose::Test, 0, 0);
        assert_eq!(f.velocity(DVec3::new(5.0, 0.0, 1.0), &mut r), DVec3::new(3.0, 0.0, 0.0));
        // r = 1 = R/2 → v_max · 3/4, along the axis, whatever the axial position.
        assert_eq!(f.velocity(DVec3::new(-7.0, 1.0, 1.0), &mut r), DVec3::new(2.25, 0.0, 0.0));
        assert_eq!(f.velocity(DVec3::new(0.0, 0.0, 3.5), &mut r), DVec3::ZERO);
    }

    #[test]
    fn uniform_cross_section_gives_uniform_speed() {
        // Over a uniformly weighted cross-section, r²/R² is uniform, so v is uniform on [0, v_max]:
        // mean v_max/2, variance v_max²/12 (validation-values §4.4).
        let f = VelocityField::Poiseuille { origin: DVec3::ZERO, axis: DVec3::Z, radius: 1.0, v_max: 1.0 };
        let mut r = PathRng::new(5, Purpose::Test, 0, 0);
        let n = 200_000;
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let (x, y) = warp::uniform_disk(r.uniform(), r.uniform());
            let v = f.velocity(DVec3::new(x, y, 0.3), &mut r).z;
            s1 += v;
            s2 += v * v;
        }
        let mean = s1 / n as f64;
        let var = s2 / n as f64 - mean * mean;
        let sd_mean = (1.0f64 / 12.0 / n as f64).sqrt();
        assert!((mean - 0.5).abs() < 4.0 * sd_mean, "{mean}");
        assert!((var - 1.0 / 12.0).abs() < 4.0 * (1.0f64 / 180.0 / n as f64).sqrt(), "{var}");
    }
}
