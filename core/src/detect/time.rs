//! Time-resolved detection: a surface detector's temporal point-spread function (TPSF) and its
//! time-gated images.
//!
//! A path's time of flight is its optical path length over the vacuum speed of light, `t = l/c`
//! (`l = Σ n_k |Δx_k|` is already index-weighted, crate docs "Path length"), from the laser's
//! emission to the detector plane. The TPSF is the detected power per time bin as a fraction of
//! the emitted power (not per second), followed by its below/above out-of-range tallies like a
//! spectrum's, so its bins plus both tallies sum to the detector's power of the same paths. The
//! walk tracks `l` only when some detector asks for a time axis ([`crate::experiment`]).

use super::{ImageSpec, detector_output, image_stack_output};
use crate::SPEED_OF_LIGHT;
use crate::output::{Axis, Kind, Output, Registry, Slots};
use crate::spectrum::{FrequencyAxis, Slot};

/// A detector's time axis: `bins` equal bins over `[t0, t1)` (s, the axis type of the spectra),
/// and whether its image is also gated by it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeSpec {
    pub axis: FrequencyAxis,
    pub image: bool,
}

/// Where a detector's time-resolved tallies lie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeLayout {
    /// The TPSF: `bins` values, then the below/above tallies.
    pub tpsf: usize,
    /// The gated image, `[bin][pixel]` (pixels row-major as the image's).
    pub image: Option<usize>,
    pub pixels: usize,
}

/// The time axis of detector `name`'s outputs: its file of bin centres.
pub fn time_axis(name: &str) -> Axis {
    Axis::file("time_s", "s", format!("{name}_time_s.npy"))
}

impl TimeSpec {
    /// Lay out detector `i`'s (`name`) time-resolved tallies from `reg`'s end and declare them.
    pub fn declare(&self, i: usize, name: &str, im: Option<&ImageSpec>, reg: &mut Registry) -> TimeLayout {
        let bins = self.axis.bins;
        let tpsf = reg.take(bins + 2);
        reg.declare(Output {
            file: format!("{name}_tpsf.npy"),
            primary: true,
            budget_key: Some((format!("detectors[{i}].time.bins"), format!("= {bins}"))),
            units: "fraction of emitted power per time bin",
            axes: vec![time_axis(name)],
            ..detector_output(i, format!("{name}.tpsf"), Kind::Curve, Slots::row(tpsf, bins, bins + 2), vec![bins])
        });
        let (image, pixels) = match im.filter(|_| self.image) {
            None => (None, 0),
            Some(im) => {
                let pixels = im.nx * im.ny;
                let start = reg.take(bins * pixels);
                reg.declare(Output {
                    file: format!("{name}_time_gated_image.npy"),
                    budget_key: Some((format!("detectors[{i}].time.image"), format!("= true ({bins} gates)"))),
                    units: "fraction of emitted power per pixel and time bin",
                    ..image_stack_output(i, format!("{name}.time_gated_image"), im, bins, start)
                        .layered(time_axis(name))
                });
                (Some(start), pixels)
            }
        };
        TimeLayout { tpsf, image, pixels }
    }

    /// Record weight `w` of a path of optical length `l` (m), landed in image pixel `pixel`.
    #[inline]
    pub fn record(&self, lay: &TimeLayout, acc: &mut [f64], w: f64, l: f64, pixel: Option<usize>) {
        let bins = self.axis.bins;
        match self.axis.locate(l / SPEED_OF_LIGHT) {
            Slot::Bin(k) => {
                acc[lay.tpsf + k] += w;
                if let (Some(start), Some(px)) = (lay.image, pixel) {
                    acc[start + k * lay.pixels + px] += w;
                }
            }
            Slot::Below => acc[lay.tpsf + bins] += w,
            Slot::Above => acc[lay.tpsf + bins + 1] += w,
            // `l` is checked finite before any detector is scored.
            Slot::NonFinite => {}
        }
    }
}
