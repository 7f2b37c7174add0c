//! What a finished run could not get right, as warnings (issue 21, item 8: 30 % of a detector's
//! power off its spectrum's axis, a lidar wind folded to −3 m/s and 16 of 2016 paths truncated
//! were all reported as if nothing were wrong). Each is read off the run's estimates and counters
//! against a documented threshold; the manifest lists them (`warnings`) and the command line
//! prints them after the run's report.

use serde::Serialize;

use crate::detect::DetectorKind;
use crate::experiment::{Experiment, RunOutput};

/// A warning: a stable code for scripts and a message for people. In the manifest:
/// `{"code": "...", "message": "..."}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Warning {
    pub code: &'static str,
    pub message: String,
}

/// Warn when more than this fraction of a detector's power falls outside its spectrum's
/// frequency axis (per chirp): the spectrum then misses that much of the signal. (The good
/// fixtures with moving media lose 1.2–1.4 % into the tails of their axes.)
pub const OFF_AXIS_POWER_FRACTION: f64 = 0.05;

/// Warn when more than this fraction of a lidar receiver's power comes from echoes whose beat
/// frequency lies outside the sampled band `[−f_s/2, f_s/2)`: their spectra fold into the band at
/// wrong velocities (aliasing).
pub const ALIASED_POWER_FRACTION: f64 = 0.01;

/// Warn when more than this fraction of the paths was truncated (at the event cap, or travelling
/// parallel to the layers in a void): a truncated path's weight is lost, so power estimates may
/// be low by up to about this fraction of the emitted power (weights are at most 1 but for
/// roulette's survivors). (An albedo-1 half-space capped at 10⁴ events truncated 16 of 2016
/// paths and lost 0.8 % of the power.)
pub const TRUNCATED_PATH_FRACTION: f64 = 1e-4;

/// Warn when the largest path scores into a camera's regions' footprints fall off slower than
/// this power: MCNP's check of a tally's history scores (the density of the largest ∝ x^−s; the
/// mean exists for s > 2, the variance for s > 3, and MCNP asks for s ≥ 3). Below
/// it the footprint's mean is carried by rare large scores that most runs do not draw, so a
/// typical run reads those pixels low, and their errors low with them (issue 54: over retina_ldh's
/// artery, 16 forward runs against the camera-side estimator, validation/README.md).
pub const TAIL_SLOPE: f64 = 3.0;

/// A fraction as a percentage to three significant digits or so (`31.2 %`, `0.794 %`).
fn percent(x: f64) -> String {
    let p = 100.0 * x;
    if p >= 10.0 {
        format!("{p:.1} %")
    } else if p >= 1.0 {
        format!("{p:.2} %")
    } else {
        format!("{p:.3} %")
    }
}

/// The warnings of run `out` of `exp`, in a fixed order: per detector (off-axis power, aliasing),
/// per detector again (FMCW estimates missing), per image with regions (a heavy tail of the scores
/// into their footprints), then the run's (truncated paths, non-finite detections).
pub fn warnings(exp: &Experiment, out: &RunOutput) -> Vec<Warning> {
    let mean = out.estimates.mean();
    let reg = &out.layout.registry;
    let mut w = Vec::new();
    for (i, d) in exp.detectors.iter().enumerate() {
        let lay = &out.layout.detectors[i];
        let power = mean[lay.power];
        if power <= 0.0 {
            continue;
        }
        let share = |x: f64| percent(x / power);
        match &d.kind {
            DetectorKind::Surface(s) => {
                let (Some(spec), Some(sl)) = (s.spectrum(), lay.spectrum()) else { continue };
                let chirps = out.beat.chirps();
                let totals = reg.within(sl.slots(chirps)).filter(|o| o.primary);
                for o in totals {
                    let (below, above) = o.tails(mean, 0);
                    if below + above > OFF_AXIS_POWER_FRACTION * power {
                        let chirp = match sl.role(o.slots.start, chirps).0 {
                            "" => String::new(),
                            c => format!(" ({c}-chirp)"),
                        };
                        w.push(Warning {
                            code: "off_axis_power",
                            message: format!(
                                "detector \"{}\": {} of its detected power fell outside its spectrum's axis{chirp}, [{}, {}] Hz ({} below, {} above; more than {} % is warned of): widen detectors[{i}].spectrum",
                                d.name,
                                share(below + above),
                                spec.axis.f_min,
                                spec.axis.f_max,
                                share(below),
                                share(above),
                                100.0 * OFF_AXIS_POWER_FRACTION
                            ),
                        });
                    }
                }
            }
            DetectorKind::Lidar(l) => {
                let Some(aliased) = lay.lidar.as_ref().map(|ll| mean[ll.aliased]) else { continue };
                if aliased > ALIASED_POWER_FRACTION * power {
                    let half = 0.5 * l.sample_rate;
                    let v = crate::retrieval::radial_velocity(half, l.wavelength);
                    let mhz = half / 1e6;
                    w.push(Warning {
                        code: "lidar_aliasing",
                        message: format!(
                            "lidar \"{}\": {} of its detected power came from echoes beyond the sampled band ±f_s/2 = ±{mhz} MHz (radial velocities beyond ±{v:.3} m/s), folded into the spectra at wrong velocities (more than {} % is warned of): raise the sample rate, detectors[{i}].lidar.sample_rate_mhz",
                            d.name,
                            share(aliased),
                            100.0 * ALIASED_POWER_FRACTION
                        ),
                    });
                }
            }
        }
    }
    // An FMCW retrieval that gives no estimates, or estimates that are not finite numbers (written
    // as null), says so here as well as in its note (issue 33, item 8: a range of null was
    // written without a warning).
    for (i, d) in exp.detectors.iter().enumerate() {
        let why = match exp.fmcw_estimates(out, i) {
            Some(Err(e)) => e.to_string(),
            Some(Ok(e)) if !e.is_finite() => "an estimate is not a finite number (written as null)".to_string(),
            _ => continue,
        };
        w.push(Warning {
            code: "fmcw_no_estimates",
            message: format!(
                "detector \"{}\": no FMCW range and radial velocity estimates: {why} (detectors.{}.fmcw.note in the manifest)",
                d.name, d.name
            ),
        });
    }
    // The regions' tail checks, per image (the manifest's `pixel_errors.<output>.regions.tail`).
    for (slot, t) in out.tail_checks() {
        let (Some(slope), Some(o)) = (t.slope, reg.outputs.iter().find(|o| o.slots.start == slot)) else { continue };
        if slope < TAIL_SLOPE {
            w.push(Warning {
                code: "heavy_tail",
                message: format!(
                    "{}: the largest path scores into the regions' footprints fall off with a slope of {slope:.1} (the largest {} of {} scores; below {TAIL_SLOPE} their variance is not yet sampled): a typical run then reads the footprint pixels low, and their errors low with them, as their mean is carried by rare large scores that most runs do not draw; run more paths, and trust the footprint's pixels when the slope is at least {TAIL_SLOPE}",
                    o.name, t.largest, t.scores
                ),
            });
        }
    }
    let st = &out.stats;
    let paths = st.paths.max(1) as f64;
    let truncated = st.truncated_paths as f64 / paths;
    if truncated > TRUNCATED_PATH_FRACTION {
        w.push(Warning {
            code: "truncated_paths",
            message: format!(
                "{} of {} paths ({}) were truncated, at run.max_scattering_events = {} events or travelling parallel to the layers in a void: their weight is lost, so power estimates may be low by up to about that fraction of the emitted power (more than {} % of the paths is warned of)",
                st.truncated_paths,
                st.paths,
                percent(truncated),
                exp.plan.walk.max_events,
                100.0 * TRUNCATED_PATH_FRACTION
            ),
        });
    }
    if st.non_finite > 0 {
        w.push(Warning {
            code: "non_finite_detections",
            message: format!(
                "{} detection(s) had a non-finite weight, path length or frequency and were not recorded",
                st.non_finite
            ),
        });
    }
    w
}
