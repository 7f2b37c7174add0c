//! The outputs of a run, declared once.
//!
//! Every per-batch number of a run lives in one flat tally vector (so that batch statistics treat
//! scalars, spectrum bins and pixels alike). The [`Registry`] says what those numbers are: each
//! named output is declared once, with its kind, shape and axes, its units, where its values lie
//! in the tally vector ([`Slots`]), the file a run writes it to, the sign that file carries, and
//! the configuration key its memory grows with. Detectors declare their outputs as they lay out
//! their tallies ([`crate::detect::TallyLayout::new`]); everything that reads a run — the
//! writers, `ohd converge` and the target-error loop, the `[reference]` check, the memory
//! budget, the terminal report, shard and checkpoint files — reads the registry, never offsets
//! of its own.
//!
//! Adding an output: declare it where its detector lays out its tallies, record into its slots,
//! and write it where its detector's outputs are written (`io::write::manifest`).

use std::ops::Range;

use crate::spectrum::FrequencyAxis;

/// Units of the tallies that are fractions of the emitted power.
pub const POWER_UNITS: &str = "fraction of emitted power";

/// Where an output's values lie in the tally vector: `rows` rows of `len` values, row `r`
/// starting at `start + r·stride`. A spectrum's rows are followed by their below/above
/// out-of-range tallies (`stride = len + 2`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slots {
    pub start: usize,
    pub rows: usize,
    pub stride: usize,
    pub len: usize,
}

impl Slots {
    /// `len` consecutive values.
    pub fn contiguous(start: usize, len: usize) -> Self {
        Slots { start, rows: 1, stride: len, len }
    }

    /// One row of `len` values in a block of stride `stride` (a spectrum channel: `len` bins, then
    /// its two out-of-range tallies).
    pub fn row(start: usize, len: usize, stride: usize) -> Self {
        Slots { start, rows: 1, stride, len }
    }

    /// The slots of row `r`.
    pub fn row_range(&self, r: usize) -> Range<usize> {
        let s = self.start + r * self.stride;
        s..s + self.len
    }

    /// The first row's values (all of them for a one-row output).
    pub fn range(&self) -> Range<usize> {
        self.row_range(0)
    }

    /// Tally slots the output occupies, with the gaps between its rows.
    pub fn footprint(&self) -> usize {
        self.rows * self.stride
    }
}

/// What an output is.
#[derive(Debug, Clone, PartialEq)]
pub enum Kind {
    /// One number (written into the manifest's `estimates`).
    Scalar,
    /// Power per frequency bin; one row per channel (`channels` names them), each followed in
    /// the tally by its below/above out-of-range tallies. `mirrored`: written on the negated
    /// axis (an LDH camera with `flip_sign`), bins reversed and tails swapped.
    Spectrum { axis: FrequencyAxis, channels: Vec<String>, mirrored: bool },
    /// An image over the rectangle `[min, max]` of the detector plane (m), `ny` rows of `nx`
    /// pixels. Tallied with row 0 at the lowest `y`; written (and given to figures) with row 0 at
    /// the largest `y` ([`Output::values`]).
    Image { nx: usize, ny: usize, min: [f64; 2], max: [f64; 2] },
    /// A full spectrum in every pixel of an image: `[y][x][bin]`, its rows ordered as an
    /// [`Kind::Image`]'s.
    PixelSpectra { nx: usize, ny: usize, axis: FrequencyAxis, mirrored: bool },
    /// A stack of `layers` images over one detector's pixels, `[layer][y][x]` (the time gates of
    /// a TPSF); each layer's rows ordered as an [`Kind::Image`]'s.
    ImageStack { layers: usize, nx: usize, ny: usize, min: [f64; 2], max: [f64; 2] },
    /// Values along an axis that is not a frequency (a TPSF's time bins, g1 over the delay τ):
    /// one row per channel; the writer of its detector writes the axis.
    Curve,
    /// Range-gate spectra `[gate][bin]` of a lidar receiver, bins in fftshift order.
    RangeDoppler { gates: usize, bins: usize },
    /// A voxel grid over the box `[min, max]` (m), `voxels = [nx, ny, nz]`, written `[nz, ny, nx]`
    /// as tallied ([`crate::detect::volume::VOLUME_LAYOUT`]).
    Volume { voxels: [usize; 3], min: [f64; 3], max: [f64; 3] },
    /// Working tallies a detector derives its outputs from (a lidar's lag sums): no file.
    Internal,
}

/// One declared output.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// `reflectance_diffuse`, `camera.detected_power`, `camera.spectrum`, `camera.m0_plus`, …
    pub name: String,
    /// The detector it belongs to (`None`: the global scalar tallies).
    pub detector: Option<usize>,
    pub kind: Kind,
    pub slots: Slots,
    /// Shape of the written array (`[]` for a scalar).
    pub shape: Vec<usize>,
    pub units: &'static str,
    /// Where a run writes it, relative to its output directory: a `.npy` file (with
    /// `_stderr.npy` beside it unless `stderr` is false) for arrays, a JSON pointer into
    /// `manifest.json` for scalars, nothing for internal tallies.
    pub file: String,
    /// Whether the standard errors are written beside the values.
    pub stderr: bool,
    /// The sign the written file carries relative to the tally (an LDH camera's M0− with
    /// `flip_sign`): the file holds `sign × tally`.
    pub sign: f64,
    /// A main output of the run: listed by [`Registry::named`] (`ohd converge`, `[reference]`,
    /// `--target-error`). Splits by channel or class, ROI values and per-pixel spectra are not.
    pub primary: bool,
    /// The configuration key its memory grows with and the value given, for the memory budget
    /// (`("detectors[0].spectrum.bins", "= 256")`).
    pub budget_key: Option<(String, String)>,
    /// NaN marks a value left undefined (a correlation estimate from too few paths, documented
    /// with the output): the finiteness check of the written outputs lets NaN through, not
    /// infinities.
    pub undefined_nan: bool,
}

impl Output {
    /// An output of the global tallies (`detector: None`) with the defaults: power units, no
    /// file, standard errors written, sign +1, not a main output, no memory key.
    pub fn new(name: String, kind: Kind, slots: Slots, shape: Vec<usize>) -> Self {
        Output {
            name,
            detector: None,
            kind,
            slots,
            shape,
            units: POWER_UNITS,
            file: String::new(),
            stderr: true,
            sign: 1.0,
            primary: false,
            budget_key: None,
            undefined_nan: false,
        }
    }

    /// Whether it is written on the negated frequency axis: each row's bins reversed and its
    /// out-of-range tails swapped ([`Kind::Spectrum`], [`Kind::PixelSpectra`]).
    pub fn mirrored(&self) -> bool {
        matches!(self.kind, Kind::Spectrum { mirrored: true, .. } | Kind::PixelSpectra { mirrored: true, .. })
    }

    /// A scalar (absolute error) rather than an array (relative RMS error).
    pub fn is_scalar(&self) -> bool {
        self.kind == Kind::Scalar
    }

    /// The tally slots of a one-row output (every output [`Registry::named`] lists).
    pub fn range(&self) -> Range<usize> {
        self.slots.range()
    }

    /// For an image-like output ([`Kind::Image`], [`Kind::PixelSpectra`]): its image rows and the
    /// written values per row (`nx`, or `nx · bins`); `None` for other kinds.
    pub fn image_rows(&self) -> Option<(usize, usize)> {
        match self.kind {
            Kind::Image { nx, ny, .. } => Some((ny, nx)),
            Kind::PixelSpectra { nx, ny, axis, .. } => Some((ny, nx * axis.bins)),
            _ => None,
        }
    }

    /// The written values (`sign ×` the tallies, every row, mirrored if [`mirrored`](Self::mirrored))
    /// and standard errors, read off a run's mean and standard error vectors. Image-like outputs
    /// come with their image rows reversed, row 0 = the largest `y` (the tallies keep row 0 at
    /// the lowest): the one place the written orientation is made, so that every file and every
    /// figure shows the detector plane as an image viewer does.
    pub fn values(&self, mean: &[f64], stderr: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let gather = |v: &[f64]| -> Vec<f64> {
            let rows = (0..self.slots.rows).map(|r| &v[self.slots.row_range(r)]);
            let v: Vec<f64> = if self.mirrored() {
                rows.flat_map(|row| row.iter().rev().copied()).collect()
            } else {
                rows.flat_map(|row| row.iter().copied()).collect()
            };
            self.flip_rows(v)
        };
        let v = gather(mean);
        let v = if self.sign == 1.0 { v } else { v.into_iter().map(|x| self.sign * x).collect() };
        (v, gather(stderr))
    }

    /// `v` with its image rows reversed (image-like outputs; unchanged otherwise). Its own
    /// inverse.
    fn flip_rows(&self, v: Vec<f64>) -> Vec<f64> {
        if let Kind::ImageStack { nx, ny, .. } = self.kind {
            if ny > 1 && v.len() % (nx * ny) == 0 {
                return v.chunks_exact(nx * ny).flat_map(|layer| rows_reversed(layer, nx)).collect();
            }
            return v;
        }
        match self.image_rows() {
            Some((ny, len)) if ny > 1 && v.len() == ny * len => rows_reversed(&v, len),
            _ => v,
        }
    }

    /// Written values (as [`values`](Self::values) gives them, or as read back from the output's
    /// file) in the tally's convention and order, its rows without their gaps: the sign undone,
    /// each row un-mirrored and image rows back to row 0 = the lowest `y`.
    pub fn to_tally(&self, written: &[f64]) -> Vec<f64> {
        let v = self.flip_rows(written.to_vec());
        let v: Vec<f64> = if self.mirrored() && self.slots.len > 0 {
            v.chunks(self.slots.len).flat_map(|row| row.iter().rev().copied()).collect()
        } else {
            v
        };
        // The sign is ±1: its own inverse.
        if self.sign == 1.0 { v } else { v.into_iter().map(|x| self.sign * x).collect() }
    }

    /// Per-pixel relative errors of an image output (`None` for other kinds), read off a run's
    /// mean and standard error vectors.
    pub fn pixel_errors(&self, mean: &[f64], stderr: &[f64]) -> Option<PixelErrors> {
        matches!(self.kind, Kind::Image { .. }).then(|| {
            let (v, e) = self.values(mean, stderr);
            PixelErrors::of(&v, &e)
        })
    }

    /// The below and above out-of-range tallies of row `r` of a spectrum, as written (swapped
    /// on a mirrored axis), read off `v` laid out as the tallies.
    pub fn tails(&self, v: &[f64], r: usize) -> (f64, f64) {
        let t = self.slots.row_range(r).end;
        if self.mirrored() { (v[t + 1], v[t]) } else { (v[t], v[t + 1]) }
    }
}

/// `v`, rows of `len` values, with the order of its rows reversed: an image tallied with row 0
/// at the lowest `y` as it is written, row 0 at the largest (and back). A `len` of 0 or a partial
/// last row leaves `v` as it is.
pub fn rows_reversed(v: &[f64], len: usize) -> Vec<f64> {
    if len == 0 || v.len() % len != 0 {
        return v.to_vec();
    }
    v.chunks_exact(len).rev().flatten().copied().collect()
}

/// The relative error `σ/|value|` of every pixel of an image, and its median and 90th
/// percentile over the pixels with a non-zero value (a pixel nothing reached has no relative
/// error: NaN in `map`, counted in `without_signal`; the percentiles are NaN if no pixel has one).
#[derive(Debug, Clone, PartialEq)]
pub struct PixelErrors {
    pub map: Vec<f64>,
    pub median: f64,
    pub p90: f64,
    pub without_signal: usize,
}

impl PixelErrors {
    pub fn of(values: &[f64], stderr: &[f64]) -> Self {
        let map: Vec<f64> =
            values.iter().zip(stderr).map(|(&v, &e)| if v != 0.0 { e / v.abs() } else { f64::NAN }).collect();
        let mut sorted: Vec<f64> = map.iter().copied().filter(|r| !r.is_nan()).collect();
        sorted.sort_by(f64::total_cmp);
        // Nearest rank: the smallest value with at least q of the pixels at or below it.
        let rank = |q: f64| {
            if sorted.is_empty() {
                f64::NAN
            } else {
                sorted[((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1]
            }
        };
        let (median, p90) = (rank(0.5), rank(0.9));
        PixelErrors { without_signal: map.len() - sorted.len(), map, median, p90 }
    }
}

/// Every output of an experiment, in declaration order, and the length of the tally vector.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Registry {
    pub len: usize,
    pub outputs: Vec<Output>,
}

impl Registry {
    /// Reserve `n` tally slots; returns the first.
    pub fn take(&mut self, n: usize) -> usize {
        let s = self.len;
        self.len += n;
        s
    }

    pub fn declare(&mut self, o: Output) {
        debug_assert!(o.slots.start + o.slots.footprint() <= self.len || o.slots.rows == 0);
        debug_assert!(!o.primary || o.slots.rows == 1, "a main output is one row");
        debug_assert!(self.get(&o.name).is_none(), "output {} declared twice", o.name);
        self.outputs.push(o);
    }

    /// The output called `name`.
    pub fn get(&self, name: &str) -> Option<&Output> {
        self.outputs.iter().find(|o| o.name == name)
    }

    /// The output called `name`, which the caller's detector declared (a bug otherwise).
    pub fn expect(&self, name: &str) -> &Output {
        self.get(name).unwrap_or_else(|| panic!("the output {name} is declared"))
    }

    /// The outputs of detector `i`, in declaration order.
    pub fn of_detector(&self, i: usize) -> impl Iterator<Item = &Output> {
        self.outputs.iter().filter(move |o| o.detector == Some(i))
    }

    /// The main outputs (see [`Output::primary`]): the scalar tallies, then per detector its
    /// power, total spectrum (per chirp), image, LDH M0± images and lidar range–Doppler spectra.
    pub fn named(&self) -> impl Iterator<Item = &Output> {
        self.outputs.iter().filter(|o| o.primary)
    }

    /// The run's main output, whose error `ohd run --target-error` controls and the progress bar
    /// shows: the first detector's LDH M0+ image, else its lidar range–Doppler spectra, else its
    /// (up-chirp) spectrum, else its image, else its power; without detectors the diffuse
    /// reflectance. Never g1, g2 or K: their values and σ exist only once the run's batches are
    /// all in (`detect::TallyLayout::finish_run`), while this error is read off the batches as
    /// they come; a correlation detector's power is what their noise follows.
    pub fn main(&self) -> &Output {
        let first: Vec<&Output> = self.named().filter(|o| o.detector == Some(0)).collect();
        let pick = |what: &str| first.iter().copied().find(|o| o.name.rsplit_once('.').is_some_and(|(_, w)| w == what));
        ["m0_plus", "range_doppler", "spectrum", "spectrum_up", "image", "detected_power"]
            .into_iter()
            .find_map(pick)
            .or_else(|| self.get("reflectance_diffuse"))
            .expect("the scalar tallies are always outputs")
    }

    /// The blocks of tallies that grow with a configuration key, `(key, value, slots)`, per
    /// detector in the order spectra, per-pixel spectra, the rest.
    pub fn budget_blocks(&self) -> Vec<(String, String, usize)> {
        let mut blocks: Vec<(usize, String, String, usize)> = Vec::new();
        for o in &self.outputs {
            let Some((key, value)) = &o.budget_key else { continue };
            let n = o.slots.footprint();
            match blocks.iter_mut().find(|b| &b.1 == key) {
                Some(b) => b.3 += n,
                None => blocks.push((o.detector.unwrap_or(usize::MAX), key.clone(), value.clone(), n)),
            }
        }
        let rank = |key: &str| {
            if key.ends_with(".spectrum.bins") {
                0
            } else if key.ends_with(".pixel_spectra") {
                1
            } else {
                2
            }
        };
        blocks.sort_by_key(|b| (b.0, rank(&b.1)));
        blocks.into_iter().map(|b| (b.1, b.2, b.3)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_errors_are_nearest_rank_percentiles_over_pixels_with_signal() {
        // Relative errors 0.1, 0.2, …, 1.0 over ten pixels with signal (signs do not matter),
        // and two pixels nothing reached.
        let mut values: Vec<f64> = (1..=10).map(|k| if k % 2 == 0 { -2.0 } else { 2.0 }).collect();
        let mut stderr: Vec<f64> = (1..=10).map(|k| 0.2 * k as f64).collect();
        values.extend([0.0, 0.0]);
        stderr.extend([0.0, 0.5]);
        let pe = PixelErrors::of(&values, &stderr);
        assert_eq!(pe.without_signal, 2);
        assert!(pe.map[10].is_nan() && pe.map[11].is_nan());
        assert!((pe.map[3] - 0.4).abs() < 1e-15);
        assert!((pe.median - 0.5).abs() < 1e-15, "median {}", pe.median);
        assert!((pe.p90 - 0.9).abs() < 1e-15, "p90 {}", pe.p90);
        let none = PixelErrors::of(&[0.0; 3], &[0.0; 3]);
        assert!(none.median.is_nan() && none.p90.is_nan() && none.without_signal == 3);
    }

    /// Images are written with row 0 = the largest `y` (the tally's last row), per-pixel spectra
    /// likewise by pixel row with each pixel's bins in order (mirrored when asked), and
    /// [`Output::to_tally`] undoes all of it.
    #[test]
    fn image_rows_are_written_top_first_and_read_back() {
        // A 3 × 2 image (nx = 3, ny = 2): tally row 0 (lowest y) = 0, 1, 2; row 1 = 3, 4, 5.
        let kind = Kind::Image { nx: 3, ny: 2, min: [0.0; 2], max: [1.0; 2] };
        let mut o = Output::new("cam.image".into(), kind, Slots::contiguous(1, 6), vec![2, 3]);
        let mean = [9.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 9.0];
        let se: Vec<f64> = mean.iter().map(|x| x / 10.0).collect();
        let (v, e) = o.values(&mean, &se);
        assert_eq!(v, [3.0, 4.0, 5.0, 0.0, 1.0, 2.0]);
        assert_eq!(e, [0.3, 0.4, 0.5, 0.0, 0.1, 0.2]);
        assert_eq!(o.to_tally(&v), &mean[1..7]);
        o.sign = -1.0;
        let (v, _) = o.values(&mean, &se);
        assert_eq!(v, [-3.0, -4.0, -5.0, -0.0, -1.0, -2.0]);
        assert_eq!(o.to_tally(&v), &mean[1..7]);

        // Per-pixel spectra of a 1 × 2 image, 2 bins and 2 out-of-range tallies per pixel.
        let axis = FrequencyAxis::new(-1.0, 1.0, 2).unwrap();
        let kind = Kind::PixelSpectra { nx: 1, ny: 2, axis, mirrored: true };
        let o = Output::new(
            "cam.pixel_spectra".into(),
            kind,
            Slots { start: 0, rows: 2, stride: 4, len: 2 },
            vec![2, 1, 2],
        );
        let mean = [1.0, 2.0, 90.0, 91.0, 3.0, 4.0, 92.0, 93.0];
        let (v, _) = o.values(&mean, &mean);
        assert_eq!(v, [4.0, 3.0, 2.0, 1.0], "top pixel row first, bins mirrored");
        assert_eq!(o.to_tally(&v), [1.0, 2.0, 3.0, 4.0]);

        // Other kinds keep their order.
        let kind = Kind::RangeDoppler { gates: 2, bins: 2 };
        let o = Output::new("lidar.range_doppler".into(), kind, Slots::contiguous(0, 4), vec![2, 2]);
        assert_eq!(o.values(&mean[..4], &mean[..4]).0, [1.0, 2.0, 90.0, 91.0]);
    }
}
