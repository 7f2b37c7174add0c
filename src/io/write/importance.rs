//! The importance table of `run.importance = "table"` ([`crate::detect::importance`]): `importance.npy`
//! (`[layer][depth][angle]`, or `[layer][lateral][depth][angle]` for a detector away from the
//! beam; NaN where the pilot had no state), `importance_states.npy` (the pilot's states per
//! bin) and `importance_relative_error.npy` (each value's σ over it), a figure (per layer: depth against the direction's polar angle over the detector, and
//! for a detector away from the beam depth against the lateral distance too; log colour scale)
//! and the manifest's `importance` entry.

use serde::Serialize;

use super::{OutputEntry, Writer};
use crate::detect::importance::ImportanceTable;
use crate::detect::importance::{ANGLE_BINS, DEPTH_BINS, LATERAL_BINS};
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
    /// For a detector away from the beam: the lateral bins and the distances to the detector's
    /// area they span (m; farther in the last bin).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lateral_bins: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lateral_range: Option<[f64; 2]>,
    pub pilot_paths: u64,
    pub seconds: f64,
    /// Whether the forward walk followed the table's weight windows.
    pub windows: bool,
    /// Whether its directions were guided by the table as well.
    pub guided: bool,
    /// With `run.importance = "auto"`: the pilot's relative variance × work of the main output
    /// without the table's help, with the windows and with the windows and guided directions
    /// (the lowest was chosen).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub auto: Option<crate::transport::windows::AutoWindows>,
}

/// The layout of `importance.npy`, and with lateral bins.
pub const LAYOUT: &str = "[layer][depth][angle]: the mean detected weight per unit weight of a path leaving a scattering event in the bin (fraction of its weight the detector receives); depth bins uniform over each layer (a semi-infinite one: over the nearer of 20 transport lengths and 10 diffusion lengths, deeper in the last bin); angle bins uniform in the polar angle θ of the direction over [0°, 180°] (0° down into the stack, 180° up out of it); NaN where the pilot had no state";
pub const LAYOUT_LATERAL: &str = "[layer][lateral][depth][angle]: the mean detected weight per unit weight of a path leaving a scattering event in the bin (fraction of its weight the detector receives); lateral bins uniform in the distance (x, y) to the detector's area over lateral_range (farther in the last bin); depth bins uniform over each layer (a semi-infinite one: over the nearer of 20 transport lengths and 10 diffusion lengths, deeper in the last bin); angle bins uniform in the polar angle θ of the direction over [0°, 180°] (0° down into the stack, 180° up out of it); NaN where the pilot had no state";

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
    // Each bin's relative error (∞ → NaN: fewer than two states, or no value).
    let rel: Vec<f64> = t.relative_error.iter().map(|&e| if e.is_finite() { e } else { f64::NAN }).collect();
    w.put("importance_relative_error.npy".to_string(), npy::to_bytes(&shape, &rel))?;
    let mut entry = OutputEntry::made("importance_relative_error", &shape, "1", Vec::new());
    entry.undefined_nan = true;
    w.table.insert("importance_relative_error.npy".to_string(), entry);
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
        layout: if t.grid.lateral.is_some() { LAYOUT_LATERAL } else { LAYOUT },
        layers,
        depth_bins: DEPTH_BINS,
        angle_bins: ANGLE_BINS,
        lateral_bins: t.grid.lateral.map(|_| LATERAL_BINS),
        lateral_range: t.grid.lateral.map(|l| [0.0, l.width * LATERAL_BINS as f64]),
        pilot_paths: t.paths,
        seconds: t.seconds,
        windows: false,
        guided: false,
        auto: None,
    })
}

/// Per layer: depth (µm, down) against θ (°) over the detector (the first lateral bin), and with
/// lateral bins depth against the lateral distance (mm; the bins' mean over θ, weighted by the
/// pilot's states); `log₁₀` of the importance on one colour scale.
fn figure(t: &ImportanceTable, scene: &Scene, detector: &str) -> ImageFigure {
    let log = |v: f64| if v > 0.0 { v.log10() } else { f64::NAN };
    let finite: Vec<f64> = t.value.iter().map(|&v| log(v)).filter(|x| x.is_finite()).collect();
    let top = quantile(&finite, TOP_QUANTILE).unwrap_or(0.0);
    let nr = t.grid.lateral_bins();
    let per_lateral = DEPTH_BINS * ANGLE_BINS;
    let mut panels = Vec::new();
    for (li, l) in scene.layers.iter().enumerate() {
        let (z0, z1) = (t.grid.depth(li, 0), t.grid.depth(li, DEPTH_BINS - 1));
        let half = 0.5 * (z1 - z0) / (DEPTH_BINS - 1).max(1) as f64;
        // Row 0 is the layer's top: depth grows downwards.
        let depths = (1e6 * (z1 + half), 1e6 * (z0 - half));
        // A panel of depth against `x` (its label, range and `nx` columns), `ny = DEPTH_BINS`.
        let panel = |title: String, values: Vec<f64>, (nx, x): (usize, (f64, f64)), x_label: &str, caption: String| {
            let mut p = Panel::new(
                title,
                values,
                (nx, DEPTH_BINS),
                x,
                depths,
                Colormap::Viridis,
                (top - DECADES, top),
                "log₁₀ detected weight per unit weight",
            );
            p.x_label = x_label.into();
            p.y_label = "depth z (µm)".into();
            p.equal = false;
            p.caption = caption;
            p
        };
        let start = li * nr * per_lateral;
        let over = if nr > 1 { " over it" } else { "" };
        panels.push(panel(
            format!("importance for `{detector}`{over} in layer `{}`", l.name),
            t.value[start..start + per_lateral].iter().map(|&v| log(v)).collect(),
            (ANGLE_BINS, (0.0, 180.0)),
            "direction's polar angle θ (°; 0 down, 180 up)",
            format!("{} pilot paths; grey: no state; {DECADES} decades shown", t.paths),
        ));
        if let Some(lat) = t.grid.lateral {
            // [depth][lateral]: each bin's mean over the angles, weighted by its states.
            let mut values = vec![f64::NAN; DEPTH_BINS * nr];
            for r in 0..nr {
                for k in 0..DEPTH_BINS {
                    let first = start + (r * DEPTH_BINS + k) * ANGLE_BINS;
                    let (mut sum, mut n) = (0.0, 0.0);
                    for b in (first..first + ANGLE_BINS).filter(|&b| t.value[b].is_finite()) {
                        sum += t.value[b] * t.states[b] as f64;
                        n += t.states[b] as f64;
                    }
                    if n > 0.0 {
                        values[k * nr + r] = log(sum / n);
                    }
                }
            }
            panels.push(panel(
                format!("importance for `{detector}` by distance to it, layer `{}`", l.name),
                values,
                (nr, (0.0, 1e3 * lat.width * nr as f64)),
                "lateral distance to the detector's area (mm)",
                "mean over directions, weighted by the pilot's states; grey: no state".into(),
            ));
        }
    }
    ImageFigure { panels }
}
