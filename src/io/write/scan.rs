//! Outputs of a scan: `vad.csv` (the wind retrieved in every range gate, with the radial velocity
//! each pointing measured), or for a chirped source `fmcw_scan.csv` (each pointing's FMCW range
//! and radial velocity per detector) with its figures; and `scan.json` (the pointings, the run
//! directory of each, and the same table). Each pointing's own outputs are a complete run
//! directory of their own.

use serde_json::{Value, json};

use super::dir::{DirWriter, FMCW_SCAN, FMCW_SCAN_FIGURES, SCAN, VAD, VAD_FIGURES};
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
        "pointings": pointing_records(pointings, runs, timings),
        "timing": Timing::sum(timings),
        "frame": "x = east, y = north, z = up; azimuth clockwise from north; wind direction is where it blows from",
        "radial_velocity": "peak of each gate's expected spectrum (all orders), λ0·f/2, positive receding",
        "gates": table,
    });
    let text = serde_json::to_string_pretty(&scan).unwrap_or_default();
    out.finish(Some((SCAN, text.as_bytes())))?;
    Ok(scan)
}

/// One pointing's FMCW read-off of one detector (`Err`: why there is none, e.g. no signal).
pub type FmcwRow = (String, std::result::Result<crate::retrieval::FmcwEstimate, String>);

/// Write `fmcw_scan.csv`, its figures (range and radial velocity against the scan's position) and
/// (last) `scan.json` into the scan's directory `out`: `rows[i]` are pointing `i`'s read-offs, one
/// per detector with a chirped spectrum; `runs[i]` its directory. Returns the JSON as written.
pub fn write_fmcw_scan(
    mut out: DirWriter,
    pointings: &[Pointing],
    runs: &[String],
    rows: &[Vec<FmcwRow>],
    figures: bool,
    timings: &[Timing],
) -> Result<Value> {
    // The estimates' columns are those of each pointing's `NAME_fmcw_estimates.csv`.
    let keys = super::fmcw::KEYS;
    let mut csv = format!("pointing,azimuth_deg,elevation_deg,detector,{},error\n", keys.join(","));
    let mut table = Vec::new();
    for (i, (p, row)) in pointings.iter().zip(rows).enumerate() {
        for (name, r) in row {
            csv.push_str(&format!("{i},{},{},{name},", p.azimuth_deg, p.elevation_deg));
            let mut entry = json!({ "pointing": i, "detector": name });
            match r {
                Ok(e) => {
                    let v = super::fmcw::values(e);
                    for (k, x) in keys.iter().zip(v) {
                        csv.push_str(&format!("{x},"));
                        entry[*k] = json!(x);
                    }
                    csv.push('\n');
                }
                Err(why) => {
                    csv.push_str(&format!("{}\"{}\"\n", ",".repeat(keys.len()), why.replace('"', "'")));
                    entry["error"] = json!(why);
                }
            }
            table.push(entry);
        }
    }
    out.put(FMCW_SCAN, csv.as_bytes())?;
    if figures {
        let [range, velocity] = fmcw_scan_plots(pointings, rows);
        out.figure(FMCW_SCAN_FIGURES[0], FMCW_SCAN_FIGURES[1], &range)?;
        out.figure(FMCW_SCAN_FIGURES[2], FMCW_SCAN_FIGURES[3], &velocity)?;
    }
    let scan = json!({
        "pointings": pointing_records(pointings, runs, timings),
        "timing": Timing::sum(timings),
        "frame": "x = east, y = north, z = the stack's depth axis; azimuth clockwise from north, elevation toward +z",
        "fmcw": table,
        "method": "per pointing and detector, the peaks of its up- and down-chirp spectra: R = cT(f_up + f_down)/(4B), v = λ0(f_up − f_down)/4, positive receding",
    });
    let text = serde_json::to_string_pretty(&scan).unwrap_or_default();
    out.finish(Some((SCAN, text.as_bytes())))?;
    Ok(scan)
}

/// The pointings of a scan as `scan.json` lists them: direction, run directory, timing.
fn pointing_records(pointings: &[Pointing], runs: &[String], timings: &[Timing]) -> Vec<Value> {
    pointings
        .iter()
        .zip(runs)
        .enumerate()
        .map(|(i, (p, r))| {
            json!({
                "azimuth_deg": p.azimuth_deg,
                "elevation_deg": p.elevation_deg,
                "direction": p.direction.to_array(),
                "run": r,
                "timing": timings.get(i),
            })
        })
        .collect()
}

/// The scan's position of each pointing, and its axis label: the elevation when only it varies,
/// the azimuth when only it does, else the pointing's index.
fn scan_position(pointings: &[Pointing]) -> (Vec<f64>, &'static str) {
    let varies = |f: fn(&Pointing) -> f64| pointings.iter().any(|p| f(p) != f(&pointings[0]));
    let (az, el) = (varies(|p| p.azimuth_deg), varies(|p| p.elevation_deg));
    match (az, el) {
        (false, true) => (pointings.iter().map(|p| p.elevation_deg).collect(), "pointing elevation (°)"),
        (true, false) => (pointings.iter().map(|p| p.azimuth_deg).collect(), "pointing azimuth (°)"),
        _ => ((0..pointings.len()).map(|i| i as f64).collect(), "pointing"),
    }
}

/// Range and radial velocity against the scan's position, a curve per detector (pointings
/// without a read-off left out, counted in the note).
fn fmcw_scan_plots(pointings: &[Pointing], rows: &[Vec<FmcwRow>]) -> [LinePlot; 2] {
    let (x, x_label) = scan_position(pointings);
    let mut range = LinePlot::new("FMCW range along the scan", x_label, "range (m)");
    let mut velocity =
        LinePlot::new("FMCW radial velocity along the scan", x_label, "radial velocity (m/s, + receding)");
    let names: Vec<&str> = rows.first().map(|r| r.iter().map(|(n, _)| n.as_str()).collect()).unwrap_or_default();
    let mut missing = 0;
    for (k, name) in names.iter().enumerate() {
        let (mut xs, mut r, mut v) = (vec![], vec![], vec![]);
        for (i, row) in rows.iter().enumerate() {
            match row.get(k).map(|(_, e)| e) {
                Some(Ok(e)) => {
                    xs.push(x[i]);
                    r.push(e.range_m);
                    v.push(e.radial_velocity_m_per_s);
                }
                _ => missing += 1,
            }
        }
        let colour = PALETTE[k % PALETTE.len()];
        for (plot, y) in [(&mut range, r), (&mut velocity, v)] {
            let mut c = Curve::line(*name, xs.clone(), y, colour);
            c.mark = Mark::LineMarkers;
            plot.curves.push(c);
        }
    }
    let note = format!(
        "peaks of the up- and down-chirp spectra per pointing; {missing} read-offs without a signal (not drawn)"
    );
    range.note = note.clone();
    velocity.note = note;
    [range, velocity]
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
