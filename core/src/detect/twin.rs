//! The layered control variate of a forward-estimated camera (`run.control_variate`).
//!
//! A scene of infinite layers with regions in them (vessels, spheres) has a *layered twin*: the
//! same stack with every region's medium replaced by its layer's filling medium (and without
//! opaque solids; the planar surfaces, a bottom and rough faces, stay: the twin reflects and
//! crosses there as its path does, and their shadow rays carry it). The twin's
//! camera response is laterally invariant, so it is a kernel over the lateral offset between a
//! path's entry point and where it meets the camera, convolved with the beam's footprint (CONV,
//! Wang, Jacques & Zheng 1997). Every forward path carries, beside its own contributions `f`, its
//! twin's `Λ·f_twin`, `Λ` being the likelihood ratio of the path under the twin (flights and
//! perturbation Monte Carlo as Hayakawa et al. 2001: the flights' transmittance ratios, and for
//! a collision in a region `σs,layer·p_layer / (σs·p)` of the particles and direction drawn, until
//! `Λ` leaves a band and the twin parts from the path to walk on by itself, `transport::carried::Split`; or where
//! the path meets an opaque solid, which the twin flies on through), and `f_twin` what the twin
//! scores (its phase function and Doppler shift, shadow rays without the regions' optical depth;
//! after parting, its own walk's).
//! Through a region of a density field (a ramp, a VDB grid) the twin is not weighted but
//! delta-tracked with its path, one uniform deciding each tentative collision for both, and parts
//! from it where they disagree (`transport::tracking::coupled_flight`). The
//! image is then
//!
//! `I(p) = Σ_j m_j·K(p − j) + (1/N)·Σ_paths [f(p) − Λ·f_twin(p)]`,
//!
//! where `K` is the kernel of every path's `Λ·f_twin` by offset and `m_j` the footprint's mass in
//! launch cell `j`: unbiased, since `E[Λ·f_twin] = I_twin`. A path that never touched a region
//! has `Λ = 1` and `f_twin = f`: it adds nothing to the pixels, only to the kernel, which pools
//! all paths of the batch — the image's background is as converged as the detected power.
//!
//! The offsets are binned on the image's pixel grid, each splatted bilinearly over the four
//! nearest offsets: that is the exact distribution of the offset in pixels for an entry point
//! uniform in its cell, so the convolution is exact for a footprint constant over each launch
//! cell (the disk's interior) and off by `O(h²)` of the profile's curvature elsewhere (a
//! Gaussian's, and the cells the disk's rim cuts). A pencil beam's single entry point is binned
//! as it falls (no splat), which is exact. The kernel of each batch is convolved by FFT at the
//! end of the batch, so that the images' batch statistics carry its noise.
//!
//! ROI values and spectra need no kernel: each twin contribution adds `Λ·f_twin` times the
//! footprint's mass within the ROI shifted by its offset, which the footprint gives in closed
//! form ([`crate::source::Footprint::mass_in_rect`]).

use std::sync::Arc;

use num_complex::Complex64;
use ohd_fft::{Fft, Planner};

use super::{ImageSpec, PathState, Twin};
use crate::source::{Footprint, Profile};

/// The twin's bookkeeping along one forward path: where it entered the stack, the likelihood
/// ratio `Λ` of the path under the twin and how the twin's Doppler state differs from the path's
/// (events on particles of a region are the twin's on its layer's medium), until the twin parts
/// from the path (`transport::carried::Split`) and walks on by itself.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinPath {
    /// The entry point on the top surface, m.
    pub launch: (f64, f64),
    pub lambda: f64,
    /// The twin's `dl/dt`, Brownian sum and Doppler events minus the path's.
    pub dldt: f64,
    pub brownian: f64,
    pub doppler_events: i64,
    /// Whether the path has met a region (flown through one, or collided in one): until then its
    /// twin is itself.
    pub touched: bool,
    /// The twin's own walk after it parted from its path: what it scores is the twin's alone.
    pub only: bool,
}

impl TwinPath {
    /// A path entering the stack at `(x, y)`.
    #[inline]
    pub fn new(x: f64, y: f64) -> Self {
        TwinPath {
            launch: (x, y),
            lambda: 1.0,
            dldt: 0.0,
            brownian: 0.0,
            doppler_events: 0,
            touched: false,
            only: false,
        }
    }

    /// A flight whose regions' optical depth exceeded that of the layer's filling medium by
    /// `excess` (the twin's transmittance over the path's: `exp(excess)`).
    #[inline]
    pub fn flight(&mut self, excess: f64) {
        if excess != 0.0 {
            self.lambda *= excess.exp();
            self.touched = true;
        }
        debug_assert!(self.lambda >= 0.0 && !self.lambda.is_nan(), "the twin's Λ = {} after a flight", self.lambda);
    }

    /// The twin of the path's state `e` (its weight times `Λ`, its Doppler state).
    #[inline]
    pub fn state(&self, e: &PathState) -> PathState {
        debug_assert!(self.lambda >= 0.0 && !self.lambda.is_nan(), "the twin's Λ = {}", self.lambda);
        PathState {
            weight: e.weight * self.lambda,
            dldt: e.dldt + self.dldt,
            brownian: e.brownian + self.brownian,
            doppler_events: (i64::from(e.doppler_events) + self.doppler_events).max(0) as u32,
            ..*e
        }
    }

    /// What the twin scores of the path's contribution `e`: the twin's alone in its own walk,
    /// the path's own share until it meets a region, else its own state.
    #[inline]
    pub fn share(&self, e: &PathState) -> Twin {
        match self {
            t if t.only => Twin::Only(t.launch),
            t if !t.touched => Twin::Same(t.launch),
            t => Twin::Other(t.state(e), t.launch),
        }
    }
}

/// Where a camera's twin kernels lie and how they become its images: the offset grid, the
/// footprint's masses by launch cell and their FFT, and the image blocks the kernels' channels
/// are convolved into.
#[derive(Clone)]
pub struct TwinLayout {
    pub footprint: Footprint,
    /// Pixel pitch, m.
    pitch: (f64, f64),
    /// The image's lower corner, m.
    origin: (f64, f64),
    /// The image's pixels.
    image: (usize, usize),
    /// The offsets (in pixels) of the kernel's first column and row, and its size.
    first: (i64, i64),
    size: (usize, usize),
    /// Launch cells: the footprint's first cell and the number of cells along x and y.
    cells: (usize, usize),
    /// Splat bilinearly (every profile but the pencil).
    splat: bool,
    /// The tally slot of each channel's first pixel (the image's, then the LDH maps').
    pub blocks: Vec<usize>,
    /// The pixels the convolution leaves alone: a `estimator = "footprints"` camera's camera
    /// pixels, whose light the camera paths estimate ([`super::image::Footprints`]).
    pub skip: Option<Arc<super::image::Footprints>>,
    /// FFT sizes, the footprint's transform (transposed: `[x][y]`) and the plans.
    fft: (usize, usize),
    masses: Arc<Vec<Complex64>>,
    plans: Plans,
}

#[derive(Clone)]
struct Plans {
    x: Arc<dyn Fft<f64>>,
    y: Arc<dyn Fft<f64>>,
    x_inv: Arc<dyn Fft<f64>>,
    y_inv: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for TwinLayout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TwinLayout")
            .field("footprint", &self.footprint)
            .field("kernel", &self.size)
            .field("channels", &self.blocks.len())
            .field("fft", &self.fft)
            .finish()
    }
}

impl PartialEq for TwinLayout {
    fn eq(&self, o: &Self) -> bool {
        self.footprint == o.footprint && self.pitch == o.pitch && self.image == o.image && self.blocks == o.blocks
    }
}

/// The footprint's extent from its centre beyond which its mass is below 1e-18 (a Gaussian's
/// tail: `exp(−2r²/w²) < 1e-18` beyond 4.55 w), m.
fn reach(profile: Profile) -> f64 {
    match profile {
        Profile::Pencil => 0.0,
        Profile::Disk { radius } => radius,
        Profile::Gaussian { waist } => 4.55 * waist,
    }
}

/// The smallest size ≥ `n` whose only prime factors are 2, 3 and 5 (fast for the FFT).
fn fast_size(n: usize) -> usize {
    (n.max(1)..)
        .find(|&m| {
            let mut k = m;
            for p in [2, 3, 5] {
                while k % p == 0 {
                    k /= p;
                }
            }
            k == 1
        })
        .expect("a 5-smooth number exists above any n")
}

/// The offsets of the kernel of a camera with image `im` under the footprint `fp` (per map):
/// `(nx + cells_x − 1)·(ny + cells_y − 1)`, the launch cells covering the footprint on the
/// image's pixel grid (saturating: a huge image gives a huge count, never an overflow).
pub fn kernel_offsets(im: &ImageSpec, fp: Footprint) -> usize {
    let r = reach(fp.profile);
    let cells = |n: usize, lo: f64, hi: f64| {
        let h = (hi - lo) / n as f64;
        let c = (2.0 * r / h).ceil() + 2.0;
        (n as f64 + c).min(1e18)
    };
    let (x, y) = (cells(im.nx, im.min[0], im.max[0]), cells(im.ny, im.min[1], im.max[1]));
    (x * y).min(usize::MAX as f64 / 2.0) as usize
}

impl TwinLayout {
    /// The kernels of a camera with image `im` under the footprint `fp`, convolved into the image
    /// blocks `blocks` (first slot of each per-pixel map).
    pub fn new(im: &ImageSpec, fp: Footprint, blocks: Vec<usize>) -> Self {
        let pitch = ((im.max[0] - im.min[0]) / im.nx as f64, (im.max[1] - im.min[1]) / im.ny as f64);
        let origin = (im.min[0], im.min[1]);
        let r = reach(fp.profile);
        let cell = |v: f64, o: f64, h: f64| ((v - o) / h).floor() as i64;
        let (j0x, j1x) = (cell(fp.center.0 - r, origin.0, pitch.0), cell(fp.center.0 + r, origin.0, pitch.0) + 1);
        let (j0y, j1y) = (cell(fp.center.1 - r, origin.1, pitch.1), cell(fp.center.1 + r, origin.1, pitch.1) + 1);
        let cells = ((j1x - j0x) as usize, (j1y - j0y) as usize);
        // Offsets from launch cell j to pixel p: i = p − j over p ∈ [0, n), j ∈ [j0, j1).
        let first = (-(j1x - 1), -(j1y - 1));
        let size = (im.nx + cells.0 - 1, im.ny + cells.1 - 1);
        let fft = (fast_size(size.0), fast_size(size.1));
        let mut planner = Planner::new();
        let plans = Plans {
            x: planner.forward(fft.0),
            y: planner.forward(fft.1),
            x_inv: planner.inverse(fft.0),
            y_inv: planner.inverse(fft.1),
        };
        // The footprint's mass per launch cell, transformed.
        let mut m = vec![Complex64::new(0.0, 0.0); fft.0 * fft.1];
        for cy in 0..cells.1 {
            let y0 = origin.1 + (j0y + cy as i64) as f64 * pitch.1;
            for cx in 0..cells.0 {
                let x0 = origin.0 + (j0x + cx as i64) as f64 * pitch.0;
                m[cy * fft.0 + cx].re = fp.mass_in_rect((x0, x0 + pitch.0), (y0, y0 + pitch.1));
            }
        }
        let masses = Arc::new(forward_2d(&plans, fft, m));
        TwinLayout {
            footprint: fp,
            pitch,
            origin,
            image: (im.nx, im.ny),
            first,
            size,
            cells,
            splat: fp.profile != Profile::Pencil,
            blocks,
            skip: None,
            fft,
            masses,
            plans,
        }
    }

    /// Slots of one batch's kernels: every channel's offset grid.
    pub fn kernel_len(&self) -> usize {
        self.blocks.len() * self.size.0 * self.size.1
    }

    /// The kernel's size in offsets (x, y) and the FFT's.
    pub fn sizes(&self) -> ((usize, usize), (usize, usize)) {
        (self.size, self.fft)
    }

    /// Add a twin contribution, which met the camera plane at `(x, y)` after entering at
    /// `launch`, with `values[c]` in channel `c`, to the kernels `kernel` (`[offset][channel]`:
    /// a contribution's channels share cache lines).
    #[inline]
    pub fn record(&self, kernel: &mut [f64], launch: (f64, f64), (x, y): (f64, f64), values: &[f64]) {
        let channels = self.blocks.len();
        let mut add = |ix: i64, iy: i64, w: f64| {
            let (kx, ky) = (ix - self.first.0, iy - self.first.1);
            if w == 0.0 || kx < 0 || ky < 0 || kx >= self.size.0 as i64 || ky >= self.size.1 as i64 {
                return;
            }
            let k = (ky as usize * self.size.0 + kx as usize) * channels;
            for (a, &v) in kernel[k..k + channels].iter_mut().zip(values) {
                *a += w * v;
            }
        };
        if self.splat {
            let (dx, dy) = ((x - launch.0) / self.pitch.0, (y - launch.1) / self.pitch.1);
            if !(dx.is_finite() && dy.is_finite()) {
                return;
            }
            let (fx, fy) = (dx.floor(), dy.floor());
            let (ax, ay) = (dx - fx, dy - fy);
            let (ix, iy) = (fx as i64, fy as i64);
            add(ix, iy, (1.0 - ax) * (1.0 - ay));
            add(ix + 1, iy, ax * (1.0 - ay));
            add(ix, iy + 1, (1.0 - ax) * ay);
            add(ix + 1, iy + 1, ax * ay);
        } else {
            let cell = |v: f64, o: f64, h: f64| ((v - o) / h).floor();
            let ix = cell(x, self.origin.0, self.pitch.0) - cell(launch.0, self.origin.0, self.pitch.0);
            let iy = cell(y, self.origin.1, self.pitch.1) - cell(launch.1, self.origin.1, self.pitch.1);
            if ix.is_finite() && iy.is_finite() {
                add(ix as i64, iy as i64, 1.0);
            }
        }
    }

    /// The footprint's mass within the rectangle `[min, max)` shifted back by the offset of a
    /// contribution from `launch` to `(x, y)`: the probability that a path entering anywhere
    /// in the footprint would meet the plane within it, for a laterally invariant twin.
    #[inline]
    pub fn shifted_mass(&self, min: [f64; 2], max: [f64; 2], launch: (f64, f64), (x, y): (f64, f64)) -> f64 {
        let (dx, dy) = (x - launch.0, y - launch.1);
        self.footprint.mass_in_rect((min[0] - dx, max[0] - dx), (min[1] - dy, max[1] - dy))
    }

    /// Convolve one batch's kernels with the footprint's masses and add them into the images of
    /// `sums`.
    pub fn convolve(&self, kernel: &[f64], sums: &mut [f64]) {
        let channels = self.blocks.len();
        let (nx, ny) = self.fft;
        let scale = 1.0 / (nx * ny) as f64;
        let (px, py) = self.image;
        // Two real channels per complex transform: the footprint's masses are real, so the real
        // and imaginary parts of the product's inverse are the two convolutions.
        for pair in (0..self.blocks.len()).collect::<Vec<_>>().chunks(2) {
            let channel = |c: usize| kernel.iter().skip(c).step_by(channels);
            if pair.iter().all(|&c| channel(c).all(|&v| v == 0.0)) {
                continue;
            }
            let mut buf = vec![Complex64::new(0.0, 0.0); nx * ny];
            // The bound on the transform's rounding of an output pixel, of both channels: the
            // pair shares one transform, so one channel's rounding reaches the other's output.
            let l1: f64 = pair.iter().map(|&c| channel(c).map(|v| v.abs()).sum::<f64>()).sum();
            let floor = rounding_floor(l1, (nx, ny));
            for (slot, &c) in pair.iter().enumerate() {
                for ky in 0..self.size.1 {
                    for kx in 0..self.size.0 {
                        let v = kernel[(ky * self.size.0 + kx) * channels + c];
                        let b = &mut buf[ky * nx + kx];
                        if slot == 0 {
                            b.re = v;
                        } else {
                            b.im = v;
                        }
                    }
                }
            }
            let mut t = forward_2d(&self.plans, self.fft, buf);
            for (a, m) in t.iter_mut().zip(self.masses.iter()) {
                *a *= m;
            }
            let out = inverse_2d(&self.plans, self.fft, t);
            // Output pixel p is the linear convolution's index p + cells − 1.
            let skipped = |p: usize| self.skip.as_ref().is_some_and(|f| f.mask[p]);
            for (slot, &c) in pair.iter().enumerate() {
                let block = self.blocks[c];
                for y in 0..py {
                    for x in (0..px).filter(|&x| !skipped(y * px + x)) {
                        let v = out[(y + self.cells.1 - 1) * nx + x + self.cells.0 - 1];
                        let v = scale * if slot == 0 { v.re } else { v.im };
                        // Rounding residue where the convolution is 0 (beyond the footprint's
                        // reach) is given as 0: it was ±10⁻²³ of either sign, a negative M0+.
                        if v.abs() > floor {
                            sums[block + y * px + x] += v;
                        }
                    }
                }
            }
        }
    }
}

/// The bound on the rounding of one output of an FFT convolution of size `nx × ny` of kernels
/// with `Σ|K| = kernel_l1` and the footprint's masses (each ≤ 1): `4 ε log₂(nx·ny) Σ|K|`, from
/// the FFT's `O(ε log N)` error per transform (forward, product, inverse), bounded by the largest
/// possible output `Σ|K|·max m` (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd
/// ed., §24.1). Below it a value is zero as far as the transform can tell.
fn rounding_floor(kernel_l1: f64, (nx, ny): (usize, usize)) -> f64 {
    4.0 * f64::EPSILON * ((nx * ny) as f64).log2().max(1.0) * kernel_l1
}

/// The 2-D FFT of the row-major `[y][x]` array `a` (sizes `(nx, ny)`), returned transposed
/// (`[x][y]`).
fn forward_2d(p: &Plans, (nx, ny): (usize, usize), mut a: Vec<Complex64>) -> Vec<Complex64> {
    p.x.process(&mut a);
    let mut t = transpose(&a, nx, ny);
    p.y.process(&mut t);
    t
}

/// The inverse of [`forward_2d`] (unnormalised), from its transposed layout back to `[y][x]`.
fn inverse_2d(p: &Plans, (nx, ny): (usize, usize), mut t: Vec<Complex64>) -> Vec<Complex64> {
    p.y_inv.process(&mut t);
    let mut a = transpose(&t, ny, nx);
    p.x_inv.process(&mut a);
    a
}

/// `[rows][cols]` → `[cols][rows]`.
fn transpose(a: &[Complex64], cols: usize, rows: usize) -> Vec<Complex64> {
    let mut t = vec![Complex64::new(0.0, 0.0); a.len()];
    for r in 0..rows {
        for c in 0..cols {
            t[c * rows + r] = a[r * cols + c];
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(n: usize) -> ImageSpec {
        ImageSpec { nx: n, ny: n + 3, min: [-1e-3, -1.2e-3], max: [1e-3, 1.3e-3] }
    }

    #[test]
    fn disk_masses_sum_to_one_and_match_the_quadrature() {
        let fp = Footprint { center: (1.3e-4, -2e-4), profile: Profile::Disk { radius: 7e-4 } };
        let h = 5e-5;
        let mut total = 0.0;
        for i in -20..20 {
            for j in -20..20 {
                let (x0, y0) = (i as f64 * h, j as f64 * h);
                let m = fp.mass_in_rect((x0, x0 + h), (y0, y0 + h));
                // Midpoint quadrature, 100² points per cell.
                let k = 100;
                let mut q = 0.0;
                for a in 0..k {
                    for b in 0..k {
                        let x = x0 + (a as f64 + 0.5) * h / k as f64 - 1.3e-4;
                        let y = y0 + (b as f64 + 0.5) * h / k as f64 + 2e-4;
                        q += f64::from(u8::from(x * x + y * y <= 49e-8));
                    }
                }
                let q = q / (k * k) as f64 * h * h / (std::f64::consts::PI * 49e-8);
                // The quadrature of an indicator is off by ~1/k of a cell the rim cuts.
                let cell = h * h / (std::f64::consts::PI * 49e-8);
                assert!((m - q).abs() < 0.02 * cell, "{i},{j}: {m} vs {q}");
                total += m;
            }
        }
        assert!((total - 1.0).abs() < 1e-12, "{total}");
    }

    #[test]
    fn gaussian_masses_sum_to_one() {
        let fp = Footprint { center: (0.0, 1e-4), profile: Profile::Gaussian { waist: 3e-4 } };
        let h = 4e-5;
        let total: f64 = (-60..60)
            .flat_map(|i| (-60..60).map(move |j| (i, j)))
            .map(|(i, j)| fp.mass_in_rect((i as f64 * h, (i + 1) as f64 * h), (j as f64 * h, (j + 1) as f64 * h)))
            .sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
    }

    /// A non-negative kernel of compact support convolves to exactly 0 beyond the footprint's
    /// reach, never to FFT residue of either sign (issue 37: M0+ images had −10⁻²³ there).
    #[test]
    fn convolution_is_exactly_zero_beyond_its_support() {
        let im = image(9);
        let fp = Footprint { center: (0.0, 0.0), profile: Profile::Pencil };
        // Two channels sharing one transform: the second is 0 everywhere (a static class's M0+).
        let lay = TwinLayout::new(&im, fp, vec![0, 9 * 12]);
        let n = lay.size.0 * lay.size.1;
        // One offset cell lit, at widely different scales: the pencil puts it on one pixel.
        let mut kernel = vec![0.0; 2 * n];
        let lit = (lay.size.1 / 2) * lay.size.0 + lay.size.0 / 2;
        kernel[2 * lit] = 2.3e-6;
        kernel[2 * (lit + 1)] = 1e-30;
        let mut sums = vec![0.0; 2 * 9 * 12];
        lay.convolve(&kernel, &mut sums);
        let (first, second) = sums.split_at(9 * 12);
        let nonzero: Vec<f64> = first.iter().copied().filter(|v| *v != 0.0).collect();
        assert!(first.iter().all(|v| *v >= 0.0), "{first:?}");
        assert!(!nonzero.is_empty() && nonzero.len() <= 2, "{nonzero:?}");
        assert!(nonzero.iter().any(|v| (v - 2.3e-6).abs() < 1e-18), "{nonzero:?}");
        assert!(second.iter().all(|v| *v == 0.0), "the zero channel: {second:?}");
    }

    #[test]
    fn convolution_matches_the_direct_sum() {
        // A kernel of random values: the FFT convolution equals Σ_j m_j K(p − j) term by term.
        for profile in [Profile::Disk { radius: 4e-4 }, Profile::Gaussian { waist: 2e-4 }, Profile::Pencil] {
            let im = image(9);
            let fp = Footprint { center: (1e-4, -3e-5), profile };
            let lay = TwinLayout::new(&im, fp, vec![0, 9 * 12]);
            let n = lay.size.0 * lay.size.1;
            let mut rng = crate::sampling::PathRng::new(3, crate::sampling::Purpose::Test, 0, 0);
            // `[offset][channel]`.
            let kernel: Vec<f64> = (0..2 * n).map(|_| rng.uniform() - 0.3).collect();
            let mut sums = vec![0.0; 2 * 9 * 12];
            lay.convolve(&kernel, &mut sums);
            let (h, o) = (lay.pitch, lay.origin);
            for c in 0..2 {
                for py in 0..im.ny as i64 {
                    for px in 0..im.nx as i64 {
                        let mut direct = 0.0;
                        for cy in 0..lay.cells.1 as i64 {
                            for cx in 0..lay.cells.0 as i64 {
                                // Launch cell j = j0 + c, j0 = −first − cells + 1.
                                let jx = -lay.first.0 - lay.cells.0 as i64 + 1 + cx;
                                let jy = -lay.first.1 - lay.cells.1 as i64 + 1 + cy;
                                let x0 = o.0 + jx as f64 * h.0;
                                let y0 = o.1 + jy as f64 * h.1;
                                let m = fp.mass_in_rect((x0, x0 + h.0), (y0, y0 + h.1));
                                let (kx, ky) = (px - jx - lay.first.0, py - jy - lay.first.1);
                                direct += m * kernel[(ky as usize * lay.size.0 + kx as usize) * 2 + c];
                            }
                        }
                        let got = sums[c * 9 * 12 + (py * 9 + px) as usize];
                        assert!(
                            (got - direct).abs() < 1e-12,
                            "{profile:?} channel {c} pixel {px},{py}: {got} vs {direct}"
                        );
                    }
                }
            }
        }
    }
}
