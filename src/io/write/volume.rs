//! A volume tally's files ([`crate::detect::volume`]): each estimate as `volume_<what>.npy` with
//! its `_stderr.npy` ([`VOLUME_LAYOUT`]), a figure of each (an x–z slice through the beam), and
//! the manifest's `volume` entry.

use serde::Serialize;

use super::Writer;
use crate::detect::volume::{VOLUME_LAYOUT, VolumeGrid};
use crate::error::Result;
use crate::io::figures::image::{ImageFigure, Panel};
use crate::io::figures::scale::{Colormap, TOP_QUANTILE, quantile};

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
    /// Per file: its units.
    pub files: std::collections::BTreeMap<String, &'static str>,
}

/// Write the volume outputs declared in the registry; `beam_y` is where the x–z slice of the
/// figures is cut (the source's `y`, m).
pub fn write_volume(w: &mut Writer, grid: &VolumeGrid, beam_y: f64) -> Result<VolumeEntry> {
    let mut files = std::collections::BTreeMap::new();
    for what in ["absorbed", "fluence_collision", "fluence_track"] {
        let Some(o) = w.registry.get(&format!("volume.{what}")) else { continue };
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
    let e = grid.edge();
    Ok(VolumeEntry {
        voxels: grid.voxels,
        x_range_m: [grid.min.x, grid.max.x],
        y_range_m: [grid.min.y, grid.max.y],
        z_range_m: [grid.min.z, grid.max.z],
        voxel_volume_m3: e.x * e.y * e.z,
        layout: VOLUME_LAYOUT,
        files,
    })
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
