//! The camera-side (adjoint) estimator of a camera's images: paths start at a pixel and connect
//! to the laser at every real scattering vertex.
//!
//! A camera pixel measures the power `P = ∫_A ∫_cone L0(x, ω) |cos θ| dω dA` crossing its area `A`
//! within the acceptance cone, `L0` being the radiance above the stack. Forward tracing with
//! next-event estimation ([`super::nee`]) spreads each path's contributions over whichever pixels
//! its shadow rays land in; the adjoint walk instead estimates `L0` for a point drawn uniformly in
//! the pixel and a direction drawn uniformly in the cone, so every pixel gets the same number of
//! paths and each path's every vertex scores into its own pixel (Veach 1997 §3.7: importance
//! transport; Pharr, Jakob & Humphreys, *PBR* 4th ed., ch. 14, volumetric path tracing from the
//! sensor with next-event estimation to lights).
//!
//! The walk itself is the forward one ([`super::walk`]) run backwards from the pixel: the same
//! free flights, absorption weighting, phase sampling and Fresnel choices, with two differences.
//! It carries radiance, not power, so refraction from a layer of index `n_a` into one of `n_b`
//! multiplies its weight by `(n_a/n_b)²` (`L/n²` is invariant, and the Fresnel transmittance is
//! the probability of the choice); the exit into the camera's medium at the start, `(1 − R)·(n0/n1)²`,
//! is applied deterministically. And at every real collision, at `x` in layer `k`, it connects to
//! the collimated beam ([`beam_connection`]): the beam reaches `x` along the one direction `ω_k`
//! that refracts from the laser's direction (`n sin θ` is conserved through the planes), with
//! the irradiance
//!
//! `E_k(x) = E0(y)·(cos θ0/cos θ_k)·Π(1 − R_i)·exp(−τ)`,
//!
//! where `E0(y)` is the profile's irradiance where the ray back from `x` leaves the emission plane
//! ([`crate::source::Source::irradiance_along`]), the cosine ratio turns power per horizontal area
//! (conserved through the planes) into irradiance across the refracted beam, `R_i` are the Fresnel
//! reflectances of the interfaces crossed and `τ` the optical depth of the straight segments
//! (analytic, or ratio tracking in density layers). The vertex scores
//! `W·p(ω_k · ω_out)·E_k(x)`, with `W` the walk's weight after the absorption weighting (the
//! collision density `σt·e^{−τ}` turns the in-scattered radiance `σs·p·E` into `albedo·p·E`) and
//! `ω_out = −dir` the light's direction towards the camera.
//!
//! Doppler and path length: the light's path is the adjoint path reversed. At a vertex reached
//! along `d_in` and left along `d_out` by the adjoint walk, the light arrives along `−d_out` and
//! leaves along `−d_in`, so `dir_in − dir_out` is the same vector both ways and the walk's own
//! Doppler bookkeeping gives the light's `dl/dt` with the library's sign (DESIGN.md: reciprocal
//! paths, same sign); the connection adds its vertex's term with `ω_k − (−dir)`.
//!
//! Two ways to the last vertex. Tissue and blood scatter strongly forward (Henyey–Greenstein
//! g = 0.95–0.97: half of each deflection within ~(1 − g) rad), so the light under the beam stays
//! within a degree or two of the beam's direction, and a connection's phase factor
//! `p(ω_k · ω_out)` is large (up to `(1 + g)/(4π(1 − g)²)` ≈ 170 sr⁻¹) only where the walk
//! happens to travel back up the beam within that cone. Measured on `configs/retina_ldh.toml`
//! (one pixel, 64 000 paths, 6.4·10⁶ connections): the largest 1 % of connections carried 95 % of
//! the signal and all but 2·10⁻⁶ of its variance, all in the retina with `ω_out` within 2° of the
//! beam. So from every vertex `x` (reached along `d`) the path is also extended by one vertex
//! the way the beam's lobe favours: a direction `u` drawn from a guide lobe about the reversed
//! beam (Henyey–Greenstein [`GUIDE_G`], density `q(u)`), the straight refracted way through the
//! layers to a real collision `y` ([`lobe_flight`], crossing interfaces by transmission), and a
//! connection at `y`. The walk reaches the same `y` by drawing `u` from `p(d · u)` and crossing the
//! same interfaces by the Fresnel coin, so the two are weighted by the balance heuristic (Veach
//! 1997, ch. 9) with the densities `p(d·u)·ΠT_i` and `q(u)` (the flights' densities are common):
//! the walk's connection at `y` by `r/(r + 1)` with `r = p(d·u)·ΠT_i/q(u)` carried in the
//! camera path's balance (`adjoint::Balance::BeamLobe`; weight 1 when an interface reflected it
//! on the way: no lobe path has that), the lobe's by `p(d·u)·ΠT_i/(p(d·u)·ΠT_i + q(u))`. Where `x` lies in a layer of broad
//! scattering (the RPE, the choroid), `p(d·u)` is smooth and the spike of the retina's phase
//! function at `y` is sampled by `q` instead of met by chance.
//!
//! A collimated beam is a delta in direction, so no walk can hit it by chance: the connections
//! are the whole estimate. A pencil beam lights a line, which a connection reaches with
//! probability zero: the camera estimator needs a disk or Gaussian footprint.
//!
//! Surfaces (issue 38). A camera path crosses a rough face between layers by drawing from its
//! microfacets as a forward path does, with `(n_i/n_t)²` on a refraction (radiance), and reflects
//! at opaque surfaces by their BSDFs (reciprocal: the same weights as for power). An opaque
//! surface's vertex connects to the beam as a collision does, with the BSDF's `f·cos θ_b` for the
//! phase function. The beam stays a Dirac direction only down to the stack's first rough face
//! (`Scene::first_rough_face`): that face connects to it where the walk meets it,
//! `E·cos θ_b·F(−b → −dir)/|cos θ_out|` (`F` the face's power per steradian: its reflection from
//! above, its transmission from below), and every vertex below connects through the face's lobe
//! ([`face_lobe`]): a transmitted direction drawn from the face's microfacets for the beam's
//! direction, the straight way up to the face along it, and the radiance the face sends down
//! there. The walk reaches the same face point by drawing the direction from its vertex, so the
//! two are balanced as the beam-lobe connection is (`adjoint::Balance::FaceLobe` carries the ratio
//! of the walk's density, times the smooth faces' transmittances, to the lobe's,
//! [`face_lobe_density`]).
//! A smooth mirror in the beam above every rough face would reflect a second collimated beam,
//! which no connection reaches: refused at resolve time.

use glam::DVec3;

use crate::detect::{Area, ImageSpec, Shot};
use crate::medium::Scene;
use crate::sampling::PathRng;
use crate::source::Source;

use super::fresnel;
use super::nee::{Crossing, reflections_below, trace_up};

/// A surface detector scored by the camera-side estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraTarget {
    /// Index of the detector.
    pub detector: usize,
    pub image: ImageSpec,
    pub area: Area,
    /// Height of the detector plane above the surface, m.
    pub distance: f64,
    /// Cone axis (pointing away from the stack, `z < 0`) and its perpendicular basis.
    pub axis: DVec3,
    pub basis: (DVec3, DVec3),
    pub cos_acceptance: f64,
    /// Whether the laser's specular reflection at the top surface is recorded.
    pub include_specular: bool,
    /// Paths leave from every `stride`-th pixel only (1 but in a pilot, [`crate::pilot`]).
    pub stride: usize,
}

impl CameraTarget {
    pub fn new(detector: usize, image: ImageSpec, area: Area, distance: f64, axis: DVec3, cos_acceptance: f64) -> Self {
        let basis = crate::sampling::warp::orthonormal_basis(axis);
        CameraTarget {
            detector,
            image,
            area,
            distance,
            axis,
            basis,
            cos_acceptance,
            include_specular: false,
            stride: 1,
        }
    }

    /// Pixel `pixel`'s area, m², and a point drawn uniformly in it on the detector plane.
    pub fn point(&self, pixel: usize, rng: &mut PathRng) -> (f64, f64, f64) {
        let im = &self.image;
        let (dx, dy) = ((im.max[0] - im.min[0]) / im.nx as f64, (im.max[1] - im.min[1]) / im.ny as f64);
        let (ix, iy) = (pixel % im.nx, pixel / im.nx);
        let x = im.min[0] + (ix as f64 + rng.uniform()) * dx;
        let y = im.min[1] + (iy as f64 + rng.uniform()) * dy;
        (dx * dy, x, y)
    }

    pub fn pixels(&self) -> usize {
        self.image.nx * self.image.ny
    }

    /// Camera paths per pixel in a batch of `paths_per_batch` forward paths: as many camera paths
    /// as forward paths, rounded up to a whole number per pixel, so that every pixel gets exactly
    /// the same number in every batch (no pixel is left without an estimate in any batch).
    pub fn paths_per_pixel(&self, paths_per_batch: u64) -> u64 {
        paths_per_batch.div_ceil(self.pixels() as u64).max(1)
    }
}

/// The start of a camera path from the point `(x, y)` of pixel `pixel` of `cam` (of area `area`):
/// a direction uniform in the acceptance cone, carried to the surface and refracted in (through
/// a rough top face, left on the face with its direction above: the walk draws its crossing
/// there, `transport::walk`'s `camera_rough_face`). `None` if the direction cannot enter the
/// stack. `batch_weight` is the tally weight of one of this
/// pixel's paths in its batch. Returns the shot and the walk's starting position, direction,
/// weight and path length.
#[allow(clippy::too_many_arguments)]
pub fn start(
    cam: &CameraTarget,
    scene: &Scene,
    pixel: usize,
    (area, x, y): (f64, f64, f64),
    batch_weight: f64,
    u1: f64,
    u2: f64,
) -> Option<(Shot, DVec3, DVec3, f64, f64)> {
    // The light's direction, uniform in the cone; the walk goes the other way.
    let out = super::nee::cone_direction(cam.axis, cam.basis, cam.cos_acceptance, u1, u2);
    if out.z >= 0.0 {
        return None;
    }
    let d = -out;
    let t0 = cam.distance / d.z;
    let pos = DVec3::new(x + t0 * d.x, y + t0 * d.y, 0.0);
    let solid_angle = crate::detect::cone_solid_angle(cam.cos_acceptance);
    let scale = batch_weight * area * solid_angle * d.z;
    let shot = Shot { detector: cam.detector, pixel, x, y, scale };
    if scene.rough_top(0) {
        // On the rough face, still travelling along `d`: the walk draws its crossing there.
        return Some((shot, pos, d, 1.0, scene.n_above * t0));
    }
    let (n0, n1) = (scene.n_above, scene.layers[0].n);
    let (r, cos_t) = fresnel::reflectance(n0, n1, d.z);
    if r >= 1.0 {
        return None;
    }
    let weight = (1.0 - r) * (n0 / n1) * (n0 / n1);
    Some((shot, pos, fresnel::refract(d, n0, n1, cos_t), weight, n0 * t0))
}

/// The laser's light that reaches the camera's point `(x, y)` without scattering: the specular
/// reflection at the top surface (when the detector records it) and the reflections at every
/// interface below, each a collimated beam leaving along the mirror image `(b_x, b_y, −b_z)` of
/// the laser's direction `b`. For each one inside the acceptance cone, `emit` gets the power per
/// unit area of the detector plane at the point (per watt emitted) and the optical path length:
/// `E0·cos θ0·R_j·Π(1 − R_i)·exp(−τ)` over the way down to interface `j` and back up, the
/// ray traced back from the point (so a beam shifted sideways by an oblique incidence, and
/// shadowed by regions, lands where it does). A pixel's share is that times its area.
///
/// Directions are deltas, which no camera path can meet by chance, so these are scored from the
/// point alone. Light reflected more than once between interfaces (`R_i R_j ≲ 10⁻⁶` of this)
/// is left out. A rough face reflects a lobe, not a beam: none from it or below it (the camera
/// paths' connections at the face score its reflection).
pub fn unscattered(
    cam: &CameraTarget,
    scene: &Scene,
    source: &Source,
    (x, y): (f64, f64),
    rng: &mut PathRng,
    mut emit: impl FnMut(f64, f64),
) {
    let b = source.emit_direction(rng);
    let mirror = DVec3::new(b.x, b.y, -b.z);
    // A rough top face scatters the whole beam: its reflection is a lobe, which the camera paths
    // meet at the face.
    if mirror.dot(cam.axis) < cam.cos_acceptance || scene.rough_top(0) {
        return;
    }
    let n0 = scene.n_above;
    // Back from the point to the surface.
    let t0 = cam.distance / b.z;
    let top = DVec3::new(x - t0 * mirror.x, y - t0 * mirror.y, 0.0);
    let l0 = n0 * t0;
    // Power per horizontal area of the beam at the surface point `s`, and its path length there.
    let at_top = |s: DVec3| {
        let back = (s - source.position).dot(source.direction) / b.dot(source.direction);
        (source.irradiance_along(s, b) * b.z, n0 * back)
    };
    if cam.include_specular {
        let (r, _) = fresnel::reflectance(n0, scene.layers[0].n, b.z);
        let (e, l) = at_top(top);
        if r > 0.0 && e > 0.0 {
            emit(e * r, l + l0);
        }
    }
    let down_in = |n: f64| refracted_down(b, n0, n);
    // Traced back from the point: the way up from interface j, back down from the surface (the
    // reflected beam travels along `(d_x, d_y, −d_z)` in each layer, so going back is along
    // `−that`), then the way down to the interface, back up to the surface (along `−d`).
    let back = |n: f64| down_in(n).map(|d| DVec3::new(-d.x, -d.y, d.z));
    let up_in = |n: f64| down_in(n).map(|d| -d);
    let start = Crossing { pos: top, length: l0, ..Crossing::START };
    reflections_below(scene, start, true, back, up_in, rng, |Crossing { pos: q, tau, transmit, length: l, .. }| {
        let (e, l_top) = at_top(q);
        if e > 0.0 && transmit > 0.0 {
            emit(e * transmit * (-tau).exp(), l + l_top);
        }
    });
}

/// The direction `beam` (travelling down, in the ambient medium of index `n0`) takes in a layer
/// of index `n`: `n sin θ` and the azimuth are conserved through planar interfaces. `None` if it
/// cannot exist there.
pub fn refracted_down(beam: DVec3, n0: f64, n: f64) -> Option<DVec3> {
    let t = DVec3::new(beam.x, beam.y, 0.0) * (n0 / n);
    let sin2 = t.length_squared();
    (sin2 < 1.0).then(|| DVec3::new(t.x, t.y, (1.0 - sin2).sqrt()))
}

/// Forward peak of the guide lobe of the beam-lobe connection: tissue and blood scatter with
/// g = 0.95–0.97, which is what the light under the beam keeps of its direction.
pub const GUIDE_G: f64 = 0.95;

/// The guide lobe (Henyey–Greenstein, [`GUIDE_G`]).
pub fn guide() -> crate::phase::HenyeyGreenstein {
    crate::phase::HenyeyGreenstein::new(GUIDE_G).expect("GUIDE_G is a valid asymmetry")
}

/// Where a beam-lobe flight collides: the point, its layer and medium, the direction there, the
/// product of the Fresnel transmittances crossed, the radiance factor `Π(n_a/n_b)²` and the
/// optical path length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LobeHit {
    pub pos: DVec3,
    pub layer: usize,
    pub medium: usize,
    pub dir: DVec3,
    pub transmit: f64,
    pub radiance: f64,
    pub length: f64,
}

/// The straight, refracted way from `pos` in layer `li` along `dir` to its first real collision
/// (free flights as the walk's), crossing interfaces by transmission. `None` if it leaves the
/// stack, meets total internal reflection, an opaque solid or a rough face, or runs parallel to
/// the layers.
pub fn lobe_flight(
    scene: &Scene,
    li: usize,
    pos: DVec3,
    dir: DVec3,
    tracking: super::Tracking,
    rng: &mut PathRng,
) -> Option<LobeHit> {
    lobe_flight_touching::<false>(scene, li, pos, dir, tracking, rng).0
}

/// [`lobe_flight`], and with `TOUCH` whether its way (to its collision, or out of the stack)
/// met a region of the scene (a flight that meets none is the same in the layered twin, drawn
/// from the same numbers: [`super::field`]).
pub fn lobe_flight_touching<const TOUCH: bool>(
    scene: &Scene,
    mut li: usize,
    mut pos: DVec3,
    mut dir: DVec3,
    tracking: super::Tracking,
    rng: &mut PathRng,
) -> (Option<LobeHit>, bool) {
    let (mut transmit, mut radiance, mut length) = (1.0, 1.0, 0.0);
    let mut touched = false;
    loop {
        let layer = &scene.layers[li];
        let down = dir.z >= 0.0;
        let dz = if down { layer.z_bottom - pos.z } else { pos.z - layer.z_top };
        let ray = super::LayerRay { scene, layer, pos, dir };
        let mut nulls = 0;
        let flight = super::free_flight(ray, dz, dir.z.abs(), tracking, rng, &mut nulls);
        // An opaque solid before the flight's end ends it: the walk's path meets its surface there,
        // a vertex of its own (no lobe path has it). (The flight's distance is drawn as the walk's,
        // whose flight a solid cuts short: up to the solid the two have the same density.)
        let (super::Flight::Collision { t, .. } | super::Flight::Boundary { t }) = flight;
        if TOUCH && !touched {
            touched = super::nee::touches_region(scene, layer, pos, dir, t);
        }
        if !layer.opaque.is_empty() && scene.blocked(layer, pos, dir, t) {
            return (None, touched);
        }
        match flight {
            super::Flight::Collision { t, medium } => {
                let pos = pos + t * dir;
                let hit = LobeHit { pos, layer: li, medium, dir, transmit, radiance, length: length + layer.n * t };
                return (Some(hit), touched);
            }
            super::Flight::Boundary { t } => {
                let next = if down { Some(li + 1) } else { li.checked_sub(1) };
                let Some((next, beyond)) = next.and_then(|j| Some((j, scene.layers.get(j)?))) else {
                    return (None, touched);
                };
                // (A rough face scatters: no straight way through it, as no solid's.)
                if !t.is_finite() || (layer.rough_faces && scene.rough_top(if down { next } else { li })) {
                    return (None, touched);
                }
                length += layer.n * t;
                pos += t * dir;
                pos.z = if down { layer.z_bottom } else { layer.z_top };
                let (r, cos_t) = fresnel::reflectance(layer.n, beyond.n, dir.z.abs());
                if r >= 1.0 {
                    return (None, touched);
                }
                transmit *= 1.0 - r;
                radiance *= (layer.n / beyond.n) * (layer.n / beyond.n);
                dir = fresnel::refract(dir, layer.n, beyond.n, cos_t);
                li = next;
            }
        }
    }
}

/// The laser's light at a vertex: the direction it arrives along, its irradiance there across
/// that direction, and its optical path length from the emission plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamHit {
    /// Direction of travel at the vertex (inside its layer).
    pub dir: DVec3,
    /// W/m² per watt emitted.
    pub irradiance: f64,
    /// m.
    pub length: f64,
    /// What the way up met, for [`twin_irradiance`](Self::twin_irradiance): the irradiance
    /// before its transmittances, its optical depth and the part of it the regions add, its
    /// transmittance and the layered twin's.
    way: (f64, f64, f64, f64, f64),
}

impl BeamHit {
    /// `irradiance` in the scene's layered twin (its regions' excess optical depth and ratio
    /// tracking left out, [`crate::medium::Scene::layered_twin`]): equal to it, bit for bit,
    /// where the way up meets no region. (Evaluated only where asked: the light field's paired
    /// connections, [`super::field`].)
    pub fn twin_irradiance(&self) -> f64 {
        let (e, tau, excess, transmit, twin_transmit) = self.way;
        if excess == 0.0 && twin_transmit == transmit {
            self.irradiance
        } else {
            e * twin_transmit * (excess - tau).exp()
        }
    }
}

/// The unscattered laser light reaching `pos` in layer `li` (see the module docs). `None` where
/// none does: outside the footprint, or a direction that cannot exist in some layer.
pub fn beam_connection(scene: &Scene, source: &Source, li: usize, pos: DVec3, rng: &mut PathRng) -> Option<BeamHit> {
    let beam = source.emit_direction(rng);
    let n0 = scene.n_above;
    let dir = refracted_down(beam, n0, scene.layers[li].n)?;
    // Back up the beam, layer by layer, to the surface.
    let up_in = |n: f64| refracted_down(beam, n0, n).map(|d| -d);
    let Crossing { pos: p, tau, transmit, length, excess, twin_transmit } =
        trace_up(scene, li, pos, -dir, up_in, Crossing::START, rng)?;
    if transmit <= 0.0 {
        return None;
    }
    let e0 = source.irradiance_along(p, beam);
    if e0 <= 0.0 {
        return None;
    }
    let back = (p - source.position).dot(source.direction) / beam.dot(source.direction);
    let e = e0 * (beam.z / dir.z);
    let irradiance = e * transmit * (-tau).exp();
    Some(BeamHit { dir, irradiance, length: length + n0 * back, way: (e, tau, excess, transmit, twin_transmit) })
}

/// The unscattered laser light arriving at `pos` on the top face of layer `face` from above: the
/// layer above's beam ([`beam_connection`]), or at the stack's top face the ambient's. `None`
/// outside the footprint.
pub fn beam_at_face(scene: &Scene, source: &Source, face: usize, pos: DVec3, rng: &mut PathRng) -> Option<BeamHit> {
    if face > 0 {
        return beam_connection(scene, source, face - 1, pos, rng);
    }
    let beam = source.emit_direction(rng);
    let irradiance = source.irradiance_along(pos, beam);
    let back = (pos - source.position).dot(source.direction) / beam.dot(source.direction);
    (irradiance > 0.0).then_some(BeamHit {
        dir: beam,
        irradiance,
        length: scene.n_above * back,
        way: (irradiance, 0.0, 0.0, 1.0, 1.0),
    })
}

/// A camera path's way from a vertex below the stack's first rough face up to that face, where the
/// laser's beam is transmitted into a lobe ([`face_lobe`]): the direction at the vertex (up), the
/// radiance arriving there along its reverse, the density of the direction at the vertex and
/// the product of the smooth faces' Fresnel transmittances on the way (for the balance heuristic
/// against the walk's own way there), and the optical path length from the emission plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceLink {
    pub dir: DVec3,
    pub radiance: f64,
    pub density: f64,
    pub transmit: f64,
    pub length: f64,
}

/// What the face-lobe strategy knows of the stack's first rough face and the beam on it: its
/// indices above and below, its microfacets, the frame with its normal up, and the beam's mean
/// direction there (local to that frame, toward the light).
struct FaceLobe {
    n_above: f64,
    n_below: f64,
    interface: crate::surface::Interface,
    up: crate::surface::Frame,
    to_light: DVec3,
}

impl FaceLobe {
    fn new(scene: &Scene, source: &Source, face: usize) -> Option<FaceLobe> {
        let n_above = scene.n_above_layer(face);
        let b = if face == 0 { source.direction } else { refracted_down(source.direction, scene.n_above, n_above)? };
        let up = crate::medium::Surface::bottom_frame();
        Some(FaceLobe {
            n_above,
            n_below: scene.layers[face].n,
            interface: scene.layers[face].face,
            up,
            to_light: up.to_local(-b),
        })
    }

    /// The density, per steradian at a vertex in a layer of index `n`, of the upward direction
    /// `u` there, whose straight refracted way reaches the face along the transmitted direction
    /// `t` (in the face's layer; `n sin θ` conserved): the face's density of `t` times the solid
    /// angles' ratio `n²|cos θ|/(n_t²|cos θ_t|)`.
    fn density(&self, u: DVec3, t: DVec3, n: f64) -> f64 {
        let pdf = self.interface.pdf(self.to_light, self.up.to_local(t), self.n_above, self.n_below);
        pdf * n * n * u.z.abs() / (self.n_below * self.n_below * t.z.abs())
    }

    /// The direction `u` (upward, in a layer of index `n`) continued to the face's layer: the
    /// transmitted direction `t` it comes from (downward). `None` if it cannot exist there.
    fn transmitted(&self, u: DVec3, n: f64) -> Option<DVec3> {
        refracted_up(u, n, self.n_below).map(|d| -d)
    }
}

/// The upward direction `u` (in a layer of index `n`) in a layer of index `m`: `n sin θ` and the
/// azimuth conserved. `None` if it cannot exist there.
fn refracted_up(u: DVec3, n: f64, m: f64) -> Option<DVec3> {
    let t = DVec3::new(u.x, u.y, 0.0) * (n / m);
    let sin2 = t.length_squared();
    (sin2 < 1.0).then(|| DVec3::new(t.x, t.y, -(1.0 - sin2).sqrt()))
}

/// The first rough face's lobe for a camera path's vertex at `pos` in layer `li` (at or below the
/// face): a direction the face's transmission of the beam's mean direction draws (a visible
/// normal, from three uniforms `u`; nothing if it reflects), continued straight up through the
/// smooth faces between (Fresnel transmittances, optical depth, no solid or other rough face
/// across) to the face, and the radiance the beam sends back down that way:
/// `E·cos θ_b·F(−b → t)/|cos θ_t|` at the face (`F` its power per steradian,
/// [`crate::surface::RoughDielectric::eval`]), times `Π(1 − R_i)·e^{−τ}·(n/n_t)²` to the vertex.
/// Below a rough face the beam's light is no Dirac direction: this is the next-event estimate
/// toward the lit face, which the walk can also reach by drawing the direction from its vertex
/// (`transport::walk`'s `camera_rough_face`, weighted by the balance heuristic with
/// [`face_lobe_density`]).
pub fn face_lobe(
    scene: &Scene,
    source: &Source,
    li: usize,
    pos: DVec3,
    u: [f64; 3],
    rng: &mut PathRng,
) -> Option<FaceLink> {
    let face = scene.first_rough_face;
    let lobe = FaceLobe::new(scene, source, face)?;
    let c = lobe.interface.sample(lobe.to_light, lobe.n_above, lobe.n_below, u)?;
    if !c.transmitted {
        return None;
    }
    let t = lobe.up.to_world(c.wo);
    let n = scene.layers[li].n;
    let up_in = |m: f64| refracted_up(-t, lobe.n_below, m);
    let dir = up_in(n)?;
    let mut way = Crossing { pos, ..Crossing::START };
    // The smooth faces' Fresnel transmittances alone (`way.transmit` also holds ratio tracking's
    // factors through density layers, which the walk's balance does not).
    let mut fresnel = 1.0;
    for j in (face..=li).rev() {
        let layer = &scene.layers[j];
        let d = if j == li { dir } else { up_in(layer.n)? };
        let len = (way.pos.z - layer.z_top) / -d.z;
        // (The face itself is the target: only solids close the way through its layer.)
        if (j > face && scene.rough_top(j)) || (!layer.opaque.is_empty() && scene.blocked(layer, way.pos, d, len)) {
            return None;
        }
        way.segment(scene, layer, d, len, rng);
        way.pos.z = layer.z_top;
        if j > face {
            let t = 1.0 - fresnel::reflectance(layer.n, scene.layers[j - 1].n, -d.z).0;
            way.transmit *= t;
            fresnel *= t;
        }
    }
    if way.transmit <= 0.0 {
        return None;
    }
    let b = beam_at_face(scene, source, face, way.pos, rng)?;
    let to_light = lobe.up.to_local(-b.dir);
    let at_face = lobe.up.to_local(t);
    let f = lobe.interface.eval(to_light, at_face, lobe.n_above, lobe.n_below);
    let radiance = b.irradiance * to_light.z * f / at_face.z.abs()
        * way.transmit
        * (-way.tau).exp()
        * (n / lobe.n_below)
        * (n / lobe.n_below);
    Some(FaceLink { dir, radiance, density: lobe.density(dir, t, n), transmit: fresnel, length: way.length + b.length })
}

/// The density with which [`face_lobe`] draws the upward direction `u` at a vertex in layer `li`
/// (0 where it cannot: a downward `u`, or one that cannot exist in a layer on the way).
pub fn face_lobe_density(scene: &Scene, source: &Source, li: usize, u: DVec3) -> f64 {
    let face = scene.first_rough_face;
    let Some(lobe) = FaceLobe::new(scene, source, face) else { return 0.0 };
    let n = scene.layers[li].n;
    if u.z >= 0.0 || scene.layers[face..li].iter().any(|l| refracted_up(u, n, l.n).is_none()) {
        return 0.0;
    }
    lobe.transmitted(u, n).map_or(0.0, |t| lobe.density(u, t, n))
}
