//! The layered twin's light field, for camera paths from the footprints
//! (`[detectors.footprints] light_field = true`, issue 54).
//!
//! A camera path from a vessel's pixel goes down through the vessel, turns round below it and
//! comes back up; most of its variance is the far end of that loop: a connection to the Dirac
//! beam at a shallow vertex, reached along the beam's reverse to within a degree or two. Below
//! the vessels the light arriving at a vertex is, to within the vessels' own shadow, the light of
//! the scene without its regions (the *layered twin*, [`crate::medium::Scene::layered_twin`]),
//! which is smooth in direction. So at a collision `j*` in a layer's filling medium once its light
//! can carry what the regions change (its first after its flight met a region, or its first
//! below every region), a camera path takes that light from a table instead of chasing it, and
//! from there on scores the difference between the scene and its twin, which is zero wherever
//! the rest of its walk meets no region:
//!
//! `C = Σ_{j ≤ j*} c_j + W_{j*}·S_table(x_{j*}, −d_{j*}) + Σ_{k > j*} (c_k − c_k^twin)`,
//!
//! `c_j` the connections to the beam at vertex `j` (the beam-lobe connection from `j*` on counted
//! with the rest of the light that scattered before reaching `j*`), `S_table` the table's scattered
//! radiance in-scattered toward the camera. The twin's connections `c_k^twin` come from the same
//! walk while it meets no region (the same collisions, particles and directions: the scene and
//! its twin differ only inside the regions), differing only where a shadow ray or a beam-lobe
//! flight crosses a region; once the walk's flight meets a region the twin parts from it and
//! walks on by itself in the twin's scene from the vertex before, with a copy of the walk's
//! numbers (as the forward twin does, [`super::carried::Split`]), scoring with the opposite sign,
//! to its first collision: there its connection to the beam and the table are all the twin's
//! light (the twin's scene has no region). The path's next collision in a filling medium is a
//! new `j*`. Its expectation is `W·(S_table + L_real − L_twin)`: the camera estimator's, up to the
//! table's error (`S_table − L_twin`), which `tests/it/camera.rs` bounds.
//!
//! Measured on retina_ldh (10⁶ paths, the second moment of the camera paths' in-band scores):
//! switching only below every region left 94 % of it on the paths' way there (those turning
//! round in the retina); switching at the first collision outside a region anywhere, 290 per
//! squared mean; after the path has met a region, 232 (against ≈ 1,400 connecting to the beam
//! only).
//!
//! **The table.** A pre-pass of forward paths through the twin (`field_paths` of them, a fixed
//! seed, the same in every shard and resume), each entering at one point (a pencil beam): the
//! collision estimator (`w/σt` at every real collision of light that has scattered at least once)
//! gives its kernel over the distance from the entry point ([`RHO_STEP`]) × depth (per layer,
//! [`Z_STEP`]) × polar angle of travel ([`THETA_BINS`]). Convolved with the beam's profile (the
//! power in each annulus about a point, [`super::field_pass`]) it is the scattered radiance at a
//! distance from the beam's axis: every pre-pass path counts at every distance, and the finite
//! beam's edge is in it (a plane wave's light, the kernel's sum, overestimated the light at the
//! centre of a 1.7 mm disk over an index-matched slab by 6.5 %). Per depth × [`THETA_GROUP`] angle
//! bins it keeps the distribution of the light's Doppler state, pooled over the kernel: its class
//! (no Doppler event, one, more) and its `dl/dt` on an arctangent scale that covers every real
//! number ([`U_BINS`]). A normally incident beam, so that the kernel's directions are symmetric
//! about the vertical ([`FieldTable::check_scene`]).
//!
//! **Its error.** The table keeps the polar angle of the light's direction, not its azimuth
//! about the beam's axis. Where the beam is flat over the light's lateral spread the light has
//! no preferred azimuth and that is exact; near the edge of a beam, or under a narrow one, the
//! light flows outward, and a camera path that wandered outward to its `j*` sees it more from
//! behind than the azimuthal mean says: the table reads high. Measured (10⁶ camera paths each,
//! a vessel of the filling medium itself, so that the scene equals its twin): under a 0.4 mm
//! Gaussian beam with a 1.3 mm diffusion length +4 to +7 %; under a 1.5 mm disk +1.6 %; the same
//! disk with a 0.33 mm diffusion length +0.12 ± 0.19 %; an index-matched 1.5 mm slab under a
//! 1.7 mm disk −0.1 % (intensity). Hence a disk beam only ([`FieldTable::check_scene`]), and the
//! bound `tests/it/camera.rs` holds. Resolving the azimuth (the kernel's rotated onto each
//! point's radial direction) would remove it.
//!
//! At `j*` the in-scattered radiance `∫ p(ω′·o) L(ω′) dω′` toward the camera (`o = −d`) is
//! estimated by [`TABLE_SAMPLES`] directions `ω′` drawn from the phase function around `o`,
//! each with a Doppler state drawn from its bin.

use glam::DVec3;

use crate::medium::Scene;
use crate::source::Source;

/// Depth bins per layer: one per this many metres of it, ...
pub const Z_STEP: f64 = 10e-6;
/// ... at most this many (a semi-infinite layer is binned over [`DEEP`] below its top).
pub const Z_BINS_MAX: usize = 64;
/// How deep a semi-infinite last layer is tabulated (deeper vertices read its last bin), m.
pub const DEEP: f64 = 3e-3;
/// Radial bins, of the table (distance from the beam's axis) and of the pencil beam's kernel
/// (distance from its entry point), m wide ...
pub const RHO_STEP: f64 = 25e-6;
/// ... at most this many.
pub const RHO_BINS_MAX: usize = 400;
/// How far beyond the images' farthest corner the table reaches (a camera path wanders), m.
pub const REACH_MARGIN: f64 = 0.5e-3;
/// Polar-angle bins of the light's direction of travel (from +z, down), uniform in angle.
pub const THETA_BINS: usize = 36;
/// Polar-angle bins per Doppler distribution.
pub const THETA_GROUP: usize = 3;
pub(super) const GROUPS: usize = THETA_BINS / THETA_GROUP;
/// Depth bins per Doppler distribution.
pub const Z_GROUP: usize = 4;
/// The kernel's Doppler distributions are kept per class of its distance from the entry point,
/// class `⌊log₂(k + 1)⌋` of kernel bin `k` (at most [`OFFSET_CLASSES`]), and the table's per
/// [`RHO_GROUP`] radial bins: the light at a distance from a narrow beam's axis has come a shorter
/// way than a plane wave's, with fewer Doppler events (pooled over the whole kernel, M0+ read
/// 6.9 % high on a 0.6 mm disk over a slab whose light spreads 1.3 mm).
pub const OFFSET_CLASSES: usize = 12;
/// Radial bins of the table per Doppler distribution.
pub const RHO_GROUP: usize = 8;
/// Bins of the Doppler distribution's `u = (2/π)·atan(dl/dt / D)` over `(−1, 1)`, per class
/// with Doppler events.
pub const U_BINS: usize = 128;
/// Slots of one Doppler distribution: no event, then one event and more than one, each over
/// [`U_BINS`].
pub(super) const SLOTS: usize = 1 + 2 * U_BINS;
/// Directions drawn per connection to the table.
pub const TABLE_SAMPLES: usize = 4;
/// Independent groups of the pre-pass, each summed in order (the table is the same whatever the
/// threads).
pub(super) const PASS_GROUPS: u64 = 8;

/// One layer's depth bins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Bins {
    pub(super) z_top: f64,
    pub(super) dz: f64,
    pub(super) first: usize,
    pub(super) n: usize,
}

/// The layered twin's scattered radiance and its Doppler states (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct FieldTable {
    pub(super) bins: Vec<Bins>,
    pub(super) nz: usize,
    /// The beam's axis on the surface, and the radial bins' width and number.
    pub(super) axis: (f64, f64),
    pub(super) dr: f64,
    pub(super) nr: usize,
    /// Per radial bin × depth bin × polar-angle bin: scattered radiance per watt emitted,
    /// W m⁻² sr⁻¹ W⁻¹.
    pub(super) radiance: Vec<f64>,
    /// Per radial group × depth group × angle group: the cumulative distribution over [`SLOTS`]
    /// (last = 1; all 0 where no light was tallied).
    pub(super) cdf: Vec<f64>,
    /// Depth groups.
    pub(super) nzg: usize,
    /// The `dl/dt` scale `D` of the arctangent map, m/s (0: nothing in the twin moves).
    pub(super) scale: f64,
    /// The depth below which a camera path's collisions read the table: the deepest point of any
    /// region, m.
    pub z_switch: f64,
    /// Forward paths of the pre-pass.
    pub paths: u64,
}

/// Why a scene cannot use the light field (the key the message is about, and the message).
pub type Refusal = (&'static str, String);

impl FieldTable {
    /// Whether `scene` and `source` suit the table: a normally incident disk beam,
    /// planar smooth faces, no opaque solid or bottom, no box phantom, no density field, and
    /// layers whose filling media move the same everywhere (no flow profile, no Brownian
    /// motion: the table holds `dl/dt` only).
    pub fn check_scene(scene: &Scene, source: &Source) -> Result<(), Refusal> {
        let d = source.direction;
        if d.x.abs() > 1e-9 || d.y.abs() > 1e-9 {
            return Err((
                "source.direction",
                "is oblique: the light field's table is azimuthally symmetric, which needs a normally incident beam ([0, 0, 1])".into(),
            ));
        }
        if !matches!(source.profile, crate::source::Profile::Disk { .. }) {
            return Err((
                "source.profile",
                "is not a disk: the light field's table keeps the polar angle of the light's direction only, which is all of it only where the beam is flat over the light's spread (a disk, wide against it)".into(),
            ));
        }
        if scene.first_rough_face < scene.layers.len() {
            return Err(("layers", "has a rough face: the light field's walks support smooth faces only".into()));
        }
        if scene.bottom.is_some() || !scene.opaque.is_empty() {
            return Err((
                "surfaces",
                "puts an opaque surface in the stack: the light field supports layers and regions only".into(),
            ));
        }
        if scene.lateral.is_some() {
            return Err(("lateral", "makes a box phantom, which is not laterally invariant".into()));
        }
        if scene.layers.iter().any(|l| l.heterogeneous) {
            return Err(("media", "has a density field: the light field needs homogeneous layers and regions".into()));
        }
        for l in &scene.layers {
            let m = &scene.media[l.medium];
            for p in m.populations() {
                let uniform =
                    matches!(p.velocity, crate::flow::VelocityField::Static | crate::flow::VelocityField::Uniform(_));
                if !uniform || p.motion.diffusion > 0.0 {
                    return Err((
                        "media",
                        format!(
                            "\"{}\" fills layer \"{}\" with a flow profile or Brownian motion: the light field needs layers whose media move the same everywhere, without Brownian motion",
                            m.name, l.name
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The depth bin of `z` in layer `li`.
    #[inline]
    fn z_bin(&self, li: usize, z: f64) -> usize {
        let b = &self.bins[li];
        b.first + (((z - b.z_top) / b.dz).max(0.0) as usize).min(b.n - 1)
    }

    /// The twin's scattered radiance at `pos` in layer `li` travelling along `dir`, W m⁻² sr⁻¹
    /// per watt emitted, and its depth and angle bins.
    #[inline]
    pub fn radiance(&self, li: usize, pos: DVec3, dir: DVec3) -> (f64, [usize; 3]) {
        let iz = self.z_bin(li, pos.z);
        let rho = (pos.x - self.axis.0).hypot(pos.y - self.axis.1);
        let ir = ((rho / self.dr) as usize).min(self.nr - 1);
        let theta = dir.z.clamp(-1.0, 1.0).acos();
        let it = ((theta / std::f64::consts::PI * THETA_BINS as f64) as usize).min(THETA_BINS - 1);
        (self.radiance[(ir * self.nz + iz) * THETA_BINS + it], [ir, iz, it])
    }

    /// A Doppler state of the light of bin `[ir, iz, it]` ([`radiance`](Self::radiance)) from the
    /// uniform `u`: its Doppler events (0, 1, or 2 for more) and its `dl/dt`, m/s.
    pub fn draw(&self, [ir, iz, it]: [usize; 3], u: f64) -> (u32, f64) {
        let g = ((ir / RHO_GROUP) * self.nzg + iz / Z_GROUP) * GROUPS + it / THETA_GROUP;
        let row = &self.cdf[g * SLOTS..][..SLOTS];
        let k = row.partition_point(|&c| c <= u).min(SLOTS - 1);
        if k == 0 || self.scale == 0.0 {
            return (0, 0.0);
        }
        let below = row[k - 1];
        let frac = if row[k] > below { ((u - below) / (row[k] - below)).clamp(0.0, 1.0) } else { 0.5 };
        let (class, ub) = (1 + (k - 1) / U_BINS, (k - 1) % U_BINS);
        let v = (-1.0 + 2.0 * (ub as f64 + frac) / U_BINS as f64).clamp(-1.0 + 1e-12, 1.0 - 1e-12);
        (class as u32, self.scale * (v * std::f64::consts::FRAC_PI_2).tan())
    }
}

/// The class of kernel bin `ik` for its Doppler distributions ([`OFFSET_CLASSES`]).
#[inline]
pub(super) fn offset_class(ik: usize) -> usize {
    ((usize::BITS - 1 - (ik + 1).leading_zeros()) as usize).min(OFFSET_CLASSES - 1)
}

/// The polar angle of the lower edge of bin `it`.
pub(super) fn theta_edge(it: usize) -> f64 {
    std::f64::consts::PI * it as f64 / THETA_BINS as f64
}
