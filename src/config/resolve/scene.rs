//! The scene: shapes, `[[layers]]` (and sublayers) and `[[regions]]`.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Arc;

use glam::DVec3;

use super::density::attach_density;
use super::flow::{check_velocity, resolve_wind};
use super::media::{Optics, Placement, check_mixture, check_unused, populations_of};
use super::{Ctx, R, err, given, index_of_refraction, join, positive, require, require_arr, unit_vector};
use crate::config::schema::*;
use crate::error::ConfigError;
use crate::medium::{Heterogeneity, Layer, MAX_REGIONS_PER_LAYER, Medium, MediumInfo, Region, Scene, Shape};

pub(super) fn resolve_shape(path: &str, s: &ShapeSection) -> R<Shape> {
    let p = join(path, "shape");
    Ok(match s {
        ShapeSection::Sphere { center, radius } => {
            let (c, _) = require_arr(&p, "center", center, "center")?;
            let r = positive(require(&p, "radius", radius, "radius")?, "a radius")?;
            Shape::Sphere { center: DVec3::from_array(c), radius: r }
        }
        ShapeSection::Box { center, size } => {
            let (c, _) = require_arr(&p, "center", center, "center")?;
            let (sz, sp) = require_arr(&p, "size", size, "size")?;
            if sz.iter().any(|&x| x <= 0.0) {
                return err(sp, format!("= {sz:?} m: expected three edge lengths > 0"));
            }
            let (c, h) = (DVec3::from_array(c), DVec3::from_array(sz) * 0.5);
            Shape::Box { min: c - h, max: c + h }
        }
        ShapeSection::Cylinder { center, axis, radius, length } => {
            let (c, _) = require_arr(&p, "center", center, "center")?;
            let axis = unit_vector(&join(&p, "axis"), *axis)?;
            let r = positive(require(&p, "radius", radius, "radius")?, "a radius")?;
            let half_length = match given(&p, length)? {
                None => f64::INFINITY,
                Some(l) => 0.5 * positive(l, "a length (omit it for a tube crossing its whole layer)")?,
            };
            Shape::Cylinder { center: DVec3::from_array(c), axis, radius: r, half_length }
        }
    })
}

/// The most layers a stack may hold, sublayers counted, one layer's sublayers included (each is
/// a medium of its own: 10⁵ sublayers of rain take 2 GB).
const MAX_LAYERS: u64 = 100_000;

/// A layer's keys, checked, before its media are made.
struct PlannedLayer<'a> {
    path: String,
    name: String,
    top: f64,
    thickness: f64,
    n: f64,
    roughness: f64,
    ms: &'a MediumSection,
    medium: &'a str,
    parts: u64,
}

impl PlannedLayer<'_> {
    /// Top and bottom of sublayer `j` of `step` (the last bottom is exact, and a single
    /// semi-infinite layer never forms 0·∞).
    fn bounds(&self, j: u64, step: f64) -> (f64, f64) {
        let z = self.top;
        let top = if j == 0 { z } else { z + j as f64 * step };
        let bottom = if j + 1 == self.parts { z + self.thickness } else { z + (j + 1) as f64 * step };
        (top, bottom)
    }

    /// The height sublayer `j`'s medium is made for (its middle; the top of a semi-infinite one).
    fn height(&self, j: u64) -> f64 {
        let (top, bottom) = self.bounds(j, self.thickness / self.parts as f64);
        if bottom.is_finite() { 0.5 * (top + bottom) } else { top }
    }
}

pub(super) fn resolve_scene(f: &ExperimentFile, n_above: f64, n_below: f64, ctx: &Ctx) -> R<Scene> {
    if f.media.is_empty() {
        return err("media", "no media defined: add a [media.NAME] table with sigma_a_* and sigma_s_*");
    }
    if f.layers.is_empty() {
        return err("layers", "no layers: add at least one [[layers]] with thickness, n and medium");
    }
    let lookup = |path: String, name: &str| -> R<&MediumSection> {
        f.media.get(name).ok_or_else(|| {
            let known = crate::error::list(f.media.keys());
            ConfigError::new(path, format!("= \"{name}\": unknown medium; defined media: {known}"))
        })
    };
    let wind = f.wind.as_ref().map(resolve_wind).transpose()?;
    // Every velocity written is checked, used or not: a medium's own that a region overrides is
    // otherwise never resolved.
    for (name, ms) in &f.media {
        if let Some(v) = &ms.velocity {
            check_velocity(&format!("media.{name}.velocity"), v)?;
        }
    }
    // The media built (a mixture's populations included); the others are checked at the end.
    let mut used: BTreeSet<String> = BTreeSet::new();
    // Optics are resolved once per named medium (a Mie ensemble can take seconds), on first use.
    let mut optics: BTreeMap<String, Optics> = BTreeMap::new();
    // Densities likewise (a grid's majorant is built once).
    let mut densities: BTreeMap<String, Arc<Heterogeneity>> = BTreeMap::new();
    // A medium at height `height` (for its height profile); `velocity` overrides the medium's
    // own (a region's), `cylinder` is the region's shape if it is one.
    let mut make = |path: &str,
                    name: &str,
                    ms: &MediumSection,
                    velocity: Option<(String, &VelocitySection)>,
                    cylinder: Option<&Shape>,
                    height: f64|
     -> R<Medium> {
        used.insert(name.to_string());
        let Some(list) = &ms.populations else {
            let velocity = velocity.or_else(|| ms.velocity.as_ref().map(|v| (join(path, "velocity"), v)));
            let at = Placement { wind: wind.as_ref(), velocity, cylinder, height };
            let (sigma_a, populations, info) = populations_of(&mut optics, ctx, path, name, ms, at)?;
            let mut m = Medium::mixture(name, sigma_a, populations);
            m.info = info;
            attach_density(path, ms, &mut m, ctx, &mut densities)?;
            return Ok(m);
        };
        check_mixture(path, ms)?;
        if let Some((p, _)) = velocity {
            return err(p, format!("medium \"{name}\" is a mixture: each population keeps its own velocity"));
        }
        if list.is_empty() {
            return err(join(path, "populations"), "an empty list: name at least one medium");
        }
        let (mut sigma_a, mut all, mut names) = (0.0, Vec::new(), Vec::new());
        for (j, pname) in list.iter().enumerate() {
            let key = format!("{}[{j}]", join(path, "populations"));
            let pms = lookup(key.clone(), pname)?;
            super::media::check_population(&key, pname, pms, name)?;
            let ppath = format!("media.{pname}");
            let pv = pms.velocity.as_ref().map(|v| (join(&ppath, "velocity"), v));
            let at = Placement { wind: wind.as_ref(), velocity: pv, cylinder, height };
            let (sa, pops, _) = populations_of(&mut optics, ctx, &ppath, pname, pms, at)?;
            sigma_a += sa;
            all.extend(pops);
            names.push(pname.clone());
            used.insert(pname.clone());
        }
        let mut m = Medium::mixture(name, sigma_a, all);
        let g =
            m.populations().iter().map(|p| p.sigma_s * p.phase.mean_cosine()).sum::<f64>() / m.sigma_s().max(1e-300);
        m.info = MediumInfo {
            preset: ms.preset.clone(),
            phase: format!("mixture of {}", names.join(", ")),
            g,
            sigma_s_scale: 1.0,
            ..MediumInfo::default()
        };
        attach_density(path, ms, &mut m, ctx, &mut densities)?;
        Ok(m)
    };
    let mut media: Vec<Medium> = Vec::new();
    let mut layers: Vec<Layer> = Vec::new();
    let mut layer_index: BTreeMap<String, usize> = BTreeMap::new();
    let mut split: Vec<String> = Vec::new();
    // First every layer's keys, and how many (sub)layers the stack will hold.
    let mut planned: Vec<PlannedLayer> = Vec::with_capacity(f.layers.len());
    let (mut z, mut count) = (0.0, 0u64);
    for (i, l) in f.layers.iter().enumerate() {
        let path = format!("layers[{i}]");
        let name = l.name.clone().unwrap_or_else(|| format!("layer{i}"));
        if layer_index.contains_key(&name) || split.contains(&name) {
            return err(join(&path, "name"), format!("= \"{name}\": layer names must be unique"));
        }
        let parts = l.sublayers.unwrap_or(1);
        if !(1..=MAX_LAYERS).contains(&parts) {
            return err(join(&path, "sublayers"), format!("= {parts}: expected 1 to {MAX_LAYERS} layers"));
        }
        count += parts;
        if count > MAX_LAYERS {
            return err(
                if parts > 1 { join(&path, "sublayers") } else { path },
                format!(
                    "{}the stack would hold {count} layers or more (sublayers counted), more than the {MAX_LAYERS} it may hold",
                    if parts > 1 { format!("= {parts}: ") } else { String::new() }
                ),
            );
        }
        let th = require(&path, "thickness", &l.thickness, "thickness")?;
        let last = i + 1 == f.layers.len();
        let thickness = if th.0 == f64::INFINITY && last {
            f64::INFINITY
        } else if th.0 == f64::INFINITY {
            return err(th.1, "= inf: only the last layer may be semi-infinite");
        } else {
            positive(th, "a thickness (or inf for a semi-infinite last layer)")?
        };
        let n = index_of_refraction(
            &join(&path, "n"),
            l.n.ok_or_else(|| ConfigError::new(join(&path, "n"), "missing: the refractive index of the layer"))?,
        )?;
        let roughness = l.roughness.unwrap_or(0.0);
        if !(0.0..=1.0).contains(&roughness) {
            return err(
                join(&path, "roughness"),
                format!("= {}: expected GGX's α of the layer's top face, 0 (smooth) … 1", super::shown(roughness)),
            );
        }
        // A face smoother than the directions f64 resolves is the smooth one.
        let roughness = if roughness < crate::surface::microfacet::ROUGHNESS_MIN { 0.0 } else { roughness };
        let ms = lookup(join(&path, "medium"), &l.medium)?;
        if parts > 1 && thickness == f64::INFINITY {
            return err(join(&path, "sublayers"), "a semi-infinite layer cannot be split");
        }
        if parts > 1 {
            split.push(name.clone());
        } else {
            layer_index.insert(name.clone(), (count - 1) as usize);
        }
        planned.push(PlannedLayer { path, name, top: z, thickness, n, roughness, ms, medium: &l.medium, parts });
        z += thickness;
    }
    // Then each layer's first medium, to count what all of its sublayers' media will take before
    // they are made (issue 21: 4 × 10⁵ sublayers of rain grew to 5.8 GB and aborted).
    let copies = ctx.scene_copies;
    let mut first: Vec<Medium> = Vec::with_capacity(planned.len());
    for p in &planned {
        let m = make(&format!("media.{}", p.medium), p.medium, p.ms, None, None, p.height(0))
            .map_err(|e| ConfigError::new(e.path, format!("{} (used by {}, a layer)", e.message, p.path)))?;
        // Each copy of the scene copies the layers and media; the tables made per medium (fall
        // speeds) are shared by the copies.
        let each = m.footprint() + std::mem::size_of::<Layer>() + p.name.len() + 8;
        let per_layer = (each as u64).saturating_mul(copies).saturating_add(m.own_tables() as u64);
        let bytes = per_layer.saturating_mul(p.parts);
        let (key, value, what) = if p.parts > 1 {
            (
                join(&p.path, "sublayers"),
                format!("= {}", p.parts),
                format!("the media of {} ({} sublayers)", p.path, p.parts),
            )
        } else {
            (join(&p.path, "medium"), format!("= \"{}\"", p.medium), format!("the medium of {}", p.path))
        };
        let how = format!(
            "{} × {} per layer: the layer and its medium, {} held {copies} times (as resolved and in each run of it), and {} of tables made for it",
            p.parts,
            super::bytes_shown(per_layer),
            super::bytes_shown(each as u64),
            super::bytes_shown(m.own_tables() as u64)
        );
        ctx.memory.charge(&key, &value, &what, &how, bytes)?;
        first.push(m);
    }
    // Then the layers.
    for (p, m0) in planned.iter().zip(first) {
        let step = p.thickness / p.parts as f64;
        let mut m0 = Some(m0);
        for j in 0..p.parts {
            let (top, bottom) = p.bounds(j, step);
            let m = match m0.take() {
                Some(m) => m,
                None => make(&format!("media.{}", p.medium), p.medium, p.ms, None, None, p.height(j))
                    .map_err(|e| ConfigError::new(e.path, format!("{} (used by {}, a layer)", e.message, p.path)))?,
            };
            media.push(m);
            layers.push(Layer {
                name: if p.parts > 1 { format!("{}[{j}]", p.name) } else { p.name.clone() },
                z_top: top,
                z_bottom: bottom,
                n: p.n,
                // The top face of the layer's first sublayer is the layer's.
                face: crate::surface::Interface::with_roughness(if j == 0 { p.roughness } else { 0.0 }),
                medium: media.len() - 1,
                regions: Vec::new(),
                majorant: 0.0,
                minorant: 0.0,
                heterogeneous: false,
                tau_above: 0.0,
                rough_faces: false,
                plain: true,
                obstructs_shadows: false,
                opaque: Vec::new(),
            });
        }
    }
    let mut regions: Vec<Region> = Vec::new();
    for (i, r) in f.regions.iter().enumerate() {
        let path = format!("regions[{i}]");
        let name = r.name.clone().unwrap_or_else(|| format!("region{i}"));
        if split.contains(&r.layer) {
            return err(
                join(&path, "layer"),
                format!("= \"{}\" is split into sublayers: regions need an unsplit layer", r.layer),
            );
        }
        let li = *layer_index.get(&r.layer).ok_or_else(|| {
            ConfigError::new(
                join(&path, "layer"),
                format!("= \"{}\": unknown layer; layers are {}", r.layer, crate::error::list(layer_index.keys())),
            )
        })?;
        let shape = resolve_shape(&path, &r.shape)?;
        let (zmin, zmax) = shape.z_range();
        let layer = &layers[li];
        if zmax <= layer.z_top || zmin >= layer.z_bottom {
            return err(
                join(&path, "shape"),
                format!(
                    "lies outside its layer \"{}\" (z from {} to {} m; the shape spans {} to {} m)",
                    layer.name, layer.z_top, layer.z_bottom, zmin, zmax
                ),
            );
        }
        if layers[li].regions.len() == MAX_REGIONS_PER_LAYER {
            return err(
                path,
                format!(
                    "layer \"{}\" already holds {MAX_REGIONS_PER_LAYER} regions, the most one layer may hold",
                    layer.name
                ),
            );
        }
        let ms = lookup(join(&path, "medium"), &r.medium)?;
        let mpath = format!("media.{}", r.medium);
        let velocity = r.velocity.as_ref().map(|v| (join(&path, "velocity"), v));
        let m = make(&mpath, &r.medium, ms, velocity, Some(&shape), 0.5 * (zmin + zmax))?;
        let each = (m.footprint() + std::mem::size_of::<Region>() + name.len()) as u64;
        let bytes = each.saturating_mul(copies).saturating_add(m.own_tables() as u64);
        ctx.memory.charge(
            &join(&path, "medium"),
            &format!("= \"{}\"", r.medium),
            "the media of the regions",
            &format!(
                "{} for regions[{i}]: the region and its medium, held {copies} times, and its tables",
                super::bytes_shown(bytes)
            ),
            bytes,
        )?;
        media.push(m);
        regions.push(Region { name, shape, medium: media.len() - 1, layer: li });
        layers[li].regions.push(regions.len() - 1);
    }
    for (name, ms) in f.media.iter().filter(|(name, _)| !used.contains(*name)) {
        check_unused(&mut optics, ctx, name, ms, &f.media)?;
    }
    let mut scene = Scene {
        layers,
        regions,
        media,
        n_above,
        n_below,
        lateral: None,
        bottom: None,
        opaque: Vec::new(),
        first_rough_face: 0,
        cycle: None,
    };
    scene.update_layers();
    Ok(scene)
}
