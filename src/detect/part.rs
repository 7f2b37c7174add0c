//! The parts of a surface detector. A detector is its geometry (side, plane, area, acceptance,
//! estimator) and a list of parts, each one feature of what it records: a spectrum, an image, a
//! time axis, correlations, an LDH camera. A part owns its spec (in its own file), lays out and
//! declares its tally slots and outputs ([`Part::declare`]), records a detected path
//! ([`Part::record`]) and finishes a batch and the run ([`Part::finish_batch`],
//! [`Part::finish_run`]). This file is the list of parts and their dispatch: adding a part is a
//! variant here, its own file, its resolve step (`config/resolve/detectors.rs`) and its docs; its
//! declared outputs are written, described in the manifest and read by Python without more.
//!
//! Parts are declared in the order of the list a detector holds, which resolve builds in the
//! order spectrum, image, time, correlation, LDH (the tally layout, and so the files' order,
//! follow it). A part that is laid out on the image's pixels (time-gated images, per-pixel
//! contrast, the LDH maps) comes after the image.

use super::ldh::{self, Detection, RecordedLine};
use super::{
    BeatModel, CorrelationLayout, CorrelationSpec, ImageSpec, LdhLayout, LdhSpec, Recorder, SpectrumLayout,
    SpectrumSpec, TimeLayout, TimeSpec,
};
use crate::output::Registry;
use crate::stats::BatchAccumulator;

/// One feature of a surface detector, as configured.
#[derive(Debug, Clone, PartialEq)]
pub enum Part {
    Spectrum(SpectrumSpec),
    /// The pixel grid and its intensity image.
    Image(ImageSpec),
    /// A time axis: the TPSF (and time-gated images) ([`super::time`]).
    Time(TimeSpec),
    /// g1, g2 and speckle contrast ([`super::correlation`]; boxed: large).
    Correlation(Box<CorrelationSpec>),
    /// An LDH camera over the image's pixels (boxed: large).
    Ldh(Box<LdhSpec>),
}

/// Where a part's tallies lie: [`Part::declare`]'s result, held in the same order as the parts.
#[derive(Debug, Clone, PartialEq)]
pub enum Placed {
    Spectrum(SpectrumLayout),
    /// The first slot of the intensity image.
    Image(usize),
    Time(TimeLayout),
    Correlation(CorrelationLayout),
    Ldh(LdhLayout),
}

/// Where a detector's parts are declared: its index and name, its pixel grid (if it has an
/// image) and the beat model.
#[derive(Debug, Clone, Copy)]
pub struct Place<'a> {
    pub i: usize,
    pub name: &'a str,
    pub image: Option<&'a ImageSpec>,
    pub beat: &'a BeatModel,
}

/// A path as the parts of a detector record it: arrived at `(x, y)` of the detector plane (in
/// image pixel `pixel`) with the optical path length `l` (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub x: f64,
    pub y: f64,
    pub pixel: Option<usize>,
    pub weight: f64,
    pub l: f64,
    /// m/s.
    pub dldt: f64,
    /// The Lorentzian half-width of its line, Hz ([`BeatModel::brownian_hwhm`]).
    pub gamma: f64,
    pub order: u32,
    pub doppler_events: u32,
}

impl Part {
    /// Lay out this part's tallies from `reg`'s end and declare its outputs.
    pub fn declare(&self, at: &Place, reg: &mut Registry) -> Placed {
        match self {
            Part::Spectrum(s) => Placed::Spectrum(s.declare(at, reg)),
            Part::Image(im) => Placed::Image(im.declare(at, reg)),
            Part::Time(t) => Placed::Time(t.declare(at.i, at.name, at.image, reg)),
            Part::Correlation(c) => Placed::Correlation(c.declare(at.i, at.name, at.image, reg)),
            Part::Ldh(l) => {
                let im = at.image.expect("an LDH camera has an image (checked when resolving)");
                Placed::Ldh(l.declare(at.i, at.name, im, reg))
            }
        }
    }

    /// Record `hit` into this part's tallies (laid out as `placed`) of `r`'s batch.
    #[inline(always)]
    pub fn record(&self, placed: &Placed, r: &mut Recorder, hit: &Hit) {
        match (self, placed) {
            (Part::Spectrum(s), Placed::Spectrum(lay)) => s.record(lay, r.acc, r.stats, &r.beat, hit),
            (Part::Image(_), Placed::Image(start)) => ImageSpec::record(*start, r.acc, hit),
            (Part::Time(t), Placed::Time(lay)) => t.record(lay, r.acc, hit.weight, hit.l, hit.pixel),
            (Part::Correlation(c), Placed::Correlation(lay)) => {
                // The Doppler frequency alone: a chirp's range term is not a motion of the field.
                let f = hit.dldt * r.beat.inv_wavelength;
                // Γ = 2π × the line's half-width.
                let rate = std::f64::consts::TAU * hit.gamma;
                c.record(lay, r.acc, hit.weight, f, rate, hit.pixel, (hit.x, hit.y));
            }
            (Part::Ldh(l), Placed::Ldh(lay)) => {
                // LDH uses a single-frequency laser (checked when resolving).
                let f = r.beat.frequency(0, hit.l, hit.dldt);
                if !f.is_finite() {
                    r.stats.non_finite += 1;
                    return;
                }
                let (w, gamma) = (hit.weight, hit.gamma);
                let class = ldh::class_of(hit.doppler_events);
                let lines = &mut r.lines;
                let d = Detection { pixel: hit.pixel, x: hit.x, y: hit.y, weight: w, frequency: f, gamma, class };
                l.record(lay, r.acc, d, |roi| {
                    if let Some(v) = lines.as_deref_mut() {
                        v.push(RecordedLine { roi: roi as u32, class: class as u8, weight: w, frequency: f, gamma });
                    }
                });
            }
            _ => unreachable!("a part is recorded with its own layout"),
        }
    }

    /// File a finished batch (number `batch`) of sums: the part's outputs that are not linear in
    /// the tallies keep their sums per group of batches (the detector's power is at `power`).
    pub fn finish_batch(&self, placed: &Placed, sums: &mut [f64], power: usize, batch: u64) {
        if let (Part::Correlation(c), Placed::Correlation(lay)) = (self, placed) {
            c.finish_batch(lay, sums, power, batch);
        }
    }

    /// Set the run-level values (and jackknife errors) of the part's non-linear outputs from the
    /// run's means.
    pub fn finish_run(&self, placed: &Placed, estimates: &mut BatchAccumulator, power: usize) {
        if let (Part::Correlation(c), Placed::Correlation(lay)) = (self, placed) {
            c.finish_run(lay, estimates, power);
        }
    }

    /// The name of its table in the manifest's `detectors.NAME` and of its config section.
    pub fn name(&self) -> &'static str {
        match self {
            Part::Spectrum(_) => "spectrum",
            Part::Image(_) => "image",
            Part::Time(_) => "time",
            Part::Correlation(_) => "correlation",
            Part::Ldh(_) => "ldh",
        }
    }
}

/// The parts of a detector, each kind at most once (resolve builds them so).
impl super::Surface {
    /// Its spectrum part, if it has one.
    #[inline]
    pub fn spectrum(&self) -> Option<&SpectrumSpec> {
        self.parts.iter().find_map(|p| if let Part::Spectrum(s) = p { Some(s) } else { None })
    }

    /// Its pixel grid (and intensity image), if it has one.
    #[inline]
    pub fn image(&self) -> Option<&ImageSpec> {
        self.parts.iter().find_map(|p| if let Part::Image(s) = p { Some(s) } else { None })
    }

    /// Its time axis, if it has one.
    #[inline]
    pub fn time(&self) -> Option<&TimeSpec> {
        self.parts.iter().find_map(|p| if let Part::Time(s) = p { Some(s) } else { None })
    }

    /// Its correlation part, if it has one.
    #[inline]
    pub fn correlation(&self) -> Option<&CorrelationSpec> {
        self.parts.iter().find_map(|p| if let Part::Correlation(s) = p { Some(s.as_ref()) } else { None })
    }

    /// Its LDH camera, if it is one.
    #[inline]
    pub fn ldh(&self) -> Option<&LdhSpec> {
        self.parts.iter().find_map(|p| if let Part::Ldh(s) = p { Some(s.as_ref()) } else { None })
    }
}

/// Where the parts of a detector lie, by kind.
impl super::DetectorLayout {
    /// Where its spectra lie, if it has any.
    pub fn spectrum(&self) -> Option<&SpectrumLayout> {
        self.parts.iter().find_map(|p| if let Placed::Spectrum(l) = p { Some(l) } else { None })
    }

    /// The first slot of its intensity image, if it has one.
    pub fn image(&self) -> Option<usize> {
        self.parts.iter().find_map(|p| if let Placed::Image(l) = p { Some(*l) } else { None })
    }

    /// Where its time-resolved tallies lie, if it has a time axis.
    pub fn time(&self) -> Option<&TimeLayout> {
        self.parts.iter().find_map(|p| if let Placed::Time(l) = p { Some(l) } else { None })
    }

    /// Where its correlation tallies lie, if it has any.
    pub fn correlation(&self) -> Option<&CorrelationLayout> {
        self.parts.iter().find_map(|p| if let Placed::Correlation(l) = p { Some(l) } else { None })
    }

    /// Where its LDH tallies lie, if it is a camera.
    pub fn ldh(&self) -> Option<&LdhLayout> {
        self.parts.iter().find_map(|p| if let Placed::Ldh(l) = p { Some(l) } else { None })
    }
}
