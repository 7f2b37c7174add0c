//! The importance table of `run.importance = "table"` ([`crate::detect::importance`]): `importance.npy`
//! (`[layer][depth][angle]`, NaN where the pilot had no state) and `importance_states.npy` (the
//! pilot's states per bin), a figure (one panel per layer: depth against the direction's polar
//! angle, log colour scale) and the manifest's `importance` entry.

use serde::Serialize;

use super::{OutputEntry, Writer};
use crate::detect::importance::ImportanceTable;
use crate::detect::importance::{ANGLE_BINS, DEPTH_BINS};
use crate::error::Result;
use crate::io::figures::image::{ImageFigure, Panel};
use crate::io::figures::scale::{Colormap, TOP_QUANTILE, quantile};
use crate::io::formats::npy;
use crate::medium::Scene;

/// Decades of the figure's colour scale below its top.
const DECADES: f64 = 6.0;

/// The manifest's `importance`.
#[derive(Debug, Clone, Serialize)]
pub struct ImportanceEntry {
    /// The detector whose importance it is.
    pub detector: String,
    pub file: String,
    pub states_file: String,
    pub layout: &'static str,
    /// Per layer: its name and the depth range its bins span (m).
    pub layers: Vec<(String, [f64; 2])>,
    pub depth_bins: usize,
    pub angle_bins: usize,
    pub pilot_paths: u64,
    pub seconds: f64,
}

/// The layout of `importance.npy`.
pub const LAYOUT: &str = "[layer][depth][angle]: the mean detected weight per unit weight of a path leaving a scattering event in the bin (fraction of its weight the detector receives); depth bins uniform over each layer (a semi-infinite one: over the nearer of 20 transport lengths and 10 diffusion lengths, deeper in the last bin); angle bins uniform in the polar angle θ of the direction over [0°, 180°] (0° down into the stack, 180° up out of it); NaN where the pilot had no state";

/// Write `t` (of `scene`'s stack) and return its manifest entry.
pub fn write_importance(w: &mut Writer, t: &ImportanceTable, scene: &Scene, detector: &str) -> Result<ImportanceEntry> {
    let shape = t.shape();
    let (file, states_file) = ("importance.npy".to_string(), "importance_states.npy".to_string());
    w.put(file.clone(), npy::to_bytes(&shape, &t.value))?;
    let states: Vec<f64> = t.states.iter().map(|&n| n as f64).collect();
    w.put(states_file.clone(), npy::to_bytes(&shape, &states))?;
    let mut entry = OutputEntry::made("importance", &shape, "fraction of the path's weight", Vec::new());
    entry.undefined_nan = true;
    w.table.insert(file.clone(), entry);
    w.table.insert(states_file.clone(), OutputEntry::made("importance_states", &shape, "states", Vec::new()));
    w.figure("importance", &figure(t, scene, detector))?;
    let layers = scene
        .layers
        .iter()
        .zip(&t.grid.layers)
        .map(|(l, &(top, width))| (l.name.clone(), [top, top + width * DEPTH_BINS as f64]))
        .collect();
    Ok(ImportanceEntry {
        detector: detector.to_string(),
        file,
        states_file,
        layout: LAYOUT,
        layers,
        depth_bins: DEPTH_BINS,
        angle_bins: ANGLE_BINS,
        pilot_paths: t.paths,
        seconds: t.seconds,
    })
}

/// One panel per layer: depth (µm, down) against θ (°), `log₁₀` of the importance on one colour
/// scale.
fn figure(t: &ImportanceTable, scene: &Scene, detector: &str) -> ImageFigure {
    let logs: Vec<f64> = t.value.iter().map(|&v| if v > 0.0 { v.log10() } else { f64::NAN }).collect();
    let finite: Vec<f64> = logs.iter().copied().filter(|x| x.is_finite()).collect();
    let top = quantile(&finite, TOP_QUANTILE).unwrap_or(0.0);
    let per_layer = DEPTH_BINS * ANGLE_BINS;
    let panels = scene
        .layers
        .iter()
        .enumerate()
        .map(|(li, l)| {
            let (z0, z1) = (t.grid.depth(li, 0), t.grid.depth(li, DEPTH_BINS - 1));
            let half = 0.5 * (z1 - z0) / (DEPTH_BINS - 1).max(1) as f64;
            let mut p = Panel::new(
                format!("importance for `{detector}` in layer `{}`", l.name),
                logs[li * per_layer..(li + 1) * per_layer].to_vec(),
                (ANGLE_BINS, DEPTH_BINS),
                (0.0, 180.0),
                // Row 0 is the layer's top: depth grows downwards.
                (1e6 * (z1 + half), 1e6 * (z0 - half)),
                Colormap::Viridis,
                (top - DECADES, top),
                "log₁₀ detected weight per unit weight",
            );
            p.x_label = "direction's polar angle θ (°; 0 down, 180 up)".into();
            p.y_label = "depth z (µm)".into();
            p.equal = false;
            p.caption = format!("{} pilot paths; grey: no state; {DECADES} decades shown", t.paths);
            p
        })
        .collect();
    ImageFigure { panels }
}
