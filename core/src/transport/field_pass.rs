//! The light field's pre-pass ([`super::field`]): forward paths through the layered twin from
//! one point of its surface, their collisions' light tallied by distance from that point, depth,
//! polar angle and Doppler state, and the kernel convolved with the beam's profile into the
//! table.

use glam::DVec3;
use rayon::prelude::*;

use crate::detect::{BeatModel, PathState, Recorder, TallyLayout};
use crate::medium::Scene;
use crate::sampling::{PathRng, Purpose, StreamKey};
use crate::source::Source;
use crate::stats::RunStats;

use super::WalkSettings;
use super::event::{Particle, deflect};
use super::field::{
    Bins, DEEP, FieldTable, GROUPS, OFFSET_CLASSES, PASS_GROUPS, RHO_BINS_MAX, RHO_GROUP, RHO_STEP, SLOTS, THETA_BINS,
    THETA_GROUP, U_BINS, Z_BINS_MAX, Z_GROUP, Z_STEP, offset_class, theta_edge,
};
use super::walk::{End, Estimator, Vertex, WalkContext, scatter, walk_to_the_end};

/// The table of `scene`'s layered twin lit by `source` out to `reach` from the beam's axis
/// (m; beyond, the last radial bin), from `paths` forward paths of the stream `seed`.
pub fn build(scene: &Scene, source: &Source, settings: &WalkSettings, reach: f64, paths: u64, seed: u64) -> FieldTable {
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
    let kernel: Vec<f64> =
        (0..nk * nz * THETA_BINS).map(|k| per(k / (nz * THETA_BINS), (k / THETA_BINS) % nz, k % THETA_BINS)).collect();
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
        pulse: Vec::new(),
        window_draws: None,
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
