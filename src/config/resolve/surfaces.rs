//! Opaque surfaces: `[bottom]`, closing the stack from below, and `[[opaque]]` solids inside the
//! layers ([`crate::medium::Surface`], [`crate::medium::Opaque`]), with the surface BSDFs of the
//! configuration ([`SurfaceSection`]).

use glam::DVec3;
use num_complex::Complex64;

use super::{R, err, given_arr, join, shown};
use crate::config::schema::{BottomSection, OpaqueSection, SurfaceSection};
use crate::config::units::{AngularSpeed, Length, Quantity, Speed};
use crate::detect::{Detector, EstimatorChoice};
use crate::medium::{Opaque, Scene, Surface};
use crate::surface::Bsdf;
use crate::surface::metals::Metal;
use crate::surface::microfacet::ROUGHNESS_MIN;

/// The surface under the last layer, checked against what the walks support: a finite last layer
/// above it, no detector below it, and no mirror in the beam for camera-side paths.
pub(super) fn resolve_bottom(
    b: Option<&BottomSection>,
    scene: &Scene,
    wavelength: f64,
    detectors: &[Detector],
) -> R<Option<Surface>> {
    let Some(b) = b else { return Ok(None) };
    let Some(last) = scene.layers.last() else { return err("layers", "an opaque [bottom] needs a layer above it") };
    if !last.z_bottom.is_finite() {
        return err(
            format!("layers[{}].thickness_mm", scene.layers.len() - 1),
            "is infinite: an opaque [bottom] closes a stack of finite layers (give the last layer a thickness)",
        );
    }
    let motion = Motion { velocity: &b.velocity, angular_velocity: &b.angular_velocity, center: &b.center };
    let extent = Extent::Plane { z: last.z_bottom };
    let bottom = surface("bottom", b.surface.as_ref(), motion, extent, wavelength, last.n)?;
    if let Some(i) = detectors.iter().position(|d| d.side() == crate::detect::Side::Bottom) {
        return err(format!("detectors[{i}].side"), "= \"bottom\": nothing leaves through an opaque [bottom] surface");
    }
    camera_meets(&bottom, "the [bottom] surface", scene, scene.layers.len() - 1, detectors)?;
    Ok(Some(bottom))
}

/// The `[[opaque]]` solids, placed in their layers of `scene` (each wholly inside one unsplit
/// layer); only forward paths from the laser meet them.
pub(super) fn resolve_opaque(
    list: &[OpaqueSection],
    scene: &mut Scene,
    wavelength: f64,
    detectors: &[Detector],
) -> R<()> {
    for (i, o) in list.iter().enumerate() {
        let path = format!("opaque[{i}]");
        let name = o.name.clone().unwrap_or_else(|| format!("opaque{i}"));
        let Some(layer) = &o.layer else { return err(path, "missing layer: the name of the layer that holds it") };
        let Some(li) = scene.layers.iter().position(|l| &l.name == layer) else {
            let split = scene.layers.iter().any(|l| l.name.starts_with(&format!("{layer}[")));
            let names: Vec<&str> = scene.layers.iter().map(|l| l.name.as_str()).collect();
            let why = if split {
                format!("= \"{layer}\" is split into sublayers: an opaque solid needs an unsplit layer")
            } else {
                format!("= \"{layer}\": unknown layer; layers are {}", crate::error::list(names))
            };
            return err(join(&path, "layer"), why);
        };
        let Some(shape) = &o.shape else {
            return err(path, "missing shape: e.g. shape = { type = \"box\", center_m = […], size_m = […] }");
        };
        let shape = super::scene::resolve_shape(&path, shape)?;
        if let crate::medium::Shape::Cylinder { half_length, .. } = shape
            && !half_length.is_finite()
        {
            return err(join(&path, "shape"), "missing length: an opaque cylinder is a closed solid (a wheel, a drum)");
        }
        let l = &scene.layers[li];
        let (zmin, zmax) = shape.z_range();
        if zmin < l.z_top || zmax > l.z_bottom {
            return err(
                join(&path, "shape"),
                format!(
                    "spans z = {} … {} m, not inside its layer \"{}\" (z = {} … {} m): an opaque solid lies wholly inside one layer",
                    shown(zmin),
                    shown(zmax),
                    l.name,
                    shown(l.z_top),
                    shown(l.z_bottom)
                ),
            );
        }
        let motion = Motion { velocity: &o.velocity, angular_velocity: &o.angular_velocity, center: &o.center };
        let extent = Extent::Solid { centre: shape_centre(&shape), radius: 0.5 * shape.size() };
        let surface = surface(&path, o.surface.as_ref(), motion, extent, wavelength, l.n)?;
        camera_meets(&surface, &format!("opaque[{i}].surface"), scene, li, detectors)?;
        let tolerance = 1e-9 * shape.size();
        scene.opaque.push(Opaque { name, shape, surface, layer: li, tolerance });
        scene.layers[li].opaque.push(scene.opaque.len() - 1);
    }
    scene.update_layers();
    Ok(())
}

/// The keys of a surface's motion.
struct Motion<'a> {
    velocity: &'a Option<Quantity<Speed, [f64; 3]>>,
    angular_velocity: &'a Option<Quantity<AngularSpeed, [f64; 3]>>,
    center: &'a Option<Quantity<Length, [f64; 3]>>,
}

/// Where a surface's points lie, for the speed of its fastest one.
#[derive(Clone, Copy)]
enum Extent {
    /// An opaque solid: inside the sphere of `radius` about `centre` (its bounding box's centre
    /// and half diagonal, a sphere's radius).
    Solid { centre: DVec3, radius: f64 },
    /// The `[bottom]`: the plane `z`, unbounded; its speed is checked out to [`BOTTOM_REACH`]
    /// from the z axis.
    Plane { z: f64 },
}

/// How far from the z axis (the beam's, at the origin) a rotating `[bottom]`'s speed is checked,
/// m: a rotating plane moves at `|ω| r` at the distance `r` from its axis, which grows without
/// bound, so some bound is needed; 1 km is far beyond where the light of a layered scene closed
/// by a floor goes (and `|ω| < c/1 km = 3·10⁵ rad/s` keeps every real spinning disk).
const BOTTOM_REACH: f64 = 1e3;

/// A surface at `path`: its BSDF (facing a medium of index `n_medium`) and its motion, rotating
/// about `center` (default the centre of its `extent`, the origin for the `[bottom]`).
fn surface(
    path: &str,
    s: Option<&SurfaceSection>,
    m: Motion,
    extent: Extent,
    wavelength: f64,
    n_medium: f64,
) -> R<Surface> {
    let Some(s) = s else {
        return err(
            path,
            "missing surface: e.g. surface = { type = \"lambertian\", albedo = 0.5 } or { type = \"conductor\", material = \"copper\", roughness = 0.3 }",
        );
    };
    let bsdf = resolve_surface(&join(path, "surface"), s, wavelength, n_medium)?;
    let (velocity, v_key) = vector(path, m.velocity)?;
    let (angular_velocity, w_key) = vector(path, m.angular_velocity)?;
    let (center, c_key) = vector(path, m.center)?;
    let centre = match extent {
        Extent::Solid { centre, .. } => centre,
        Extent::Plane { .. } => DVec3::ZERO,
    };
    let surface = Surface {
        bsdf,
        velocity: velocity.unwrap_or(DVec3::ZERO),
        angular_velocity: angular_velocity.unwrap_or(DVec3::ZERO),
        center: center.unwrap_or(centre),
    };
    // Speeds below the speed of light, as media's (`flow::SPEED_LIMIT`): the translation's, then
    // that of the fastest point, `|v| + |ω| r` with `r` the farthest distance of the surface's
    // points from the rotation's centre (a bound on their distance from its axis).
    let c = super::flow::SPEED_LIMIT;
    let v = norm(surface.velocity);
    if let Some(key) = v_key
        && (!v.is_finite() || v >= c)
    {
        return err(
            &key,
            format!(
                "= {} {}: expected a finite speed below the speed of light, |v| < c = {c} m/s (a physical bound)",
                written(m.velocity),
                super::unit_of(&key)
            ),
        );
    }
    let Some(w_key) = w_key else { return Ok(surface) };
    let w = norm(surface.angular_velocity);
    let reach = |center: DVec3| match extent {
        Extent::Solid { centre, radius } => norm(centre - center) + radius,
        Extent::Plane { z } => norm(DVec3::new(0.0, 0.0, z) - center) + BOTTOM_REACH,
    };
    let (r, fastest) = (reach(surface.center), v + w * reach(surface.center));
    if fastest.is_finite() && fastest < c {
        return Ok(surface);
    }
    let where_ = match extent {
        Extent::Solid { .. } => "of the solid".to_string(),
        Extent::Plane { .. } => format!("of the plane within {} m of the z axis", shown(BOTTOM_REACH)),
    };
    let why = format!(
        "the surface's fastest point would move at |v| + |ω| r = {} m/s (|ω| = {} rad/s, r = {} m from the rotation's centre ({} m) to the farthest point {where_}); expected below the speed of light, c = {c} m/s (a physical bound)",
        shown(fastest),
        shown(w),
        shown(r),
        written_vec(surface.center),
    );
    // The centre is to blame where the surface's own centre would keep it below c.
    if let Some(key) = c_key
        && v + w * reach(centre) < c
    {
        let unit = super::unit_of(&key);
        return err(&key, format!("= {} {unit}: {why}", written(m.center)));
    }
    err(&w_key, format!("= {} {}: {why}", written(m.angular_velocity), super::unit_of(&w_key)))
}

/// A vector's length, without overflow for components up to f64's largest.
fn norm(v: DVec3) -> f64 {
    let m = v.abs().max_element();
    if m > 0.0 && m.is_finite() { m * (v / m).length() } else { m }
}

/// A vector key's SI value and key path, if given (finite).
fn vector<S>(path: &str, q: &Option<Quantity<S, [f64; 3]>>) -> R<(Option<DVec3>, Option<String>)> {
    Ok(match given_arr(path, q)? {
        Some((v, key)) => (Some(DVec3::from(v)), Some(key)),
        None => (None, None),
    })
}

/// A vector key's numbers as written.
fn written<S>(q: &Option<Quantity<S, [f64; 3]>>) -> String {
    q.as_ref().map_or_else(String::new, |q| format!("[{}]", q.value.map(shown).join(", ")))
}

fn written_vec(v: DVec3) -> String {
    format!("[{}]", v.to_array().map(shown).join(", "))
}

/// The centre of a shape (its bounding box's).
fn shape_centre(s: &crate::medium::Shape) -> DVec3 {
    match *s {
        crate::medium::Shape::Sphere { center, .. } | crate::medium::Shape::Cylinder { center, .. } => center,
        crate::medium::Shape::Box { min, max } => 0.5 * (min + max),
    }
}

/// The narrowest microfacet lobe in the laser's beam that paths traced from a camera's pixels
/// find (GGX α). In the beam (the stack's first rough face, and surfaces above it) a narrower
/// lobe is nearly a second collimated beam, which camera paths meet only where their own
/// direction falls into it: rarely, with weights of the lobe's peak, so a run comes out low with a
/// small error bar. Measured on `tests/configs/good/camera_surfaces.toml` (first face alone rough,
/// 20,000 paths, power against the forward estimator's 0.0364 ± 0.0011): α = 10⁻⁵ gave 0.0138 ±
/// 0.0002, 10⁻⁴ 0.0139 ± 0.0002, 10⁻³ 0.023 ± 0.005, 3·10⁻³ 0.032 ± 0.005, 10⁻² 0.035 ± 0.0014,
/// 3·10⁻² 0.0359 ± 0.0005.
pub(super) const CAMERA_ROUGHNESS_MIN: f64 = 0.01;

/// Camera-side paths and the stack's first rough face: refused if its lobe is narrower than
/// [`CAMERA_ROUGHNESS_MIN`].
pub(super) fn camera_lobes(scene: &Scene, detectors: &[Detector]) -> R<()> {
    let Some(face) = scene.layers.get(scene.first_rough_face) else { return Ok(()) };
    let camera = |d: &Detector| d.surface().is_some_and(|s| s.choice != EstimatorChoice::Forward);
    if face.face.roughness() >= CAMERA_ROUGHNESS_MIN {
        return Ok(());
    }
    if let Some(i) = detectors.iter().position(camera) {
        return err(
            format!("detectors[{i}].estimator"),
            format!(
                "the top face of layer \"{}\" (roughness = {}) is the first rough face in the laser's beam, with a lobe narrower than paths traced from a camera's pixels find (α < {CAMERA_ROUGHNESS_MIN}: their estimate comes out low with a small error bar); give it a roughness ≥ {CAMERA_ROUGHNESS_MIN} (or 0, the smooth face), or use estimator = \"forward\"",
                face.name,
                shown(face.face.roughness())
            ),
        );
    }
    Ok(())
}

/// A surface in layer `li` that camera-side paths (from a camera's pixels back to the laser)
/// meet: where the laser's beam reaches it straight (above every rough face), a smooth mirror
/// would turn it into a second collimated beam, which no camera path's connection reaches.
fn camera_meets(surface: &Surface, what: &str, scene: &Scene, li: usize, detectors: &[Detector]) -> R<()> {
    let narrow = surface.bsdf.narrowest_lobe().filter(|&a| a < CAMERA_ROUGHNESS_MIN);
    if (!surface.bsdf.has_delta_part() && narrow.is_none()) || li >= scene.first_rough_face {
        return Ok(());
    }
    let camera = |d: &Detector| d.surface().is_some_and(|s| s.choice != EstimatorChoice::Forward);
    if let (Some(a), Some(i)) = (narrow, detectors.iter().position(camera))
        && !surface.bsdf.has_delta_part()
    {
        return err(
            format!("detectors[{i}].estimator"),
            format!(
                "{what} is a rough conductor of roughness {} in the laser's beam, a lobe narrower than paths traced from a camera's pixels find (α < {CAMERA_ROUGHNESS_MIN}: their estimate comes out low with a small error bar); give it a roughness ≥ {CAMERA_ROUGHNESS_MIN}, or use estimator = \"forward\"",
                shown(a)
            ),
        );
    }
    if let Some(i) = detectors.iter().position(camera) {
        return err(
            format!("detectors[{i}].estimator"),
            format!(
                "{what} is a smooth mirror (a conductor of roughness 0, or below {ROUGHNESS_MIN}) in the laser's beam: it reflects a second collimated beam, which paths traced from a camera's pixels never connect to; give it a roughness > 0, or use estimator = \"forward\""
            ),
        );
    }
    Ok(())
}

/// The range of a conductor's `n` and `k` (`surface = { type = "conductor", n, k }`): wide enough
/// for measured metals from 10 nm to 1 mm (silver's n ≈ 0.03 in the visible; a Drude metal's
/// n ≈ k ≈ 10³ at 1 mm), narrow enough that the Fresnel reflectance of the index relative to any
/// medium (n 1 … 10: |η| from 10⁻⁴ to 1.4·10⁴) stays exact in f64 (`surface::conductor_reflectance`;
/// beyond, `η²` overflows near 10¹⁵⁴ and the reflectance is NaN).
const CONDUCTOR_N: (f64, f64) = (1e-3, 1e4);
const CONDUCTOR_K: (f64, f64) = (0.0, 1e4);

/// A surface's BSDF, with the medium it faces of index `n_medium` (a conductor's Fresnel
/// reflectance is that of its index relative to it).
pub(super) fn resolve_surface(path: &str, s: &SurfaceSection, wavelength: f64, n_medium: f64) -> R<Bsdf> {
    match s {
        SurfaceSection::Lambertian { albedo } => {
            let key = join(path, "albedo");
            let Some(a) = *albedo else { return err(path, "missing albedo: the diffuse reflectance, 0 … 1") };
            if !(0.0..=1.0).contains(&a) {
                return err(key, format!("= {}: expected a reflectance 0 … 1", shown(a)));
            }
            Ok(Bsdf::Lambertian { albedo: a })
        }
        SurfaceSection::Conductor { roughness, material, n, k } => {
            let alpha = roughness.unwrap_or(0.0);
            if !(0.0..=1.0).contains(&alpha) {
                return err(
                    join(path, "roughness"),
                    format!("= {}: expected GGX's α, 0 (a smooth mirror) … 1", shown(alpha)),
                );
            }
            // A surface smoother than the directions f64 resolves is the smooth mirror.
            let alpha = if alpha < ROUGHNESS_MIN { 0.0 } else { alpha };
            let eta = match (material, n, k) {
                (Some(m), None, None) => {
                    let names: Vec<&str> = Metal::NAMES.iter().map(|(n, _)| *n).collect();
                    let Some(metal) = Metal::from_name(m) else {
                        return err(
                            join(path, "material"),
                            format!("= {m:?}: expected one of {} (or give n and k)", names.join(", ")),
                        );
                    };
                    let Some(eta) = metal.index(wavelength) else {
                        let (a, b) = metal.range_nm();
                        return err(
                            join(path, "material"),
                            format!(
                                "= {m:?}: its measured index ({}) covers {a} … {b} nm (both included), not the source's {} nm: give n and k",
                                metal.reference(),
                                crate::surface::metals::nm_shown(wavelength)
                            ),
                        );
                    };
                    eta
                }
                (None, Some(n), Some(k)) => {
                    let (lo, hi) = CONDUCTOR_N;
                    if !(n.is_finite() && (lo..=hi).contains(n)) {
                        return err(
                            join(path, "n"),
                            format!(
                                "= {}: expected a metal's refractive index in [{}, {}] (measured metals lie inside, from silver's 0.03 in the visible to ≈ 10³ in the far infrared)",
                                shown(*n),
                                shown(lo),
                                shown(hi)
                            ),
                        );
                    }
                    let (lo, hi) = CONDUCTOR_K;
                    if !(k.is_finite() && (lo..=hi).contains(k)) {
                        return err(
                            join(path, "k"),
                            format!(
                                "= {}: expected an extinction coefficient in [{lo}, {}] (measured metals lie inside, up to ≈ 10³ in the far infrared)",
                                shown(*k),
                                shown(hi)
                            ),
                        );
                    }
                    Complex64::new(*n, *k)
                }
                (Some(_), _, _) => return err(join(path, "material"), "give either material or n and k, not both"),
                _ => {
                    return err(
                        path,
                        "missing the metal: material = \"copper\" (or \"gold\", \"aluminium\"), or its index n and extinction k",
                    );
                }
            };
            Ok(Bsdf::Conductor { alpha, eta: eta / n_medium })
        }
        SurfaceSection::Mixture { parts } => {
            let parts = parts.as_deref().unwrap_or_default();
            if parts.len() < 2 {
                return err(join(path, "parts"), "expected two or more parts: [{ weight = 0.3, surface = {…} }, …]");
            }
            let mut out = Vec::with_capacity(parts.len());
            for (i, p) in parts.iter().enumerate() {
                let at = format!("{path}.parts[{i}]");
                let w = p.weight.unwrap_or(f64::NAN);
                if !(w.is_finite() && w > 0.0 && w <= 1.0) {
                    return err(join(&at, "weight"), format!("= {}: expected a weight 0 < w ≤ 1", shown(w)));
                }
                let Some(s) = &p.surface else { return err(at, "missing surface") };
                out.push((w, resolve_surface(&join(&at, "surface"), s, wavelength, n_medium)?));
            }
            let total: f64 = out.iter().map(|(w, _)| w).sum();
            if (total - 1.0).abs() > 1e-9 {
                return err(join(path, "parts"), format!("weights sum to {}: expected 1", shown(total)));
            }
            Ok(Bsdf::Mixture(out))
        }
    }
}
