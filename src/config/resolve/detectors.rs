//! `[[detectors]]`: areas, spectra, images, LDH cameras and lidar receivers.

use glam::DVec3;

use super::{
    Given, R, err, factor, given, given_arr, join, last, non_negative, positive, require, require_arr, shown,
    unit_vector,
};
use crate::config::schema::*;
use crate::config::units::unit_of;
use crate::config::units::{Delay, Length, Quantity, UnitSet};
use crate::detect::ldh::Acquisition;
use crate::detect::{
    Area, CorrelationSpec, Detector, DetectorKind, EstimatorChoice, ImageSpec, LdhOptions, LdhSpec, LidarSpec, Part,
    Roi, Side, SpeckleSpec, SpectrumSpec, Surface, TimeSpec, image::Footprints,
};
use crate::error::ConfigError;
use crate::medium::Scene;
use crate::source::Source;
use crate::spectrum::{FrequencyAxis, Stft, Window};

/// Longest detector or ROI name: the longest file they name adds ~40 characters to both
/// (`NAME_roi_ROI_speckle_algorithm1.npy`, `NAME_up_spectrum_by_doppler_events_stderr.npy`, and a
/// temporary `.NAME….tmp-PID` while written), within the 255 bytes a file name may have on
/// common file systems.
pub const MAX_NAME: usize = 64;

/// `name` names output files: a non-empty word of letters, digits, `_` and `-`, at most
/// [`MAX_NAME`] long (checked here, before a run, not when its files are written).
fn file_name(path: &str, name: &str) -> R<()> {
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        return err(
            join(path, "name"),
            format!("= \"{name}\": expected a non-empty name of letters, digits, _ and - (it names output files)"),
        );
    }
    if name.len() > MAX_NAME {
        return err(
            join(path, "name"),
            format!(
                "= \"{}…\" ({} characters): expected at most {MAX_NAME} (it names output files)",
                &name[..16],
                name.len()
            ),
        );
    }
    Ok(())
}

/// A rectangle of the detector plane from `center` (default the origin) and `size`: its
/// `(min, max)` corners.
fn rectangle(
    path: &str,
    center: &Option<Quantity<Length, [f64; 2]>>,
    size: &Option<Quantity<Length, [f64; 2]>>,
) -> R<([f64; 2], [f64; 2])> {
    let c = given_arr(path, center)?.map_or([0.0; 2], |c| c.0);
    let (s, sp) = require_arr(path, "size", size, "size")?;
    if s.iter().any(|&x| x <= 0.0) {
        return err(sp, format!("= {s:?} m: expected two edge lengths > 0"));
    }
    Ok(([c[0] - 0.5 * s[0], c[1] - 0.5 * s[1]], [c[0] + 0.5 * s[0], c[1] + 0.5 * s[1]]))
}

/// `bins` equal bins over `[lo, hi)` (the SI values of two keys; `bins_key` the key of the count),
/// with every number derived from it finite (issue 33, item 8: edges of ±1.7e308 Hz made an
/// infinite bin width, an axis of infinite bin centres and a spectrum of zeros): the span
/// `hi − lo` (and with it the bin width and the centres), the bins per unit, and bins wide enough
/// that their edges are distinct numbers. `reversed`: the message for `hi ≤ lo`.
fn checked_axis(
    lo: &Given,
    hi: &Given,
    bins: u64,
    bins_key: &str,
    reversed: impl FnOnce() -> String,
) -> R<FrequencyAxis> {
    let (lo_unit, hi_unit) = (unit_of(&lo.1), unit_of(&hi.1));
    if lo.0 < hi.0 && !(hi.0 - lo.0).is_finite() {
        return err(
            hi.1.clone(),
            format!(
                "= {} {hi_unit}: expected {} − {} ({} = {} {lo_unit}) of at most {} {hi_unit}, the largest finite number (the bin width and the bin centres are computed from it)",
                shown(hi.2),
                last(&hi.1),
                last(&lo.1),
                last(&lo.1),
                shown(lo.2),
                shown(f64::MAX / factor(&hi.1))
            ),
        );
    }
    let span = hi.0 - lo.0;
    let width = span / bins as f64;
    if lo.0 < hi.0 && !(lo.0 + width > lo.0 && hi.0 - width < hi.0 && (bins as f64 / span).is_finite()) {
        return err(
            bins_key,
            format!(
                "= {bins}: bins over [{} {lo_unit}, {} {hi_unit}] would be {} {hi_unit} wide, too narrow for their edges to be distinct numbers: expected fewer bins or a wider axis",
                shown(lo.2),
                shown(hi.2),
                shown(width / factor(&hi.1))
            ),
        );
    }
    FrequencyAxis::new(lo.0, hi.0, bins as usize).ok_or_else(|| ConfigError::new(hi.1.clone(), reversed()))
}

/// Defaults of an LDH camera: Kim et al. 2025's replica of Puyo et al. 2018 (39 kHz, N_w = 512)
/// with HoloDoppler's M0 band (6–18.3 kHz); see `media/references.md` §A4.
pub const LDH_DEFAULT_FRAME_RATE_HZ: f64 = 39_000.0;
pub const LDH_DEFAULT_WINDOW_SAMPLES: u64 = 512;
pub const LDH_DEFAULT_BAND_HZ: [f64; 2] = [6_000.0, 18_300.0];
pub const LDH_DEFAULT_SPECKLE_WINDOWS: u64 = 16;

fn resolve_ldh(path: &str, l: &LdhSection, im: &ImageSpec, scene: &Scene) -> R<LdhSpec> {
    let rate = given(path, &l.frame_rate)?;
    let fs = rate.clone().map_or(Ok(LDH_DEFAULT_FRAME_RATE_HZ), |v| positive(v, "a camera frame rate"))?;
    let n = l.window_samples.unwrap_or(LDH_DEFAULT_WINDOW_SAMPLES);
    if !(2..=1 << 20).contains(&n) || n % 2 != 0 {
        return err(join(path, "window_samples"), format!("= {n}: expected an even number of samples from 2 to 2^20"));
    }
    // Every number derived from the rate finite and non-zero (issue 33, item 8): the frame period
    // 1/f_s, the STFT bin f_s/N and the default spectrum axis, N + 1 bins of it centred on DC.
    let half = (0.5 * n as f64 + 0.5) * (fs / n as f64);
    let default_axis = FrequencyAxis::new(-half, half, n as usize + 1);
    if !((1.0 / fs).is_finite() && fs / n as f64 >= f64::MIN_POSITIVE) || default_axis.is_none() {
        let (key, written) = rate.map_or((join(path, "frame_rate_hz"), fs), |r| (r.1, r.2));
        let f = factor(&key);
        let (lo, hi) = (n as f64 * f64::MIN_POSITIVE, f64::MAX / (1.0 + 1.0 / n as f64));
        return err(
            &key,
            format!(
                "= {} {}: expected a frame rate from {} to {} {} with window_samples = {n} (the frame period 1/f_s, the STFT bin f_s/N and the spectrum's N + 1 bins must be finite and non-zero)",
                shown(written),
                unit_of(&key),
                shown(lo / f),
                shown(hi / f),
                unit_of(&key)
            ),
        );
    }
    let window = match l.window.unwrap_or(WindowKind::Hann) {
        WindowKind::Rect => Window::Rect,
        WindowKind::Hann => Window::Hann,
    };
    let stft = Stft::new(fs, n as usize, window)
        .ok_or_else(|| ConfigError::new(join(path, "frame_rate_hz"), format!("= {fs}: expected a finite rate > 0")))?;
    let (band, band_path) = given_arr(path, &l.band)?.unwrap_or((LDH_DEFAULT_BAND_HZ, join(path, "band_hz")));
    let nyquist = 0.5 * fs;
    if !(0.0 < band[0] && band[0] < band[1] && band[1] <= nyquist) {
        let unit = unit_of(&band_path);
        return err(
            band_path,
            format!(
                "= {:?} {}: expected 0 < f1 < f2 ≤ f_s/2 = {nyquist} Hz (the camera's Nyquist frequency)",
                l.band.as_ref().map_or(band, |q| q.value),
                unit
            ),
        );
    }
    let bin = stft.bin_width();
    let axis = match &l.spectrum {
        // The STFT's own frequencies, odd-centred on DC: N_w + 1 bins of f_s/N_w. Also the
        // per-pixel speckle's: each bin centre is an STFT frequency, so counting a path at its
        // bin centre moves it by at most half an STFT bin, and the expected periodogram of a
        // pixel is two FFTs (the +f_s/2 bin folds onto −f_s/2).
        None => default_axis.expect("checked with the frame rate"),
        Some(s) => {
            let p = join(path, "spectrum");
            let fmin = require(&p, "f_min", &s.f_min, "the lower edge")?;
            let fmax = require(&p, "f_max", &s.f_max, "the upper edge")?;
            let bins = s.bins.unwrap_or(n + 1);
            if !(1..=1_000_000).contains(&bins) {
                return err(join(&p, "bins"), format!("= {bins}: expected 1 to 10^6 bins"));
            }
            checked_axis(&fmin, &fmax, bins, &join(&p, "bins"), || {
                format!("= {} Hz: expected f_min ({} Hz) < f_max", fmax.0, fmin.0)
            })?
        }
    };
    let mut rois: Vec<Roi> = Vec::new();
    for (i, r) in l.roi.iter().enumerate() {
        let p = format!("{path}.roi[{i}]");
        file_name(&p, &r.name)?;
        if rois.iter().any(|o| o.name == r.name) {
            return err(join(&p, "name"), format!("= \"{}\": ROI names must be unique", r.name));
        }
        let (min, max) = rectangle(&p, &r.center, &r.size)?;
        let roi = Roi { name: r.name.clone(), min, max };
        let inside = |x: f64, y: f64| im.min[0] <= x && x <= im.max[0] && im.min[1] <= y && y <= im.max[1];
        if !(inside(roi.min[0], roi.min[1]) && inside(roi.max[0], roi.max[1])) {
            return err(
                p,
                format!(
                    "the ROI spans x {:?}, y {:?} m, not inside the image (x {:?}, y {:?} m)",
                    [roi.min[0], roi.max[0]],
                    [roi.min[1], roi.max[1]],
                    [im.min[0], im.max[0]],
                    [im.min[1], im.max[1]]
                ),
            );
        }
        rois.push(roi);
    }
    let pixel_spectra = l.pixel_spectra.unwrap_or(false);
    let speckle = match &l.speckle {
        None => None,
        Some(sp) => {
            let pixels = sp.pixels.unwrap_or(false);
            if pixels && !pixel_spectra {
                return err(
                    join(path, "speckle.pixels"),
                    format!(
                        "= true: per-pixel speckle is drawn from the per-pixel spectra: set {} = true",
                        join(path, "pixel_spectra")
                    ),
                );
            }
            if rois.is_empty() && !pixels {
                return err(
                    join(path, "speckle"),
                    "speckle is synthesised for ROIs: add [[detectors.ldh.roi]] entries (or set speckle.pixels = true \
                     for every pixel)",
                );
            }
            let w = sp.windows.unwrap_or(LDH_DEFAULT_SPECKLE_WINDOWS);
            if !(1..=1_000_000).contains(&w) {
                return err(join(path, "speckle.windows"), format!("= {w}: expected 1 to 10^6 windows"));
            }
            Some(SpeckleSpec { windows: w as u32, pixels })
        }
    };
    let acquisition = match &l.acquisition {
        None => None,
        Some(a) => Some(resolve_acquisition(&join(path, "acquisition"), a, &stft, scene)?),
    };
    let options = LdhOptions {
        acquisition,
        flip_sign: l.flip_sign.unwrap_or(false),
        m1: l.m1.unwrap_or(false),
        moments: l.moments.unwrap_or(false),
        by_class: l.by_class.unwrap_or(false),
        rois,
        spectrum_axis: axis,
        pixel_spectra,
        speckle,
    };
    LdhSpec::new(stft, (band[0], band[1]), options).ok_or_else(|| {
        ConfigError::new(
            join(path, "band_hz"),
            format!("= [{}, {}] Hz holds no STFT bin (bins are {bin} Hz wide): widen the band", band[0], band[1]),
        )
    })
}

/// The most windows an acquisition holds (HoloDoppler's 1.6 ms windows over 10 cycles at
/// 70 bpm are ≈ 5,000).
const MAX_WINDOWS: usize = 100_000;

/// `[detectors.ldh.acquisition]` on the camera's STFT, in a scene whose flows pulse.
fn resolve_acquisition(path: &str, a: &AcquisitionSection, stft: &Stft, scene: &Scene) -> R<Acquisition> {
    let Some(cycle) = scene.cycle else {
        return err(
            path,
            "windows over the cardiac cycle need flows that pulse: give [cardiac] and a velocity.waveform (or motion.waveform) on a moving medium",
        );
    };
    let (rate, samples) = (stft.sample_rate(), stft.samples());
    let hop = a.hop_samples.unwrap_or(samples as u64);
    if !(1..=1 << 32).contains(&hop) {
        return err(join(path, "hop_samples"), format!("= {hop}: expected 1 to 2^32 frames between windows"));
    }
    let (duration, duration_key) = match given(path, &a.duration)? {
        None => (cycle.period(), join(path, "duration_s")),
        Some((d, key, _)) if d.is_finite() && d > 0.0 && d <= 1e4 => (d, key),
        Some((_, key, written)) => {
            return err(key, format!("= {}: expected a duration in (0, 10^4] s", shown(written)));
        }
    };
    let start = acquisition_start(path, &a.start)?;
    let window = samples as f64 / rate;
    let windows = ((duration * rate - samples as f64) / hop as f64).floor() + 1.0;
    if duration < window {
        return err(
            duration_key,
            format!(
                "= {} s: shorter than one window ({samples} frames at {} Hz = {} s): lengthen the acquisition or shorten detectors.ldh.window_samples",
                shown(duration),
                shown(rate),
                shown(window)
            ),
        );
    }
    if windows > MAX_WINDOWS as f64 {
        return err(
            join(path, "hop_samples"),
            format!("= {hop}: {windows} windows over {} s, expected at most {MAX_WINDOWS}", shown(duration)),
        );
    }
    let acq = Acquisition::new(&cycle, window, hop as f64 / rate, start, duration).expect("one window fits");
    Ok(acq.with_waveforms(scene))
}

/// An acquisition's `start_ms` (s; 0 by default), at most 10⁴ s either way.
fn acquisition_start(path: &str, q: &Option<Quantity<Delay>>) -> R<f64> {
    match given(path, q)? {
        None => Ok(0.0),
        Some((s, _, _)) if s.is_finite() && s.abs() <= 1e4 => Ok(s),
        Some((_, key, written)) => {
            err(key, format!("= {}: expected a start of at most 10⁴ s either way", shown(written)))
        }
    }
}

/// `[detectors.spectrum.acquisition]`: spectra in windows over the cardiac cycle (laser Doppler
/// flowmetry's), in a scene whose flows pulse.
fn resolve_spectrum_acquisition(path: &str, a: &SpectrumAcquisitionSection, scene: &Scene) -> R<Acquisition> {
    let Some(cycle) = scene.cycle else {
        return err(
            path,
            "windows over the cardiac cycle need flows that pulse: give [cardiac] and a velocity.waveform (or motion.waveform) on a moving medium",
        );
    };
    let time = |q: &Option<Quantity<Delay>>, name: &str, default: Option<f64>| -> R<(f64, String)> {
        match given(path, q)? {
            None => match default {
                Some(d) => Ok((d, join(path, name))),
                None => err(path, format!("missing {name}: give one of {}", Delay::keys(name).join(", "))),
            },
            Some((v, key, _)) if v.is_finite() && v > 0.0 && v <= 1e4 => Ok((v, key)),
            Some((_, key, written)) => err(key, format!("= {}: expected a time in (0, 10^4] s", shown(written))),
        }
    };
    let (window, _) = time(&a.window, "window", None)?;
    let (hop, hop_key) = time(&a.hop, "hop", Some(window))?;
    let (duration, duration_key) = time(&a.duration, "duration", Some(cycle.period()))?;
    let start = acquisition_start(path, &a.start)?;
    if duration < window {
        return err(
            duration_key,
            format!(
                "= {} s: shorter than one window ({} s): lengthen the acquisition or shorten the window",
                shown(duration),
                shown(window)
            ),
        );
    }
    let windows = ((duration - window) / hop).floor() + 1.0;
    if windows > MAX_WINDOWS as f64 {
        return err(hop_key, format!("= {} s: {windows} windows, expected at most {MAX_WINDOWS}", shown(hop)));
    }
    let acq = Acquisition::new(&cycle, window, hop, start, duration).expect("one window fits");
    Ok(acq.with_waveforms(scene))
}

/// A monostatic lidar receiver at the source. Its local estimate traces straight shadow rays, so
/// every index in the scene must be 1 (the atmosphere; 1.0003 is within the model's accuracy).
/// Accepted pulse FWHM of a lidar, s: 1 ps to 1 ms (coherent wind lidars use 0.1–1 µs).
const LIDAR_PULSE_FWHM: (f64, f64) = (1e-12, 1e-3);
/// Accepted digitiser rate of a lidar, Hz: 1 MHz to 100 GHz (wind lidars sample at 50 MHz–1 GHz).
const LIDAR_SAMPLE_RATE: (f64, f64) = (1e6, 1e11);
/// Accepted range of the first gate, m: 0 to 10⁸ m (a satellite lidar looks down from 10⁶ m).
const LIDAR_FIRST_GATE: (f64, f64) = (0.0, 1e8);
/// Accepted pulse energy, J: 1 pJ to 1 kJ (wind lidars: µJ to J).
const LIDAR_PULSE_ENERGY: (f64, f64) = (1e-12, 1e3);

/// `v` if it lies in `[lo, hi]` (SI), else an error naming the key, the value as written and the
/// range in the key's unit.
fn within(v: Given, (lo, hi): (f64, f64), what: &str) -> R<f64> {
    if v.0.is_finite() && (lo..=hi).contains(&v.0) {
        return Ok(v.0);
    }
    let unit = unit_of(&v.1);
    let factor = crate::config::units::split_key(&v.1).map_or(1.0, |(_, u)| u.factor);
    let (lo, hi) = (shown(lo / factor), shown(hi / factor));
    err(v.1, format!("= {} {unit}: expected {what} in [{lo}, {hi}] {unit}", shown(v.2)))
}

pub(super) fn resolve_lidar(path: &str, l: &LidarSection, source: &Source, scene: &Scene) -> R<LidarSpec> {
    if scene.n_above != 1.0 {
        return err("ambient.n_above", format!("= {}: a lidar receiver needs n = 1 above the stack", scene.n_above));
    }
    if let Some((i, layer)) = scene.layers.iter().enumerate().find(|(_, l)| l.n != 1.0) {
        return err(
            format!("layers[{i}].n"),
            format!("= {}: a lidar receiver traces straight rays and needs n = 1 in every layer", layer.n),
        );
    }
    let radius =
        positive(require(path, "aperture_radius", &l.aperture_radius, "the aperture radius")?, "an aperture radius")?;
    let fov = require(path, "field_of_view", &l.field_of_view, "the field-of-view half-angle")?;
    if !(fov.0 > 0.0 && fov.0 <= std::f64::consts::FRAC_PI_2) {
        return err(fov.1, format!("= {}: expected a half-angle in (0, 90°]", fov.2));
    }
    // The ranges below keep every derived quantity (sample times, the range axis, the pulse's
    // samples, the shot-noise floor) finite and the receiver a lidar's (issue 21: a sample rate of
    // 1e-200 MHz or a first gate at 1e308 m wrote NaN and infinite axes).
    let fwhm = within(require(path, "pulse_fwhm", &l.pulse_fwhm, "the pulse FWHM")?, LIDAR_PULSE_FWHM, "a pulse FWHM")?;
    let rate = within(
        require(path, "sample_rate", &l.sample_rate, "the digitiser rate")?,
        LIDAR_SAMPLE_RATE,
        "a sample rate",
    )?;
    let first = match given(path, &l.first_gate)? {
        None => 0.0,
        Some(v) => within(v, LIDAR_FIRST_GATE, "a range")?,
    };
    let count = |key: &str, v: Option<u64>, default: u64, max: u64| -> R<usize> {
        let v = v.unwrap_or(default);
        if (1..=max).contains(&v) {
            Ok(v as usize)
        } else {
            err(join(path, key), format!("= {v}: expected 1 to {max}"))
        }
    };
    let gate_points = count("gate_points", l.gate_points, 10, 4096)?;
    let gates = count("gates", l.gates, 32, 100_000)?;
    let fft_points = count("fft_points", l.fft_points, gate_points.next_power_of_two().max(64) as u64, 65_536)?;
    if fft_points < gate_points {
        return err(join(path, "fft_points"), format!("= {fft_points}: expected at least gate_points ({gate_points})"));
    }
    if gates * fft_points > 20_000_000 {
        return err(join(path, "gates"), format!("= {gates}: gates × fft_points must stay below 2·10^7 (memory)"));
    }
    let pulse_energy = match given(path, &l.pulse_energy)? {
        Some(v) => within(v, LIDAR_PULSE_ENERGY, "a pulse energy")?,
        None => crate::detect::lidar::DEFAULT_PULSE_ENERGY,
    };
    let efficiency = |key: &str, v: Option<f64>, default: f64| -> R<f64> {
        match v {
            None => Ok(default),
            Some(v) if v > 0.0 && v <= 1.0 => Ok(v),
            Some(v) => err(join(path, key), format!("= {v}: expected an efficiency in (0, 1]")),
        }
    };
    let quantum_efficiency =
        efficiency("quantum_efficiency", l.quantum_efficiency, crate::detect::lidar::DEFAULT_QUANTUM_EFFICIENCY)?;
    let heterodyne_efficiency = efficiency(
        "heterodyne_efficiency",
        l.heterodyne_efficiency,
        crate::detect::lidar::DEFAULT_HETERODYNE_EFFICIENCY,
    )?;
    Ok(LidarSpec {
        position: source.position,
        axis: source.direction,
        aperture_radius: radius,
        cos_fov: fov.0.cos(),
        pulse_fwhm: fwhm,
        sample_rate: rate,
        first_sample_time: 2.0 * first / crate::SPEED_OF_LIGHT,
        gate_points,
        gates,
        fft_points,
        wavelength: source.wavelength,
        pulse_energy,
        quantum_efficiency,
        heterodyne_efficiency,
    })
}

/// The estimator of a surface detector (`estimator`, default `"forward"`): the camera-side one
/// ([`crate::transport::camera`]), and `"auto"` which may choose it, need a top detector, an
/// image (its paths are spread over the pixels) and a beam with a footprint.
fn resolve_estimator(
    path: &str,
    kind: Option<EstimatorKind>,
    side: Side,
    image: bool,
    source: &Source,
) -> R<EstimatorChoice> {
    let (estimator, name) = match kind {
        None | Some(EstimatorKind::Forward) => return Ok(EstimatorChoice::Forward),
        Some(EstimatorKind::Camera) => (EstimatorChoice::Camera, "camera"),
        Some(EstimatorKind::Footprints) => (EstimatorChoice::Footprints, "footprints"),
        Some(EstimatorKind::Auto) => (EstimatorChoice::Auto, "auto"),
    };
    let why_not = if side != Side::Top {
        "camera paths leave from a top detector (they enter the stack through z = 0)"
    } else if !image {
        "camera paths are spread over the detector's pixels: add [detectors.image] pixels = [nx, ny]"
    } else if !source.has_footprint() {
        "a pencil beam lights a line, which a camera path's connections reach with probability zero: use source.profile = \"disk\" or \"gaussian\""
    } else {
        return Ok(estimator);
    };
    err(join(path, "estimator"), format!("= \"{name}\": {why_not}"))
}

/// `[detectors.footprints] field_paths` by default.
pub const FIELD_DEFAULT_PATHS: u64 = 2_000_000;

/// The light field's pre-pass paths (`[detectors.footprints] light_field`, `field_paths`), `None`
/// without it; refused where the scene or the beam does not suit its table
/// (`FieldTable::check_scene`) or the path length is tracked (a chirp).
fn light_field(p: &str, f: &FootprintsSection, scene: &Scene, source: &Source) -> R<Option<u64>> {
    if !f.light_field.unwrap_or(false) {
        return match f.field_paths {
            Some(_) => err(join(p, "field_paths"), "is set, but light_field is not true"),
            None => Ok(None),
        };
    }
    let paths = f.field_paths.unwrap_or(FIELD_DEFAULT_PATHS);
    if !(10_000..=1_000_000_000).contains(&paths) {
        return err(join(p, "field_paths"), format!("= {paths}: expected 10⁴ to 10⁹ forward paths"));
    }
    if let Err((key, why)) = crate::transport::field::FieldTable::check_scene(scene, source) {
        return err(join(p, "light_field"), format!("= true, but {key} {why}"));
    }
    if source.chirp.is_some() {
        return err(
            join(p, "light_field"),
            "= true, but the source is chirped: the light field's table holds no path lengths",
        );
    }
    Ok(Some(paths))
}

/// `[detectors.footprints] halo_um` by default, m.
pub const FOOTPRINT_DEFAULT_HALO_M: f64 = 20e-6;

/// The widest halo, in pixel pitches.
pub const FOOTPRINT_MAX_HALO_PIXELS: f64 = 64.0;

/// The camera pixels of `estimator = "footprints"` ([`Footprints`]), `None` for any other
/// estimator (where `[detectors.footprints]` is refused). The image's maps and ROIs are what it
/// covers: refused beside a spectrum, time or correlation part or per-pixel spectra, which the
/// two kinds of path would each estimate over a part of the area.
fn resolve_footprints(
    path: &str,
    d: &DetectorSection,
    choice: EstimatorChoice,
    (scene, source): (&Scene, &Source),
    parts: &[Option<Part>; 5],
) -> R<Option<std::sync::Arc<Footprints>>> {
    let p = join(path, "footprints");
    if choice != EstimatorChoice::Footprints {
        return match d.footprints {
            Some(_) => err(p, "is set, but the detector's estimator is not \"footprints\""),
            None => Ok(None),
        };
    }
    let f = d.footprints.clone().unwrap_or_default();
    let halo = match given(&p, &f.halo)? {
        None => FOOTPRINT_DEFAULT_HALO_M,
        Some(v) => non_negative(v, "a distance")?,
    };
    let camera_paths = f.camera_paths.unwrap_or(1.0);
    if !(camera_paths.is_finite() && (1e-3..=1e3).contains(&camera_paths)) {
        return err(
            join(&p, "camera_paths"),
            format!("= {camera_paths}: expected camera paths per forward path from 0.001 to 1000"),
        );
    }
    let light_field = light_field(&p, &f, scene, source)?;
    let mut im = None;
    let mut rois = Vec::new();
    for part in parts.iter().flatten() {
        match part {
            Part::Image(i) => im = Some(*i),
            Part::Ldh(l) if l.pixel_spectra => {
                return err(
                    join(path, "ldh.pixel_spectra"),
                    "= true: with estimator = \"footprints\" each pixel's light is one estimator's, which per-pixel spectra of both kinds of path would mix: remove one of them",
                );
            }
            Part::Ldh(l) => rois.extend(l.rois.iter().map(|r| (r.min, r.max))),
            other => {
                let name = match other {
                    Part::Spectrum(_) => "spectrum",
                    Part::Time(_) => "time",
                    _ => "correlation",
                };
                return err(
                    join(path, name),
                    format!(
                        "is set: estimator = \"footprints\" covers the image and its LDH maps and ROIs, not a {name}: estimate it with \"forward\" on a detector of its own"
                    ),
                );
            }
        }
    }
    let Some(im) = im else {
        return err(
            join(path, "estimator"),
            "= \"footprints\": camera paths leave from the image's pixels: add [detectors.image] pixels = [nx, ny]",
        );
    };
    // A few pixels' halo is what a vessel's light needs; a wide one is a camera estimator's job.
    let pitch = ((im.max[0] - im.min[0]) / im.nx as f64).min((im.max[1] - im.min[1]) / im.ny as f64);
    if halo > FOOTPRINT_MAX_HALO_PIXELS * pitch {
        let key = f.halo.as_ref().map_or_else(|| join(&p, "halo_um"), |q| join(&p, &q.key));
        return err(
            key,
            format!(
                "= {} µm: expected at most {FOOTPRINT_MAX_HALO_PIXELS} pixels' pitch ({} µm; use estimator = \"camera\" for a wider area)",
                shown(halo * 1e6),
                shown(FOOTPRINT_MAX_HALO_PIXELS * pitch * 1e6)
            ),
        );
    }
    let Some(mut fp) = Footprints::new(scene, &im, halo, &rois, camera_paths) else {
        return err(
            join(path, "estimator"),
            "= \"footprints\": no region of the scene lies under the image, and no ROI: nothing for camera paths to estimate (use \"forward\")",
        );
    };
    fp.light_field = light_field;
    Ok(Some(std::sync::Arc::new(fp)))
}

pub(super) fn resolve_detectors(ds: &[DetectorSection], scene: &Scene, source: &Source) -> R<Vec<Detector>> {
    let mut out: Vec<Detector> = Vec::new();
    for (i, d) in ds.iter().enumerate() {
        let path = format!("detectors[{i}]");
        file_name(&path, &d.name)?;
        if out.iter().any(|o| o.name == d.name) {
            return err(join(&path, "name"), format!("= \"{}\": detector names must be unique", d.name));
        }
        let side = match d.side.unwrap_or(SideKind::Top) {
            SideKind::Top => Side::Top,
            SideKind::Bottom => {
                if !scene.z_bottom().is_finite() {
                    return err(
                        join(&path, "side"),
                        "= \"bottom\": the stack ends in a semi-infinite layer, so nothing leaves through a bottom",
                    );
                }
                Side::Bottom
            }
        };
        let outward = if side == Side::Top { DVec3::NEG_Z } else { DVec3::Z };
        let monostatic = d.monostatic.unwrap_or(false);
        let axis = match d.axis {
            None if monostatic => {
                if side != Side::Top || source.direction.z <= 0.0 {
                    return err(
                        join(&path, "monostatic"),
                        "= true: a monostatic receiver looks back along the beam from above the stack: a top detector",
                    );
                }
                -source.direction
            }
            Some(_) if monostatic => {
                return err(
                    join(&path, "axis"),
                    "is set with monostatic = true, whose axis is the beam's reverse: remove one of them",
                );
            }
            None => outward,
            Some(a) => {
                let a = unit_vector(&join(&path, "axis"), a)?;
                if a.dot(outward) <= 0.0 {
                    return err(
                        join(&path, "axis"),
                        format!(
                            "= {:?}: must point away from the stack ({} z for a {} detector)",
                            d.axis.unwrap(),
                            if side == Side::Top { "negative" } else { "positive" },
                            if side == Side::Top { "top" } else { "bottom" }
                        ),
                    );
                }
                a
            }
        };
        // Degrees as written.
        let half = d.acceptance_half_angle.as_ref().map_or(90.0, |q| q.value);
        if !(half > 0.0 && half <= 90.0) {
            return err(
                join(&path, "acceptance_half_angle_deg"),
                format!("= {half}: expected a half-angle in (0, 90] degrees"),
            );
        }
        let distance = match given(&path, &d.distance)? {
            None => 0.0,
            Some(v) => non_negative(v, "a distance from the surface")?,
        };
        let area = match d.area.as_ref().unwrap_or(&AreaSection::All {}) {
            AreaSection::All {} => Area::All,
            AreaSection::Disk { center, radius } => {
                let p = join(&path, "area");
                let c = given_arr(&p, center)?.map_or([0.0; 2], |c| c.0);
                let r = positive(require(&p, "radius", radius, "radius")?, "a radius")?;
                Area::Disk { center: c, radius: r }
            }
            AreaSection::Rect { center, size } => {
                let (min, max) = rectangle(&join(&path, "area"), center, size)?;
                Area::Rect { min, max }
            }
            AreaSection::Annulus { center, inner_radius, outer_radius } => {
                let p = join(&path, "area");
                let c = given_arr(&p, center)?.map_or([0.0; 2], |c| c.0);
                let given_inner = require(&p, "inner_radius", inner_radius, "inner radius")?;
                let inner_key = given_inner.1.rsplit('.').next().unwrap_or("").to_string();
                let inner_value = given_inner.2;
                let inner = non_negative(given_inner, "an inner radius")?;
                let (o, op, ov) = require(&p, "outer_radius", outer_radius, "outer radius")?;
                if !(o.is_finite() && o > inner) {
                    let why =
                        format!("expected an outer radius > the inner radius ({inner_key} = {})", shown(inner_value));
                    return err(op, format!("= {}: {why}", shown(ov)));
                }
                Area::Annulus { center: c, inner, outer: o }
            }
        };
        let spectrum = match &d.spectrum {
            None => None,
            Some(s) => {
                let p = join(&path, "spectrum");
                let fmin = require(&p, "f_min", &s.f_min, "the lower edge of the frequency axis")?;
                let fmax = require(&p, "f_max", &s.f_max, "the upper edge of the frequency axis")?;
                let bins = s.bins.unwrap_or(256);
                if !(1..=10_000_000).contains(&bins) {
                    return err(join(&p, "bins"), format!("= {bins}: expected 1 to 10^7 bins"));
                }
                let axis = checked_axis(&fmin, &fmax, bins, &join(&p, "bins"), || {
                    format!("= {} Hz: expected finite edges with f_min ({} Hz) < f_max", fmax.0, fmin.0)
                })?;
                let split = |key: &str, v: Option<u64>| -> R<Option<u32>> {
                    match v {
                        None => Ok(None),
                        Some(k) if (1..=1000).contains(&k) => Ok(Some(k as u32)),
                        Some(k) => {
                            err(join(&p, key), format!("= {k}: expected K from 1 to 1000 (channels 0 … K−1 and ≥ K)"))
                        }
                    }
                };
                let acquisition = match &s.acquisition {
                    None => None,
                    Some(a) => Some(resolve_spectrum_acquisition(&join(&path, "spectrum.acquisition"), a, scene)?),
                };
                Some(SpectrumSpec {
                    axis,
                    by_order: split("by_order", s.by_order)?,
                    by_doppler_events: split("by_doppler_events", s.by_doppler_events)?,
                    acquisition,
                })
            }
        };
        let image = match &d.image {
            None => None,
            Some(im) => {
                let Some((min, max)) = area.bounds() else {
                    return err(
                        join(&path, "image"),
                        "an image needs a bounded detector area (area.type = \"disk\" or \"rect\")",
                    );
                };
                let [nx, ny] = im.pixels;
                if !(1..=16_384).contains(&nx) || !(1..=16_384).contains(&ny) {
                    return err(
                        join(&path, "image.pixels"),
                        format!("= {:?}: expected [nx, ny], each 1 to 16384", im.pixels),
                    );
                }
                // Pixel sizes and their inverses finite and non-zero (issue 33, item 8).
                let pixel_ok = |lo: f64, hi: f64, n: u64| {
                    let w = (hi - lo) / n as f64;
                    lo.is_finite()
                        && hi.is_finite()
                        && w.is_finite()
                        && lo + w > lo
                        && (n as f64 / (hi - lo)).is_finite()
                };
                if !(pixel_ok(min[0], max[0], nx) && pixel_ok(min[1], max[1], ny)) {
                    return err(
                        join(&path, "area"),
                        format!(
                            "spans x {:?}, y {:?} m: expected an image area whose extent and pixels ({nx} × {ny}) have a finite, non-zero size",
                            [min[0], max[0]],
                            [min[1], max[1]]
                        ),
                    );
                }
                Some(ImageSpec { nx: nx as usize, ny: ny as usize, min, max })
            }
        };
        let time = match &d.time {
            None => None,
            Some(t) => Some(resolve_time(&join(&path, "time"), t, image.is_some())?),
        };
        let correlation = match &d.correlation {
            None => None,
            Some(c) => Some(Box::new(resolve_correlation(&join(&path, "correlation"), c, image.is_some())?)),
        };
        let next_event = d.next_event.unwrap_or(false);
        if next_event && side != Side::Top {
            return err(
                join(&path, "next_event"),
                "= true: next-event estimation scores top detectors only (shadow rays leave through z = 0)",
            );
        }
        let choice = resolve_estimator(&path, d.estimator, side, image.is_some(), source)?;
        let ldh = match &d.ldh {
            None => None,
            Some(l) => {
                let p = join(&path, "ldh");
                let Some(im) = image else {
                    return err(
                        p,
                        "an LDH camera needs the detector's image (add [detectors.image] pixels = [nx, ny])",
                    );
                };
                if out.iter().any(|o| o.ldh().is_some()) {
                    return err(p, "only one detector may be an LDH camera");
                }
                Some(Box::new(resolve_ldh(&p, l, &im, scene)?))
            }
        };
        // Correlation on an LDH camera: also per ROI.
        let correlation = correlation.map(|mut c| {
            if let Some(l) = &ldh {
                c.rois = l.rois.clone();
            }
            c
        });
        // An LDH camera is scored by next-event estimation.
        let next_event = next_event || ldh.is_some();
        let parts = [
            spectrum.map(Part::Spectrum),
            image.map(Part::Image),
            time.map(Part::Time),
            correlation.map(Part::Correlation),
            ldh.map(Part::Ldh),
        ];
        let footprints = resolve_footprints(&path, d, choice, (scene, source), &parts)?;
        let surface = Surface {
            side,
            distance,
            area,
            axis,
            monostatic,
            cos_acceptance: if half >= 90.0 { 0.0 } else { half.to_radians().cos() },
            include_specular: d.include_specular.unwrap_or(true),
            next_event,
            parts: parts.into_iter().flatten().collect(),
            choice,
            footprints,
        };
        out.push(Detector { name: d.name.clone(), kind: DetectorKind::Surface(surface) });
    }
    Ok(out)
}

/// `[detectors.time]`: bins of the time of flight over `[t_min, t_max)`.
pub(super) fn resolve_time(p: &str, t: &TimeSection, has_image: bool) -> R<TimeSpec> {
    let t0g = require(p, "t_min", &t.t_min, "the start of the time axis")?;
    let t0 = non_negative(t0g.clone(), "a time of flight")?;
    let t1 = require(p, "t_max", &t.t_max, "the end of the time axis")?;
    let bins = t.bins.unwrap_or(100);
    if !(1..=1_000_000).contains(&bins) {
        return err(join(p, "bins"), format!("= {bins}: expected 1 to 10^6 bins"));
    }
    // The path lengths of the bins, c·t, finite (issue 33, item 8; a volume tally bins by them).
    let longest = f64::MAX / crate::SPEED_OF_LIGHT;
    if t1.0 > t0 && t1.0 > longest {
        let unit = unit_of(&t1.1);
        return err(
            t1.1.clone(),
            format!(
                "= {} {unit}: expected a time of flight of at most {} {unit} (its optical path length c·t must be a finite number)",
                shown(t1.2),
                shown(longest / factor(&t1.1))
            ),
        );
    }
    let axis = checked_axis(&t0g, &t1, bins, &join(p, "bins"), || {
        format!("= {} ns: expected t_max > t_min ({} ns)", shown(t1.2), t0 * 1e9)
    })?;
    let image = t.image.unwrap_or(false);
    if image && !has_image {
        return err(
            join(p, "image"),
            "= true: a time-gated image needs the detector's image (add [detectors.image] pixels = [nx, ny])",
        );
    }
    Ok(TimeSpec { axis, image })
}

/// `[detectors.correlation]`: log-spaced delays, β, exposure times.
fn resolve_correlation(p: &str, c: &CorrelationSection, has_image: bool) -> R<CorrelationSpec> {
    let tau_min_given = require(p, "tau_min", &c.tau_min, "the shortest delay")?;
    let tau_min = positive(tau_min_given.clone(), "a delay")?;
    let tau_max = require(p, "tau_max", &c.tau_max, "the longest delay")?;
    if !(tau_max.0.is_finite() && tau_max.0 > tau_min) {
        return err(
            tau_max.1,
            format!("= {}: expected a longest delay > tau_min ({} s)", shown(tau_max.2), shown(tau_min)),
        );
    }
    // The delays are log-spaced, τ_k = tau_min·exp(k·ln(tau_max/tau_min)/(points − 1)): the
    // ratio must be a finite number (issue 33, item 8: 1e-160 to 1e160 s, or tau_min = 5e-324 s,
    // passed `ohd check` and ended the run with non-finite delays). The key named is the delay
    // further from 1 s (in decades).
    if !(tau_max.0 / tau_min).is_finite() {
        let (key, value, other, other_value) = if -tau_min.log10() > tau_max.0.log10() {
            (&tau_min_given.1, tau_min_given.2, "tau_max", tau_max.0)
        } else {
            (&tau_max.1, tau_max.2, "tau_min", tau_min)
        };
        let unit = unit_of(key);
        return err(
            key.clone(),
            format!(
                "= {} {unit}: expected tau_max/tau_min of at most {} with {other} = {} s (the delays are log-spaced over ln(tau_max/tau_min), which must be finite)",
                shown(value),
                shown(f64::MAX),
                shown(other_value)
            ),
        );
    }
    let points = c.points.unwrap_or(64);
    if !(2..=10_000).contains(&points) {
        return err(join(p, "points"), format!("= {points}: expected 2 to 10^4 delays"));
    }
    let tau = crate::detect::correlation::log_spaced(tau_min, tau_max.0, points as usize);
    if !(tau.iter().all(|t| t.is_finite() && *t > 0.0) && tau.windows(2).all(|w| w[0] < w[1])) {
        return err(
            join(p, "points"),
            format!(
                "= {points}: the delays log-spaced from {} to {} s are not distinct finite numbers: expected fewer points or a wider range",
                shown(tau_min),
                shown(tau_max.0)
            ),
        );
    }
    let beta = c.beta.unwrap_or(1.0);
    if !(beta > 0.0 && beta <= 1.0) {
        return err(join(p, "beta"), format!("= {}: expected a coherence factor β in (0, 1]", shown(beta)));
    }
    let mut exposures = Vec::new();
    if let Some(q) = &c.exposures {
        let key = join(p, &q.key);
        for &v in &q.value {
            let t = v * q.unit.factor;
            if !(t > 0.0 && t <= tau_max.0 * (1.0 + 1e-12)) {
                return err(
                    key,
                    format!(
                        "= {:?}: expected exposure times in (0, tau_max = {} s] (K(T) needs g1 up to T)",
                        q.value,
                        shown(tau_max.0)
                    ),
                );
            }
            exposures.push(t.min(tau_max.0));
        }
    }
    let pixels = c.pixels.unwrap_or(false);
    if pixels && !has_image {
        return err(
            join(p, "pixels"),
            "= true: per-pixel correlation needs the detector's image (add [detectors.image] pixels = [nx, ny])",
        );
    }
    if pixels && exposures.is_empty() {
        return err(join(p, "pixels"), "= true: per pixel the speckle contrast is written: give exposures_ms");
    }
    Ok(CorrelationSpec { tau, beta, exposures, pixels, rois: Vec::new() })
}
