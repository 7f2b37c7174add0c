//! `[bottom]`: an opaque surface closing the stack from below ([`crate::medium::Bottom`]), and
//! the surface BSDFs of the configuration ([`SurfaceSection`]).

use glam::DVec3;
use num_complex::Complex64;

use super::{R, err, given_arr, join, shown};
use crate::config::schema::{BottomSection, SurfaceSection};
use crate::detect::{Detector, EstimatorChoice};
use crate::medium::{Bottom, Scene};
use crate::surface::Bsdf;
use crate::surface::metals::Metal;

/// The surface under the last layer, checked against what the walks support: a finite last layer
/// above it, and only forward paths from the laser (with or without shadow rays) meet it.
pub(super) fn resolve_bottom(
    b: Option<&BottomSection>,
    scene: &Scene,
    wavelength: f64,
    detectors: &[Detector],
) -> R<Option<Bottom>> {
    let Some(b) = b else { return Ok(None) };
    let Some(last) = scene.layers.last() else { return err("layers", "an opaque [bottom] needs a layer above it") };
    if !last.z_bottom.is_finite() {
        return err(
            format!("layers[{}].thickness_mm", scene.layers.len() - 1),
            "is infinite: an opaque [bottom] closes a stack of finite layers (give the last layer a thickness)",
        );
    }
    let Some(surface) = &b.surface else {
        return err(
            "bottom",
            "missing surface: e.g. surface = { type = \"lambertian\", albedo = 0.5 } or { type = \"conductor\", material = \"copper\", roughness = 0.3 }",
        );
    };
    let bsdf = resolve_surface("bottom.surface", surface, wavelength, last.n)?;
    let vec = |v: Option<([f64; 3], String)>| v.map_or(DVec3::ZERO, |(v, _)| DVec3::from(v));
    let bottom = Bottom {
        bsdf,
        velocity: vec(given_arr("bottom", &b.velocity)?),
        angular_velocity: vec(given_arr("bottom", &b.angular_velocity)?),
        center: vec(given_arr("bottom", &b.center)?),
    };
    if let Some(i) = detectors.iter().position(|d| d.side() == crate::detect::Side::Bottom) {
        return err(format!("detectors[{i}].side"), "= \"bottom\": nothing leaves through an opaque [bottom] surface");
    }
    // The camera-side walk (from a camera's pixels back to the laser) does not meet surfaces yet.
    if let Some(i) = detectors.iter().position(|d| d.surface().is_some_and(|s| s.choice != EstimatorChoice::Forward)) {
        return err(
            format!("detectors[{i}].estimator"),
            "paths traced from a camera's pixels do not meet an opaque [bottom] surface: use estimator = \"forward\" with this scene",
        );
    }
    Ok(Some(bottom))
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
