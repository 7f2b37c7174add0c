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
//! An output is declared once, completely: besides its slots, its kind, shape and [`Axis`] per
//! dimension, units, sign, [`Style`] and title for its figure, the memory key, and its
//! [`Derivation`] (a linear tally, or a ratio of grouped tallies whose σ is the group jackknife,
//! [`Registry::finish_run`]). The manifest's `outputs` table, the Python package and `ohd check`
//! read these declarations; writers find an output by the slot its detector's layout holds
//! ([`Registry::at`]), never by a formatted name.
//!
//! Adding an output: declare it where its detector lays out its tallies and record into its
//! slots; an image or array that no writer of its detector knows is written completely (files,
//! EXR, figure, manifest entry) as declared (`io::write::Writer::rest`).

use std::ops::Range;

use crate::spectrum::FrequencyAxis;
use crate::stats::{BatchAccumulator, GROUPS, jackknife_variance};

/// Units of the tallies that are fractions of the emitted power.
pub const POWER_UNITS: &str = "fraction of emitted power";
/// Units of a spectrum's bins.
pub const PER_BIN: &str = "fraction of emitted power per bin";
/// Units of an image's pixels.
pub const PER_PIXEL: &str = "fraction of emitted power per pixel";

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
    PixelSpectra { nx: usize, ny: usize, min: [f64; 2], max: [f64; 2], axis: FrequencyAxis, mirrored: bool },
    /// A series of `len` values in every pixel of an image, `[y][x][k]` (an acquisition's windows
    /// over the cardiac cycle), its rows ordered as an [`Kind::Image`]'s; the series' axis is
    /// named by its declaration.
    PixelSeries { nx: usize, ny: usize, min: [f64; 2], max: [f64; 2], len: usize },
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

/// One axis of an output's array: what an index along it means.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Axis {
    /// `frequency_hz`, `x_m`, `y_m`, `channel`, `time_s`, …
    pub name: String,
    pub units: &'static str,
    #[serde(flatten)]
    pub values: AxisValues,
}

/// The coordinates along an [`Axis`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisValues {
    /// Bin and pixel centres, `start + (k + ½)·width` for `k = 0 … count − 1` (as the axis files
    /// compute them, to the bit; `width` is negative for image rows, `y` descending).
    Bins { start: f64, width: f64, count: usize },
    /// `first + k·step` for `k = 0 … count − 1` (indices: windows, layers, time bins).
    Linear { first: f64, step: f64, count: usize },
    /// The values of the axis file of that name, written beside the output.
    File(String),
    /// Named entries (channels, path classes, parts).
    Labels(Vec<String>),
}

impl Axis {
    pub fn linear(name: &str, units: &'static str, first: f64, step: f64, count: usize) -> Self {
        Axis { name: name.to_string(), units, values: AxisValues::Linear { first, step, count } }
    }

    pub fn bins(name: &str, units: &'static str, start: f64, width: f64, count: usize) -> Self {
        Axis { name: name.to_string(), units, values: AxisValues::Bins { start, width, count } }
    }

    pub fn file(name: &str, units: &'static str, file: String) -> Self {
        Axis { name: name.to_string(), units, values: AxisValues::File(file) }
    }

    pub fn labels(name: &str, labels: Vec<String>) -> Self {
        Axis { name: name.to_string(), units: "", values: AxisValues::Labels(labels) }
    }

    /// Bin centres of a frequency axis as written (negated and reversed when `mirrored`).
    pub fn frequency(axis: &FrequencyAxis, mirrored: bool) -> Self {
        let start = if mirrored { -axis.f_max } else { axis.f_min };
        Axis::bins("frequency_hz", "Hz", start, axis.bin_width(), axis.bins)
    }

    /// The pixel rows (`y_m`, descending: row 0 = the largest `y`) and columns (`x_m`) of an
    /// image over `[min, max]`, centres in m.
    pub fn image(nx: usize, ny: usize, min: [f64; 2], max: [f64; 2]) -> [Self; 2] {
        let (dx, dy) = ((max[0] - min[0]) / nx as f64, (max[1] - min[1]) / ny as f64);
        [Axis::bins("y_m", "m", max[1], -dy, ny), Axis::bins("x_m", "m", min[0], dx, nx)]
    }
}

/// How an output's figure draws it: a sequential colour map from 0 for what is non-negative, a
/// diverging map on a symmetric range for what has a sign, a sequential map over the values'
/// spread for what is far from 0 everywhere (a mean frequency).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Style {
    Sequential,
    Diverging,
    Spread,
}

impl Kind {
    /// The axes of an array of this kind and `shape`, as far as the kind knows them: images,
    /// spectra and volumes fully; the first axis of a stack, curves and range–Doppler maps are
    /// named by their declarations.
    pub fn axes(&self, shape: &[usize]) -> Vec<Axis> {
        match self {
            Kind::Scalar | Kind::Internal | Kind::Curve | Kind::RangeDoppler { .. } => Vec::new(),
            Kind::Spectrum { axis, channels, mirrored } => {
                let f = Axis::frequency(axis, *mirrored);
                if shape.len() == 2 { vec![Axis::labels("channel", channels.clone()), f] } else { vec![f] }
            }
            &Kind::Image { nx, ny, min, max } => Axis::image(nx, ny, min, max).to_vec(),
            Kind::PixelSpectra { nx, ny, min, max, axis, mirrored } => {
                let [y, x] = Axis::image(*nx, *ny, *min, *max);
                vec![y, x, Axis::frequency(axis, *mirrored)]
            }
            &Kind::ImageStack { layers, nx, ny, min, max } => {
                let [y, x] = Axis::image(nx, ny, min, max);
                vec![Axis::linear("layer", "", 0.0, 1.0, layers), y, x]
            }
            &Kind::PixelSeries { nx, ny, min, max, len } => {
                let [y, x] = Axis::image(nx, ny, min, max);
                vec![y, x, Axis::linear("index", "", 0.0, 1.0, len)]
            }
            &Kind::Volume { voxels: [nx, ny, nz], min, max } => {
                let d = |a: usize, n: usize| (max[a] - min[a]) / n as f64;
                let z = Axis::bins("z_m", "m", min[2], d(2, nz), nz);
                let y = Axis::bins("y_m", "m", max[1], -d(1, ny), ny);
                let x = Axis::bins("x_m", "m", min[0], d(0, nx), nx);
                if shape.len() == 4 {
                    vec![Axis::linear("time_bin", "", 0.0, 1.0, shape[0]), z, y, x]
                } else {
                    vec![z, y, x]
                }
            }
        }
    }

    /// The name of the kind in the manifest's `outputs`.
    pub fn name(&self) -> &'static str {
        match self {
            Kind::Scalar => "scalar",
            Kind::Spectrum { .. } => "spectrum",
            Kind::Image { .. } => "image",
            Kind::PixelSpectra { .. } => "pixel_spectra",
            Kind::PixelSeries { .. } => "pixel_series",
            Kind::ImageStack { .. } => "image_stack",
            Kind::Curve => "curve",
            Kind::RangeDoppler { .. } => "range_doppler",
            Kind::Volume { .. } => "volume",
            Kind::Internal => "internal",
        }
    }
}

/// How an output's values come from the tallies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Derivation {
    /// Recorded into its slots: the mean over batches of the per-path means, σ their spread.
    #[default]
    Tally,
    /// Element by element `numerator / denominator` (`sqrt`: its square root) of two tally
    /// ranges of the output's length, each kept per group of batches ([`Registry::group`]): the
    /// value from the run's means, σ by the delete-one-group jackknife over [`GROUPS`] groups
    /// ([`Registry::finish_run`]). NaN where the ratio is undefined (a zero denominator, a
    /// negative ratio under the root), so such outputs are declared `undefined_nan`.
    Ratio { numerator: usize, denominator: usize, sqrt: bool },
    /// Three values of the waveform `source .. source + len` over an acquisition's windows, its
    /// tallies kept per group of batches: its largest value (systolic), its smallest (diastolic)
    /// and Pourcelot's resistivity index `(max − min)/max`, each from the run's means, σ by the
    /// delete-one-group jackknife (the windows' correlation, and which window is the largest,
    /// accounted for).
    Waveform { source: usize, len: usize },
}

/// The values of a [`Derivation::Waveform`], in its slots' order.
pub const WAVEFORM_VALUES: [&str; 3] = ["systolic", "diastolic", "resistivity_index"];

/// `[max, min, (max − min)/max]` of `w` (NaN for an index whose max is not positive).
fn waveform_values(w: impl Iterator<Item = f64>) -> [f64; 3] {
    let (lo, hi) = w.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    [hi, lo, if hi > 0.0 { (hi - lo) / hi } else { f64::NAN }]
}

/// A tally range whose per-batch values are also kept per group of batches (`[group][len]` from
/// `block`), for the jackknife of the outputs derived from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Grouped {
    pub source: usize,
    pub len: usize,
    pub block: usize,
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
    /// One per dimension of `shape` ([`Kind::axes`] unless declared otherwise).
    pub axes: Vec<Axis>,
    /// How its figure draws it.
    pub style: Style,
    /// What its figure is titled (after its detector's name); the output's name if empty.
    pub title: String,
    /// How its values come from the tallies.
    pub derivation: Derivation,
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
            axes: kind.axes(&shape),
            style: Style::Sequential,
            title: String::new(),
            derivation: Derivation::Tally,
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
            Kind::PixelSeries { nx, ny, len, .. } => Some((ny, nx * len)),
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

/// An image's per-pixel errors split by a mask of the regions' footprints (the pixels whose
/// vertical line meets a region, [`crate::detect::image::region_mask`]) and the rest: what a
/// study of vessels reads, where the all-pixel median mixes pixels of very different signal.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RegionErrors {
    /// Pixels in the mask.
    pub region_pixels: usize,
    /// Median `σ/|value|` over the mask's pixels and over the rest.
    pub median_region: Option<f64>,
    pub median_rest: Option<f64>,
    /// The rest's median `σ` over the mean value of the mask's pixels: the background's noise on
    /// the scale of the signal a study reads.
    pub rest_sigma_over_region_mean: Option<f64>,
    /// The share of the mask's pixels' summed variance held by their largest 1 % (at least one
    /// pixel): near 0.01 for a converged tail, near 1 when a few contributions dominate.
    pub region_top_percent_variance_share: Option<f64>,
    /// The relative error of the sum over the mask's pixels (their variances added).
    pub region_pooled: Option<f64>,
    /// ε: the RMS of the mask's pixels' σ over their mean value, `√(mean σ²)/|mean value|`
    /// (= `region_pooled · √region_pixels`), the relative error of a typical footprint pixel.
    /// Unlike the median it cannot read low: the pixels that have not yet drawn their rare large
    /// scores (small σ) do not hide those that have (issue 54).
    pub region_rms: Option<f64>,
    /// `N·ε²` over the run's `N` paths (set by the run, [`RegionErrors::with_run`]): the
    /// relative variance per path of a typical footprint pixel, so `ε` reaches `e` at
    /// `N·ε²/e²` paths. Constant in `N` once the tail is sampled; growing with `N` while it is not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub region_variance_per_path: Option<f64>,
    /// The slope of the largest of the paths' scores into the mask's pixels, pooled (MCNP's
    /// check, [`crate::stats::TailCheck`]; set by the run, [`RegionErrors::with_tail`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tail: Option<crate::stats::TailCheck>,
}

impl RegionErrors {
    /// The split of `values` and `stderr` by `mask` (same length).
    pub fn of(values: &[f64], stderr: &[f64], mask: &[bool]) -> Self {
        let finite = |v: f64| v.is_finite().then_some(v);
        let median = |mut r: Vec<f64>| {
            r.sort_by(f64::total_cmp);
            (!r.is_empty()).then(|| r[r.len() / 2])
        };
        let rel = |inside: bool| {
            values
                .iter()
                .zip(stderr)
                .zip(mask)
                .filter(|&((&v, _), &m)| m == inside && v != 0.0)
                .map(|((&v, &e), _)| e / v.abs())
                .collect::<Vec<f64>>()
        };
        let region: Vec<(f64, f64)> =
            values.iter().zip(stderr).zip(mask).filter(|(_, m)| **m).map(|((&v, &e), _)| (v, e)).collect();
        let n = region.len();
        let mean = region.iter().map(|r| r.0).sum::<f64>() / n.max(1) as f64;
        let rest_sigma: Vec<f64> = stderr.iter().zip(mask).filter(|(_, m)| !**m).map(|(&e, _)| e).collect();
        let mut var: Vec<f64> = region.iter().map(|r| r.1 * r.1).collect();
        var.sort_by(|a, b| b.total_cmp(a));
        let total: f64 = var.iter().sum();
        let top = var.iter().take((n / 100).max(1)).sum::<f64>();
        RegionErrors {
            region_pixels: n,
            median_region: median(rel(true)).and_then(finite),
            median_rest: median(rel(false)).and_then(finite),
            rest_sigma_over_region_mean: median(rest_sigma).map(|s| s / mean.abs()).and_then(finite),
            region_top_percent_variance_share: (total > 0.0).then(|| top / total),
            region_pooled: finite(total.sqrt() / (mean * n as f64).abs()),
            region_rms: finite((total / n as f64).sqrt() / mean.abs()),
            region_variance_per_path: None,
            tail: None,
        }
    }

    /// The same with the run's tail check of the image and its number of paths.
    pub fn with_run(self, tail: Option<crate::stats::TailCheck>, paths: f64) -> Self {
        let region_variance_per_path = self.region_rms.map(|e| paths * e * e);
        RegionErrors { tail, region_variance_per_path, ..self }
    }
}

/// An M0+ image's Monte Carlo error on the scale of the instrument's own noise: one window of the
/// LDH camera's set-up has the speckle contrast `c` over its band (a flat in-band spectrum,
/// [`crate::spectrum::stft::Stft::flat_band_contrast`]), the mean of `k` windows `c/√k`, so a
/// per-pixel relative error `σ` is the speckle noise of `k = (c/σ)²` windows. A simulated image is
/// as good as a measured one of `k` windows when its error is at most half theirs.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SpeckleScale {
    /// `c`: `σ/M0` of one window over the band.
    pub single_window_contrast: f64,
    /// Frames per window.
    pub window_frames: usize,
    /// `(c/σ)²` at the image's median per-pixel relative error, and at the medians of the regions'
    /// footprints and of the rest (with a mask of them).
    pub windows_at_median: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub windows_at_region_median: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub windows_at_rest_median: Option<f64>,
    /// `(c/ε)²` at the footprint's RMS relative error ε ([`RegionErrors::region_rms`]): the
    /// windows a measurement of the regions' pixels must average to be as noisy as the image
    /// there; the medians read high where a few pixels hold the variance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub windows_at_region_rms: Option<f64>,
}

impl SpeckleScale {
    /// The scale of an image with one window's contrast `contrast` over `frames` frames, its
    /// median per-pixel relative error `median` and, with a mask, its split `regions`.
    pub fn new(contrast: f64, frames: usize, median: f64, regions: Option<&RegionErrors>) -> Self {
        let windows = |sigma: Option<f64>| sigma.filter(|s| *s > 0.0 && s.is_finite()).map(|s| (contrast / s).powi(2));
        SpeckleScale {
            single_window_contrast: contrast,
            window_frames: frames,
            windows_at_median: windows(Some(median)),
            windows_at_region_median: windows(regions.and_then(|r| r.median_region)),
            windows_at_rest_median: windows(regions.and_then(|r| r.median_rest)),
            windows_at_region_rms: windows(regions.and_then(|r| r.region_rms)),
        }
    }
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
    /// The tally ranges kept per group of batches ([`Registry::group`]).
    pub grouped: Vec<Grouped>,
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
        debug_assert!(self.outputs.iter().all(|x| x.name != o.name), "output {} declared twice", o.name);
        self.outputs.push(o);
    }

    /// Keep the tallies `source .. source + len` per group of batches as well (once, however
    /// many outputs are derived from them), in an internal output `name` of detector `detector`
    /// whose memory grows with `budget_key`.
    pub fn group(
        &mut self,
        name: String,
        detector: Option<usize>,
        source: usize,
        len: usize,
        budget: Option<(String, String)>,
    ) {
        if self.grouped.iter().any(|g| g.source == source && g.len == len) {
            return;
        }
        let block = self.take(GROUPS * len);
        self.declare(Output {
            detector,
            budget_key: budget,
            ..Output::new(name, Kind::Internal, Slots::contiguous(block, GROUPS * len), vec![GROUPS, len])
        });
        self.grouped.push(Grouped { source, len, block });
    }

    /// File a finished batch (number `batch` of the run) under its group: each grouped range's
    /// sums added into its group's block.
    pub fn finish_batch(&self, sums: &mut [f64], batch: u64) {
        let h = (batch % GROUPS as u64) as usize;
        for g in &self.grouped {
            let to = g.block + h * g.len;
            for j in 0..g.len {
                sums[to + j] += sums[g.source + j];
            }
        }
    }

    /// Give every derived output ([`Derivation::Ratio`]) its value from the run's means and its
    /// variance by the delete-one-group jackknife over the groups that hold batches. Applied once,
    /// when a run's batches are all folded in, whatever the threads, shards or resumes.
    pub fn finish_run(&self, est: &mut BatchAccumulator) {
        let b = est.batches();
        let used = b.min(GROUPS);
        let block = |source: usize| self.grouped.iter().find(|g| g.source == source).map(|g| (g.block, g.len));
        for o in &self.outputs {
            if let Derivation::Waveform { source, len } = o.derivation {
                let Some((g, _)) = block(source) else { unreachable!("{}: the waveform is grouped", o.name) };
                let m = est.mean();
                let values = waveform_values(m[source..source + len].iter().copied());
                // Replicate h: the mean over the batches outside group h (which holds Σ over its
                // batches / B of the per-batch means).
                let reps: Vec<[f64; 3]> = (0..used)
                    .map(|h| {
                        let n_h = (b - h).div_ceil(GROUPS) as f64;
                        let scale = b as f64 / (b as f64 - n_h);
                        waveform_values((0..len).map(|j| scale * (m[source + j] - m[g + h * len + j])))
                    })
                    .collect();
                for (k, &value) in values.iter().enumerate() {
                    let var = if b < 3 { 0.0 } else { jackknife_variance(reps.iter().map(|r| r[k])) };
                    est.set_mean(o.slots.start + k, value);
                    est.set_variance(o.slots.start + k, if value.is_finite() { var } else { f64::NAN });
                }
                continue;
            }
            let Derivation::Ratio { numerator, denominator, sqrt } = o.derivation else { continue };
            let (Some((num_block, len)), Some((den_block, _))) = (block(numerator), block(denominator)) else {
                unreachable!("{}: the tallies of a ratio are grouped", o.name)
            };
            let f = |a: f64, d: f64| {
                let r = if d != 0.0 { a / d } else { f64::NAN };
                if sqrt { if r >= 0.0 { r.sqrt() } else { f64::NAN } } else { r }
            };
            for j in 0..o.slots.len {
                let m = est.mean();
                let (a, d) = (m[numerator + j], m[denominator + j]);
                let value = f(a, d);
                // Replicate h: the run without group h's batches (the slots hold Σ over them / B).
                let reps = (0..used).map(|h| f(a - m[num_block + h * len + j], d - m[den_block + h * len + j]));
                let var = if b < 3 { 0.0 } else { jackknife_variance(reps) };
                let slot = o.slots.start + j;
                est.set_mean(slot, value);
                est.set_variance(slot, if value.is_finite() { var } else { f64::NAN });
            }
        }
    }

    /// The last line of defence against non-finite outputs (issue 21, item 4): validation refuses
    /// what cannot give finite output, so a NaN or an infinity in a run's estimates or standard errors
    /// is a bug, and the run fails (exit status 1) naming the first output that holds one, before any
    /// file is written, rather than write it silently (NaN is let through where an output documents it
    /// as undefined: [`crate::output::Output::undefined_nan`]). Every written output is checked, its
    /// out-of-range tallies included; internal ones (a lidar's lag sums) are not written, and show in
    /// the outputs made from them.
    pub fn check_finite(&self, mean: &[f64], stderr: &[f64]) -> crate::error::Result<()> {
        for o in self.outputs.iter().filter(|o| o.kind != Kind::Internal) {
            let slots = o.slots.start..o.slots.start + o.slots.footprint();
            let bad = |x: &f64| if o.undefined_nan { x.is_infinite() } else { !x.is_finite() };
            let count = |v: &[f64]| v[slots.clone()].iter().filter(|x| bad(x)).count();
            let (values, errors) = (count(mean), count(stderr));
            if values + errors > 0 {
                let what = format!(
                    "output {} ({values} of its {} values and {errors} of their standard errors; file {})",
                    o.name,
                    slots.len(),
                    o.file.trim_start_matches('/')
                );
                return Err(crate::error::Error::NotFinite { what, count: values + errors });
            }
        }
        Ok(())
    }

    /// The output whose values start at tally slot `start` (a slot its detector's layout holds).
    pub fn at(&self, start: usize) -> &Output {
        self.outputs
            .iter()
            .find(|o| o.slots.start == start && o.kind != Kind::Internal)
            .unwrap_or_else(|| panic!("an output is declared at slot {start}"))
    }

    /// The output called `name`, as a user names it (tests and scripts; the crate's own code
    /// finds an output by the slot its detector's layout holds, [`Registry::at`]).
    pub fn get(&self, name: &str) -> Option<&Output> {
        self.outputs.iter().find(|o| o.name == name)
    }

    /// The output called `name`, which must be declared ([`Registry::get`]).
    pub fn expect(&self, name: &str) -> &Output {
        self.get(name).unwrap_or_else(|| panic!("the output {name} is declared"))
    }

    /// The outputs of detector `i`, in declaration order.
    pub fn of_detector(&self, i: usize) -> impl Iterator<Item = &Output> {
        self.outputs.iter().filter(move |o| o.detector == Some(i))
    }

    /// The outputs whose first slot lies in `slots` (a part's block), in declaration order.
    pub fn within(&self, slots: std::ops::Range<usize>) -> impl Iterator<Item = &Output> {
        self.outputs.iter().filter(move |o| slots.contains(&o.slots.start) && o.kind != Kind::Internal)
    }

    /// The main outputs (see [`Output::primary`]): the scalar tallies, then per detector its
    /// power, total spectrum (per chirp), image, LDH M0± images and lidar range–Doppler spectra.
    pub fn named(&self) -> impl Iterator<Item = &Output> {
        self.outputs.iter().filter(|o| o.primary)
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

    /// A waveform's systolic and diastolic values and resistivity index from the run's means,
    /// their σ the delete-one-group jackknife of the same three values over the means of the
    /// batches outside each group (computed here from the batches themselves).
    #[test]
    fn waveform_values_and_their_jackknife() {
        let len = 5;
        let mut reg = Registry::default();
        let source = reg.take(len);
        reg.group("w_groups".into(), None, source, len, None);
        let o = reg.take(3);
        reg.declare(Output {
            derivation: Derivation::Waveform { source, len },
            ..Output::new("w".into(), Kind::Curve, Slots::contiguous(o, 3), vec![3])
        });
        let batches = 2 * GROUPS + 3;
        let paths = 10u64;
        let mut rng = crate::sampling::PathRng::new(4, crate::sampling::Purpose::Test, 0, 0);
        let mut est = BatchAccumulator::new(reg.len);
        let mut means: Vec<Vec<f64>> = Vec::new();
        for b in 0..batches {
            let mut sums = vec![0.0; reg.len];
            for (j, s) in sums[source..source + len].iter_mut().enumerate() {
                // A pulse peaking at window 1, with noise.
                let shape = [1.0, 1.8, 1.3, 1.0, 0.9][j];
                *s = paths as f64 * (shape + 0.3 * (rng.uniform() - 0.5));
            }
            means.push(sums[source..source + len].iter().map(|s| s / paths as f64).collect());
            reg.finish_batch(&mut sums, b as u64);
            est.push(&sums, paths);
        }
        reg.finish_run(&mut est);
        let all: Vec<f64> = (0..len).map(|j| means.iter().map(|m| m[j]).sum::<f64>() / batches as f64).collect();
        let want = waveform_values(all.iter().copied());
        let reps: Vec<[f64; 3]> = (0..GROUPS)
            .map(|h| {
                let kept: Vec<&Vec<f64>> =
                    means.iter().enumerate().filter(|(b, _)| b % GROUPS != h).map(|(_, m)| m).collect();
                waveform_values((0..len).map(|j| kept.iter().map(|m| m[j]).sum::<f64>() / kept.len() as f64))
            })
            .collect();
        let stderr = est.stderr();
        for k in 0..3 {
            let var = jackknife_variance(reps.iter().map(|r| r[k]));
            let (got, err) = (est.mean()[o + k], stderr[o + k]);
            assert!((got - want[k]).abs() < 1e-12 * want[k].abs(), "{}: {got} vs {}", WAVEFORM_VALUES[k], want[k]);
            assert!((err - var.sqrt()).abs() < 1e-9 * var.sqrt(), "{}: σ {err} vs {}", WAVEFORM_VALUES[k], var.sqrt());
            assert!(err > 0.0);
        }
        assert!((want[2] - 0.8 / 1.8).abs() < 0.1, "{want:?}");
    }

    /// ε is the RMS of the footprint's σ over its mean, which one noisy pixel among quiet ones
    /// moves where the median does not; the variance per path is N·ε².
    #[test]
    fn the_footprints_rms_error_reads_the_noisy_pixel_the_median_hides() {
        // 99 footprint pixels of value 1 and σ 0.1, one of value 1 and σ 10; one pixel outside.
        let mut values = vec![1.0; 100];
        let mut stderr = vec![0.1; 100];
        stderr[7] = 10.0;
        values.push(5.0);
        stderr.push(0.5);
        let mask: Vec<bool> = (0..101).map(|p| p < 100).collect();
        let r = RegionErrors::of(&values, &stderr, &mask).with_run(None, 1e6);
        assert!((r.median_region.unwrap() - 0.1).abs() < 1e-15);
        let eps = ((99.0 * 0.01 + 100.0) / 100.0f64).sqrt();
        assert!((r.region_rms.unwrap() - eps).abs() < 1e-12, "ε {:?} against {eps}", r.region_rms);
        assert!((r.region_rms.unwrap() - r.region_pooled.unwrap() * 10.0).abs() < 1e-12);
        assert!((r.region_variance_per_path.unwrap() - 1e6 * eps * eps).abs() < 1e-6);
        assert!(RegionErrors::of(&values, &stderr, &mask).region_variance_per_path.is_none());
    }

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
        let kind = Kind::PixelSpectra { nx: 1, ny: 2, min: [0.0; 2], max: [1.0; 2], axis, mirrored: true };
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
