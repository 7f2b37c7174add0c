//! The scene: a stack of planar layers (MCML-style), each filled with a medium, with regions of
//! other media embedded in them. Regions are index-matched to their layer; where regions of one
//! layer overlap, the one listed first wins.

use glam::DVec3;

use super::{Medium, Shape};

/// Most regions one layer may hold (the free-flight segment buffer lives on the stack).
pub const MAX_REGIONS_PER_LAYER: usize = 16;

/// One planar layer `z_top ≤ z < z_bottom`.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    pub name: String,
    pub z_top: f64,
    /// `f64::INFINITY` for a semi-infinite last layer.
    pub z_bottom: f64,
    /// Real refractive index.
    pub n: f64,
    /// The layer's top face: smooth (Fresnel's) or a rough surface model. A rough face between
    /// equal indices is no interface at all.
    pub face: crate::surface::Interface,
    /// Index into [`Scene::media`] of the medium filling the layer outside its regions.
    pub medium: usize,
    /// Indices into [`Scene::regions`], in priority order.
    pub regions: Vec<usize>,
    /// Largest σt in the layer (m⁻¹): the majorant for delta tracking.
    pub majorant: f64,
    /// Smallest σt in the layer (m⁻¹).
    pub minorant: f64,
    /// Whether the layer's medium or one of its regions' has a density field: its free flights
    /// and shadow rays then go through the majorant segments (`transport::tracking`).
    pub heterogeneous: bool,
    /// Smallest optical depth from the layer's top up to the surface (straight up through the
    /// minorants of the layers above): bounds what a shadow ray from the layer can carry.
    pub tau_above: f64,
    /// Indices into [`Scene::opaque`] of the opaque solids inside the layer.
    pub opaque: Vec<usize>,
    /// Whether its top or bottom face is rough between different indices (derived): the walk
    /// crosses such a face outside its loop.
    pub rough_faces: bool,
    /// Whether it holds neither regions nor opaque solids (derived): its filling medium alone.
    pub plain: bool,
    /// Whether a straight way up through it can be closed (derived): it holds opaque solids, or
    /// its top face is rough between different indices.
    pub obstructs_shadows: bool,
}

impl Layer {
    /// A lower bound on the optical depth of any way from depth `z` in this layer up to the
    /// surface.
    #[inline]
    pub fn min_optical_depth_up(&self, z: f64) -> f64 {
        self.tau_above + self.minorant * (z - self.z_top)
    }
}

/// A solid region of another medium inside one layer (clipped to that layer).
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    pub name: String,
    pub shape: Shape,
    /// Index into [`Scene::media`].
    pub medium: usize,
    /// Index of the layer that holds it.
    pub layer: usize,
}

/// Lateral bounds of the stack (`[lateral]`): every layer cut to `x0 ≤ x ≤ x1`, `y0 ≤ y ≤ y1`,
/// a box phantom whose four side faces look onto a non-scattering medium of index `n_outside`.
/// A path that crosses a side face ends there (counted in `transmittance_lateral`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lateral {
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub n_outside: f64,
}

impl Lateral {
    /// Whether `(x, y)` lies within the bounds (faces included).
    #[inline]
    pub fn contains(&self, x: f64, y: f64) -> bool {
        self.x.0 <= x && x <= self.x.1 && self.y.0 <= y && y <= self.y.1
    }

    /// From `pos` inside the bounds along `dir`: the distance to the side face ahead (≥ 0; ∞
    /// for a vertical ray) and its axis (0: an x face, 1: a y face).
    #[inline(always)]
    pub fn exit(&self, pos: DVec3, dir: DVec3) -> (f64, usize) {
        let ahead = |p: f64, d: f64, (lo, hi): (f64, f64)| {
            if d > 0.0 {
                (hi - p) / d
            } else if d < 0.0 {
                (lo - p) / d
            } else {
                f64::INFINITY
            }
        };
        let (tx, ty) = (ahead(pos.x, dir.x, self.x), ahead(pos.y, dir.y, self.y));
        if tx <= ty { (tx.max(0.0), 0) } else { (ty.max(0.0), 1) }
    }
}

/// An opaque reflecting surface (issue 38): its BSDF and its motion. It closes the stack from
/// below (`[bottom]`) or bounds an opaque solid inside a layer ([`Opaque`]): the light reaching
/// it is reflected by the BSDF or absorbed there. It may move: a translation and a rotation about
/// `center`, whose Doppler term is `n v·(dir_in − dir_out)` per reflection, as a particle's.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    pub bsdf: crate::surface::Bsdf,
    /// Velocity of translation, m/s.
    pub velocity: DVec3,
    /// Angular velocity, rad/s, about the axis through `center`.
    pub angular_velocity: DVec3,
    pub center: DVec3,
}

impl Surface {
    /// The surface's velocity at `p`: `v + ω × (p − center)`.
    #[inline]
    pub fn velocity_at(&self, p: DVec3) -> DVec3 {
        self.velocity + self.angular_velocity.cross(p - self.center)
    }

    /// Whether any point of it moves.
    pub fn is_moving(&self) -> bool {
        self.velocity != DVec3::ZERO || self.angular_velocity != DVec3::ZERO
    }

    /// The local frame of the surface under the stack: its normal points up (`−z`), into the
    /// stack.
    #[inline]
    pub fn bottom_frame() -> crate::surface::Frame {
        crate::surface::Frame { n: DVec3::NEG_Z, t: DVec3::X, b: DVec3::NEG_Y }
    }
}

/// An opaque solid inside one layer (`[[opaque]]`): a plate, a wall, a belt, a wheel. Light
/// meets its boundary and is reflected there by its [`Surface`]; nothing enters it, and it
/// blocks shadow rays. It lies wholly inside its layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Opaque {
    pub name: String,
    /// A convex shape: a ray leaving its boundary never meets it again.
    pub shape: Shape,
    pub surface: Surface,
    /// Index of the layer that holds it.
    pub layer: usize,
    /// Distances along a ray shorter than this (m; 10⁻⁹ of the shape's size) are the boundary the
    /// ray starts on: a path reflected there does not meet it again by rounding.
    pub tolerance: f64,
}

impl Opaque {
    /// The distance along `o + t·d` (unit `d`) to where the ray first meets the solid, if ahead.
    #[inline]
    pub fn hit(&self, o: DVec3, d: DVec3) -> Option<f64> {
        let (a, b) = self.shape.intersect(o, d)?;
        (b > self.tolerance).then_some(a.max(0.0))
    }
}

/// Everything light travels through. Outside the stack are non-scattering half-spaces with
/// indices `n_above` (z < 0) and `n_below`; with `lateral`, the stack is a box; with `bottom`, an
/// opaque surface closes it from below (and `n_below` is the last layer's index: no interface
/// there); `opaque` solids sit inside layers.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub layers: Vec<Layer>,
    pub regions: Vec<Region>,
    pub media: Vec<Medium>,
    pub n_above: f64,
    pub n_below: f64,
    /// The box's side faces (`None`: layers of infinite extent; the walk is compiled without
    /// them).
    pub lateral: Option<Lateral>,
    /// The opaque surface under the last layer (which is then finite), if any.
    pub bottom: Option<Surface>,
    /// Opaque solids inside the layers (each listed by its layer, [`Layer::opaque`]).
    pub opaque: Vec<Opaque>,
    /// The first layer whose top face is rough (derived; the number of layers if none): the
    /// laser's collimated beam is a Dirac direction only above it, in the layers before (no
    /// camera path connects to it below but through that face).
    pub first_rough_face: usize,
    /// The cardiac cycle its pulsatile flows share (`None`: every flow is steady; the walk is
    /// compiled without the harmonics, [`crate::flow::pulse`]).
    pub cycle: Option<crate::flow::pulse::Cycle>,
}

impl Scene {
    /// The medium at `p`, which must lie in `layer`.
    #[inline]
    pub fn medium_at(&self, layer: &Layer, p: DVec3) -> usize {
        for &r in &layer.regions {
            let region = &self.regions[r];
            if region.shape.contains(p) {
                return region.medium;
            }
        }
        layer.medium
    }

    /// The layered twin of this scene: every region removed (its layer's filling medium in its
    /// place) and every opaque solid, the layers' majorants and optical depths recomputed
    /// ([`crate::detect::twin`]). The planar surfaces stay: the bottom and the rough faces.
    pub fn layered_twin(&self) -> Scene {
        let mut twin = self.clone();
        twin.regions.clear();
        twin.opaque.clear();
        for l in &mut twin.layers {
            l.regions.clear();
            l.opaque.clear();
        }
        twin.update_layers();
        twin
    }

    /// Derive what each layer caches of its media and faces (the σt bounds, whether it is
    /// heterogeneous, the optical depth above it, whether it is plain and its faces rough); call
    /// after changing the media, regions, opaque solids or faces.
    pub fn update_layers(&mut self) {
        let mut tau_above = 0.0;
        let faces: Vec<(bool, bool)> = (0..self.layers.len())
            .map(|j| {
                let top = self.rough_top(j);
                (top, top || (j + 1 < self.layers.len() && self.rough_top(j + 1)))
            })
            .collect();
        self.first_rough_face = faces.iter().position(|&(top, _)| top).unwrap_or(self.layers.len());
        for (layer, (rough_top, rough_faces)) in self.layers.iter_mut().zip(faces) {
            layer.rough_faces = rough_faces;
            layer.plain = layer.regions.is_empty() && layer.opaque.is_empty();
            layer.obstructs_shadows = rough_top || !layer.opaque.is_empty();
            let media = || std::iter::once(layer.medium).chain(layer.regions.iter().map(|&r| self.regions[r].medium));
            layer.majorant = media().map(|m| self.media[m].sigma_t_range().1).fold(0.0, f64::max);
            layer.minorant = media().map(|m| self.media[m].sigma_t_range().0).fold(f64::INFINITY, f64::min);
            layer.heterogeneous = media().any(|m| self.media[m].density().is_some());
            layer.tau_above = tau_above;
            tau_above += layer.minorant * (layer.z_bottom - layer.z_top);
        }
    }

    /// The refractive index above layer `j`'s top face: the layer above's, or the ambient medium's.
    #[inline(always)]
    pub fn n_above_layer(&self, j: usize) -> f64 {
        if j == 0 { self.n_above } else { self.layers[j - 1].n }
    }

    /// Whether layer `j`'s top face is rough between different indices (a face of the same index
    /// on both sides is no interface at all).
    #[inline]
    pub fn rough_top(&self, j: usize) -> bool {
        self.layers[j].face.is_rough() && self.layers[j].n != self.n_above_layer(j)
    }

    /// The `[wind]` the scene's particles are carried by (the first population moved by it), for
    /// figures that set a retrieved wind against it.
    pub fn wind(&self) -> Option<&crate::flow::WindProfile> {
        use crate::flow::VelocityField;
        self.media.iter().flat_map(|m| m.populations()).find_map(|p| match &p.velocity {
            VelocityField::Wind(w) | VelocityField::TerminalFall { wind: w, .. } => Some(w),
            _ => None,
        })
    }

    /// Whether any particle or surface in the scene moves (otherwise no Doppler term is computed
    /// at all).
    pub fn is_moving(&self) -> bool {
        self.media.iter().any(|m| m.is_dynamic())
            || self.bottom.as_ref().is_some_and(Surface::is_moving)
            || self.opaque.iter().any(|o| o.surface.is_moving())
    }

    /// The first opaque solid of `layer` that the ray `o + t·d` meets, and the distance to it
    /// (`(∞, usize::MAX)`: none).
    #[inline]
    pub fn first_opaque(&self, layer: &Layer, o: DVec3, d: DVec3) -> (f64, usize) {
        let mut best = (f64::INFINITY, usize::MAX);
        for &k in &layer.opaque {
            if let Some(t) = self.opaque[k].hit(o, d)
                && t < best.0
            {
                best = (t, k);
            }
        }
        best
    }

    /// Whether an opaque solid of `layer` lies across the segment `o + t·d`, `0 ≤ t ≤ len`.
    #[inline]
    pub fn blocked(&self, layer: &Layer, o: DVec3, d: DVec3, len: f64) -> bool {
        layer.opaque.iter().any(|&k| self.opaque[k].hit(o, d).is_some_and(|t| t < len))
    }

    /// Depth of the bottom of the stack (∞ if the last layer is semi-infinite).
    pub fn z_bottom(&self) -> f64 {
        self.layers.last().map_or(0.0, |l| l.z_bottom)
    }

    /// Refractive index above (`side < 0`) or below the stack.
    pub fn ambient_n(&self, below: bool) -> f64 {
        if below { self.n_below } else { self.n_above }
    }
}
