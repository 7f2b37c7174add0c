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
    let bottom = surface("bottom", b.surface.as_ref(), motion, DVec3::ZERO, wavelength, last.n)?;
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
        let centre = shape_centre(&shape);
        let surface = surface(&path, o.surface.as_ref(), motion, centre, wavelength, l.n)?;
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

/// A surface at `path`: its BSDF (facing a medium of index `n_medium`) and its motion, rotating
/// about `center` (default `centre`).
fn surface(
    path: &str,
    s: Option<&SurfaceSection>,
    m: Motion,
    centre: DVec3,
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
    let vec = |v: Option<([f64; 3], String)>| v.map(|(v, _)| DVec3::from(v));
    Ok(Surface {
        bsdf,
        velocity: vec(given_arr(path, m.velocity)?).unwrap_or(DVec3::ZERO),
        angular_velocity: vec(given_arr(path, m.angular_velocity)?).unwrap_or(DVec3::ZERO),
        center: vec(given_arr(path, m.center)?).unwrap_or(centre),
    })
}

/// The centre of a shape (its bounding box's).
fn shape_centre(s: &crate::medium::Shape) -> DVec3 {
    match *s {
        crate::medium::Shape::Sphere { center, .. } | crate::medium::Shape::Cylinder { center, .. } => center,
        crate::medium::Shape::Box { min, max } => 0.5 * (min + max),
    }
}

/// A surface in layer `li` that camera-side paths (from a camera's pixels back to the laser)
/// meet: where the laser's beam reaches it straight (above every rough face), a smooth mirror
/// would turn it into a second collimated beam, which no camera path's connection reaches.
fn camera_meets(surface: &Surface, what: &str, scene: &Scene, li: usize, detectors: &[Detector]) -> R<()> {
    if !surface.bsdf.has_delta_part() || li >= scene.first_rough_face {
        return Ok(());
    }
    let camera = |d: &Detector| d.surface().is_some_and(|s| s.choice != EstimatorChoice::Forward);
    if let Some(i) = detectors.iter().position(camera) {
        return err(
            format!("detectors[{i}].estimator"),
            format!(
                "{what} is a smooth mirror (a conductor of roughness 0) in the laser's beam: it reflects a second collimated beam, which paths traced from a camera's pixels never connect to; give it a roughness > 0, or use estimator = \"forward\""
            ),
        );
    }
    Ok(())
}

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
                        let (a, b) = metal.range();
                        return err(
                            join(path, "material"),
                            format!(
                                "= {m:?}: its measured index ({}) covers {:.0} … {:.0} nm, not the source's {:.0} nm: give n and k",
                                metal.reference(),
                                a * 1e9,
                                b * 1e9,
                                wavelength * 1e9
                            ),
                        );
                    };
                    eta
                }
                (None, Some(n), Some(k)) => {
                    if !(n.is_finite() && *n > 0.0) {
                        return err(join(path, "n"), format!("= {}: expected a refractive index > 0", shown(*n)));
                    }
                    if !(k.is_finite() && *k >= 0.0) {
                        return err(
                            join(path, "k"),
                            format!("= {}: expected an extinction coefficient ≥ 0", shown(*k)),
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
