//! The parts of a surface detector. A detector is its geometry (side, plane, area, acceptance,
//! estimator) and a list of parts, each one feature of what it records: a spectrum, an image, a
//! time axis, correlations, an LDH camera. A part owns its spec (in its own file), lays out and
//! declares its tally slots and outputs ([`Part::declare`], giving the [`Placed`] part: its spec
//! and where its tallies lie), records a detected path ([`Placed::record`]) and finishes a batch
//! and the run ([`Placed::finish_batch`], [`Placed::finish_run`]). This file is the list of parts
//! and their dispatch, each `match` exhaustive, so that the compiler lists what a new part needs:
//! a variant here, its own file, its resolve step (`config/resolve/detectors.rs`), its arm in
//! `io/write/parts.rs` (files of its own, if any, and its manifest table) and its docs. Its
//! declared outputs are written, listed in the manifest and read by Python without more.
//!
//! Parts are declared in the order of the list a detector holds, which resolve builds in the
//! order spectrum, image, time, correlation, LDH (the tally layout, and so the files' order,
//! follow it). A part that is laid out on the image's pixels (time-gated images, per-pixel
//! contrast, the LDH maps) comes after the image.

use super::ldh::{self, Detection, RecordedLine};
use super::tail;
use super::twin::TwinLayout;
use super::{
    CorrelationLayout, CorrelationSpec, Hit, ImageSpec, LdhLayout, LdhSpec, Place, Recorder, SpectrumLayout,
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

/// A part laid out in the tally vector ([`Part::declare`]): its spec and where its tallies lie.
/// A detector's layout holds them in the order of its parts; recording and writing read them
/// alone.
#[derive(Debug, Clone, PartialEq)]
pub enum Placed {
    Spectrum(SpectrumSpec, SpectrumLayout),
    /// The pixel grid and the first slot of the intensity image.
    Image(ImageSpec, usize),
    Time(TimeSpec, TimeLayout),
    Correlation(Box<CorrelationSpec>, CorrelationLayout),
    Ldh(Box<LdhSpec>, LdhLayout),
}

impl Part {
    /// Lay out this part's tallies from `reg`'s end and declare its outputs.
    pub fn declare(&self, at: &Place, reg: &mut Registry) -> Placed {
        match self {
            Part::Spectrum(s) => Placed::Spectrum(s.clone(), s.declare(at, reg)),
            Part::Image(im) => Placed::Image(*im, im.declare(at, reg)),
            Part::Time(t) => Placed::Time(*t, t.declare(at.i, at.name, at.image, reg)),
            Part::Correlation(c) => {
                let lay = c.declare(at.i, at.name, at.image, reg);
                Placed::Correlation(c.clone(), lay)
            }
            Part::Ldh(l) => {
                let im = at.image.expect("an LDH camera has an image (checked when resolving)");
                let lay = l.declare(at.i, at.name, im, reg);
                Placed::Ldh(l.clone(), lay)
            }
        }
    }
}

impl Placed {
    /// Record `hit` into this part's tallies of `r`'s batch.
    #[inline(always)]
    pub fn record(&self, r: &mut Recorder, hit: &Hit) {
        self.record_into(r, hit, true);
    }

    /// [`record`](Self::record) without the speckle records (a camera path's connection where the
    /// forward paths keep them, `estimator = "footprints"`).
    pub fn record_without_lines(&self, r: &mut Recorder, hit: &Hit) {
        self.record_into(r, hit, false);
    }

    #[inline(always)]
    fn record_into(&self, r: &mut Recorder, hit: &Hit, keep_lines: bool) {
        match self {
            Placed::Spectrum(s, lay) => {
                s.record(lay, r.acc, r.stats, &r.beat, hit);
                if let Some(o) = lay.windows {
                    s.record_windows(o, lay.stride, r.acc, &r.beat, hit, &r.pulse, &mut r.scratch);
                }
            }
            Placed::Image(_, start) => {
                ImageSpec::record(*start, r.acc, hit);
                r.tail_score(hit, tail::INTENSITY, hit.weight);
            }
            Placed::Time(t, lay) => t.record(lay, r.acc, hit.weight, hit.l, hit.pixel),
            Placed::Correlation(c, lay) => {
                // The Doppler frequency alone: a chirp's range term is not a motion of the field.
                let f = hit.dldt * r.beat.inv_wavelength;
                // Γ = 2π × the line's half-width.
                let rate = std::f64::consts::TAU * hit.gamma;
                c.record(lay, r.acc, hit.weight, f, rate, hit.pixel, (hit.x, hit.y));
            }
            Placed::Ldh(l, lay) => {
                let Some(d) = detection(r, hit) else { return };
                let lines = if keep_lines { r.lines.as_deref_mut() } else { None };
                let mut lines = lines;
                let draw = r.line_draws.as_mut();
                let m0_plus = l.record(lay, r.acc, d, draw, |roi| push_line(lines.as_deref_mut(), roi, &d));
                r.tail_score(hit, tail::M0_PLUS, m0_plus);
                if let Some(wl) = &lay.windows {
                    let u = r.window_draws.as_mut().map_or(0.5, |g| g.uniform());
                    let beat = &r.beat;
                    let frequency = |rate: f64| beat.frequency(0, hit.l, rate);
                    l.record_windows(lay, wl, r.acc, &d, hit.dldt, &r.pulse, u, &mut r.scratch, frequency);
                }
            }
        }
    }

    /// Whether the layered control variate covers this part ([`super::twin`]): the image and the
    /// LDH maps and ROIs.
    pub fn varies(&self) -> bool {
        matches!(self, Placed::Image(..) | Placed::Ldh(..))
    }

    /// What the control variate leaves plain of `hit` (a path whose twin cancels its share of
    /// the covered tallies): the LDH part's per-pixel spectra and speckle records.
    pub fn record_uncovered(&self, r: &mut Recorder, hit: &Hit) {
        let Placed::Ldh(l, lay) = self else { return };
        let Some(d) = detection(r, hit) else { return };
        let mut lines = r.lines.as_deref_mut();
        l.record_uncovered(lay, r.acc, d, |roi| push_line(lines.as_deref_mut(), roi, &d));
    }

    /// A twin contribution `hit` of a path that entered at `launch`: this part's values per
    /// kernel channel into `out` (returns how many: the image's intensity, the LDH maps'
    /// [`super::LdhLayout::blocks`]) and its ROIs' share (the footprint's mass within each ROI
    /// shifted by the offset, [`TwinLayout::shifted_mass`]) straight into the tallies; with
    /// `subtract` (a twin of its own, met on the area), also its share taken out of the maps'
    /// pixel and the ROIs it lands in (the pixel spectra are not covered: they keep the path's).
    /// Without `rois` (the ROIs are camera paths', `estimator = "footprints"`), nothing into them.
    #[allow(clippy::too_many_arguments)]
    pub fn twin_values(
        &self,
        r: &mut Recorder,
        hit: &Hit,
        launch: (f64, f64),
        twin: &TwinLayout,
        subtract: bool,
        rois: bool,
        out: &mut [f64],
    ) -> usize {
        let w = hit.weight;
        match self {
            Placed::Image(_, start) => {
                if subtract && let Some(p) = hit.pixel {
                    r.acc[start + p] -= w;
                    r.tail_score(hit, tail::INTENSITY, -w);
                }
                out[0] = w;
                1
            }
            Placed::Ldh(l, lay) => {
                let n = lay.blocks.len();
                let Some(d) = detection(r, hit) else {
                    out[..n].fill(0.0);
                    return n;
                };
                let v = l.pixel_values(lay, d.frequency, d.gamma, d.class);
                for (o, x) in out[..n].iter_mut().zip(v.of_block) {
                    *o = w * x;
                }
                if subtract && let Some(p) = hit.pixel {
                    for (&block, &x) in lay.blocks.iter().zip(&out[..n]) {
                        if x != 0.0 {
                            r.acc[block + p] -= x;
                        }
                    }
                    r.tail_score(hit, tail::M0_PLUS, -out[0]);
                }
                for (roi, rl) in l.rois.iter().zip(&lay.rois).filter(|_| rois) {
                    if subtract && roi.contains(hit.x, hit.y) {
                        l.record_roi(lay, rl, r.acc, -w, &v, d.frequency, d.gamma, d.class, None);
                    }
                    let m = twin.shifted_mass(roi.min, roi.max, launch, (hit.x, hit.y));
                    if m > 0.0 {
                        l.record_roi(lay, rl, r.acc, w * m, &v, d.frequency, d.gamma, d.class, None);
                    }
                }
                n
            }
            Placed::Spectrum(..) | Placed::Time(..) | Placed::Correlation(..) => 0,
        }
    }

    /// File a finished batch (number `batch`) of sums: a part's outputs that are not linear in
    /// the tallies keep their sums per group of batches (the detector's power is at `power`).
    pub fn finish_batch(&self, sums: &mut [f64], power: usize, batch: u64) {
        match self {
            Placed::Correlation(c, lay) => c.finish_batch(lay, sums, power, batch),
            Placed::Spectrum(..) | Placed::Image(..) | Placed::Time(..) | Placed::Ldh(..) => {}
        }
    }

    /// Set the run-level values (and jackknife errors) of the part's non-linear outputs from the
    /// run's means.
    pub fn finish_run(&self, estimates: &mut BatchAccumulator, power: usize) {
        match self {
            Placed::Correlation(c, lay) => c.finish_run(lay, estimates, power),
            Placed::Spectrum(..) | Placed::Image(..) | Placed::Time(..) | Placed::Ldh(..) => {}
        }
    }

    /// The name of its table in the manifest's `detectors.NAME` and of its config section.
    pub fn name(&self) -> &'static str {
        match self {
            Placed::Spectrum(..) => "spectrum",
            Placed::Image(..) => "image",
            Placed::Time(..) => "time",
            Placed::Correlation(..) => "correlation",
            Placed::Ldh(..) => "ldh",
        }
    }
}

/// An LDH camera's view of `hit` (`None`, counted, if its frequency is not finite). LDH uses a
/// single-frequency laser (checked when resolving).
#[inline(always)]
fn detection(r: &mut Recorder, hit: &Hit) -> Option<Detection> {
    let f = r.beat.frequency(0, hit.l, hit.dldt);
    if !f.is_finite() {
        r.stats.non_finite += 1;
        return None;
    }
    let class = ldh::class_of(hit.doppler_events);
    Some(Detection { pixel: hit.pixel, x: hit.x, y: hit.y, weight: hit.weight, frequency: f, gamma: hit.gamma, class })
}

/// Keep `d`, detected in ROI `roi`, for speckle synthesis (if records are kept).
#[inline(always)]
fn push_line(lines: Option<&mut Vec<RecordedLine>>, roi: usize, d: &Detection) {
    if let Some(v) = lines {
        v.push(RecordedLine {
            roi: roi as u32,
            class: d.class as u8,
            weight: d.weight,
            frequency: d.frequency,
            gamma: d.gamma,
        });
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
        self.parts.iter().find_map(|p| if let Placed::Spectrum(_, l) = p { Some(l) } else { None })
    }

    /// The first slot of its intensity image, if it has one.
    pub fn image(&self) -> Option<usize> {
        self.parts.iter().find_map(|p| if let Placed::Image(_, l) = p { Some(*l) } else { None })
    }

    /// Where its time-resolved tallies lie, if it has a time axis.
    pub fn time(&self) -> Option<&TimeLayout> {
        self.parts.iter().find_map(|p| if let Placed::Time(_, l) = p { Some(l) } else { None })
    }

    /// Where its correlation tallies lie, if it has any.
    pub fn correlation(&self) -> Option<&CorrelationLayout> {
        self.parts.iter().find_map(|p| if let Placed::Correlation(_, l) = p { Some(l) } else { None })
    }

    /// Where its LDH tallies lie, if it is a camera.
    pub fn ldh(&self) -> Option<&LdhLayout> {
        self.parts.iter().find_map(|p| if let Placed::Ldh(_, l) = p { Some(l) } else { None })
    }
}
