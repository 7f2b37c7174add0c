//! Velocity fields attached to media: the velocity of the particle a path scatters on.
//!
//! A closed set dispatched by `match`. A medium whose field is [`VelocityField::Static`] never
//! looks a velocity up, and a scene in which nothing moves compiles its random walk without the
//! Doppler term at all (see `transport::walk`).

use std::sync::Arc;

use glam::DVec3;

use crate::medium::density::GridField;
use crate::sampling::{Discrete, PathRng, warp};

pub mod pulse;

/// Von Kármán's constant of the logarithmic wind profile (media/references.md §B5).
pub const VON_KARMAN: f64 = 0.40;

/// Wind as a function of height. In an atmosphere the scene's `z` is the height above the ground
/// (`z = 0`), with the lidar at `z ≤ 0` looking up; `x` is east and `y` north.
#[derive(Debug, Clone, PartialEq)]
pub enum WindProfile {
    /// The same velocity at every height.
    Uniform(DVec3),
    /// Power law (Hellmann): horizontal speed `u(h) = u_ref·(h/h_ref)^α` along the unit
    /// horizontal `direction` (0 at `h ≤ 0`), plus a constant vertical velocity.
    PowerLaw { direction: DVec3, speed_ref: f64, height_ref: f64, exponent: f64, vertical: f64 },
    /// Logarithmic surface layer: `u(h) = (u*/κ)·ln((h − d)/z0)` for `h − d > z0`, else 0
    /// (friction velocity `u*`, roughness length `z0`, displacement height `d`).
    LogLaw { direction: DVec3, friction_velocity: f64, roughness: f64, displacement: f64, vertical: f64 },
    /// A table per layer of height: `velocities[i]` for `edges[i] ≤ h < edges[i + 1]`, the first
    /// below `edges[0]` and the last above the top edge.
    Table { edges: Arc<[f64]>, velocities: Arc<[DVec3]> },
}

impl WindProfile {
    /// The wind at height `h`, m/s.
    #[inline]
    pub fn at(&self, h: f64) -> DVec3 {
        match self {
            WindProfile::Uniform(v) => *v,
            WindProfile::PowerLaw { direction, speed_ref, height_ref, exponent, vertical } => {
                let u = if h > 0.0 { speed_ref * (h / height_ref).powf(*exponent) } else { 0.0 };
                *direction * u + DVec3::new(0.0, 0.0, *vertical)
            }
            WindProfile::LogLaw { direction, friction_velocity, roughness, displacement, vertical } => {
                let above = h - displacement;
                let u =
                    if above > *roughness { friction_velocity / VON_KARMAN * (above / roughness).ln() } else { 0.0 };
                *direction * u + DVec3::new(0.0, 0.0, *vertical)
            }
            WindProfile::Table { edges, velocities } => {
                // Layers are few (≈ 100): the partition point is a short binary search.
                let i = edges.partition_point(|&e| e <= h).saturating_sub(1).min(velocities.len() - 1);
                velocities[i]
            }
        }
    }

    /// Whether the wind is zero everywhere.
    pub fn is_calm(&self) -> bool {
        match self {
            WindProfile::Uniform(v) => *v == DVec3::ZERO,
            WindProfile::PowerLaw { speed_ref, vertical, .. } => *speed_ref == 0.0 && *vertical == 0.0,
            WindProfile::LogLaw { friction_velocity, vertical, .. } => *friction_velocity == 0.0 && *vertical == 0.0,
            WindProfile::Table { velocities, .. } => velocities.iter().all(|v| *v == DVec3::ZERO),
        }
    }

    /// The same profile with every velocity multiplied by `k`.
    pub fn scaled(&self, k: f64) -> Self {
        match self {
            WindProfile::Uniform(v) => WindProfile::Uniform(k * *v),
            WindProfile::PowerLaw { direction, speed_ref, height_ref, exponent, vertical } => WindProfile::PowerLaw {
                direction: *direction,
                speed_ref: k * speed_ref,
                height_ref: *height_ref,
                exponent: *exponent,
                vertical: k * vertical,
            },
            WindProfile::LogLaw { direction, friction_velocity, roughness, displacement, vertical } => {
                WindProfile::LogLaw {
                    direction: *direction,
                    friction_velocity: k * friction_velocity,
                    roughness: *roughness,
                    displacement: *displacement,
                    vertical: k * vertical,
                }
            }
            WindProfile::Table { edges, velocities } => {
                WindProfile::Table { edges: edges.clone(), velocities: velocities.iter().map(|v| k * *v).collect() }
            }
        }
    }

    /// The same profile with every velocity reversed.
    pub fn reversed(&self) -> Self {
        self.scaled(-1.0)
    }
}

/// Terminal fall speed (m/s) of a raindrop of diameter `d` (m) in still air near the ground:
/// Atlas, Srivastava & Sekhon (1973, Rev. Geophys. 11:1, Eq. 24),
/// `v = 9.65 − 10.3·exp(−0.6·D/mm)` m/s, a fit to Gunn & Kinzer (1949) for D ≈ 0.1–6 mm; it turns
/// negative below D = 0.109 mm, where it is clamped to 0 (those drops hardly fall: Stokes gives
/// 0.3 m/s at 0.1 mm).
pub fn atlas_fall_speed(d: f64) -> f64 {
    (9.65 - 10.3 * (-0.6 * d * 1e3).exp()).max(0.0)
}

/// A discrete distribution of fall speeds (m/s): the speeds of the drop sizes of one population,
/// each with its share of the population's σs.
#[derive(Debug, Clone, PartialEq)]
pub struct FallSpeeds {
    speeds: Vec<f64>,
    /// Each speed's share of σs.
    shares: Discrete,
}

impl FallSpeeds {
    /// From `(speed, weight)` pairs with weights ≥ 0 and a positive sum; `None` otherwise.
    pub fn new(pairs: &[(f64, f64)]) -> Option<Self> {
        if pairs.iter().any(|p| !p.0.is_finite()) {
            return None;
        }
        let shares = Discrete::new(pairs.iter().map(|p| p.1))?;
        Some(FallSpeeds { speeds: pairs.iter().map(|p| p.0).collect(), shares })
    }

    /// The speed of the uniform number `u ∈ [0, 1)`.
    #[inline]
    pub fn sample(&self, u: f64) -> f64 {
        self.speeds[self.shares.index(u)]
    }

    /// Bytes of the table on the heap (its speeds and their cumulative shares).
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.speeds.as_slice()) + self.shares.heap_bytes()
    }

    /// The speeds (m/s) with their shares of σs (summing to 1).
    pub fn shares(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.speeds.iter().copied().zip(self.shares.shares())
    }

    /// The σs-weighted mean speed, m/s.
    pub fn mean(&self) -> f64 {
        self.shares().map(|(s, w)| s * w).sum()
    }
}

/// The velocity (m/s) of the scatterers of a medium.
#[derive(Debug, Clone, PartialEq)]
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
    /// Particles carried by the wind at their height ([`WindProfile`]).
    Wind(WindProfile),
    /// Falling drops: the wind at their height plus a terminal fall speed toward `−z` (down, in
    /// an atmosphere), the speed drawn per scattering event from the population's drop sizes.
    TerminalFall { wind: WindProfile, fall: Arc<FallSpeeds> },
    /// A velocity grid (m/s per voxel), read trilinearly (or nearest) at the scattering point:
    /// a flow solver's field, a wind box. Independent of the medium's density.
    Grid(Arc<GridField<[f32; 3]>>),
    /// Womersley flow in a tube frozen at time `t` of its cycle ([`pulse::WomersleyTube`]).
    Womersley { tube: Arc<pulse::WomersleyTube>, t: f64 },
}

impl VelocityField {
    /// Whether any particle can have a non-zero velocity.
    pub fn is_moving(&self) -> bool {
        match *self {
            VelocityField::Static => false,
            VelocityField::Uniform(v) => v != DVec3::ZERO,
            VelocityField::Poiseuille { v_max, .. } => v_max != 0.0,
            VelocityField::RandomDirection { speed } => speed != 0.0,
            VelocityField::Wind(ref w) => !w.is_calm(),
            VelocityField::TerminalFall { ref wind, ref fall } => {
                !wind.is_calm() || fall.speeds.iter().any(|&s| s != 0.0)
            }
            VelocityField::Grid(ref g) => g.grid.background != [0.0; 3] || g.grid.data.iter().any(|v| *v != [0.0; 3]),
            VelocityField::Womersley { ref tube, .. } => tube.v_max != 0.0,
        }
    }

    /// The velocity of the particle scattering at `p`. Random fields draw from `rng`.
    ///
    /// Inlined into the walk, with the lookups that need no random number (wind profiles, grids)
    /// outlined in `VelocityField::lookup`: an outlined function receiving `&mut PathRng`
    /// would make the walk keep the generator's state in memory (see `PathRng`). Measured on the
    /// van de Hulst slab with a uniform velocity: 61.2M → 58.6M instructions per 5·10⁴ paths
    /// (callgrind; the static slab: 48.6M).
    #[inline(always)]
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
            VelocityField::TerminalFall { ref fall, .. } => {
                let u = rng.uniform();
                self.lookup(p) - DVec3::new(0.0, 0.0, fall.sample(u))
            }
            VelocityField::Wind(_) | VelocityField::Grid(_) | VelocityField::Womersley { .. } => self.lookup(p),
        }
    }

    /// The part of [`VelocityField::velocity`] that needs no random number and more than a few
    /// instructions: the wind at `p` (also under falling drops) or the grid's value; zero for the
    /// other fields.
    #[inline(never)]
    fn lookup(&self, p: DVec3) -> DVec3 {
        match *self {
            VelocityField::Wind(ref w) | VelocityField::TerminalFall { wind: ref w, .. } => w.at(p.z),
            VelocityField::Grid(ref g) => g.value(p),
            VelocityField::Womersley { ref tube, t } => tube.velocity_at(p, t),
            _ => DVec3::ZERO,
        }
    }

    /// Bytes the field owns on the heap beyond what fields share through an `Arc` made once: a
    /// terminal fall's speed table (made for each medium that uses it), 0 for the others (a wind
    /// table and a velocity grid are shared by every medium using them).
    pub fn owned_bytes(&self) -> usize {
        match self {
            VelocityField::TerminalFall { fall, .. } => std::mem::size_of::<FallSpeeds>() + fall.heap_bytes(),
            _ => 0,
        }
    }

    /// The same field with every velocity reversed (used by the mirror-symmetry check).
    pub fn reversed(&self) -> Self {
        self.scaled(-1.0)
    }

    /// The same field with every velocity multiplied by `k` (a pulsatile flow frozen at one
    /// instant of its cycle, [`pulse`]).
    pub fn scaled(&self, k: f64) -> Self {
        match *self {
            VelocityField::Static => VelocityField::Static,
            VelocityField::Uniform(v) => VelocityField::Uniform(k * v),
            VelocityField::Poiseuille { origin, axis, radius, v_max } => {
                VelocityField::Poiseuille { origin, axis, radius, v_max: k * v_max }
            }
            VelocityField::RandomDirection { speed } => VelocityField::RandomDirection { speed: k * speed },
            VelocityField::Wind(ref w) => VelocityField::Wind(w.scaled(k)),
            VelocityField::TerminalFall { ref wind, ref fall } => VelocityField::TerminalFall {
                wind: wind.scaled(k),
                fall: Arc::new(FallSpeeds {
                    speeds: fall.speeds.iter().map(|s| k * s).collect(),
                    shares: fall.shares.clone(),
                }),
            },
            VelocityField::Grid(ref g) => {
                VelocityField::Grid(Arc::new(g.map(|v| v.map(|c| (k * f64::from(c)) as f32))))
            }
            VelocityField::Womersley { ref tube, t } => VelocityField::Womersley { tube: Arc::new(tube.scaled(k)), t },
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
    fn wind_profiles_follow_their_laws() {
        let east = DVec3::X;
        // Log law: u(h) = (u*/κ) ln((h − d)/z0), zero at and below d + z0.
        let log = WindProfile::LogLaw {
            direction: east,
            friction_velocity: 0.4,
            roughness: 0.03,
            displacement: 2.0,
            vertical: 0.1,
        };
        let u = |h: f64| log.at(h);
        assert!((u(102.0).x - (100.0f64 / 0.03).ln()).abs() < 1e-12);
        assert_eq!(u(102.0).z, 0.1);
        assert_eq!(u(2.01).x, 0.0);
        // Power law: u_ref at h_ref, (h/h_ref)^α elsewhere, zero at the ground.
        let pow = WindProfile::PowerLaw {
            direction: DVec3::Y,
            speed_ref: 5.0,
            height_ref: 10.0,
            exponent: 1.0 / 7.0,
            vertical: 0.0,
        };
        assert!((pow.at(10.0).y - 5.0).abs() < 1e-12);
        assert!((pow.at(1280.0).y - 5.0 * 2.0).abs() < 1e-12); // 128^(1/7) = 2
        assert_eq!(pow.at(-1.0), DVec3::ZERO);
        // Table: constant per layer, clamped beyond the edges.
        let table =
            WindProfile::Table { edges: vec![0.0, 10.0, 20.0].into(), velocities: vec![DVec3::X, DVec3::Y].into() };
        assert_eq!(table.at(-5.0), DVec3::X);
        assert_eq!(table.at(9.999), DVec3::X);
        assert_eq!(table.at(10.0), DVec3::Y);
        assert_eq!(table.at(1e9), DVec3::Y);
        assert_eq!(table.reversed().at(15.0), -DVec3::Y);
        assert!(!table.is_calm() && WindProfile::Uniform(DVec3::ZERO).is_calm());
    }

    #[test]
    fn atlas_fall_speeds_match_gunn_and_kinzer() {
        // Atlas et al. 1973 against the Gunn & Kinzer values of media/references.md §B4.
        for (d_mm, v) in [(0.5, 2.0), (2.0, 6.5), (5.0, 9.1)] {
            assert!((atlas_fall_speed(d_mm * 1e-3) - v).abs() < 0.1, "{d_mm} mm");
        }
        assert_eq!(atlas_fall_speed(0.05e-3), 0.0);
    }

    #[test]
    fn fall_speeds_are_drawn_by_weight() {
        let f = FallSpeeds::new(&[(1.0, 1.0), (2.0, 3.0)]).unwrap();
        assert_eq!((f.sample(0.0), f.sample(0.2499), f.sample(0.25), f.sample(0.999)), (1.0, 1.0, 2.0, 2.0));
        assert!((f.mean() - 1.75).abs() < 1e-15);
        assert!(FallSpeeds::new(&[(1.0, 0.0)]).is_none() && FallSpeeds::new(&[]).is_none());
        // A falling drop in still air moves down (−z) at its speed.
        let field = VelocityField::TerminalFall { wind: WindProfile::Uniform(DVec3::X), fall: Arc::new(f) };
        let mut r = PathRng::new(1, Purpose::Test, 0, 0);
        let n = 100_000;
        let mean_w = (0..n).map(|_| field.velocity(DVec3::ZERO, &mut r).z).sum::<f64>() / n as f64;
        // Var of the speed is 0.25·0.75 = 0.1875: 5σ of the mean is 0.0069.
        assert!((mean_w + 1.75).abs() < 5.0 * (0.1875f64 / n as f64).sqrt(), "{mean_w}");
        assert_eq!(field.velocity(DVec3::ZERO, &mut r).x, 1.0);
    }

    #[test]
    fn a_velocity_grid_reproduces_poiseuille_flow() {
        use crate::medium::density::{Interpolation, Placement};
        use crate::medium::grid::{IndexTransform, VoxelGrid};
        // A tube of radius R = 50 µm along x (tilted in nothing), v_max = 3 mm/s, sampled on a
        // 2.5 µm lattice; trilinear reads of the grid against the analytic field at random
        // points. Discretisation error of linear interpolation: |v''|·h²/8 per axis with
        // |v''| = 2·v_max/R², i.e. v_max·h²/(2R²) per axis ≈ 1.9e-6 m/s here (plus the kink at
        // the wall, where the analytic profile is cut off: within one voxel of r = R the error
        // is bounded by the slope 2·v_max/R times a voxel diagonal).
        let (r, vmax, h) = (50e-6, 3e-3, 2.5e-6);
        let analytic = VelocityField::Poiseuille { origin: DVec3::ZERO, axis: DVec3::X, radius: r, v_max: vmax };
        let t = IndexTransform { voxel_size: DVec3::splat(h), translation: DVec3::ZERO };
        let n = 24;
        let mut g = VoxelGrid::new([-4, -n, -n], [9, 2 * n as usize + 1, 2 * n as usize + 1], [0.0f32; 3], t);
        let mut rng = PathRng::new(9, Purpose::Test, 0, 0);
        for k in -n..=n {
            for j in -n..=n {
                for i in -4..=4 {
                    let p = t.to_world(DVec3::new(i as f64, j as f64, k as f64));
                    let v = analytic.velocity(p, &mut rng);
                    g.set([i, j, k], [v.x as f32, v.y as f32, v.z as f32]);
                }
            }
        }
        // Placed 1 mm down: the analytic field moves with it.
        let place = Placement { translation: DVec3::new(0.0, 0.0, 1e-3), scale: 1.0 };
        let field = VelocityField::Grid(Arc::new(GridField::new(Arc::new(g), Interpolation::Trilinear, place)));
        let moved =
            VelocityField::Poiseuille { origin: DVec3::new(0.0, 0.0, 1e-3), axis: DVec3::X, radius: r, v_max: vmax };
        assert!(field.is_moving());
        let smooth = vmax * h * h / (2.0 * r * r) * 3.0 + 1e-9;
        let kink = 2.0 * vmax / r * h * 3f64.sqrt();
        let mut worst = 0.0f64;
        for _ in 0..20_000 {
            let p = DVec3::new(
                rng.uniform() * 8.0 * h - 4.0 * h,
                (rng.uniform() - 0.5) * 1.2 * r,
                (rng.uniform() - 0.5) * 1.2 * r,
            );
            let want = moved.velocity(p + DVec3::new(0.0, 0.0, 1e-3), &mut rng);
            let got = field.velocity(p + DVec3::new(0.0, 0.0, 1e-3), &mut rng);
            let rr = (p.y * p.y + p.z * p.z).sqrt();
            let tol = if (rr - r).abs() < 2.0 * h { kink } else { smooth };
            let e = (got - want).length();
            assert!(e <= tol, "at r = {rr:e}: {got} vs {want}, error {e:e} > {tol:e}");
            if (rr - r).abs() >= 2.0 * h {
                worst = worst.max(e);
            }
        }
        assert!(worst > 0.0 && worst < smooth);
        // (The voxels hold f32: v_max to 1e-8 relative.)
        assert!((field.reversed().velocity(DVec3::new(0.0, 0.0, 1e-3), &mut rng).x + vmax).abs() < 1e-9);
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
