//! Outputs of a scan: `vad.csv` (the wind retrieved in every range gate, with the radial velocity
//! each pointing measured) and `scan.json` (the pointings, the run directory of each, and the same
//! table). Each pointing's own outputs are a complete run directory of their own.

use serde_json::{Value, json};

use super::dir::{DirWriter, SCAN, VAD, VAD_FIGURES};
use super::manifest::Timing;
use crate::error::Result;
use crate::io::figures::lines::{Curve, LinePlot, Mark, PALETTE};
use crate::scan::GateWind;
use crate::source::Pointing;

/// Write `vad.csv` and (last) `scan.json` into the scan's directory `out`; `runs[i]` is the
/// directory of pointing `i` (relative to it) and `timings[i]` where its wall time went. Returns
/// the JSON as written.
pub fn write_scan(
    mut out: DirWriter,
    pointings: &[Pointing],
    runs: &[String],
    gates: &[GateWind],
    wind: Option<&crate::flow::WindProfile>,
    figures: bool,
    timings: &[Timing],
) -> Result<Value> {
    let mut csv = String::from(
        "gate,range_m,height_m,u_east_m_per_s,v_north_m_per_s,w_up_m_per_s,u_stderr,v_stderr,w_stderr,\
         horizontal_speed_m_per_s,direction_from_deg,chi2,dof,pointings_used,error",
    );
    for i in 0..pointings.len() {
        csv.push_str(&format!(",radial_velocity_{i}_m_per_s"));
    }
    csv.push('\n');
    let num = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
    let mut table = Vec::with_capacity(gates.len());
    for (g, w) in gates.iter().enumerate() {
        let used = w.radial_velocities.iter().filter(|v| v.is_some()).count();
        let mut row = json!({
            "range_m": w.range_m,
            "height_m": w.height_m,
            "radial_velocities_m_per_s": w.radial_velocities,
            "pointings_used": used,
        });
        csv.push_str(&format!("{g},{:.3},{:.3},", w.range_m, w.height_m));
        match &w.fit {
            Ok(f) => {
                let se = f.wind_stderr();
                csv.push_str(&format!(
                    "{:.6},{:.6},{:.6},{},{},{},{:.6},{:.3},{:.6e},{},{used},",
                    f.wind.x,
                    f.wind.y,
                    f.wind.z,
                    num(se.map(|s| s.x)),
                    num(se.map(|s| s.y)),
                    num(se.map(|s| s.z)),
                    f.horizontal_speed,
                    f.direction_from_deg,
                    f.chi2,
                    f.dof
                ));
                row["wind_m_per_s"] = json!(f.wind.to_array());
                row["wind_stderr_m_per_s"] = json!(se.map(|s| s.to_array()));
                row["horizontal_speed_m_per_s"] = json!(f.horizontal_speed);
                row["direction_from_deg"] = json!(f.direction_from_deg);
                row["chi2"] = json!(f.chi2);
                row["dof"] = json!(f.dof);
            }
            Err(e) => {
                csv.push_str(&format!(",,,,,,,,,,{used},\"{e}\""));
                row["error"] = json!(e.to_string());
            }
        }
        for v in &w.radial_velocities {
            csv.push_str(&format!(",{}", num(*v)));
        }
        csv.push('\n');
        table.push(row);
    }
    out.put(VAD, csv.as_bytes())?;
    if figures {
        out.figure(VAD_FIGURES[0], VAD_FIGURES[1], &wind_profile(gates, wind))?;
    }
    let scan = json!({
        "pointings": pointings.iter().zip(runs).enumerate().map(|(i, (p, r))| json!({
            "azimuth_deg": p.azimuth_deg,
            "elevation_deg": p.elevation_deg,
            "direction": p.direction.to_array(),
            "run": r,
            "timing": timings.get(i),
        })).collect::<Vec<_>>(),
        "timing": Timing::sum(timings),
        "frame": "x = east, y = north, z = up; azimuth clockwise from north; wind direction is where it blows from",
        "radial_velocity": "peak of each gate's expected spectrum (all orders), λ0·f/2, positive receding",
        "gates": table,
    });
    let text = serde_json::to_string_pretty(&scan).unwrap_or_default();
    out.finish(Some((SCAN, text.as_bytes())))?;
    Ok(scan)
}

/// The VAD wind profile: east, north and vertical wind against height, each gate's value with
/// its standard error as a horizontal error bar (gates without a fit left out), and dashed, the
/// scene's `wind` at each gate's height. The vertical wind is drawn first, as markers, so that
/// the north wind (also near 0 in a westerly) stays visible over it.
pub fn wind_profile(gates: &[GateWind], wind: Option<&crate::flow::WindProfile>) -> LinePlot {
    let mut plot = LinePlot::new("VAD wind profile", "wind (m/s)", "height (m)");
    let names = ["u (east)", "v (north)", "w (up)"];
    let mut largest_sigma: f64 = 0.0;
    for k in [2, 1, 0] {
        let (mut x, mut y, mut e) = (vec![], vec![], vec![]);
        for g in gates {
            if let Ok(f) = &g.fit {
                x.push(f.wind[k]);
                y.push(g.height_m);
                let s = f.wind_stderr().map_or(f64::NAN, |s| s[k]);
                largest_sigma = largest_sigma.max(if s.is_finite() { s } else { 0.0 });
                e.push(s);
            }
        }
        let mut c = Curve::line(names[k], x, y, PALETTE[k]);
        c.x_err = Some(e);
        c.mark = if k == 2 { Mark::Markers } else { Mark::LineMarkers };
        plot.curves.push(c);
    }
    if let Some(w) = wind {
        for k in [2, 1, 0] {
            let y: Vec<f64> = gates.iter().map(|g| g.height_m).collect();
            let x = y.iter().map(|&h| w.at(h)[k]).collect();
            let label = if k == 0 { "the scene's wind (dashed)" } else { "" };
            let mut c = Curve::line(label, x, y, PALETTE[k]);
            c.mark = Mark::Dashed;
            plot.curves.push(c);
        }
    }
    let failed = gates.iter().filter(|g| g.fit.is_err()).count();
    plot.note = format!(
        "error bars: ±σ of the fit (at most {} m/s); {failed} of {} gates without a fit (not drawn)",
        crate::describe::num(largest_sigma),
        gates.len()
    );
    plot
}
