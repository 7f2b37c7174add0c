//! The laser Doppler holography (LDH) camera: power Doppler images M0± over a band, region-of-
//! interest (ROI) spectra, and the path records that speckle synthesis
//! ([`crate::post::speckle`]) needs.
//!
//! A camera pixel is an area of the retina's surface seen through the pupil (the detector's area
//! and acceptance cone); the camera samples the hologram at `f_s` and a short-time Fourier
//! transform of `N_w` samples with a window `w` gives each pixel's spectrum. The expected
//! periodogram of a path's line at `f` (Lorentzian half-width `γ`) is the window kernel
//! `K(ν_k − f, γ)` (Kim et al. 2025 Eq. 28, `S ∗ |W|²`), so the band moments
//! (Kim et al. Eq. 56, summed over the STFT bins as HoloDoppler does)
//!
//! * `M0+ = Σ_{f1 ≤ |ν_k| ≤ f2} P_k` (flow magnitude),
//! * `M0− = Σ_{f1 ≤ ν_k ≤ f2} P_k − Σ_{f1 ≤ −ν_k ≤ f2} P_k` (axial direction: positive = receding
//!   with the library's sign convention),
//! * `M1 = Σ_{f1 ≤ |ν_k| ≤ f2} |ν_k| P_k` (Hz × power, optional),
//!
//! are linear in the paths and are accumulated per pixel directly, one exact band evaluation per
//! detected path ([`BandKernel::eval`]; a static path's is computed once): memory O(pixels), no
//! per-pixel spectrum. Units: fraction of the emitted power (M1: that times Hz).
//!
//! Paths are split into classes by their number of Doppler events (scattering on moving or
//! diffusing particles): static tissue only (0), one, several.

use super::{ImageSpec, detector_output};
use crate::output::{Derivation, Kind, Output, Registry, Slots, Style, WAVEFORM_VALUES};
use crate::sampling::PathRng;
use crate::spectrum::{BandKernel, BandMoments, BandPowers, BandTable, FrequencyAxis, Stft};
use crate::stats::GROUPS;

/// Units of the M0± images.
pub const M0_UNITS: &str = "fraction of emitted power per pixel (band sum of the expected periodogram)";
/// Units of the M1 images.
pub const M1_UNITS: &str = "Hz × fraction of emitted power per pixel";
/// Units of the M2 images.
pub const M2_UNITS: &str = "Hz² × fraction of emitted power per pixel";
/// Units of the ROI spectra.
pub const SPECTRUM_UNITS: &str = "fraction of emitted power per bin (no window kernel)";

/// Path classes, by Doppler events: 0, 1, ≥ 2.
pub const CLASS_NAMES: [&str; 3] = ["static", "single_doppler", "multiple_doppler"];

/// The class of a path with `doppler_events` events on moving particles.
#[inline(always)]
pub fn class_of(doppler_events: u32) -> usize {
    doppler_events.min(2) as usize
}

/// A named rectangle of the detector plane (m) whose spectrum and M0± are recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct Roi {
    pub name: String,
    pub min: [f64; 2],
    pub max: [f64; 2],
}

impl Roi {
    #[inline]
    pub fn contains(&self, x: f64, y: f64) -> bool {
        super::Area::Rect { min: self.min, max: self.max }.contains(x, y)
    }
}

/// Single-measurement speckle for the ROIs (Kim et al. 2025 §5.2–5.3), and per pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeckleSpec {
    /// Independent windows (speckle realisations) per ROI and algorithm, and per pixel.
    pub windows: u32,
    /// Algorithm 1 in every pixel, from the per-pixel spectra ([`crate::post::speckle`]; the
    /// camera then records `pixel_spectra`).
    pub pixels: bool,
}

/// What an LDH camera records besides its M0± images, as configured ([`LdhSpec::new`]; the
/// fields mean what [`LdhSpec`]'s of the same names do).
#[derive(Debug, Clone, PartialEq)]
pub struct LdhOptions {
    pub flip_sign: bool,
    pub m1: bool,
    pub moments: bool,
    pub by_class: bool,
    pub rois: Vec<Roi>,
    pub spectrum_axis: FrequencyAxis,
    pub pixel_spectra: bool,
    pub speckle: Option<SpeckleSpec>,
    pub acquisition: Option<Acquisition>,
}

/// An acquisition over the cardiac cycle of a scene whose flows pulse (HoloDoppler's STFT windows,
/// a point detector's spectra): the windows' centre times. In every window each detected path's line sits at its frequency then,
/// `dl/dt(t_m)/λ0` from its harmonics ([`crate::flow::pulse::rate`]): the flow is taken as
/// steady within a window (quasi-static; a 13 ms window spans 1.5 % of a 70 bpm cycle).
#[derive(Debug, Clone, PartialEq)]
pub struct Acquisition {
    /// Centre of each window, s from the cycle's start.
    pub times: Vec<f64>,
    /// Between windows' starts, s.
    pub hop: f64,
    /// `[k − 1][window]`: `cos kωt_m` and `sin kωt_m` ([`crate::flow::pulse::Cycle::phasors`]),
    /// a harmonic's factors over the windows side by side (the rates of all windows are one
    /// vectorised product, [`Acquisition::rates`]).
    pub cos: Vec<Vec<f64>>,
    pub sin: Vec<Vec<f64>>,
    /// The scene's pulsing populations' waveforms at the windows' times, relative to their cycle
    /// means (`population flow`, `population random velocity`), drawn beside the ROIs' M0+.
    pub waveforms: Vec<(String, Vec<f64>)>,
}

impl Acquisition {
    /// Windows `window` s long, `hop` s apart, over `duration` s from `start` s, on the cycle
    /// `cycle`; `None` if not one window fits.
    pub fn new(cycle: &crate::flow::pulse::Cycle, window: f64, hop: f64, start: f64, duration: f64) -> Option<Self> {
        if duration < window {
            return None;
        }
        // (A span that is a whole number of hops keeps its last window despite rounding.)
        let windows = ((duration - window) / hop + 1e-9).floor() as usize + 1;
        let times: Vec<f64> = (0..windows).map(|m| start + m as f64 * hop + 0.5 * window).collect();
        let phasors: Vec<_> = times.iter().map(|&t| cycle.phasors(t)).collect();
        let part = |f: fn(&num_complex::Complex64) -> f64| -> Vec<Vec<f64>> {
            (0..cycle.harmonics).map(|k| phasors.iter().map(|p| f(&p[k])).collect()).collect()
        };
        Some(Acquisition { times, hop, cos: part(|z| z.re), sin: part(|z| z.im), waveforms: Vec::new() })
    }

    /// With the waveforms of the pulsing populations of `scene` at its windows' times, named by
    /// the region or layer they fill.
    pub fn with_waveforms(mut self, scene: &crate::medium::Scene) -> Self {
        use crate::flow::pulse::FlowPulse;
        let omega = scene.cycle.map_or(0.0, |c| c.omega);
        let at = |w: &crate::flow::pulse::Waveform| self.times.iter().map(|&t| w.value(omega, t)).collect::<Vec<_>>();
        let places =
            scene.regions.iter().map(|r| (&r.name, r.medium)).chain(scene.layers.iter().map(|l| (&l.name, l.medium)));
        let mut out: Vec<(String, Vec<f64>)> = Vec::new();
        for (place, m) in places {
            let pops = scene.media[m].populations();
            for p in pops {
                let who = if pops.len() > 1 { format!("{place} ({})", p.name) } else { place.clone() };
                let flow = match &p.pulse.flow {
                    Some(FlowPulse::Separable(w)) => Some(w.as_ref()),
                    Some(FlowPulse::Womersley(t)) => Some(&t.waveform),
                    None => None,
                };
                if let Some(w) = flow {
                    out.push((format!("{who} flow"), at(w)));
                }
                if let Some(w) = &p.pulse.dispersion {
                    out.push((format!("{who} random velocity"), at(w)));
                }
            }
        }
        self.waveforms = out;
        self
    }

    /// The rate `dl/dt` in every window of a path of steady rate `dldt` and harmonics `pulse`
    /// ([`crate::flow::pulse::rate`]), into `out`.
    #[inline]
    pub fn rates(&self, dldt: f64, pulse: &[num_complex::Complex64], out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.times.len(), dldt);
        for ((f, c), s) in pulse.iter().zip(&self.cos).zip(&self.sin) {
            for ((r, c), s) in out.iter_mut().zip(c).zip(s) {
                *r += f.re * c - f.im * s;
            }
        }
    }

    /// The windows' time axis (their centres, s).
    pub fn axis(&self) -> crate::output::Axis {
        crate::output::Axis::linear("time_s", "s", self.times[0], self.hop, self.times.len())
    }
}

/// The band moments an LDH camera records with `moments = true`, per pixel and ROI, in their
/// order in the tallies: `M1± = ∫_{f1}^{f2} f [S(f) ± S(−f)] df`, `M2± = ∫ f² [S(f) ± S(−f)] df`
/// (`M1+` is `m1`'s `M1`), as `(name, title)`.
pub const MOMENTS: [(&str, &str); 4] =
    [("m1_plus", "M1+"), ("m1_minus", "M1−"), ("m2_plus", "M2+"), ("m2_minus", "M2−")];

/// The frequency images of `moments = true`, ratios of the band moments with their σ by the
/// group jackknife: `(name, numerator in MOMENTS, sqrt, signed, title)`. `M2−/M0+` has no root
/// (it is negative wherever the approaching side dominates), so only `M2+` gives an RMS frequency.
pub const FREQUENCIES: [(&str, usize, bool, bool, &str); 3] = [
    ("mean_frequency_plus", 0, false, false, "mean |frequency| M1+/M0+"),
    ("mean_frequency_minus", 1, false, true, "mean signed frequency M1−/M0+"),
    ("rms_frequency", 2, true, false, "RMS frequency √(M2+/M0+)"),
];

/// The LDH acquisition and what to accumulate.
#[derive(Debug, Clone)]
pub struct LdhSpec {
    pub stft: Stft,
    /// The band `[f1, f2]`, Hz (0 < f1 < f2).
    pub band: (f64, f64),
    pub kernel: BandKernel,
    /// M0± of a static path (f = 0, γ = 0): the leakage of the DC peak into the band.
    pub static_powers: BandPowers,
    /// Report frequencies with the opposite sign (a set-up whose reference arm flips it); applied
    /// to the outputs only.
    pub flip_sign: bool,
    pub m1: bool,
    /// The band moments M1±, M2± and the mean and RMS frequency images ([`MOMENTS`],
    /// [`FREQUENCIES`]), per pixel and ROI.
    pub moments: bool,
    /// `M1−`, `M2±` of a static path.
    pub static_moments: BandMoments,
    pub by_class: bool,
    pub rois: Vec<Roi>,
    /// Axis of the ROI (and per-pixel) spectra.
    pub spectrum_axis: FrequencyAxis,
    /// Full spectra in every pixel (memory: pixels × bins).
    pub pixel_spectra: bool,
    pub speckle: Option<SpeckleSpec>,
    /// Windows over the cardiac cycle (a scene whose flows pulse): M0± images, ROI values and
    /// spectra per window.
    pub acquisition: Option<Acquisition>,
    /// The band's `M0±` tabulated for the acquisition's many evaluations.
    pub table: Option<std::sync::Arc<BandTable>>,
}

impl PartialEq for LdhSpec {
    fn eq(&self, o: &Self) -> bool {
        self.stft.sample_rate() == o.stft.sample_rate()
            && self.stft.samples() == o.stft.samples()
            && self.stft.window() == o.stft.window()
            && self.band == o.band
            && self.flip_sign == o.flip_sign
            && self.m1 == o.m1
            && self.moments == o.moments
            && self.by_class == o.by_class
            && self.rois == o.rois
            && self.spectrum_axis == o.spectrum_axis
            && self.pixel_spectra == o.pixel_spectra
            && self.speckle == o.speckle
            && self.acquisition == o.acquisition
    }
}

impl LdhSpec {
    /// Build the band kernel and the static path's band powers. `None` if the band holds no bin.
    pub fn new(stft: Stft, band: (f64, f64), o: LdhOptions) -> Option<Self> {
        let kernel = if o.moments {
            BandKernel::with_moments(&stft, band.0, band.1)?
        } else {
            BandKernel::new(&stft, band.0, band.1)?
        };
        let (static_powers, static_moments) = (kernel.eval(0.0, 0.0), kernel.eval_moments(0.0, 0.0));
        let table = o.acquisition.as_ref().map(|_| std::sync::Arc::new(BandTable::new(&kernel)));
        let LdhOptions { flip_sign, m1, moments, by_class, rois, spectrum_axis, pixel_spectra, speckle, acquisition } =
            o;
        Some(LdhSpec {
            stft,
            band,
            kernel,
            static_powers,
            flip_sign,
            m1,
            moments,
            static_moments,
            by_class,
            rois,
            spectrum_axis,
            pixel_spectra,
            speckle,
            acquisition,
            table,
        })
    }

    /// Band powers of a unit line at `f` with half-width `gamma`.
    #[inline]
    pub fn band_powers(&self, f: f64, gamma: f64) -> BandPowers {
        if f == 0.0 && gamma == 0.0 { self.static_powers } else { self.kernel.eval(f, gamma) }
    }

    /// The higher band moments of a unit line at `f` with half-width `gamma` (with `moments`).
    #[inline]
    pub fn band_moments(&self, f: f64, gamma: f64) -> BandMoments {
        if f == 0.0 && gamma == 0.0 { self.static_moments } else { self.kernel.eval_moments(f, gamma) }
    }

    /// Channels of an ROI spectrum: the total, then one per path class.
    pub const ROI_CHANNELS: usize = 1 + CLASS_NAMES.len();

    /// Lay out this camera's tallies (detector `i`, called `name`, over the image `im`) from the
    /// end of `reg`, and declare its outputs: M0± (and M1, per-class) images, each ROI's M0±
    /// and spectra, the per-pixel spectra. M0− carries the set-up's sign, the spectra its
    /// mirrored axis.
    pub fn declare(&self, i: usize, name: &str, im: &ImageSpec, reg: &mut Registry) -> LdhLayout {
        let pixels = im.nx * im.ny;
        let bins = self.spectrum_axis.bins;
        let stride = bins + 2;
        let sign = if self.flip_sign { -1.0 } else { 1.0 };
        let budget = Some(im.budget_key(i));
        // What has a sign (M0−; and M1, drawn so since it was added) is drawn on a diverging map.
        let (seq, div) = (Style::Sequential, Style::Diverging);
        let image = |reg: &mut Registry, start: usize, stem: String, sign: f64, primary: bool, style: Style| {
            reg.declare(Output {
                file: format!("{name}_{stem}.npy"),
                units: M0_UNITS,
                sign,
                primary,
                style,
                budget_key: budget.clone(),
                ..detector_output(i, format!("{name}.{stem}"), im.kind(), Slots::contiguous(start, pixels), im.shape())
            });
        };
        let m0_plus = reg.take(pixels);
        image(reg, m0_plus, "m0_plus".into(), 1.0, true, seq);
        let m0_minus = reg.take(pixels);
        image(reg, m0_minus, "m0_minus".into(), sign, true, div);
        let m1 = self.m1.then(|| {
            let o = reg.take(pixels);
            image(reg, o, "m1".into(), 1.0, false, div);
            reg.outputs.last_mut().expect("just declared").units = M1_UNITS;
            o
        });
        let classes = self.by_class.then(|| {
            let o = reg.take(2 * CLASS_NAMES.len() * pixels);
            for (c, cname) in CLASS_NAMES.iter().enumerate() {
                image(reg, o + 2 * c * pixels, format!("m0_plus_{cname}"), 1.0, false, seq);
                image(reg, o + (2 * c + 1) * pixels, format!("m0_minus_{cname}"), sign, false, div);
            }
            o
        });
        let channels: Vec<String> =
            std::iter::once("total".to_string()).chain(CLASS_NAMES.iter().map(|c| c.to_string())).collect();
        let spectrum =
            |channels: Vec<String>| Kind::Spectrum { axis: self.spectrum_axis, channels, mirrored: self.flip_sign };
        let rois = self
            .rois
            .iter()
            .map(|roi| {
                let mut scalar = |what: &str, sign: f64| {
                    let o = reg.take(1);
                    reg.declare(Output {
                        file: format!("/estimates/{what}_roi_{}/value", roi.name),
                        units: "fraction of emitted power (band sum of the expected periodogram)",
                        sign,
                        ..detector_output(
                            i,
                            format!("{name}.roi_{}.{what}", roi.name),
                            Kind::Scalar,
                            Slots::contiguous(o, 1),
                            vec![],
                        )
                    });
                    o
                };
                let (m0_plus, m0_minus) = (scalar("m0_plus", 1.0), scalar("m0_minus", sign));
                let s = reg.take(Self::ROI_CHANNELS * stride);
                reg.declare(Output {
                    file: format!("{name}_roi_{}_spectrum.npy", roi.name),
                    units: SPECTRUM_UNITS,
                    ..detector_output(
                        i,
                        format!("{name}.roi_{}.spectrum", roi.name),
                        spectrum(channels.clone()),
                        Slots { start: s, rows: Self::ROI_CHANNELS, stride, len: bins },
                        vec![Self::ROI_CHANNELS, bins],
                    )
                });
                RoiLayout { m0_plus, m0_minus, spectrum: s, moments: None }
            })
            .collect();
        let pixel_spectra = self.pixel_spectra.then(|| {
            let o = reg.take(pixels * stride);
            reg.declare(Output {
                file: format!("{name}_pixel_spectra.npy"),
                units: "fraction of emitted power per pixel and bin (no window kernel)",
                stderr: false,
                budget_key: Some((
                    format!("detectors[{i}].ldh.pixel_spectra"),
                    format!("= true ({bins} bins per pixel)"),
                )),
                ..detector_output(
                    i,
                    format!("{name}.pixel_spectra"),
                    Kind::PixelSpectra {
                        nx: im.nx,
                        ny: im.ny,
                        min: im.min,
                        max: im.max,
                        axis: self.spectrum_axis,
                        mirrored: self.flip_sign,
                    },
                    Slots { start: o, rows: pixels, stride, len: bins },
                    vec![im.ny, im.nx, bins],
                )
            });
            o
        });
        let mut lay = LdhLayout {
            pixels,
            stride,
            m0_plus,
            m0_minus,
            m1,
            classes,
            rois,
            pixel_spectra,
            moments: None,
            blocks: Vec::new(),
            windows: None,
        };
        if self.moments {
            self.declare_moments(i, name, im, reg, &mut lay);
        }
        if let Some(acq) = &self.acquisition {
            lay.windows = Some(self.declare_windows(i, name, im, reg, acq, stride));
        }
        lay.with_blocks()
    }

    /// Declare the acquisition's outputs, each with a window axis (`time_s`, the windows'
    /// centres): the M0± series of every pixel `[y][x][window]`, each ROI's M0± `[window]` and
    /// total spectrum `[window][bin]`. A pixel's windows lie side by side in the tallies, M0+'s
    /// then M0−'s (a detected path adds to all of them: laid out `[window][pixel]`, the 2·64
    /// windows of a 128² camera were as many cache misses per path, ×4.6 the run's time).
    fn declare_windows(
        &self,
        i: usize,
        name: &str,
        im: &ImageSpec,
        reg: &mut Registry,
        acq: &Acquisition,
        stride: usize,
    ) -> WindowsLayout {
        let (w, pixels) = (acq.times.len(), im.nx * im.ny);
        let sign = if self.flip_sign { -1.0 } else { 1.0 };
        let budget = Some((format!("detectors[{i}].ldh.acquisition"), format!("= {w} windows")));
        let band = format!("{}–{} kHz", self.band.0 / 1e3, self.band.1 / 1e3);
        // (M0−'s rows start `w` into each pixel's block, so its declared footprint, rows × stride,
        // reaches `w` past the block's end: reserved, never written.)
        let start = reg.take(2 * w * pixels + w);
        let series = |reg: &mut Registry, offset: usize, stem: &str, title: &str, sign: f64, style: Style| {
            let kind = Kind::PixelSeries { nx: im.nx, ny: im.ny, min: im.min, max: im.max, len: w };
            let slots = Slots { start: start + offset, rows: pixels, stride: 2 * w, len: w };
            let mut out = Output {
                file: format!("{name}_{stem}.npy"),
                units: M0_UNITS,
                sign,
                style,
                title: format!("{title} ({band}) over the cycle"),
                budget_key: budget.clone(),
                ..detector_output(i, format!("{name}.{stem}"), kind, slots, vec![im.ny, im.nx, w])
            };
            out.axes[2] = acq.axis();
            reg.declare(out);
        };
        series(reg, 0, "m0_plus_windows", "M0+", 1.0, Style::Sequential);
        series(reg, w, "m0_minus_windows", "M0−", sign, Style::Diverging);
        let bins = self.spectrum_axis.bins;
        let rois = self
            .rois
            .iter()
            .map(|roi| {
                let mut curve = |what: &str, sign: f64| {
                    let o = reg.take(w);
                    let mut out = Output {
                        file: format!("{name}_roi_{}_{what}.npy", roi.name),
                        units: "fraction of emitted power (band sum of the expected periodogram)",
                        sign,
                        ..detector_output(
                            i,
                            format!("{name}.roi_{}.{what}", roi.name),
                            Kind::Curve,
                            Slots::contiguous(o, w),
                            vec![w],
                        )
                    };
                    out.axes = vec![acq.axis()];
                    reg.declare(out);
                    o
                };
                let (plus, minus) = (curve("m0_plus_windows", 1.0), curve("m0_minus_windows", sign));
                // The M0+ waveform's systolic and diastolic values and resistivity index.
                reg.group(format!("{name}.roi_{}.m0_plus_windows_groups", roi.name), Some(i), plus, w, budget.clone());
                let o = reg.take(WAVEFORM_VALUES.len());
                let mut summary = Output {
                    file: format!("{name}_roi_{}_m0_plus_waveform.npy", roi.name),
                    units: "fraction of emitted power (systolic, diastolic); 1 (resistivity index)",
                    derivation: Derivation::Waveform { source: plus, len: w },
                    undefined_nan: true,
                    title: "M0+ over the cycle: systolic, diastolic, resistivity index".into(),
                    ..detector_output(
                        i,
                        format!("{name}.roi_{}.m0_plus_waveform", roi.name),
                        Kind::Curve,
                        Slots::contiguous(o, WAVEFORM_VALUES.len()),
                        vec![WAVEFORM_VALUES.len()],
                    )
                };
                summary.axes = vec![crate::output::Axis::labels("value", WAVEFORM_VALUES.map(String::from).to_vec())];
                reg.declare(summary);
                let s = reg.take(w * stride);
                let labels = (0..w).map(|m| format!("window_{m}")).collect();
                let mut out = Output {
                    file: format!("{name}_roi_{}_spectrum_windows.npy", roi.name),
                    units: SPECTRUM_UNITS,
                    budget_key: budget.clone(),
                    ..detector_output(
                        i,
                        format!("{name}.roi_{}.spectrum_windows", roi.name),
                        Kind::Spectrum { axis: self.spectrum_axis, channels: labels, mirrored: self.flip_sign },
                        Slots { start: s, rows: w, stride, len: bins },
                        vec![w, bins],
                    )
                };
                out.axes[0] = acq.axis();
                reg.declare(out);
                RoiWindows { m0_plus: plus, m0_minus: minus, spectrum: s }
            })
            .collect();
        WindowsLayout { start, windows: w, rois }
    }

    /// Record `d` (detected with the steady rate `dldt`) into every window of the acquisition:
    /// its line at `frequency(rate)` for the rate then ([`crate::flow::pulse::rate`] of the
    /// harmonics `pulse`). A path that met no pulsing flow (all harmonics 0) has one line for all.
    /// A broadened line goes into the ROI spectra by one slot drawn with `u` (the same for every
    /// window; [`FrequencyAxis::drawn_slot`]): integrated over the bins, 66 windows of a 513-bin
    /// axis cost 3·10⁴ arctangents per path.
    #[allow(clippy::too_many_arguments)]
    pub fn record_windows(
        &self,
        lay: &LdhLayout,
        wl: &WindowsLayout,
        acc: &mut [f64],
        d: &Detection,
        dldt: f64,
        pulse: &[num_complex::Complex64],
        u: f64,
        rates: &mut Vec<f64>,
        frequency: impl Fn(f64) -> f64,
    ) {
        let Some(acq) = &self.acquisition else { return };
        let Detection { pixel, x, y, weight: w, gamma, .. } = *d;
        let any_roi = self.rois.iter().any(|r| r.contains(x, y));
        if pixel.is_none() && !any_roi {
            return;
        }
        let steady = pulse.iter().all(|f| *f == num_complex::Complex64::ZERO);
        let table = self.table.as_deref();
        let mut at = (f64::NAN, (0.0, 0.0));
        if !steady {
            acq.rates(dldt, pulse, rates);
        }
        for m in 0..acq.times.len() {
            let f = if steady { d.frequency } else { frequency(rates[m]) };
            if !f.is_finite() {
                continue;
            }
            if at.0.to_bits() != f.to_bits() {
                let powers = table.and_then(|t| t.eval(f, gamma)).unwrap_or_else(|| {
                    let b = self.band_powers(f, gamma);
                    (b.m0_plus, b.m0_minus)
                });
                at = (f, powers);
            }
            let (plus, minus) = at.1;
            if let Some(p) = pixel {
                let o = wl.start + 2 * wl.windows * p + m;
                acc[o] += w * plus;
                acc[o + wl.windows] += w * minus;
            }
            for (roi, r) in self.rois.iter().zip(&wl.rois) {
                if !any_roi || !roi.contains(x, y) {
                    continue;
                }
                acc[r.m0_plus + m] += w * plus;
                acc[r.m0_minus + m] += w * minus;
                let s = r.spectrum + m * lay.stride;
                if gamma > 0.0 {
                    if let Some(k) = self.spectrum_axis.drawn_slot(f, gamma, u) {
                        acc[s + k] += w;
                    }
                } else {
                    self.spectrum_axis.add_line(&mut acc[s..s + lay.stride], w, f, gamma);
                }
            }
        }
    }

    /// Declare the band moments ([`MOMENTS`]) of every pixel and ROI, after all other tallies, and
    /// the frequency images and ROI values derived from them ([`FREQUENCIES`]).
    fn declare_moments(&self, i: usize, name: &str, im: &ImageSpec, reg: &mut Registry, lay: &mut LdhLayout) {
        let sign = if self.flip_sign { -1.0 } else { 1.0 };
        let budget = Some((
            format!("detectors[{i}].ldh.moments"),
            format!("= true ({} images, {} kept per group of batches)", MOMENTS.len() + FREQUENCIES.len(), 4 * GROUPS),
        ));
        // One unit (the image's pixels, or an ROI, `len` values each): its four moments from
        // `start`, declared as `kind` outputs called `prefix.m1_plus`, …; then the frequencies,
        // ratios to its M0+ at `m0_plus`.
        let unit = |reg: &mut Registry, prefix: &str, stem: &str, kind: Kind, shape: Vec<usize>, m0_plus: usize| {
            let len = shape.iter().product::<usize>();
            let start = reg.take(MOMENTS.len() * len);
            // A scalar lies in its detector's estimates under its name after the detector's.
            let output = |what: &str, slots: Slots| Output {
                file: if shape.is_empty() {
                    format!("/estimates/detectors/{name}/{}.{what}/value", &prefix[name.len() + 1..])
                } else {
                    format!("{name}_{stem}{what}.npy")
                },
                budget_key: budget.clone(),
                ..detector_output(i, format!("{prefix}.{what}"), kind.clone(), slots, shape.clone())
            };
            let (band, moments_of) =
                (format!("{}–{} kHz", self.band.0 / 1e3, self.band.1 / 1e3), |k: usize| start + k * len);
            for (k, (what, title)) in MOMENTS.iter().enumerate() {
                // M1− and M2− are odd in the frequency: they carry the set-up's sign.
                let odd = k % 2 == 1;
                reg.declare(Output {
                    units: if k < 2 { M1_UNITS } else { M2_UNITS },
                    sign: if odd { sign } else { 1.0 },
                    style: if odd { Style::Diverging } else { Style::Sequential },
                    title: format!("{title} ({band})"),
                    ..output(what, Slots::contiguous(moments_of(k), len))
                });
            }
            reg.group(format!("{prefix}.m0_plus_groups"), Some(i), m0_plus, len, budget.clone());
            for (k, (what, _)) in MOMENTS.iter().enumerate().take(3) {
                reg.group(format!("{prefix}.{what}_groups"), Some(i), moments_of(k), len, budget.clone());
            }
            let frequencies = reg.take(FREQUENCIES.len() * len);
            for (j, &(what, k, sqrt, signed, title)) in FREQUENCIES.iter().enumerate() {
                reg.declare(Output {
                    units: "Hz",
                    sign: if signed { sign } else { 1.0 },
                    // A frequency image's values lie far from 0 (the static background's leakage
                    // has its band centroid): drawn over their spread, not from 0.
                    style: if signed { Style::Diverging } else { Style::Spread },
                    title: format!("{title} ({band})"),
                    undefined_nan: true,
                    derivation: Derivation::Ratio { numerator: moments_of(k), denominator: m0_plus, sqrt },
                    ..output(what, Slots::contiguous(frequencies + j * len, len))
                });
            }
            start
        };
        lay.moments = Some(unit(reg, name, "", im.kind(), im.shape(), lay.m0_plus));
        for (roi, rl) in self.rois.iter().zip(lay.rois.iter_mut()) {
            let (prefix, stem) = (format!("{name}.roi_{}", roi.name), format!("roi_{}_", roi.name));
            rl.moments = Some(unit(reg, &prefix, &stem, Kind::Scalar, Vec::new(), rl.m0_plus));
        }
    }

    /// Record one detected path `d`. Calls `in_roi` with the index of every ROI it fell in, for
    /// the speckle records. Returns what it added to its pixel of the M0+ image (0 outside).
    /// With `draw`, its lines go into the spectra by one drawn slot each
    /// ([`FrequencyAxis::drawn_slot`]).
    #[inline]
    pub fn record(
        &self,
        lay: &LdhLayout,
        acc: &mut [f64],
        d: Detection,
        mut draw: Option<&mut PathRng>,
        mut in_roi: impl FnMut(usize),
    ) -> f64 {
        let Detection { pixel, x, y, weight: w, frequency: f, gamma, class } = d;
        // Each evaluated once, when first needed (a path in a pixel and an ROI).
        let mut values: Option<PixelValues> = None;
        let mut v = || *values.get_or_insert_with(|| self.pixel_values(lay, f, gamma, class));
        let mut m0_plus = 0.0;
        if let Some(p) = pixel {
            let v = v();
            m0_plus = w * v.of_block[0];
            for (&block, &x) in lay.blocks.iter().zip(&v.of_block) {
                if x != 0.0 {
                    acc[block + p] += w * x;
                }
            }
            self.record_pixel_spectrum(lay, acc, p, w, f, gamma, draw.as_deref_mut());
        }
        for (i, (roi, rl)) in self.rois.iter().zip(&lay.rois).enumerate() {
            if !roi.contains(x, y) {
                continue;
            }
            self.record_roi(lay, rl, acc, w, &v(), f, gamma, class, draw.as_deref_mut());
            in_roi(i);
        }
        m0_plus
    }

    /// Record of `d` only what the control variate leaves plain: its pixel's spectrum; calls
    /// `in_roi` with the index of every ROI it fell in, for the speckle records.
    pub fn record_uncovered(&self, lay: &LdhLayout, acc: &mut [f64], d: Detection, mut in_roi: impl FnMut(usize)) {
        let Detection { pixel, x, y, weight: w, frequency: f, gamma, .. } = d;
        if let Some(p) = pixel {
            self.record_pixel_spectrum(lay, acc, p, w, f, gamma, None);
        }
        for (i, roi) in self.rois.iter().enumerate() {
            if roi.contains(x, y) {
                in_roi(i);
            }
        }
    }

    /// Add a line of weight `w` at `f` (half-width `gamma`) to pixel `p`'s spectrum, if recorded.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn record_pixel_spectrum(
        &self,
        lay: &LdhLayout,
        acc: &mut [f64],
        p: usize,
        w: f64,
        f: f64,
        gamma: f64,
        draw: Option<&mut PathRng>,
    ) {
        if let Some(o) = lay.pixel_spectra {
            let s = o + p * lay.stride;
            self.add_lines(acc, &[s], w, f, gamma, draw);
        }
    }

    /// Add a line of weight `w` at `f` (half-width `gamma`) to the spectra starting at `starts`:
    /// integrated over every bin, or with `draw` (a broadened line) by one slot drawn from it,
    /// the same for all.
    #[inline]
    fn add_lines(&self, acc: &mut [f64], starts: &[usize], w: f64, f: f64, gamma: f64, draw: Option<&mut PathRng>) {
        let axis = &self.spectrum_axis;
        match draw {
            Some(rng) if gamma > 0.0 && w.is_finite() => {
                if let Some(k) = axis.drawn_slot(f, gamma, rng.uniform()) {
                    for &s in starts {
                        acc[s + k] += w;
                    }
                }
            }
            _ => {
                for &s in starts {
                    axis.add_line(&mut acc[s..s + axis.bins + 2], w, f, gamma);
                }
            }
        }
    }

    /// Add a path of weight `w` (its line at `f` with half-width `gamma`, its class, its values
    /// per unit weight `v`) to an ROI's M0± (and moments) and spectra.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn record_roi(
        &self,
        lay: &LdhLayout,
        rl: &RoiLayout,
        acc: &mut [f64],
        w: f64,
        v: &PixelValues,
        f: f64,
        gamma: f64,
        class: usize,
        draw: Option<&mut PathRng>,
    ) {
        acc[rl.m0_plus] += w * v.of_block[0];
        acc[rl.m0_minus] += w * v.of_block[1];
        self.add_lines(acc, &[rl.spectrum, rl.spectrum + (1 + class) * lay.stride], w, f, gamma, draw);
        if let Some(o) = rl.moments {
            for (k, m) in v.moments.into_iter().enumerate() {
                acc[o + k] += w * m;
            }
        }
    }

    /// What a path of unit weight with its line at `f` (half-width `gamma`) in class `class` adds
    /// to a pixel of each per-pixel map of `lay` ([`LdhLayout::blocks`], in their order).
    #[inline]
    pub fn pixel_values(&self, lay: &LdhLayout, f: f64, gamma: f64, class: usize) -> PixelValues {
        let b = self.band_powers(f, gamma);
        let mut v = PixelValues { of_block: [0.0; MAX_BLOCKS], moments: [0.0; 4] };
        v.of_block[0] = b.m0_plus;
        v.of_block[1] = b.m0_minus;
        let mut k = 2;
        if lay.m1.is_some() {
            v.of_block[k] = b.m1;
            k += 1;
        }
        if lay.classes.is_some() {
            v.of_block[k + 2 * class] = b.m0_plus;
            v.of_block[k + 2 * class + 1] = b.m0_minus;
            k += 2 * CLASS_NAMES.len();
        }
        if lay.moments.is_some() || lay.rois.iter().any(|r| r.moments.is_some()) {
            let m = self.band_moments(f, gamma);
            v.moments = [b.m1, m.m1_minus, m.m2_plus, m.m2_minus];
            if lay.moments.is_some() {
                v.of_block[k..k + 4].copy_from_slice(&v.moments);
            }
        }
        v
    }
}

/// The most per-pixel maps an LDH camera has: M0±, M1, M0± per class, four moments.
pub const MAX_BLOCKS: usize = 3 + 2 * CLASS_NAMES.len() + MOMENTS.len();

/// What a path of unit weight adds to a pixel of each per-pixel map ([`LdhSpec::pixel_values`]),
/// and its four band moments (for the ROIs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelValues {
    pub of_block: [f64; MAX_BLOCKS],
    pub moments: [f64; 4],
}

/// A detected path as an LDH camera records it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// The image pixel it lands in (`None` outside the image).
    pub pixel: Option<usize>,
    /// Where it lands on the detector plane, m.
    pub x: f64,
    pub y: f64,
    pub weight: f64,
    /// Beat frequency, Hz (library sign).
    pub frequency: f64,
    /// Lorentzian half-width, Hz.
    pub gamma: f64,
    /// Its Doppler class ([`class_of`]).
    pub class: usize,
}

/// Offsets of an LDH camera's tallies.
#[derive(Debug, Clone, PartialEq)]
pub struct LdhLayout {
    pub pixels: usize,
    /// Slots of one spectrum: the axis's bins and the below/above tallies.
    pub stride: usize,
    pub m0_plus: usize,
    pub m0_minus: usize,
    pub m1: Option<usize>,
    /// `[class][M0+, M0−][pixel]`.
    pub classes: Option<usize>,
    pub rois: Vec<RoiLayout>,
    /// `[pixel][slot]`.
    pub pixel_spectra: Option<usize>,
    /// `[moment][pixel]` ([`MOMENTS`]).
    pub moments: Option<usize>,
    /// The first slot of every per-pixel map (not the pixel spectra): M0+, M0−, M1, each class's
    /// M0+ and M0−, the four moments, those it has in this order ([`LdhSpec::pixel_values`]).
    pub blocks: Vec<usize>,
    /// The acquisition's windows over the cardiac cycle, if any.
    pub windows: Option<WindowsLayout>,
}

/// Offsets of an acquisition's tallies: the M0± series `[pixel][M0+, M0−][window]` from `start`,
/// and per ROI its M0± `[window]` and total spectrum `[window][slot]`.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowsLayout {
    pub start: usize,
    pub windows: usize,
    pub rois: Vec<RoiWindows>,
}

/// One ROI's tallies per window.
#[derive(Debug, Clone, PartialEq)]
pub struct RoiWindows {
    pub m0_plus: usize,
    pub m0_minus: usize,
    pub spectrum: usize,
}

impl LdhLayout {
    /// Fill [`LdhLayout::blocks`] from the layout's offsets.
    fn with_blocks(mut self) -> Self {
        let p = self.pixels;
        let mut b = vec![self.m0_plus, self.m0_minus];
        b.extend(self.m1);
        if let Some(o) = self.classes {
            b.extend((0..2 * CLASS_NAMES.len()).map(|k| o + k * p));
        }
        if let Some(o) = self.moments {
            b.extend((0..MOMENTS.len()).map(|k| o + k * p));
        }
        self.blocks = b;
        self
    }
}

/// Offsets of one ROI's tallies: its M0± and its spectra `[channel][slot]` (total, then by class).
#[derive(Debug, Clone, PartialEq)]
pub struct RoiLayout {
    pub m0_plus: usize,
    pub m0_minus: usize,
    pub spectrum: usize,
    /// Its four moments ([`MOMENTS`]).
    pub moments: Option<usize>,
}

/// A detected path inside an ROI, kept for speckle synthesis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordedLine {
    pub roi: u32,
    pub class: u8,
    pub weight: f64,
    /// Beat frequency, Hz (library sign).
    pub frequency: f64,
    /// Lorentzian half-width, Hz.
    pub gamma: f64,
}
