//! A volume tally's files ([`crate::detect::volume`]): each estimate as `volume_<what>.npy` with
//! its `_stderr.npy` ([`VOLUME_LAYOUT`]; the time-binned ones `volume_<what>_time.npy`,
//! [`VOLUME_TIME_LAYOUT`]), a figure of each (an x–z slice through the beam; for the time-binned
//! ones the slice at a few time bins on one colour scale), and the manifest's `volume` entry.

use serde::Serialize;

use super::Writer;
use crate::detect::volume::{VOLUME_LAYOUT, VOLUME_TIME_LAYOUT, VolumeGrid, VolumeSlots};
use crate::error::Result;
use crate::io::figures::image::{ImageFigure, Panel};
use crate::io::figures::scale::{Colormap, TOP_QUANTILE, quantile};
use crate::io::formats::vdb_write::{self, DenseFloatGrid};
use crate::spectrum::FrequencyAxis;

/// Decades of the log colour scale below its top.
pub const SLICE_DECADES: f64 = 5.0;

/// The manifest's `volume`: the grid and what its files hold.
#[derive(Debug, Clone, Serialize)]
pub struct VolumeEntry {
    /// `[nx, ny, nz]`.
    pub voxels: [usize; 3],
    pub x_range_m: [f64; 2],
    pub y_range_m: [f64; 2],
    pub z_range_m: [f64; 2],
    pub voxel_volume_m3: f64,
    pub layout: &'static str,
    /// With `volume.vdb = true`: how `volume.vdb`'s index space maps to the scene.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vdb_layout: Option<&'static str>,
    /// With `[volume.time]`: the time bins of the `_time` files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<VolumeTimeEntry>,
    /// Per file: its units.
    pub files: std::collections::BTreeMap<String, &'static str>,
}

/// The OpenVDB file of `volume.vdb = true`.
pub const VDB_FILE: &str = "volume.vdb";

/// How `volume.vdb`'s grids map to the scene.
pub const VDB_LAYOUT: &str = "FloatGrids named as the .npy files without volume_ and .npy (fluence_track, fluence_track_stderr, absorbed, …); index (i, j, k) = voxel (ix, iy, iz) counted from the box's min corner along x, y, z (not the .npy's descending rows); world = ohd's scene coordinates in m (z = depth, downwards), voxel centre (i, j, k) at min + (i + ½, j + ½, k + ½)·edge (ScaleTranslateMap); zero voxels inactive (background 0)";

/// Write the untimed volumes and their standard errors as `FloatGrid`s of one OpenVDB file
/// ([`VDB_LAYOUT`]).
fn write_vdb(w: &mut Writer, grid: &VolumeGrid, slots: VolumeSlots) -> Result<()> {
    let [nx, ny, nz] = grid.voxels;
    // Written rows are y descending: index j = ny − 1 − row.
    let reorder = |v: &[f64]| -> Vec<f32> {
        let mut out = vec![0.0f32; v.len()];
        for k in 0..nz {
            for j in 0..ny {
                let row = ny - 1 - j;
                for i in 0..nx {
                    out[(k * ny + j) * nx + i] = v[(k * ny + row) * nx + i] as f32;
                }
            }
        }
        out
    };
    let mut volumes = Vec::new();
    let declared = |slot: usize| (slot != usize::MAX).then(|| w.registry.at(slot));
    for (what, slot) in [
        ("fluence_track", slots.fluence_track),
        ("fluence_collision", slots.fluence_collision),
        ("absorbed", slots.absorbed),
    ] {
        let Some(o) = declared(slot) else { continue };
        let (v, e) = o.values(w.mean, w.stderr);
        volumes.push((what.to_string(), o.units, reorder(&v)));
        volumes.push((format!("{what}_stderr"), o.units, reorder(&e)));
    }
    let edge = grid.edge();
    let grids: Vec<DenseFloatGrid> = volumes
        .iter()
        .map(|(name, units, values)| DenseFloatGrid {
            name,
            units,
            dims: grid.voxels,
            values,
            voxel_size: edge,
            origin: grid.min + 0.5 * edge,
        })
        .collect();
    w.put(VDB_FILE.to_string(), vdb_write::to_bytes(&grids, concat!("ohd ", env!("CARGO_PKG_VERSION"))))
}

/// The manifest's `volume.time`: `bins` equal bins over `[t_min_s, t_max_s)`.
#[derive(Debug, Clone, Serialize)]
pub struct VolumeTimeEntry {
    pub t_min_s: f64,
    pub t_max_s: f64,
    pub bins: usize,
    pub layout: &'static str,
}

/// Write the volume outputs declared in the registry at `slots`; `beam_y` is where the x–z slice
/// of the figures is cut (the source's `y`, m).
pub fn write_volume(w: &mut Writer, grid: &VolumeGrid, slots: VolumeSlots, beam_y: f64) -> Result<VolumeEntry> {
    let mut files = std::collections::BTreeMap::new();
    let declared = |slot: usize| (slot != usize::MAX).then(|| w.registry.at(slot));
    for (what, slot) in [
        ("absorbed", slots.absorbed),
        ("fluence_collision", slots.fluence_collision),
        ("fluence_track", slots.fluence_track),
    ] {
        let Some(o) = declared(slot) else { continue };
        let (v, _) = w.array(o)?;
        files.insert(o.file.clone(), o.units);
        let title = match what {
            "absorbed" => "absorbed power, x–z slice through the beam",
            "fluence_collision" => "fluence (collision estimator), x–z slice",
            _ => "fluence (track length), x–z slice through the beam",
        };
        let unit = if what == "absorbed" {
            "log₁₀ fraction of emitted power per voxel"
        } else {
            "log₁₀ fluence (1/m²)"
        };
        w.figure(&super::figures::stem(o), &slice_figure(grid, &v, beam_y, title, unit))?;
    }
    for (what, slot) in [
        ("absorbed", slots.absorbed_time),
        ("fluence_collision", slots.fluence_collision_time),
        ("fluence_track", slots.fluence_track_time),
    ] {
        let Some(o) = declared(slot) else { continue };
        let Some(axis) = grid.time else { continue };
        let (v, _) = w.array(o)?;
        files.insert(o.file.clone(), o.units);
        let unit = if what == "absorbed" {
            "log₁₀ fraction of emitted energy per voxel and bin"
        } else {
            "log₁₀ fluence per bin (1/m²)"
        };
        let fig = time_slices_figure(grid, &axis, &v, beam_y, what.replace('_', " ").as_str(), unit);
        w.figure(&super::figures::stem(o), &fig)?;
    }
    if grid.vdb {
        write_vdb(w, grid, slots)?;
        files.insert(VDB_FILE.to_string(), "OpenVDB FloatGrids of the untimed volumes and their σ (see the layout)");
    }
    let e = grid.edge();
    Ok(VolumeEntry {
        voxels: grid.voxels,
        x_range_m: [grid.min.x, grid.max.x],
        y_range_m: [grid.min.y, grid.max.y],
        z_range_m: [grid.min.z, grid.max.z],
        voxel_volume_m3: e.x * e.y * e.z,
        layout: VOLUME_LAYOUT,
        vdb_layout: grid.vdb.then_some(VDB_LAYOUT),
        time: grid.time.map(|a| VolumeTimeEntry {
            t_min_s: a.f_min,
            t_max_s: a.f_max,
            bins: a.bins,
            layout: VOLUME_TIME_LAYOUT,
        }),
        files,
    })
}

/// Time bins shown by [`time_slices_figure`], at most.
pub const TIME_PANELS: usize = 4;

/// The x–z slice through the beam at up to [`TIME_PANELS`] time bins spread over the axis (the
/// first and the last included), side by side on one log colour scale (so the panels show the
/// light spreading and fading), `v` the written `[nt, nz, ny, nx]` array.
pub fn time_slices_figure(
    g: &VolumeGrid,
    axis: &FrequencyAxis,
    v: &[f64],
    y: f64,
    what: &str,
    unit: &str,
) -> ImageFigure {
    let (nt, n) = (axis.bins, g.count());
    let shown = TIME_PANELS.min(nt);
    let mut bins: Vec<usize> =
        (0..shown).map(|j| if shown == 1 { 0 } else { (j * (nt - 1) + (shown - 1) / 2) / (shown - 1) }).collect();
    bins.dedup();
    let mut panels: Vec<Panel> = bins
        .iter()
        .map(|&k| {
            let (t0, t1) = (
                1e9 * (axis.f_min + k as f64 * axis.bin_width()),
                1e9 * (axis.f_min + (k + 1) as f64 * axis.bin_width()),
            );
            let title = format!("{what}, t = {t0:.3}–{t1:.3} ns (bin {k})");
            slice_figure(g, &v[k * n..(k + 1) * n], y, &title, unit).panels.remove(0)
        })
        .collect();
    // One colour scale: the top of the brightest panel.
    let top = panels.iter().map(|p| p.range.1).fold(f64::NEG_INFINITY, f64::max);
    let top = if top.is_finite() { top } else { 0.0 };
    for p in &mut panels {
        p.range = (top - SLICE_DECADES, top);
        let at = p.caption.find(';').unwrap_or(p.caption.len());
        p.caption = format!("{}; one log₁₀ scale, {SLICE_DECADES} decades; grey: 0", &p.caption[..at]);
    }
    ImageFigure { panels }
}

/// The largest width-to-depth ratio (or its inverse) of a slice drawn true to scale.
const MAX_ASPECT: f64 = 3.0;

/// The x–z slice of `v` (as written) at the row of `y`, on a log scale: `SLICE_DECADES`
/// decades up to the 99.5th percentile of the slice's positive values; zero voxels grey. Axes in
/// mm, depth downwards.
pub fn slice_figure(g: &VolumeGrid, v: &[f64], y: f64, title: &str, unit: &str) -> ImageFigure {
    let [nx, ny, nz] = g.voxels;
    // The written row (y descending) holding `y`, or the nearest.
    let iy = (((y - g.min.y) / g.edge().y).floor().max(0.0) as usize).min(ny - 1);
    let row = ny - 1 - iy;
    let slice: Vec<f64> = (0..nz)
        .flat_map(|iz| v[(iz * ny + row) * nx..(iz * ny + row + 1) * nx].iter())
        .map(|&x| if x > 0.0 { x.log10() } else { f64::NAN })
        .collect();
    let finite: Vec<f64> = slice.iter().copied().filter(|x| x.is_finite()).collect();
    let top = quantile(&finite, TOP_QUANTILE).unwrap_or(0.0);
    let mut p = Panel::new(
        title,
        slice,
        (nx, nz),
        (1e3 * g.min.x, 1e3 * g.max.x),
        // Row 0 is the top of the box: depth grows downwards.
        (1e3 * g.max.z, 1e3 * g.min.z),
        Colormap::Viridis,
        (top - SLICE_DECADES, top),
        unit,
    );
    p.y_label = "depth z (mm)".into();
    p.caption = format!(
        "y = {:.3} mm; log₁₀, {SLICE_DECADES} decades below the {:.1}th percentile; grey: 0",
        1e3 * (g.min.y + (iy as f64 + 0.5) * g.edge().y),
        100.0 * TOP_QUANTILE
    );
    // True to scale unless the box is far wider than deep or the reverse: a thin slab's slice
    // drawn to scale is a strip a few pixels high (and its colour bar too short for its label).
    let aspect = (g.max.x - g.min.x) / (g.max.z - g.min.z);
    if !(1.0 / MAX_ASPECT..=MAX_ASPECT).contains(&aspect) {
        p.equal = false;
        p.y_label = "depth z (mm, not to scale)".into();
    }
    ImageFigure { panels: vec![p] }
}
