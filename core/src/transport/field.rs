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
//! power in each annulus about a point, [`annulus_mass`]) it is the scattered radiance at a
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
use rayon::prelude::*;

use crate::detect::{BeatModel, PathState, Recorder, TallyLayout};
use crate::medium::{Layer, Scene};
use crate::sampling::{PathRng, Purpose, StreamKey};
use crate::source::Source;
use crate::stats::RunStats;

use super::WalkSettings;
use super::event::{Particle, deflect};
use super::walk::{End, Estimator, Vertex, WalkContext, scatter, walk_to_the_end};

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
const GROUPS: usize = THETA_BINS / THETA_GROUP;
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
const SLOTS: usize = 1 + 2 * U_BINS;
/// Directions drawn per connection to the table.
pub const TABLE_SAMPLES: usize = 4;
/// Independent groups of the pre-pass, each summed in order (the table is the same whatever the
/// threads).
const PASS_GROUPS: u64 = 8;

/// One layer's depth bins.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bins {
    z_top: f64,
    dz: f64,
    first: usize,
    n: usize,
}

/// The layered twin's scattered radiance and its Doppler states (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct FieldTable {
    bins: Vec<Bins>,
    nz: usize,
    /// The beam's axis on the surface, and the radial bins' width and number.
    axis: (f64, f64),
    dr: f64,
    nr: usize,
    /// Per radial bin × depth bin × polar-angle bin: scattered radiance per watt emitted,
    /// W m⁻² sr⁻¹ W⁻¹.
    radiance: Vec<f64>,
    /// Per radial group × depth group × angle group: the cumulative distribution over [`SLOTS`]
    /// (last = 1; all 0 where no light was tallied).
    cdf: Vec<f64>,
    /// Depth groups.
    nzg: usize,
    /// The `dl/dt` scale `D` of the arctangent map, m/s (0: nothing in the twin moves).
    scale: f64,
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

    /// The table of `scene`'s layered twin lit by `source` out to `reach` from the beam's axis
    /// (m; beyond, the last radial bin), from `paths` forward paths of the stream `seed`.
    pub fn build(
        scene: &Scene,
        source: &Source,
        settings: &WalkSettings,
        reach: f64,
        paths: u64,
        seed: u64,
    ) -> FieldTable {
        let twin = scene.layered_twin();
        let mut bins = Vec::with_capacity(twin.layers.len());
        let mut nz = 0;
        for l in &twin.layers {
            let depth = if l.z_bottom.is_finite() { l.z_bottom - l.z_top } else { DEEP };
            let n = ((depth / Z_STEP).ceil() as usize).clamp(1, Z_BINS_MAX);
            bins.push(Bins { z_top: l.z_top, dz: depth / n as f64, first: nz, n });
            nz += n;
        }
        let scale = doppler_scale(&twin);
        let z_switch = scene.regions.iter().map(|r| r.shape.z_range().1).fold(0.0, f64::max);
        let nr = ((reach / RHO_STEP).ceil() as usize).clamp(1, RHO_BINS_MAX);
        let dr = reach.max(RHO_STEP) / nr as f64;
        let axis = (source.position.x, source.position.y);
        // The kernel reaches as far as a vertex within `reach` can be from the beam's light.
        let spread = reach
            + match source.profile {
                crate::source::Profile::Disk { radius } => radius,
                crate::source::Profile::Gaussian { waist } => 2.5 * waist,
                crate::source::Profile::Pencil => 0.0,
            };
        let nk = ((spread / dr).ceil() as usize).clamp(1, 4 * RHO_BINS_MAX);
        let shape = Shape { bins: &bins, nz, scale, dr, nk };
        let key = StreamKey::new(seed, Purpose::Field, 0);
        let sums: Vec<Sums> = (0..PASS_GROUPS)
            .into_par_iter()
            .map(|g| {
                let (a, b) = (paths * g / PASS_GROUPS, paths * (g + 1) / PASS_GROUPS);
                pass(&twin, source, settings, &shape, &key, a..b)
            })
            .collect();
        let mut total = Sums::new(nk, nz);
        let nzg = nz.div_ceil(Z_GROUP);
        for s in &sums {
            total.add(s);
        }
        // The pencil beam's kernel per unit area of its annulus, depth and solid angle, then
        // convolved with the beam's profile: the radiance at distance ρ from its axis is the sum
        // over the kernel's annuli of the kernel times the beam's power in the annulus of that
        // radius about the point (the kernel keeps the polar angle of the light's direction
        // only, which a rotation about the vertical leaves as it is).
        let per = |ik: usize, iz: usize, it: usize| {
            let area = std::f64::consts::PI * dr * dr * ((ik + 1) * (ik + 1) - ik * ik) as f64;
            let (c0, c1) = (theta_edge(it).cos(), theta_edge(it + 1).cos());
            let solid_angle = std::f64::consts::TAU * (c0 - c1);
            let b = bins.iter().find(|b| (b.first..b.first + b.n).contains(&iz)).expect("a depth bin's layer");
            total.radiance[(ik * nz + iz) * THETA_BINS + it] / (paths.max(1) as f64 * area * b.dz * solid_angle)
        };
        let kernel: Vec<f64> = (0..nk * nz * THETA_BINS)
            .map(|k| per(k / (nz * THETA_BINS), (k / THETA_BINS) % nz, k % THETA_BINS))
            .collect();
        let mut radiance = vec![0.0; nr * nz * THETA_BINS];
        for ir in 0..nr {
            let rho = (ir as f64 + 0.5) * dr;
            for ik in 0..nk {
                let mass = annulus_mass(source, axis, rho, (ik as f64 * dr, (ik + 1) as f64 * dr));
                if mass <= 0.0 {
                    continue;
                }
                let from = &kernel[ik * nz * THETA_BINS..][..nz * THETA_BINS];
                let to = &mut radiance[ir * nz * THETA_BINS..][..nz * THETA_BINS];
                for (t, k) in to.iter_mut().zip(from) {
                    *t += mass * k;
                }
            }
        }
        // Each radial group's Doppler distributions: the kernel's classes weighted by the beam's
        // power in their annuli about the group's middle, per unit area of the class.
        let per_class = nzg * GROUPS * SLOTS;
        let nrg = nr.div_ceil(RHO_GROUP);
        let mut cdf = vec![0.0; nrg * per_class];
        for g in 0..nrg {
            let rho = ((g * RHO_GROUP) as f64 + 0.5 * RHO_GROUP.min(nr - g * RHO_GROUP) as f64) * dr;
            let (mut mass, mut area) = ([0.0; OFFSET_CLASSES], [0.0; OFFSET_CLASSES]);
            for ik in 0..nk {
                let c = offset_class(ik);
                mass[c] += annulus_mass(source, axis, rho, (ik as f64 * dr, (ik + 1) as f64 * dr));
                area[c] += std::f64::consts::PI * dr * dr * ((ik + 1) * (ik + 1) - ik * ik) as f64;
            }
            let to = &mut cdf[g * per_class..][..per_class];
            for c in 0..OFFSET_CLASSES {
                if mass[c] <= 0.0 || area[c] <= 0.0 {
                    continue;
                }
                // The class's tally per unit area, times the beam's power in its annuli.
                let factor = mass[c] / area[c];
                let from = &total.doppler[c * per_class..][..per_class];
                for (t, f) in to.iter_mut().zip(from) {
                    *t += factor * f;
                }
            }
        }
        for row in cdf.chunks_mut(SLOTS) {
            let sum: f64 = row.iter().sum();
            if sum > 0.0 {
                let mut acc = 0.0;
                for v in row.iter_mut() {
                    acc += *v;
                    *v = acc / sum;
                }
                row[SLOTS - 1] = 1.0;
            }
        }
        FieldTable { bins, nz, axis, dr, nr, radiance, cdf, nzg, scale, z_switch, paths }
    }

    /// Bytes the table holds.
    pub fn bytes(&self) -> usize {
        (self.radiance.len() + self.cdf.len()) * std::mem::size_of::<f64>()
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

    /// Depth bins in all.
    pub fn depth_bins(&self) -> usize {
        self.nz
    }
}

/// Whether the segment `p + s·d`, `0 ≤ s ≤ t`, in `layer` meets one of its regions.
#[inline]
pub fn touches_region(scene: &Scene, layer: &Layer, p: DVec3, d: DVec3, t: f64) -> bool {
    layer.regions.iter().any(|&r| scene.regions[r].shape.intersect(p, d).is_some_and(|(a, b)| b.min(t) >= a.max(0.0)))
}

/// The `dl/dt` scale of the arctangent map: twice the largest index times the largest speed a
/// filling medium's particles reach (its flow plus three standard deviations), m/s.
fn doppler_scale(twin: &Scene) -> f64 {
    let mut scale: f64 = 0.0;
    for l in &twin.layers {
        for p in twin.media[l.medium].populations() {
            let flow = match p.velocity {
                crate::flow::VelocityField::Uniform(v) => v.length(),
                _ => 0.0,
            };
            scale = scale.max(2.0 * l.n * (flow + 3.0 * p.motion.dispersion));
        }
    }
    scale
}

/// The beam's power (per watt emitted) on the surface in the annulus `r0 ≤ r < r1` about the
/// point at distance `rho` from its axis `axis`: the profile's irradiance across the
/// (vertical) beam, by the midpoint rule over 4 radii × 128 angles per 25 µm of radius.
fn annulus_mass(source: &Source, axis: (f64, f64), rho: f64, (r0, r1): (f64, f64)) -> f64 {
    const RADII: usize = 4;
    const ANGLES: usize = 128;
    let mut sum = 0.0;
    let dr = (r1 - r0) / RADII as f64;
    let dphi = std::f64::consts::TAU / ANGLES as f64;
    for i in 0..RADII {
        let r = r0 + (i as f64 + 0.5) * dr;
        for j in 0..ANGLES {
            let phi = (j as f64 + 0.5) * dphi;
            let p = DVec3::new(axis.0 + rho + r * phi.cos(), axis.1 + r * phi.sin(), 0.0);
            sum += source.irradiance_along(p, source.direction) * r * dr * dphi;
        }
    }
    sum
}

/// The class of kernel bin `ik` for its Doppler distributions ([`OFFSET_CLASSES`]).
#[inline]
fn offset_class(ik: usize) -> usize {
    ((usize::BITS - 1 - (ik + 1).leading_zeros()) as usize).min(OFFSET_CLASSES - 1)
}

/// The polar angle of the lower edge of bin `it`.
fn theta_edge(it: usize) -> f64 {
    std::f64::consts::PI * it as f64 / THETA_BINS as f64
}

/// What a pass bins by.
struct Shape<'a> {
    bins: &'a [Bins],
    nz: usize,
    scale: f64,
    /// The kernel's radial bins: width and number.
    dr: f64,
    nk: usize,
}

/// One group's sums: `w/σt` per depth × angle bin, and the same weight per Doppler slot.
struct Sums {
    radiance: Vec<f64>,
    doppler: Vec<f64>,
}

impl Sums {
    fn new(nk: usize, nz: usize) -> Sums {
        let doppler = OFFSET_CLASSES * nz.div_ceil(Z_GROUP) * GROUPS * SLOTS;
        Sums { radiance: vec![0.0; nk * nz * THETA_BINS], doppler: vec![0.0; doppler] }
    }

    fn add(&mut self, o: &Sums) {
        for (a, b) in self.radiance.iter_mut().zip(&o.radiance) {
            *a += b;
        }
        for (a, b) in self.doppler.iter_mut().zip(&o.doppler) {
            *a += b;
        }
    }
}

/// The pre-pass's paths `range` through the twin `scene`.
fn pass(
    scene: &Scene,
    source: &Source,
    settings: &WalkSettings,
    shape: &Shape,
    key: &StreamKey,
    range: std::ops::Range<u64>,
) -> Sums {
    let mut sums = Sums::new(shape.nk, shape.nz);
    // The walk wants a recorder; the pass records nothing into it.
    let beat = BeatModel::new(source.wavelength, None);
    let layout = TallyLayout::new(&[], &beat);
    let mut acc = vec![0.0; layout.tallies()];
    let mut stats = RunStats::default();
    let mut rec = Recorder {
        detectors: &[],
        layout: &layout,
        beat,
        acc: &mut acc,
        stats: &mut stats,
        lines: None,
        scratch: Vec::new(),
        kernels: Vec::new(),
        path_scores: Vec::new(),
        trace: None,
        line_draws: None,
    };
    let ctx = WalkContext {
        scene,
        source,
        settings,
        nee: &[],
        shot: None,
        volume: None,
        reflections: false,
        twin: false,
        twin_scene: None,
        launches: None,
        windows: None,
        field: None,
    };
    let n_top = scene.layers[0].n;
    for i in range {
        let mut rng = key.path(i);
        let dir = source.emit_direction(&mut rng);
        let (r, cos_t) = super::fresnel::reflectance(scene.n_above, n_top, dir.z);
        if r >= 1.0 {
            continue;
        }
        let dir = super::fresnel::refract(dir, scene.n_above, n_top, cos_t);
        let mut s = PathState::new(DVec3::ZERO, dir, 1.0 - r, 0.0);
        let mut est = FieldPass { shape, sums: &mut sums };
        let (mut absorbed, mut nulls) = (0.0, 0);
        walk_to_the_end(&mut est, &ctx, 0, &mut s, &mut rng, &mut absorbed, &mut nulls, &mut rec, false);
    }
    sums
}

/// The pre-pass's walk: a forward path carrying power, tallying the light arriving at each real
/// collision once it has scattered.
struct FieldPass<'a, 's> {
    shape: &'a Shape<'a>,
    sums: &'s mut Sums,
}

impl FieldPass<'_, '_> {
    #[inline]
    fn tally(&mut self, li: usize, s: &PathState, sigma_t: f64) {
        let b = &self.shape.bins[li];
        let iz = b.first + (((s.pos.z - b.z_top) / b.dz).max(0.0) as usize).min(b.n - 1);
        if s.pos.z - b.z_top > b.dz * b.n as f64 {
            return; // below a semi-infinite layer's tabulated depth
        }
        let theta = s.dir.z.clamp(-1.0, 1.0).acos();
        let it = ((theta / std::f64::consts::PI * THETA_BINS as f64) as usize).min(THETA_BINS - 1);
        let w = s.weight / sigma_t;
        let sh = self.shape;
        let ik = s.pos.x.hypot(s.pos.y) / sh.dr;
        if ik >= sh.nk as f64 {
            return;
        }
        let ik = ik as usize;
        self.sums.radiance[(ik * sh.nz + iz) * THETA_BINS + it] += w;
        let slot = match s.doppler_events {
            0 => 0,
            e => {
                let scale = self.shape.scale;
                let u = if scale > 0.0 { s.dldt.atan2(scale) * std::f64::consts::FRAC_2_PI } else { 0.0 };
                let ub = (((u + 1.0) * 0.5 * U_BINS as f64) as usize).min(U_BINS - 1);
                1 + (e.min(2) as usize - 1) * U_BINS + ub
            }
        };
        let nzg = sh.nz.div_ceil(Z_GROUP);
        let g = (offset_class(ik) * nzg + iz / Z_GROUP) * GROUPS + it / THETA_GROUP;
        self.sums.doppler[g * SLOTS + slot] += w;
    }
}

impl Estimator for FieldPass<'_, '_> {
    const DOPPLER: bool = true;
    const LENGTH: bool = false;
    const GATE: bool = false;
    const LATERAL: bool = false;
    const VOLUME: bool = false;

    #[inline(always)]
    fn collide(
        &mut self,
        ctx: &WalkContext,
        s: &mut PathState,
        t: f64,
        v: Vertex,
        rng: &mut PathRng,
        _absorbed: &mut f64,
        checkpoint: &mut u32,
        _rec: &mut Recorder,
    ) -> Option<End> {
        super::walk::advance::<Self>(s, t, v.n);
        if s.order >= 1 {
            self.tally(v.li, s, v.medium.sigma_t());
        }
        s.weight *= v.albedo;
        if s.weight <= 0.0 {
            return Some(End::Absorbed);
        }
        let particle = Particle::pick::<true>(v.medium, s.pos, rng);
        let (_, out, delta) = deflect(s.dir, &particle.pop.phase, rng);
        scatter(s, particle, v.n, (out, delta), ctx.settings, rng, checkpoint)
    }
}
