//! Next-event estimation toward a detector on the top surface (the "local estimate").
//!
//! A camera behind a pupil accepts only the light leaving the surface within a narrow cone, which
//! forward tracing almost never hits (a 10° cone holds 1.5 % of a Lambertian exit). Instead, at
//! every real scattering vertex the path sends a deterministic "shadow" photon: an exit direction
//! `ω0` is drawn uniformly in the detector's cone (in the ambient medium above the stack), the
//! direction `ω_k` inside the vertex's layer that refracts into it is found by Snell's law through
//! the planar interfaces (`n sin θ` is conserved), and the contribution is scored where that ray
//! leaves the surface, with weight
//!
//! `w · p(dir_in · ω_k) · (n0² cos θ0)/(n_k² cos θ_k) · Ω_cone · Π(1 − R_i) · exp(−τ)`,
//!
//! where `p` is the phase function (sr⁻¹), the ratio of cosines and indices is the change of solid
//! angle across the interfaces (étendue `n² cos θ dΩ` is conserved), `Ω_cone = 2π(1 − cos α)` is
//! the inverse density of `ω0`, `R_i` the Fresnel reflectances of the interfaces crossed and `τ`
//! the optical depth of the straight segments through the layers and the regions they cross (no
//! shadow ray where an opaque solid or a rough face closes the way, [`trace_up`]).
//!
//! The path's own escapes into the cone straight after a scattering event estimate the same
//! thing by sampling the phase function, so the two are combined by the balance heuristic (Veach
//! 1997, ch. 9), with both densities in the exit solid angle: `p·n0² cos θ0/(n_k² cos θ_k)` for
//! the phase function, `1/Ω_cone` for the shadow ray. With blood's Mie peak (p ≈ 10⁴ sr⁻¹ forward)
//! the shadow ray alone has weights of thousands when a path travels up the cone; weighted, a
//! shadow ray never carries more than the path's weight. Escapes that were reflected at an
//! interface since their last scattering, or never scattered, are not direct connections and
//! keep their full weight. Regions of one layer are assumed not to overlap along the shadow ray
//! (the optical depth adds their excess σt over the layer's medium).

use glam::DVec3;

use crate::medium::Scene;
use crate::sampling::PathRng;

use super::tracking::ratio_transmittance;

use super::fresnel;

/// Shadow rays that cannot carry more than this weight play Russian roulette (the path starts
/// with weight 1). Measured on `configs/retina_ldh.toml`: see `validation/README.md`.
pub const SHADOW_ROULETTE_WEIGHT: f64 = 1e-4;

/// A detector scored by next-event estimation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeeTarget {
    /// Index of the detector.
    pub detector: usize,
    /// Cone axis (pointing away from the stack, `z < 0`).
    pub axis: DVec3,
    pub cos_acceptance: f64,
    /// Basis of the plane perpendicular to the axis.
    pub basis: (DVec3, DVec3),
    /// A receiving aperture at a point (a lidar) rather than a far-field cone.
    pub aperture: Option<Aperture>,
}

/// A small receiving aperture (a disk perpendicular to its pointing direction) above the stack:
/// the classical local estimate of a lidar (see [`receiver_ray`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aperture {
    pub center: DVec3,
    pub radius: f64,
}

impl NeeTarget {
    pub fn new(detector: usize, axis: DVec3, cos_acceptance: f64) -> Self {
        NeeTarget {
            detector,
            axis,
            cos_acceptance,
            basis: crate::sampling::warp::orthonormal_basis(axis),
            aperture: None,
        }
    }

    /// A lidar receiver at `center` looking along `pointing` (light arrives travelling along
    /// `−pointing`), with a field-of-view half-angle of cosine `cos_fov`.
    pub fn receiver(detector: usize, center: DVec3, radius: f64, pointing: DVec3, cos_fov: f64) -> Self {
        NeeTarget { aperture: Some(Aperture { center, radius }), ..Self::new(detector, -pointing, cos_fov) }
    }

    /// Solid angle of the acceptance cone, sr.
    pub fn solid_angle(&self) -> f64 {
        crate::detect::cone_solid_angle(self.cos_acceptance)
    }
}

/// A shadow ray that reaches the top surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadowHit {
    /// Where it leaves the stack (z = 0).
    pub pos: DVec3,
    /// Its direction above the stack (within the cone).
    pub dir: DVec3,
    /// Its direction at the vertex (inside the vertex's layer).
    pub dir_vertex: DVec3,
    /// Factor multiplying the path's weight.
    pub factor: f64,
    /// Optical path length from the vertex to the surface, m.
    pub length: f64,
    /// The optical depth its regions add over their layers' filling media (the layered twin's
    /// way up is without it, [`crate::detect::twin`]).
    pub excess: f64,
    /// `factor` per unit phase-function density, without the optical depth: the layered twin's
    /// factor is [`ShadowHit::twin_factor`].
    unit: f64,
    /// `unit` of the twin: its interfaces' transmittances and, through a layer with density
    /// regions, its filling medium's transmittance (ratio tracking's estimate is the path's).
    twin_unit: f64,
    tau: f64,
}

impl ShadowHit {
    /// The factor of the layered twin, whose phase-function density toward the ray is `p`: the
    /// twin's transmittance (without the regions' excess optical depth), the path's multiple
    /// importance weight (the twin's escapes keep the path's too).
    #[inline]
    pub fn twin_factor(&self, p: f64) -> f64 {
        p * self.twin_unit * (self.excess - self.tau).exp()
    }

    /// Whether the layered twin's way up is the path's (no region's optical depth on it).
    #[inline]
    pub fn twin_is_path(&self) -> bool {
        self.excess == 0.0 && self.twin_unit == self.unit
    }
}

/// The shadow ray toward an aperture: the local estimate of Kalos (1963), as lidar Monte Carlo
/// codes use it (e.g. Bissonnette et al. 1995). A point `y` is drawn uniformly on the aperture
/// disk; the straight ray from the vertex `x` (every index must be 1: no refraction) arrives there
/// travelling along `ω = (y − x)/R`, and is accepted if within the field of view of the pointing
/// direction. Its weight factor is the density of scattering toward `y` per unit aperture area
/// times the area, `f(ω)·A·cos θ_r/R²·exp(−τ)` (`f` the first of `density(ω)`, as for
/// [`shadow_ray`]), with `cos θ_r = ω·(−pointing)` and `τ` the
/// optical depth of the segment through the stack. Direct escapes never score a receiver (their
/// chance of meeting a millimetre aperture within microradians is nil), so no weighting is needed.
//
// The allow is a measured exception (issue 19): see `walk::collide_nee`, the only caller of this
// and of `shadow_ray` with `reflect_at_surface` (a `ShadowOrigin { layer, pos, dir_in, phase }`
// for the first four arguments cost +1.0 to +1.75 % of the instructions of the next-event scenes).
#[allow(clippy::too_many_arguments)]
pub fn receiver_ray(
    scene: &Scene,
    li: usize,
    pos: DVec3,
    density: impl Fn(DVec3) -> (f64, f64),
    target: &NeeTarget,
    aperture: &Aperture,
    u1: f64,
    u2: f64,
    rng: &mut PathRng,
) -> Option<ShadowHit> {
    let (point, dir, r, r2, cos_r) = aperture_point(pos, target, aperture, u1, u2)?;
    // Straight up through the layers to z = 0 (every index 1: no refraction, no reflection),
    // then the (clear) ambient medium to the aperture.
    let Crossing { tau, transmit, excess, twin_transmit, .. } =
        trace_up(scene, li, pos, dir, |_| Some(dir), Crossing::START, rng)?;
    let area = std::f64::consts::PI * aperture.radius * aperture.radius;
    let factor = density(dir).0 * area * cos_r / r2 * transmit * (-tau).exp();
    let unit = area * cos_r / r2 * transmit;
    let twin_unit = area * cos_r / r2 * twin_transmit;
    Some(ShadowHit { pos: point, dir, dir_vertex: dir, factor, length: r, excess, unit, twin_unit, tau })
}

/// A point drawn uniformly on `target`'s `aperture` (from the uniforms `(u1, u2)`) and the
/// straight way to it from `pos`: `(point, direction, distance, distance², cos θ_r)` with
/// `cos θ_r` the direction's cosine to the pointing's reverse; `None` outside the field of view or
/// not upward.
#[inline(always)]
fn aperture_point(
    pos: DVec3,
    target: &NeeTarget,
    aperture: &Aperture,
    u1: f64,
    u2: f64,
) -> Option<(DVec3, DVec3, f64, f64, f64)> {
    let (x, y) = crate::sampling::warp::uniform_disk(u1, u2);
    let point = aperture.center + aperture.radius * (x * target.basis.0 + y * target.basis.1);
    let to = point - pos;
    let r2 = to.length_squared();
    let r = r2.sqrt();
    let dir = to / r;
    let cos_r = dir.dot(target.axis);
    (!(cos_r < target.cos_acceptance || dir.z >= 0.0)).then_some((point, dir, r, r2, cos_r))
}

/// The shadow ray from a vertex on the stack's top surface at `pos` straight into the ambient
/// medium (a rough surface's reflection or transmission), toward a cone detector (`aperture`
/// `None`: an exit direction uniform in the cone, balanced against the direct escapes as in
/// [`shadow_ray`], with no interface in between) or a receiving aperture (a point drawn on it, as
/// in [`receiver_ray`], without optical depth).
pub fn exit_ray(
    pos: DVec3,
    density: impl Fn(DVec3) -> (f64, f64),
    target: &NeeTarget,
    aperture: Option<&Aperture>,
    u1: f64,
    u2: f64,
) -> Option<ShadowHit> {
    let (dir, factor, unit, length, at) = match aperture {
        None => {
            let dir = cone_direction(target.axis, target.basis, target.cos_acceptance, u1, u2);
            if dir.z >= 0.0 {
                return None;
            }
            let (f, q) = density(dir);
            let unit = 1.0 / (q + 1.0 / target.solid_angle());
            (dir, f * unit, unit, 0.0, pos)
        }
        Some(a) => {
            let (point, dir, r, r2, cos_r) = aperture_point(pos, target, a, u1, u2)?;
            let unit = std::f64::consts::PI * a.radius * a.radius * cos_r / r2;
            (dir, density(dir).0 * unit, unit, r, point)
        }
    };
    Some(ShadowHit { pos: at, dir, dir_vertex: dir, factor, length, excess: 0.0, unit, twin_unit: unit, tau: 0.0 })
}

/// Optical depth of the segment `p + s·d`, `0 ≤ s ≤ t`, inside `layer`: its filling medium plus
/// what its regions add over it (regions assumed not to overlap along the segment), and that
/// excess alone.
#[inline(always)]
pub(super) fn segment_optical_depth(
    scene: &Scene,
    layer: &crate::medium::Layer,
    p: DVec3,
    d: DVec3,
    t: f64,
) -> (f64, f64) {
    let fill = scene.media[layer.medium].sigma_t();
    let (mut tau, mut excess) = (fill * t, 0.0);
    for &r in &layer.regions {
        let region = &scene.regions[r];
        if let Some((a, b)) = region.shape.intersect(p, d) {
            let (a, b) = (a.max(0.0), b.min(t));
            if b > a {
                let x = (scene.media[region.medium].sigma_t() - fill) * (b - a);
                tau += x;
                excess += x;
            }
        }
    }
    (tau, excess)
}

/// The optical depth the regions of `layer` add over its filling medium along `p + s·d`,
/// `0 ≤ s ≤ t` (0 in a layer without regions): a forward path's flight under its layered twin.
pub fn region_excess(scene: &Scene, layer: &crate::medium::Layer, p: DVec3, d: DVec3, t: f64) -> f64 {
    segment_optical_depth(scene, layer, p, d, t).1
}

/// Whether the segment `p + s·d`, `0 ≤ s ≤ t`, in `layer` meets one of its regions.
#[inline]
pub fn touches_region(scene: &Scene, layer: &crate::medium::Layer, p: DVec3, d: DVec3, t: f64) -> bool {
    layer.regions.iter().any(|&r| scene.regions[r].shape.intersect(p, d).is_some_and(|(a, b)| b.min(t) >= a.max(0.0)))
}

/// A direction uniform in the cone of half-angle cosine `cos_acceptance` about `axis` (with
/// `basis` completing it) from the uniforms `(u1, u2)`: `cos θ′` uniform on `[cos α, 1]`.
#[inline(always)]
pub fn cone_direction(axis: DVec3, basis: (DVec3, DVec3), cos_acceptance: f64, u1: f64, u2: f64) -> DVec3 {
    let c = 1.0 - u1 * (1.0 - cos_acceptance);
    let s = (1.0 - c * c).max(0.0).sqrt();
    let (sin_phi, cos_phi) = (std::f64::consts::TAU * u2).sin_cos();
    axis * c + (basis.0 * cos_phi + basis.1 * sin_phi) * s
}

/// What a straight way up to the surface went through ([`trace_up`]): where it ended, the optical
/// depth of its analytic segments, the product of its Fresnel transmittances (and ratio-tracking
/// factors) and its optical path length; and the layered twin's transmittances.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    pub pos: DVec3,
    pub tau: f64,
    pub transmit: f64,
    pub length: f64,
    /// The part of `tau` its regions add over their layers' filling media.
    pub excess: f64,
    /// `transmit` of the layered twin: through a layer with density regions, instead of ratio
    /// tracking's estimate, the exact transmittance of its (homogeneous) filling medium.
    pub twin_transmit: f64,
}

impl Crossing {
    /// Nothing crossed yet (`pos` is set by [`trace_up`]).
    pub const START: Crossing =
        Crossing { pos: DVec3::ZERO, tau: 0.0, transmit: 1.0, length: 0.0, excess: 0.0, twin_transmit: 1.0 };

    /// Cross the segment `pos + s·d`, `0 ≤ s ≤ t`, inside `layer`: its optical depth (ratio
    /// tracking in a density layer, a factor of `transmit`) and optical length; `pos` moves to its
    /// end.
    #[inline(always)]
    pub(super) fn segment(&mut self, scene: &Scene, layer: &crate::medium::Layer, d: DVec3, t: f64, rng: &mut PathRng) {
        if layer.heterogeneous {
            let r = ratio_transmittance(scene, layer, self.pos, d, t, rng);
            self.transmit *= r;
            // The twin's filling medium: equal to the path's where the ray meets no region (ratio
            // tracking is exact over a homogeneous span), the twin is then the path. (A layer
            // without regions is a density medium of its own, which has no twin: no `exp`.)
            self.twin_transmit *=
                if layer.regions.is_empty() { r } else { (-(scene.media[layer.medium].sigma_t() * t)).exp() };
        } else {
            let (tau, excess) = segment_optical_depth(scene, layer, self.pos, d, t);
            self.tau += tau;
            self.excess += excess;
        }
        self.length += layer.n * t;
        self.pos += t * d;
    }
}

/// Trace from `pos` in layer `li` straight up through the planar interfaces to `z = 0`, along
/// `first` in layer `li` and `up_in(n)` in each layer of index `n` above it (upward directions,
/// `z < 0`; `None` where the direction cannot exist: total internal reflection), continuing the
/// sums of `acc`: each segment's optical depth (ratio tracking in density layers, a factor of
/// `transmit`), the Fresnel transmittance of each top face, the optical path length. The shadow
/// rays, and a camera path's connections to the laser traced back from their vertex, go this way.
#[inline(always)]
pub(super) fn trace_up(
    scene: &Scene,
    li: usize,
    pos: DVec3,
    first: DVec3,
    up_in: impl Fn(f64) -> Option<DVec3>,
    acc: Crossing,
    rng: &mut PathRng,
) -> Option<Crossing> {
    let mut c = Crossing { pos, ..acc };
    for j in (0..=li).rev() {
        let layer = &scene.layers[j];
        let d = if j == li { first } else { up_in(layer.n)? };
        let t = (c.pos.z - layer.z_top) / -d.z;
        // (One flag per layer for the rare obstacles: checked separately, the rough face and the
        // solids cost the next-event scenes 1.7 % of their instructions.)
        if layer.obstructs_shadows && obstructed(scene, j, c.pos, d, t) {
            return None;
        }
        c.segment(scene, layer, d, t, rng);
        c.pos.z = layer.z_top;
        let n_next = scene.n_above_layer(j);
        let (r, _) = fresnel::reflectance(layer.n, n_next, -d.z);
        c.transmit *= 1.0 - r;
        c.twin_transmit *= 1.0 - r;
    }
    Some(c)
}

/// Whether the way `p + s·d`, `0 ≤ s ≤ t`, through layer `j` up to its top face and through that
/// face is closed: an opaque solid of the layer lies across it, or the face is rough (a rough face
/// scatters: no straight way through it; the path's own crossing of it is a vertex of its own
/// shadow rays).
#[cold]
#[inline(never)]
fn obstructed(scene: &Scene, j: usize, p: DVec3, d: DVec3, t: f64) -> bool {
    scene.rough_top(j) || scene.blocked(&scene.layers[j], p, d, t)
}

/// A collimated beam's unscattered reflections at the interfaces below the surface: from
/// `start` at the surface (its sums so far), the straight way down through each finite layer
/// along `down(n)` in a layer of index `n` (with the Fresnel transmittance of each top face
/// crossed, the surface's only if `surface`), the reflectance `R` of its bottom, and the way back
/// up to the surface along `up(n)`; `each` gets every reflection's [`Crossing`] at the surface.
/// Stops where a direction cannot exist (total internal reflection), at a rough face (whose
/// reflection is a lobe, not a beam) and where an opaque solid closes the way. The forward paths'
/// deterministic reflections and the camera-side estimator's (traced back from the camera) go
/// this way. Returns the steps taken ([`crate::stats::Work::reflection_steps`]).
///
/// The way up from interface `j` crosses every layer above it, so traced layer by layer (as
/// [`trace_up`] does) the reflections of a stack of `N` interfaces cost `N²/2` crossings per path
/// (issue 52: a run through 1,000 interfaces took 17–37 s, 0.1–0.25 s with sampled reflections). A layer of one homogeneous medium
/// without regions or solids ([`UpRun`]) is crossed the same way wherever the way enters it: its
/// optical depth, optical length, lateral shift and Fresnel transmittance depend on its thickness
/// and the direction alone. The ways up keep those layers' crossings summed run by run as the way
/// down meets them, and cross each run in one step; only the other layers (density media,
/// regions: their crossing depends on where, and ratio tracking draws from `rng` in the same
/// order as before) are crossed one by one. A stack of such layers costs `2N` steps per path. The
/// sums are the same terms added in another order: the results differ from the layer-by-layer
/// way in their last bits only.
pub(super) fn reflections_below(
    scene: &Scene,
    start: Crossing,
    surface: bool,
    down: impl Fn(f64) -> Option<DVec3>,
    up: impl Fn(f64) -> Option<DVec3>,
    rng: &mut PathRng,
    mut each: impl FnMut(Crossing),
) -> u64 {
    let mut way = start;
    let mut steps = 0;
    // The way up from the current interface, top down: the run of plain layers under the surface,
    // then each other layer with the run of plain layers under it ([`Under`]).
    let mut top = UpRun::EMPTY;
    let mut under = Under::default();
    for j in 0..scene.layers.len() {
        let layer = &scene.layers[j];
        if !layer.z_bottom.is_finite() {
            break;
        }
        // A rough face scatters the beam: beyond it no reflection is a Dirac direction.
        if j >= scene.first_rough_face {
            return steps;
        }
        let Some(d) = down(layer.n) else { return steps };
        if surface || j > 0 {
            let n_above = scene.n_above_layer(j);
            let t_top = 1.0 - fresnel::reflectance(layer.n, n_above, d.z).0;
            way.transmit *= t_top;
            way.twin_transmit *= t_top;
        }
        let t = (layer.z_bottom - way.pos.z) / d.z;
        if !layer.opaque.is_empty() && scene.blocked(layer, way.pos, d, t) {
            return steps;
        }
        way.segment(scene, layer, d, t, rng);
        way.pos.z = layer.z_bottom;
        steps += 1;
        // Its way up, for this interface's reflection and every one below.
        let Some(u) = up(layer.n) else { return steps };
        if layer.plain && !layer.heterogeneous && !layer.obstructs_shadows {
            under.last_run().unwrap_or(&mut top).add(scene, j, u);
        } else {
            under.push((j, UpRun::EMPTY));
        }
        // (The stack's bottom face is smooth: `first_rough_face` is the number of layers without one.)
        if j + 1 < scene.layers.len() && j + 1 == scene.first_rough_face {
            return steps;
        }
        let n_below = scene.layers.get(j + 1).map_or(scene.n_below, |l| l.n);
        let (r, _) = fresnel::reflectance(layer.n, n_below, d.z);
        if r <= 0.0 || way.transmit <= 0.0 {
            continue;
        }
        let mut c = Crossing { transmit: way.transmit * r, twin_transmit: way.twin_transmit * r, ..way };
        for &(k, run) in under.rev() {
            if run.layers > 0 {
                run.cross(&mut c);
                steps += 1;
            }
            // As `trace_up` crosses a layer.
            let layer = &scene.layers[k];
            let Some(d) = up(layer.n) else { return steps };
            let t = (c.pos.z - layer.z_top) / -d.z;
            if layer.obstructs_shadows && obstructed(scene, k, c.pos, d, t) {
                return steps;
            }
            c.segment(scene, layer, d, t, rng);
            c.pos.z = layer.z_top;
            let (r, _) = fresnel::reflectance(layer.n, scene.n_above_layer(k), -d.z);
            c.transmit *= 1.0 - r;
            c.twin_transmit *= 1.0 - r;
            steps += 1;
        }
        if top.layers > 0 {
            top.cross(&mut c);
            steps += 1;
        }
        each(c);
    }
    steps
}

/// The layers the ways up of [`reflections_below`] cross one by one (density media, regions,
/// solids), top down, each with the run of plain layers under it: the first [`Under::INLINE`]
/// held in place, more on the heap — no allocation per path in a scene of up to that many such
/// layers (every shipped one has at most two).
struct Under {
    inline: [(usize, UpRun); Under::INLINE],
    len: usize,
    spill: Vec<(usize, UpRun)>,
}

impl Default for Under {
    fn default() -> Self {
        Under { inline: [(0, UpRun::EMPTY); Under::INLINE], len: 0, spill: Vec::new() }
    }
}

impl Under {
    const INLINE: usize = 8;

    fn push(&mut self, e: (usize, UpRun)) {
        match self.inline.get_mut(self.len) {
            Some(slot) => *slot = e,
            None => self.spill.push(e),
        }
        self.len += 1;
    }

    /// The run under the lowest layer held, if any.
    fn last_run(&mut self) -> Option<&mut UpRun> {
        match self.len {
            0 => None,
            n if n <= Self::INLINE => Some(&mut self.inline[n - 1].1),
            _ => self.spill.last_mut().map(|e| &mut e.1),
        }
    }

    /// Bottom up.
    fn rev(&self) -> impl Iterator<Item = &(usize, UpRun)> {
        self.spill.iter().rev().chain(self.inline[..self.len.min(Self::INLINE)].iter().rev())
    }
}

/// The way up through consecutive layers each of one homogeneous medium without regions or
/// solids, summed ([`reflections_below`]): their optical depth, optical length and lateral shift
/// along the ways up, the product of their top faces' Fresnel transmittances, and the depth of
/// the top face of the highest.
#[derive(Debug, Clone, Copy)]
struct UpRun {
    layers: u32,
    tau: f64,
    length: f64,
    shift: (f64, f64),
    transmit: f64,
    z_top: f64,
}

impl UpRun {
    const EMPTY: UpRun = UpRun { layers: 0, tau: 0.0, length: 0.0, shift: (0.0, 0.0), transmit: 1.0, z_top: 0.0 };

    /// Add layer `j`, the next below the run, crossed along `u` (upward).
    fn add(&mut self, scene: &Scene, j: usize, u: DVec3) {
        let layer = &scene.layers[j];
        let t = (layer.z_bottom - layer.z_top) / -u.z;
        if self.layers == 0 {
            self.z_top = layer.z_top;
        }
        self.layers += 1;
        self.tau += scene.media[layer.medium].sigma_t() * t;
        self.length += layer.n * t;
        self.shift.0 += t * u.x;
        self.shift.1 += t * u.y;
        self.transmit *= 1.0 - fresnel::reflectance(layer.n, scene.n_above_layer(j), -u.z).0;
    }

    /// Cross the run from its bottom face up through its top face.
    fn cross(&self, c: &mut Crossing) {
        c.tau += self.tau;
        c.length += self.length;
        c.pos.x += self.shift.0;
        c.pos.y += self.shift.1;
        c.pos.z = self.z_top;
        c.transmit *= self.transmit;
        c.twin_transmit *= self.transmit;
    }
}

/// The shadow ray from a scattering vertex at `pos` in layer `li` for the exit direction drawn
/// from the uniforms `(u1, u2)`; `density(ω)` is the scatterer's `(f, q)` toward the direction `ω`
/// at the vertex: the scattered share per steradian (`p` of a particle's phase function, `f|cos|`
/// of a surface's BSDF) and the density the walk draws its own continuation from (`p` again; the
/// BSDF's sampling density). `None` when nothing can come out that way (the direction cannot exist in some
/// layer: total internal reflection).
// The allow is a measured exception (issue 19): see `receiver_ray`.
#[allow(clippy::too_many_arguments)]
pub fn shadow_ray(
    scene: &Scene,
    li: usize,
    pos: DVec3,
    density: impl Fn(DVec3) -> (f64, f64),
    target: &NeeTarget,
    u1: f64,
    u2: f64,
    rng: &mut PathRng,
) -> Option<ShadowHit> {
    let dir = cone_direction(target.axis, target.basis, target.cos_acceptance, u1, u2);
    if dir.z >= 0.0 {
        return None;
    }
    let n0 = scene.n_above;
    // n sin θ and the azimuth are conserved through planar interfaces.
    let tangential = DVec3::new(dir.x, dir.y, 0.0) * n0;
    let direction_in = |n: f64| -> Option<DVec3> {
        let t = tangential / n;
        let sin2 = t.length_squared();
        (sin2 < 1.0).then(|| DVec3::new(t.x, t.y, -(1.0 - sin2).sqrt()))
    };
    let n_k = scene.layers[li].n;
    let dir_vertex = direction_in(n_k)?;
    let Crossing { pos: p, tau, transmit, length, excess, twin_transmit } =
        trace_up(scene, li, pos, dir_vertex, direction_in, Crossing::START, rng)?;
    // (Ratio tracking's estimate is 0 only where a density equals its segment's majorant at a
    // point drawn at random, inside a segment where it does not everywhere: never, in practice.
    // The twin's way would be open there.)
    if transmit <= 0.0 {
        return None;
    }
    let cos0 = -dir.z;
    let cos_k = -dir_vertex.z;
    let etendue = (n0 * n0 * cos0) / (n_k * n_k * cos_k);
    // Balance heuristic against the direct escapes of directions drawn by the scatterer (in exit
    // solid angle: pdf q·etendue for those, 1/Ω for the cone): f/pdf_cone · w = f·et·T·e^{−τ}/(q·et
    // + 1/Ω). For a phase function f = q = p, never above T·e^{−τ} ≤ 1, so a forward-peaked phase
    // function cannot make a huge weight; for a surface f is its BSDF's value, q its sampling
    // density.
    let (f, q) = density(dir_vertex);
    let qe = q * etendue;
    let factor = f * etendue / (qe + 1.0 / target.solid_angle()) * transmit * (-tau).exp();
    let unit = etendue / (qe + 1.0 / target.solid_angle()) * transmit;
    let twin_unit = etendue / (qe + 1.0 / target.solid_angle()) * twin_transmit;
    Some(ShadowHit { pos: p, dir, dir_vertex, factor, length, excess, unit, twin_unit, tau })
}

/// The roulette of a vertex's connections (shadow rays to a detector, or a camera path's to the
/// laser): none carries more than `weight·exp(−τ_min)`, `τ_min` being the optical depth straight
/// up through the least dense media. Below `SHADOW_ROULETTE_WEIGHT` they are traced with
/// probability `bound/threshold`; returns the factor they are weighted by (its inverse, or 1;
/// 0: not traced), which keeps them unbiased. Deep vertices (under a pigmented layer) then cost a
/// free flight and a phase sample, not a connection through every layer above.
#[inline(always)]
pub(super) fn connection_roulette(scene: &Scene, li: usize, s: &crate::detect::PathState, rng: &mut PathRng) -> f64 {
    let q = s.weight * (-scene.layers[li].min_optical_depth_up(s.pos.z)).exp() / super::nee::SHADOW_ROULETTE_WEIGHT;
    if q >= 1.0 {
        1.0
    } else if rng.uniform() < q {
        1.0 / q
    } else {
        0.0
    }
}
