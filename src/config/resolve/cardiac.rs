//! `[cardiac]`: the heart rate and the waveforms pulsatile flows follow, and each population's
//! [`Pulse`] from its `velocity.waveform` and `motion.waveform`.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use super::{R, err, given, join, shown};
use crate::config::schema::{CardiacSection, VelocitySection, WaveformSection};
use crate::flow::VelocityField;
use crate::flow::pulse::{
    BLOOD_KINEMATIC_VISCOSITY, Cycle, DEFAULT_HARMONICS, FlowPulse, MAX_HARMONICS, MAX_WOMERSLEY, Pulse, Shape,
    Waveform, WomersleyTube,
};

/// The slowest and fastest heart rates accepted, bpm (a sleeping human's ≈ 40, a mouse's ≈ 600).
pub(super) const HEART_RATE_BPM: (f64, f64) = (1.0, 1200.0);

/// The resolved `[cardiac]` section.
#[derive(Debug, Clone)]
pub(super) struct Cardiac {
    /// Angular frequency, rad/s.
    pub omega: f64,
    /// Kinematic viscosity of blood, m²/s.
    pub nu: f64,
    /// Each waveform, delayed.
    pub waveforms: BTreeMap<String, Arc<Waveform>>,
    /// `frozen_at_ms`: every flow steady at this time of the cycle, s.
    pub frozen_at: Option<f64>,
}

pub(super) fn resolve_cardiac(c: Option<&CardiacSection>, base: &Path) -> R<Option<Cardiac>> {
    let Some(c) = c else { return Ok(None) };
    let path = "cardiac";
    let Some(bpm) = c.heart_rate_bpm else {
        return err(path, "missing heart_rate_bpm: the heart rate every pulsatile flow shares, beats per minute");
    };
    let (lo, hi) = HEART_RATE_BPM;
    if !(bpm.is_finite() && (lo..=hi).contains(&bpm)) {
        return err(
            join(path, "heart_rate_bpm"),
            format!("= {}: expected a heart rate in [{lo}, {hi}] beats per minute", shown(bpm)),
        );
    }
    let omega = std::f64::consts::TAU * bpm / 60.0;
    let nu = match given(path, &c.kinematic_viscosity)? {
        None => BLOOD_KINEMATIC_VISCOSITY,
        Some((v, _, _)) if v.is_finite() && v > 0.0 && v <= 1e-3 => v,
        Some((_, key, written)) => {
            return err(
                key,
                format!(
                    "= {}: expected a kinematic viscosity in (0, 10⁻³] m²/s (blood: ≈ 3.3·10⁻⁶ m²/s)",
                    shown(written)
                ),
            );
        }
    };
    if c.waveforms.is_empty() {
        return err(join(path, "waveforms"), "is empty: name at least one waveform ([cardiac.waveforms.NAME])");
    }
    let mut waveforms = BTreeMap::new();
    for (name, w) in &c.waveforms {
        let wpath = format!("{path}.waveforms.{name}");
        let wave = resolve_waveform(&wpath, w, base, 60.0 / bpm)?;
        let delay = match given(&wpath, &w.delay)? {
            None => 0.0,
            Some((d, _, _)) if d.is_finite() && d.abs() <= 1e4 => d,
            Some((_, key, written)) => {
                return err(key, format!("= {}: expected a delay of at most 10⁴ s either way", shown(written)));
            }
        };
        waveforms.insert(name.clone(), Arc::new(wave.delayed(delay, omega).trimmed()));
    }
    let frozen_at = match given(path, &c.frozen_at)? {
        None => None,
        Some((t, _, _)) if t.is_finite() && t.abs() <= 1e4 => Some(t),
        Some((_, key, written)) => {
            return err(key, format!("= {}: expected a time of at most 10⁴ s either way", shown(written)));
        }
    };
    Ok(Some(Cardiac { omega, nu, waveforms, frozen_at }))
}

/// One waveform from exactly one of its four forms; `period` in s.
fn resolve_waveform(path: &str, w: &WaveformSection, base: &Path, period: f64) -> R<Waveform> {
    let given = [
        ("shape", w.shape.is_some()),
        ("fourier", w.fourier.is_some()),
        ("samples", w.samples.is_some()),
        ("table", w.table.is_some()),
    ];
    let forms: Vec<&str> = given.iter().filter(|g| g.1).map(|g| g.0).collect();
    if forms.len() != 1 {
        return err(
            path,
            format!(
                "give exactly one of shape, fourier, samples, table (given: {})",
                if forms.is_empty() { "none".to_string() } else { forms.join(", ") }
            ),
        );
    }
    let harmonics = match w.harmonics {
        None => None,
        Some(k) if (1..=MAX_HARMONICS as i64).contains(&k) => Some(k as usize),
        Some(k) => {
            return err(
                join(path, "harmonics"),
                format!("= {k}: expected 1 to {MAX_HARMONICS} harmonics (each costs every path two numbers)"),
            );
        }
    };
    if w.resistivity_index.is_some() && w.shape.is_none() {
        return err(join(path, "resistivity_index"), "applies to a built-in shape only: remove it or give shape");
    }
    let k = harmonics.unwrap_or(DEFAULT_HARMONICS);
    let wave = if let Some(name) = &w.shape {
        let Some(shape) = Shape::from_name(name) else {
            return err(join(path, "shape"), format!("= \"{name}\": expected one of {}", Shape::NAMES.join(", ")));
        };
        let ri = w.resistivity_index.unwrap_or(shape.default_resistivity_index());
        if !(ri.is_finite() && (0.0..1.0).contains(&ri)) {
            return err(
                join(path, "resistivity_index"),
                format!("= {}: expected (max − min)/max in [0, 1) (1 would stop the flow)", shown(ri)),
            );
        }
        Waveform::built_in(shape, ri, k)
    } else if let Some(pairs) = &w.fourier {
        if pairs.is_empty() || pairs.len() > MAX_HARMONICS {
            return err(
                join(path, "fourier"),
                format!("has {} pairs: expected 1 to {MAX_HARMONICS} [a_k, b_k] pairs", pairs.len()),
            );
        }
        if let Some(i) = pairs.iter().position(|p| !(p[0].is_finite() && p[1].is_finite())) {
            return err(join(path, "fourier"), format!("pair {i} is not finite"));
        }
        if harmonics.is_some_and(|h| h != pairs.len()) {
            return err(join(path, "harmonics"), "is the number of fourier pairs given: remove it");
        }
        Waveform::from_fourier(pairs)
    } else if let Some(v) = &w.samples {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return err(join(path, "samples"), format!("sample {i} is not finite"));
        }
        Waveform::from_samples(v, k).or_else(|e| err(join(path, "samples"), e.to_string()))?
    } else {
        let file = w.table.as_deref().expect("one form is given");
        let values = crate::io::formats::waveform::read_table(&base.join(file), period)
            .or_else(|m| err(join(path, "table"), format!("{file}: {m}")))?;
        Waveform::from_samples(&values, k).or_else(|e| err(join(path, "table"), format!("{file}: {e}")))?
    };
    Ok(wave)
}

/// The pulse of a population whose flow is `field` (from the velocity section `velocity` at key
/// `vpath`) and whose motion section (at `mpath`) names `motion_waveform`, with a dispersion
/// `dispersion` (m/s).
pub(super) fn resolve_pulse(
    cardiac: Option<&Cardiac>,
    velocity: Option<(&str, &VelocitySection)>,
    field: &VelocityField,
    motion: Option<(&str, Option<&str>)>,
    dispersion: f64,
) -> R<Pulse> {
    let mut pulse = Pulse::default();
    let lookup = |key: String, name: &str| -> R<Arc<Waveform>> {
        let Some(c) = cardiac else {
            return err(key, format!("= \"{name}\": no [cardiac] section gives the heart rate and the waveforms"));
        };
        match c.waveforms.get(name) {
            Some(w) => Ok(w.clone()),
            None => err(
                key,
                format!(
                    "= \"{name}\": not a waveform of [cardiac.waveforms]; expected one of {}",
                    crate::error::list(c.waveforms.keys())
                ),
            ),
        }
    };
    if let Some((vpath, v)) = velocity {
        let (waveform, womersley) = velocity_pulse_keys(v);
        if let Some(name) = waveform {
            let w = lookup(join(vpath, "waveform"), name)?;
            pulse.flow = Some(if womersley == Some(true) {
                let VelocityField::Poiseuille { origin, axis, radius, v_max } = *field else {
                    unreachable!("womersley is a key of the Poiseuille section only")
                };
                let c = cardiac.expect("looked up");
                let alpha = radius * (c.omega / c.nu).sqrt();
                let top = alpha * (w.harmonics.len() as f64).sqrt();
                if top > MAX_WOMERSLEY {
                    return err(
                        join(vpath, "womersley"),
                        format!(
                            "the tube's highest harmonic has a Womersley number {} (R·√(kω/ν) with R = {} m): expected at most {MAX_WOMERSLEY}; keep fewer harmonics",
                            shown(top),
                            shown(radius)
                        ),
                    );
                }
                FlowPulse::Womersley(Arc::new(WomersleyTube::new(origin, axis, radius, (v_max, c.omega), alpha, &w)))
            } else {
                FlowPulse::Separable(w)
            });
        } else if womersley == Some(true) {
            return err(join(vpath, "womersley"), "needs a waveform: give waveform = \"NAME\" of [cardiac.waveforms]");
        }
    }
    if let Some((mpath, Some(name))) = motion {
        if dispersion <= 0.0 {
            return err(
                join(mpath, "waveform"),
                "pulses the random velocity dispersion: give dispersion_mm_per_s > 0 (its cycle mean)",
            );
        }
        pulse.dispersion = Some(lookup(join(mpath, "waveform"), name)?);
    }
    Ok(pulse)
}

/// A velocity section's `waveform` and `womersley` keys.
fn velocity_pulse_keys(v: &VelocitySection) -> (Option<&str>, Option<bool>) {
    match v {
        VelocitySection::None {} => (None, None),
        VelocitySection::Poiseuille { waveform, womersley, .. } => (waveform.as_deref(), *womersley),
        VelocitySection::Uniform { waveform, .. }
        | VelocitySection::RandomDirection { waveform, .. }
        | VelocitySection::Wind { waveform }
        | VelocitySection::TerminalFall { waveform }
        | VelocitySection::Vdb { waveform, .. }
        | VelocitySection::Npy { waveform, .. } => (waveform.as_deref(), None),
    }
}

/// The scene's cycle: the heart rate and the most harmonics any of its populations carries
/// (`None` if nothing pulses).
pub(super) fn scene_cycle(cardiac: Option<&Cardiac>, scene: &crate::medium::Scene) -> Option<Cycle> {
    let c = cardiac?;
    let harmonics = scene.media.iter().flat_map(|m| m.populations().iter()).map(|p| p.pulse.harmonics()).max()?;
    (harmonics > 0).then_some(Cycle { omega: c.omega, harmonics })
}

/// What a run of a scene whose flows pulse cannot do yet (its forward paths carry the harmonics;
/// camera paths, the layered twin, split copies and the walks compiled for a volume tally, a time
/// gate or a box phantom do not): each refused with its key.
pub(super) fn check_pulsatile_run(
    f: &crate::config::schema::ExperimentFile,
    plan: &crate::experiment::RunPlan,
    detectors: &[crate::detect::Detector],
) -> R<()> {
    use crate::detect::EstimatorChoice;
    let why = "with flows that pulse ([cardiac]), whose harmonics only forward paths carry yet";
    if let Some(i) = detectors.iter().position(|d| d.surface().is_some_and(|s| s.choice != EstimatorChoice::Forward)) {
        return err(format!("detectors[{i}].estimator"), format!("{why}: use estimator = \"forward\""));
    }
    if f.volume.is_some() {
        return err("volume", format!("a volume tally is not scored {why}: remove [volume]"));
    }
    if f.lateral.is_some() {
        return err("lateral", format!("a box phantom is not traced {why}: remove [lateral]"));
    }
    if plan.walk.gate.is_some() {
        return err("run.time_gate_ns", format!("a time gate is not applied {why}: remove it"));
    }
    if f.source.chirp.is_some() {
        return err("source.chirp", format!("a chirp is not traced {why}: remove it"));
    }
    Ok(())
}

/// A population whose velocities pulse as `pulse`, frozen at `[cardiac] frozen_at_ms` if given:
/// its flow and dispersion then (a separable flow scaled by its waveform's value, a Womersley tube
/// as its profile then), steady. Unchanged otherwise.
pub(super) fn frozen(
    cardiac: Option<&Cardiac>,
    pulse: Pulse,
    field: VelocityField,
    motion: crate::medium::Motion,
) -> (Pulse, VelocityField, crate::medium::Motion) {
    let Some((c, t)) = cardiac.and_then(|c| c.frozen_at.map(|t| (c, t))) else { return (pulse, field, motion) };
    let field = match &pulse.flow {
        None => field,
        Some(FlowPulse::Separable(w)) => field.scaled(w.value(c.omega, t)),
        Some(FlowPulse::Womersley(tube)) => VelocityField::Womersley { tube: tube.clone(), t },
    };
    let motion = match &pulse.dispersion {
        None => motion,
        // A Gaussian dispersion's sign is no matter: its spread is |s(t)| times the mean's.
        Some(w) => crate::medium::Motion { dispersion: motion.dispersion * w.value(c.omega, t).abs(), ..motion },
    };
    (Pulse::default(), field, motion)
}
