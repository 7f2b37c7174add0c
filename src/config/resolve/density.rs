//! `density` of a medium: ramps and voxel grids, their placement and majorants.

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::DVec3;

use super::{Ctx, R, err, given_arr, join, require};
use crate::config::schema::*;
use crate::config::units::{Length, Quantity, unit_of};
use crate::error::ConfigError;
use crate::medium::density::{
    CellSize, Density, DensityInfo, GridDensity, GridError, Interpolation, MajorantKind, MajorantSpec, Placement, Ramp,
};
use crate::medium::grid::{IndexTransform, VoxelGrid};
use crate::medium::{Heterogeneity, Medium};

/// A grid's placement from its keys `scale` and `translate_*` under `path`.
pub(super) fn resolve_placement(
    path: &str,
    scale: Option<f64>,
    translate: &Option<Quantity<Length, [f64; 3]>>,
) -> R<Placement> {
    let scale = match scale {
        None => 1.0,
        Some(s) if s.is_finite() && s > 0.0 => s,
        Some(s) => {
            return err(
                join(path, "scale"),
                format!("= {s}: expected the file's length unit in metres, > 0 (1e-3 for millimetres)"),
            );
        }
    };
    // Finite numbers are checked with the quantity.
    let translation = given_arr(path, translate)?.map_or(DVec3::ZERO, |(t, _)| DVec3::from_array(t));
    Ok(Placement { translation, scale })
}

pub(super) fn interpolation(i: Option<InterpolationSection>) -> Interpolation {
    match i {
        None | Some(InterpolationSection::Trilinear) => Interpolation::Trilinear,
        Some(InterpolationSection::Nearest) => Interpolation::Nearest,
    }
}

/// Give `m` the density of its section, if it has one: built once per named medium (`built`),
/// shared by every layer, sublayer and region that uses it.
pub(super) fn attach_density(
    path: &str,
    ms: &MediumSection,
    m: &mut Medium,
    ctx: &Ctx,
    built: &mut BTreeMap<String, Arc<Heterogeneity>>,
) -> R<()> {
    let Some(d) = &ms.density else { return Ok(()) };
    let h = match built.get(&m.name) {
        Some(h) => h.clone(),
        None => {
            let key = join(path, "density");
            let h = resolve_density(&key, d, m.sigma_t(), ctx)?;
            // The majorant grid (a min and max per cell), counted once made: it takes at most
            // twice the density grid counted before it was read.
            if let Some(cells) = h.info.majorant_cells {
                let bytes = cells.iter().fold(8u64, |b, &n| b.saturating_mul(n as u64));
                ctx.memory.charge(
                    &join(&key, "majorant_cell_voxels"),
                    "",
                    &format!("the majorant grid of {path}"),
                    &format!("{}×{}×{} cells of 8 bytes", cells[0], cells[1], cells[2]),
                    bytes,
                )?;
            }
            let h = Arc::new(h);
            built.insert(m.name.clone(), h.clone());
            h
        }
    };
    m.set_shared_heterogeneity(h);
    Ok(())
}

/// The keys of a density that no layer or region uses: a ramp is resolved (it is only numbers), a
/// VDB density's placement and majorant keys are checked without reading its file.
pub(super) fn check_density_keys(path: &str, d: &DensitySection, sigma_t: f64, ctx: &Ctx) -> R<()> {
    match d {
        DensitySection::Ramp { .. } => resolve_density(path, d, sigma_t, ctx).map(drop),
        DensitySection::Vdb { scale, translate, majorant, majorant_cell_voxels, .. } => {
            resolve_placement(path, *scale, translate)?;
            resolve_majorant(path, *majorant, *majorant_cell_voxels, sigma_t).map(drop)
        }
        DensitySection::Npy { voxel_size, translate, majorant, majorant_cell_voxels, .. } => {
            npy_transform(path, voxel_size, translate)?;
            resolve_majorant(path, *majorant, *majorant_cell_voxels, sigma_t).map(drop)
        }
    }
}

/// Where a `.npy` volume's voxels lie: its `voxel_size_*` (required, > 0) and `translate_*` (the
/// centre of voxel (0, 0, 0)).
pub(super) fn npy_transform(
    path: &str,
    voxel_size: &Option<Quantity<Length>>,
    translate: &Option<Quantity<Length, [f64; 3]>>,
) -> R<IndexTransform> {
    let (size, key, shown) = require(path, "voxel_size", voxel_size, "the voxels' edge")?;
    if !(size > 0.0 && size.is_finite()) {
        let unit = unit_of(&key);
        return err(key, format!("= {shown}: expected a voxel edge > 0 {unit}"));
    }
    let translation = resolve_placement(path, None, translate)?.translation;
    Ok(IndexTransform { voxel_size: DVec3::splat(size), translation })
}

fn majorant_kind(m: Option<MajorantSection>) -> MajorantKind {
    match m {
        None | Some(MajorantSection::Grid) => MajorantKind::Grid,
        Some(MajorantSection::Global) => MajorantKind::Global,
    }
}

/// Largest extinction a density may reach, 1/m (10⁶ /mm, a mean free path of 1 nm): delta
/// tracking takes a tentative collision per majorant free path, which no cap on real collisions
/// bounds, so a denser medium would never finish (issue 21: `density_to = 1e300` ran without
/// end).
pub const MAX_EXTINCTION_PER_M: f64 = 1e9;

/// `density = { type = "ramp" | "vdb", … }`, its largest extinction at most
/// [`MAX_EXTINCTION_PER_M`].
fn resolve_density(path: &str, d: &DensitySection, sigma_t: f64, ctx: &Ctx) -> R<Heterogeneity> {
    let h = resolve_density_field(path, d, sigma_t, ctx)?;
    let peak = h.info.max * sigma_t;
    if peak.is_nan() || peak > MAX_EXTINCTION_PER_M {
        return err(
            path,
            format!(
                "its largest density {:.3e} × the medium's σt {:.3e} /mm = {:.3e} /mm: expected an extinction of at most {:e} /mm (a mean free path of 1 nm; delta tracking takes a step per free path)",
                h.info.max,
                sigma_t * 1e-3,
                peak * 1e-3,
                MAX_EXTINCTION_PER_M * 1e-3
            ),
        );
    }
    Ok(h)
}

fn resolve_density_field(path: &str, d: &DensitySection, sigma_t: f64, ctx: &Ctx) -> R<Heterogeneity> {
    match d {
        DensitySection::Vdb {
            file,
            grid,
            albedo_grid,
            interpolation: i,
            scale,
            translate,
            majorant,
            majorant_cell_voxels,
        } => {
            let density = ctx.files.float(path, (ctx.base, &ctx.memory), file, grid.as_deref(), 2)?;
            let albedo = match albedo_grid {
                Some(name) => Some(ctx.files.float(path, (ctx.base, &ctx.memory), file, Some(name), 2)?),
                None => None,
            };
            let place = resolve_placement(path, *scale, translate)?;
            let majorant = resolve_majorant(path, *majorant, *majorant_cell_voxels, sigma_t)?;
            let mut h = grid_heterogeneity(
                path,
                Arc::unwrap_or_clone(density),
                albedo.map(Arc::unwrap_or_clone),
                place,
                interpolation(*i),
                majorant,
            )?;
            h.info.kind = "vdb".into();
            h.info.source = Some(format!("{file}:{}", grid.as_deref().unwrap_or("(first float grid)")));
            Ok(h)
        }
        DensitySection::Npy { file, voxel_size, translate, interpolation: i, majorant, majorant_cell_voxels } => {
            let transform = npy_transform(path, voxel_size, translate)?;
            let majorant = resolve_majorant(path, *majorant, *majorant_cell_voxels, sigma_t)?;
            let grid = super::GridFiles::npy::<f32>(path, (ctx.base, &ctx.memory), file, transform, 2, |dims| {
                majorant_bytes(majorant, dims)
            })?;
            let mut h = grid_heterogeneity(path, grid, None, Placement::default(), interpolation(*i), majorant)?;
            h.info.kind = "npy".into();
            h.info.source = Some(file.clone());
            Ok(h)
        }
        DensitySection::Ramp { axis, from, to, density_from, density_to, majorant } => {
            let a = match axis.as_str() {
                "x" => 0,
                "y" => 1,
                "z" => 2,
                other => return err(join(path, "axis"), format!("= \"{other}\": expected \"x\", \"y\" or \"z\"")),
            };
            let from = require(path, "from", from, "from")?;
            let to = require(path, "to", to, "to")?;
            for g in [&from, &to] {
                if !g.0.is_finite() {
                    return err(g.1.clone(), format!("= {}: expected a finite position {}", g.2, unit_of(&g.1)));
                }
            }
            if from.0 == to.0 {
                return err(
                    to.1,
                    format!("= {}: the ramp's two planes coincide (from = to); give two different positions", to.2),
                );
            }
            for (key, v) in [("density_from", density_from), ("density_to", density_to)] {
                if !(v.is_finite() && *v >= 0.0) {
                    return err(
                        join(path, key),
                        format!("= {v}: expected a density ≥ 0 (a factor on σa and σs, no unit)"),
                    );
                }
            }
            let kind = majorant_kind(*majorant);
            let ramp = Ramp::new(a, from.0, to.0, *density_from, *density_to, kind)
                .ok_or_else(|| ConfigError::new(path, "not a valid ramp"))?;
            let (min, max) = ramp.range();
            let info = DensityInfo { kind: "ramp".into(), majorant: Some(kind), min, max, ..DensityInfo::default() };
            Ok(Heterogeneity { density: Density::Ramp(ramp), albedo: None, info })
        }
    }
}

/// The majorant settings of a grid density from its keys `majorant` and `majorant_cell_voxels`
/// under `path` (for the file-backed densities), of a medium with extinction `sigma_t` (1/m) at
/// density 1: without `majorant_cell_voxels` the cell size is chosen for it ([`CellSize::Auto`]).
pub fn resolve_majorant(
    path: &str,
    kind: Option<MajorantSection>,
    cell_voxels: Option<u64>,
    sigma_t: f64,
) -> R<MajorantSpec> {
    let kind = majorant_kind(kind);
    let cell = match cell_voxels {
        None => CellSize::Auto { sigma_t },
        Some(_) if kind == MajorantKind::Global => {
            return err(join(path, "majorant_cell_voxels"), "only applies with majorant = \"grid\"");
        }
        Some(n) if (1..=4096).contains(&n) => CellSize::Voxels(n as usize),
        Some(n) => {
            return err(
                join(path, "majorant_cell_voxels"),
                format!("= {n}: expected 1 to 4096 voxels per majorant cell edge"),
            );
        }
    };
    Ok(MajorantSpec { kind, cell })
}

/// The majorant grid a density of `dims` voxels builds ([`GridDensity::new`]), for the memory
/// count: 8 bytes per cell over the block padded by a voxel each side; an automatic cell size
/// holds the finest grid twice and its coarser levels while it chooses, counted as three.
/// `None` for a global majorant.
pub(super) fn majorant_bytes(spec: MajorantSpec, dims: [usize; 3]) -> Option<(String, u64)> {
    let (n, held) = match (spec.kind, spec.cell) {
        (MajorantKind::Global, _) => return None,
        (_, CellSize::Voxels(n)) => (n.max(1), 1),
        (_, CellSize::Auto { .. }) => (crate::medium::density::DEFAULT_CELL_VOXELS, 3),
    };
    let cells = dims.iter().fold(1u64, |a, &d| a.saturating_mul((d.saturating_add(2).div_ceil(n)) as u64));
    let copies = if held > 1 { format!(", {held} while the cell size is chosen") } else { String::new() };
    Some((
        format!("its majorant grid ({cells} cells of {n}³ voxels × 8 bytes{copies})"),
        cells.saturating_mul(8 * held),
    ))
}

/// The medium fields of a voxel-grid density: the hook the file loaders call (`path` is the key
/// of the `density` table, for messages). `density` is scaled onto σa and σs (negative voxels
/// are clamped to 0 and counted in the manifest), `albedo` (values in [0, 1]) overrides the
/// single-scattering albedo at a collision; both are placed by their own index-to-world map and
/// then `placement`, and read with `interpolation`.
pub fn grid_heterogeneity(
    path: &str,
    density: VoxelGrid<f32>,
    albedo: Option<VoxelGrid<f32>>,
    placement: Placement,
    interpolation: Interpolation,
    majorant: MajorantSpec,
) -> R<Heterogeneity> {
    let voxels = density.dims;
    let describe = |e: GridError, what: &str| -> ConfigError {
        let (key, msg) = match e {
            GridError::NotFinite(None) => (what.to_string(), "the background value is not a finite number".to_string()),
            GridError::NotFinite(Some(ijk)) => (what.to_string(), format!("voxel {ijk:?} is not a finite number")),
            GridError::AlbedoRange(None, v) => (what.to_string(), format!("background albedo {v}: expected 0 to 1")),
            GridError::AlbedoRange(Some(ijk), v) => {
                (what.to_string(), format!("voxel {ijk:?} = {v}: expected an albedo from 0 to 1"))
            }
            GridError::Placement => (
                "placement".to_string(),
                format!(
                    "scale {} / translation {:?}: expected a finite scale > 0 and a finite translation in m",
                    placement.scale,
                    placement.translation.to_array()
                ),
            ),
            GridError::CellVoxels(n) => ("majorant_cell_voxels".to_string(), format!("= {n}: expected 1 to 4096")),
        };
        ConfigError::new(join(path, &key), msg)
    };
    let (grid, clamped) =
        GridDensity::new(density, interpolation, placement, majorant).map_err(|e| describe(e, "density"))?;
    let albedo = albedo
        .map(|a| Heterogeneity::albedo_grid(a, interpolation, placement))
        .transpose()
        .map_err(|e| describe(e, "albedo"))?;
    let info = DensityInfo {
        kind: "grid".into(),
        interpolation: Some(interpolation),
        majorant: Some(majorant.kind),
        majorant_cells: grid.majorant.as_ref().map(|m| m.dims),
        majorant_cell_voxels: grid.majorant_cell_voxels(),
        voxels: Some(voxels),
        negative_voxels_clamped: clamped,
        min: grid.min,
        max: grid.max,
        albedo_grid: albedo.is_some(),
        source: None,
    };
    Ok(Heterogeneity { density: Density::Grid(grid), albedo, info })
}
