//! `[run]`: the run plan (samples, batches, seed, walk settings).

use super::{DEFAULT_MEMORY_BUDGET_GIB, R, err};
use crate::config::schema::*;
use crate::experiment::RunPlan;
use crate::transport::windows::Importance;
use crate::transport::{ControlVariate, LaunchSettings, Reflections, Tracking, WalkSettings};

pub(super) fn resolve_run(r: &RunSection) -> R<RunPlan> {
    let batches = r.batches.unwrap_or(32);
    if !(16..=65_536).contains(&batches) {
        return err("run.batches", format!("= {batches}: expected 16 to 65536 independent batches"));
    }
    let samples = r.samples.unwrap_or(1_000_000);
    if samples == 0 || samples > 1 << 48 {
        return err("run.samples", format!("= {samples}: expected 1 to 2^48 paths"));
    }
    let threads = r.threads.unwrap_or(0);
    if threads > 1024 {
        return err("run.threads", format!("= {threads}: expected 0 (all cores) to 1024"));
    }
    let tracking = match r.tracking.unwrap_or(TrackingKind::Analytic) {
        TrackingKind::Analytic => {
            if r.majorant_scale.is_some() {
                return err("run.majorant_scale", "only applies with run.tracking = \"delta\"");
            }
            Tracking::Analytic
        }
        TrackingKind::Delta => {
            let s = r.majorant_scale.unwrap_or(1.0);
            if !(s.is_finite() && (1.0..=1e6).contains(&s)) {
                return err("run.majorant_scale", format!("= {s}: expected a factor in [1, 1e6]"));
            }
            Tracking::Delta { majorant_scale: s }
        }
    };
    let roulette_threshold = r.roulette_threshold.unwrap_or(1e-4);
    if !(roulette_threshold.is_finite() && (0.0..1.0).contains(&roulette_threshold)) {
        return err("run.roulette_threshold", format!("= {roulette_threshold}: expected a weight in [0, 1)"));
    }
    let roulette_survival = r.roulette_survival.unwrap_or(0.1);
    if !(roulette_survival > 0.0 && roulette_survival <= 1.0) {
        return err("run.roulette_survival", format!("= {roulette_survival}: expected a probability in (0, 1]"));
    }
    let max_events = r.max_scattering_events.unwrap_or(1_000_000);
    if max_events == 0 || max_events > u32::MAX as u64 {
        return err("run.max_scattering_events", format!("= {max_events}: expected 1 to {}", u32::MAX));
    }
    let budget = r.memory_budget_gib.unwrap_or(DEFAULT_MEMORY_BUDGET_GIB);
    if !(budget.is_finite() && budget > 0.0 && budget <= 1e6) {
        return err("run.memory_budget_gib", format!("= {budget}: expected a budget in (0, 10^6] GiB"));
    }
    let (memory_budget, memory_limited_by) = lowered_budget(budget);
    let gate = match &r.time_gate {
        None => None,
        Some(q) => {
            let [t0, t1] = q.si();
            if !(t0.is_finite() && t1.is_finite() && 0.0 <= t0 && t0 < t1) {
                return err(
                    format!("run.{}", q.key),
                    format!("= {:?}: expected [t0, t1] with 0 ≤ t0 < t1, finite", q.value),
                );
            }
            // As path lengths c·t, finite (issue 33, item 8).
            let longest = f64::MAX / crate::SPEED_OF_LIGHT;
            if t1 > longest {
                let key = format!("run.{}", q.key);
                let unit = crate::config::units::unit_of(&key);
                return err(
                    &key,
                    format!(
                        "= {:?}: expected t1 of at most {} {unit} (the optical path length c·t1 must be a finite number)",
                        q.value,
                        super::shown(longest / q.unit.factor)
                    ),
                );
            }
            // As optical path lengths (the walk's `l`): time of flight = l / c.
            Some((crate::SPEED_OF_LIGHT * t0, crate::SPEED_OF_LIGHT * t1))
        }
    };
    let paths_per_batch = samples.div_ceil(batches);
    let launches = match r.launches.unwrap_or(LaunchesKind::Profile) {
        LaunchesKind::Profile => {
            let margin_key = r.launch_margin.as_ref().map(|q| q.key.clone());
            for (key, given) in [
                (margin_key.clone().unwrap_or_default(), margin_key.is_some()),
                ("launch_profile_share".to_string(), r.launch_profile_share.is_some()),
            ] {
                if given {
                    return err(
                        format!("run.{key}"),
                        "applies to run.launches = \"near_regions\" only: remove it or set run.launches",
                    );
                }
            }
            None
        }
        LaunchesKind::NearRegions => {
            let margin = r.launch_margin.as_ref().map_or(200e-6, |q| q.si());
            if !(margin.is_finite() && margin > 0.0) {
                let q = r.launch_margin.as_ref().expect("the default is valid");
                return err(
                    format!("run.{}", q.key),
                    format!("= {}: expected a distance > 0 around the regions", q.value),
                );
            }
            let share = r.launch_profile_share.unwrap_or(0.3);
            if !(0.3..1.0).contains(&share) {
                return err(
                    "run.launch_profile_share",
                    format!(
                        "= {share}: expected the profile's share of the paths in [0.3, 1) (the rest start near the regions)"
                    ),
                );
            }
            Some(LaunchSettings { margin, profile_share: share })
        }
    };
    Ok(RunPlan {
        requested_samples: samples,
        batches,
        paths_per_batch,
        seed: r.seed.unwrap_or(1),
        threads: threads as usize,
        walk: WalkSettings {
            tracking,
            roulette_threshold,
            roulette_survival,
            max_events: max_events as u32,
            gate,
            reflections: match r.reflections.unwrap_or(ReflectionsKind::Auto) {
                ReflectionsKind::Auto => Reflections::Auto,
                ReflectionsKind::Deterministic => Reflections::Deterministic,
                ReflectionsKind::Sampled => Reflections::Sampled,
            },
            control_variate: match r.control_variate.unwrap_or(ControlVariateKind::Auto) {
                ControlVariateKind::Auto => ControlVariate::Auto,
                ControlVariateKind::Layered => ControlVariate::Layered,
                ControlVariateKind::Off => ControlVariate::Off,
            },
            launches,
        },
        memory_budget,
        memory_limited_by,
        camera_pixel_stride: 1,
        memory: Vec::new(),
        importance: match r.importance.unwrap_or(ImportanceKind::Off) {
            ImportanceKind::Off => Importance::Off,
            ImportanceKind::Table => Importance::Table,
            ImportanceKind::Windows => Importance::Windows,
            ImportanceKind::Guided => Importance::Guided,
            ImportanceKind::Auto => Importance::Auto,
        },
        importance_trace: None,
    })
}

/// The memory budget of `gib` GiB in bytes, never more than the process may still take (a
/// default of 8 GiB under `ulimit -v 2G` let an image be allocated until the allocator aborted):
/// a tighter limit lowers it, and is returned for the memory check to name.
pub fn lowered_budget(gib: f64) -> (u64, Option<&'static str>) {
    let configured = (gib * (1u64 << 30) as f64) as u64;
    match crate::sys::memory_limit() {
        Some(l) if l.available < configured => (l.available, Some(l.source)),
        _ => (configured, None),
    }
}

/// The key a memory refusal names: `run.memory_budget_gib`, and the limit that lowered it.
pub fn budget_key(limited_by: Option<&str>) -> String {
    match limited_by {
        Some(limit) => format!(
            "run.memory_budget_gib, lowered to {:.0} % of what {limit} leaves this process",
            100.0 * crate::sys::SHARE
        ),
        None => "run.memory_budget_gib".into(),
    }
}
