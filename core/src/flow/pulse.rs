//! Pulsatile flows: velocities that repeat over a cardiac cycle.
//!
//! A path's Doppler shift is linear in the velocities it meets,
//! `dl/dt = Σ_events n (d_in − d_out)·v(x, t)`, and its geometry does not depend on them. A flow
//! written as a Fourier series over the cycle, `v(x, t) = V_0(x) + Σ_k Re[V_k(x) e^{ikωt}]`, so
//! gives every path a few complex numbers `F_k = Σ_events n (d_in − d_out)·V_k(x)` beside its
//! steady `dl/dt` (the `V_0` term, which the walk already carries), and its rate at any time of
//! the cycle, `dl/dt(t) = dl/dt + Σ_k Re[F_k e^{ikωt}]` ([`Harmonics::rate`]), without tracing it
//! again. Every pulsatile flow of a scene shares one heart rate (ω) and one set of harmonics.
//!
//! Two kinds of time dependence:
//! - **separable**: a profile times a waveform, `v(x, t) = v(x)·s(t)` with `s` normalised to a
//!   cycle mean of 1 ([`Waveform`]), so that the configured field `v(x)` is the cycle-mean flow.
//!   Any velocity field (analytic, grid) and a population's random velocity dispersion pulse so;
//! - **Womersley** flow in a rigid circular tube (Womersley 1955, J. Physiol. 127:553): harmonic
//!   `k` of the mean velocity drives the profile [`womersley_profile`] of Womersley number
//!   `α_k = R·√(kω/ν)`; at `α → 0` it is Poiseuille's and the flow is separable.

use std::sync::Arc;

use glam::DVec3;
use num_complex::Complex64;

/// The most harmonics a scene's paths carry (each costs two numbers per path and a term per
/// window at every detection). A waveform with sharper features than 32 harmonics resolve is
/// beyond the quasi-static windows anyway (a 70 bpm cycle's 32nd harmonic has a 27 ms period).
pub const MAX_HARMONICS: usize = 32;

/// Harmonics kept when a waveform does not say.
pub const DEFAULT_HARMONICS: usize = 10;

/// The largest Womersley number of a tube's highest harmonic: the profile's series
/// ([`womersley_profile`]) keeps 10⁻¹² relative precision up to it (the aorta's α is ≈ 20;
/// the retinal vessels' ≈ 0.1).
pub const MAX_WOMERSLEY: f64 = 50.0;

/// The kinematic viscosity of blood, m²/s: η ≈ 3.5 mPa·s at high shear over ρ ≈ 1060 kg/m³
/// [unverified: textbook values recalled, not read from a source here].
pub const BLOOD_KINEMATIC_VISCOSITY: f64 = 3.5e-3 / 1060.0;

/// The cardiac cycle every pulsatile flow of a scene shares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cycle {
    /// Angular frequency of the heart rate, rad/s.
    pub omega: f64,
    /// Harmonics the paths carry (the most any of the scene's waveforms keeps), `1..=MAX_HARMONICS`.
    pub harmonics: usize,
}

impl Cycle {
    /// The cycle's period, s.
    pub fn period(&self) -> f64 {
        std::f64::consts::TAU / self.omega
    }

    /// `e^{ikωt}` for `k = 1..=harmonics`, the factors of [`Harmonics::rate`] at time `t`.
    pub fn phasors(&self, t: f64) -> Vec<Complex64> {
        // The phase of the fundamental reduced to one period first, so that late windows keep
        // their precision.
        let phase = (t / self.period()).rem_euclid(1.0) * std::f64::consts::TAU;
        (1..=self.harmonics).map(|k| Complex64::from_polar(1.0, k as f64 * phase)).collect()
    }
}

/// A waveform over the cardiac cycle relative to its mean: `s(t) = 1 + Σ_k Re[s_k e^{ikωt}]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Waveform {
    /// `s_k` for `k = 1..=K`.
    pub harmonics: Vec<Complex64>,
}

/// Why a waveform could not be built (the resolver names the key).
#[derive(Debug, Clone, PartialEq)]
pub enum WaveformError {
    /// Its mean over the cycle is not positive: a waveform is relative to its mean.
    MeanNotPositive(f64),
    /// Too few samples for the harmonics asked (`samples`, the least needed).
    TooFewSamples(usize, usize),
}

impl std::fmt::Display for WaveformError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WaveformError::MeanNotPositive(m) => write!(
                f,
                "its mean over the cycle is {m:e}: a waveform must have a positive mean (it scales the configured cycle-mean velocity)"
            ),
            WaveformError::TooFewSamples(n, need) => {
                write!(f, "{n} samples over the cycle resolve fewer harmonics than asked: give at least {need}")
            }
        }
    }
}

impl Waveform {
    /// A steady waveform (`s ≡ 1`, no harmonic).
    pub fn steady() -> Self {
        Waveform { harmonics: Vec::new() }
    }

    /// From the real coefficients `[a_k, b_k]` of `s(t) = 1 + Σ a_k cos(kωt) + b_k sin(kωt)`.
    pub fn from_fourier(pairs: &[[f64; 2]]) -> Self {
        Waveform { harmonics: pairs.iter().map(|&[a, b]| Complex64::new(a, -b)).collect() }
    }

    /// From `values` at `N` equally spaced times over one cycle (the first at `t = 0`, the
    /// cycle not closed: the value at `T` is the first's), keeping `harmonics` harmonics of its
    /// discrete Fourier transform, relative to its mean.
    pub fn from_samples(values: &[f64], harmonics: usize) -> Result<Self, WaveformError> {
        let n = values.len();
        if n < 2 * harmonics + 1 {
            return Err(WaveformError::TooFewSamples(n, 2 * harmonics + 1));
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        if mean.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(WaveformError::MeanNotPositive(mean));
        }
        let harmonics = (1..=harmonics)
            .map(|k| {
                let sum: Complex64 = values
                    .iter()
                    .enumerate()
                    .map(|(j, &v)| {
                        let phase = std::f64::consts::TAU * ((k * j) % n) as f64 / n as f64;
                        Complex64::from_polar(v, -phase)
                    })
                    .sum();
                sum * (2.0 / (n as f64 * mean))
            })
            .collect();
        Ok(Waveform { harmonics })
    }

    /// The same waveform `delay` seconds later, `s(t − delay)`, on a cycle of angular frequency
    /// `omega`.
    pub fn delayed(&self, delay: f64, omega: f64) -> Self {
        let harmonics = self
            .harmonics
            .iter()
            .enumerate()
            .map(|(i, &s)| s * Complex64::from_polar(1.0, -((i + 1) as f64) * omega * delay))
            .collect();
        Waveform { harmonics }
    }

    /// The same waveform without its trailing zero harmonics (a steady one has none).
    pub fn trimmed(mut self) -> Self {
        while self.harmonics.last().is_some_and(|z| *z == Complex64::new(0.0, 0.0)) {
            self.harmonics.pop();
        }
        self
    }

    /// Its value at time `t` of a cycle of angular frequency `omega`.
    pub fn value(&self, omega: f64, t: f64) -> f64 {
        let phase = omega * t;
        1.0 + self
            .harmonics
            .iter()
            .enumerate()
            .map(|(i, s)| (s * Complex64::from_polar(1.0, (i + 1) as f64 * phase)).re)
            .sum::<f64>()
    }

    /// Its extremes over the cycle `(min, max)`, from 1024 equally spaced times.
    pub fn extremes(&self) -> (f64, f64) {
        let n = 1024;
        (0..n)
            .map(|j| self.value(std::f64::consts::TAU, j as f64 / n as f64))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
    }

    /// Pourcelot's resistivity index `(max − min)/max` of the waveform.
    pub fn resistivity_index(&self) -> f64 {
        let (lo, hi) = self.extremes();
        (hi - lo) / hi
    }

    /// One of the built-in shapes ([`Shape`]) with resistivity index `ri` (before the truncation to
    /// `harmonics`, which rounds its corners: [`Waveform::resistivity_index`] gives the kept one).
    pub fn built_in(shape: Shape, ri: f64, harmonics: usize) -> Self {
        let n = 512;
        let raw: Vec<f64> = (0..n).map(|j| shape.raw(j as f64 / n as f64)).collect();
        let (lo, hi) = raw.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let values: Vec<f64> = raw.iter().map(|v| (1.0 - ri) + ri * (v - lo) / (hi - lo)).collect();
        Waveform::from_samples(&values, harmonics).expect("a built-in shape has a positive mean and 512 samples")
    }
}

/// The built-in waveform shapes: smooth illustrative shapes of the published velocity waveforms'
/// features (a systolic peak early in the cycle, a dicrotic bump, a diastolic decay), scaled to a
/// resistivity index. Their shapes and default indices are illustrative [unverified]: give a
/// measured waveform as coefficients or a table for a study.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A sharp systolic peak at 12 % of the cycle, a dicrotic bump at 35 % and a slow diastolic
    /// decay.
    Artery,
    /// A broad, nearly sinusoidal swing peaking at 30 % of the cycle.
    Vein,
    /// The arterial shape, broadened (a capillary bed's damped pulse).
    Choroid,
}

impl Shape {
    pub const NAMES: [&'static str; 3] = ["artery", "vein", "choroid"];

    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "artery" => Some(Shape::Artery),
            "vein" => Some(Shape::Vein),
            "choroid" => Some(Shape::Choroid),
            _ => None,
        }
    }

    /// The default resistivity index of the shape's velocity [unverified]: colour Doppler imaging
    /// of the central retinal artery reads RI ≈ 0.7 (peak systolic ≈ 10 cm/s, end diastolic
    /// ≈ 3 cm/s); the central retinal vein pulses far less; the choroid's waveform is synchronous
    /// with the arteries' but less pulsatile (Puyo et al. 2019, Biomed. Opt. Express 10:4942).
    pub fn default_resistivity_index(self) -> f64 {
        match self {
            Shape::Artery => 0.7,
            Shape::Vein => 0.3,
            Shape::Choroid => 0.4,
        }
    }

    /// The unscaled shape at phase `x ∈ [0, 1)`.
    fn raw(self, x: f64) -> f64 {
        // A Gaussian bump of the phase, wrapped over the cycle.
        let bump = |c: f64, w: f64| {
            let d = (x - c + 0.5).rem_euclid(1.0) - 0.5;
            (-0.5 * (d / w).powi(2)).exp()
        };
        let decay = |x: f64| (-(x - 0.12).rem_euclid(1.0) / 0.45).exp();
        match self {
            Shape::Artery => bump(0.12, 0.045) + 0.35 * bump(0.35, 0.06) + 0.3 * decay(x),
            Shape::Vein => 0.5 * (1.0 + (std::f64::consts::TAU * (x - 0.3)).cos()),
            Shape::Choroid => bump(0.14, 0.08) + 0.35 * bump(0.40, 0.09) + 0.3 * decay(x),
        }
    }
}

/// The axial velocity of a Womersley harmonic of Womersley number `alpha` at `rho = r/R`, per unit
/// mean velocity over the cross-section: `u(ρ)/ū = [1 − J0(Λρ)/J0(Λ)] / [1 − 2J1(Λ)/(ΛJ0(Λ))]`,
/// `Λ = i^{3/2}α` (Womersley 1955). Summed as the series of its numerator and denominator,
/// `Σ_{m≥1} a_m (1 − ρ^{2m})` over `Σ_{m≥1} a_m m/(m+1)` with `a_m = (iα²/4)^m/(m!)²`, in which
/// the leading 1s of the Bessel functions cancel exactly: no loss of precision as `α → 0`, where
/// it tends to Poiseuille's `2(1 − ρ²)`. Zero at and beyond the wall.
pub fn womersley_profile(alpha: f64, rho: f64) -> Complex64 {
    if rho >= 1.0 {
        return Complex64::new(0.0, 0.0);
    }
    let x = Complex64::new(0.0, alpha * alpha / 4.0);
    let rho2 = rho * rho;
    let (mut num, mut den) = (Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0));
    let mut a = Complex64::new(1.0, 0.0);
    let mut rho_pow = 1.0;
    for m in 1..400 {
        let mf = m as f64;
        a = a * x / (mf * mf);
        rho_pow *= rho2;
        let dn = a * (1.0 - rho_pow);
        let dd = a * (mf / (mf + 1.0));
        num += dn;
        den += dd;
        if dd.norm() <= 1e-17 * den.norm() && dn.norm() <= 1e-17 * num.norm().max(den.norm()) {
            break;
        }
    }
    num / den
}

/// A tube's Womersley flow, its profile per harmonic tabulated over `ρ²` for the walk.
#[derive(Debug, Clone, PartialEq)]
pub struct WomersleyTube {
    pub origin: DVec3,
    pub axis: DVec3,
    pub radius: f64,
    /// Cycle-mean centre-line speed, m/s.
    pub v_max: f64,
    /// Angular frequency of the cycle, rad/s.
    pub omega: f64,
    /// Womersley number of the fundamental, `R·√(ω/ν)`.
    pub alpha: f64,
    /// The waveform of its mean velocity.
    pub waveform: Waveform,
    /// `[k − 1][i]`: `ū·s_k·u_k(ρ)/ū_k` at `ρ² = i/(TABLE − 1)` (m/s), the harmonic's axial velocity.
    table: Vec<Vec<Complex64>>,
}

/// Points of a Womersley table over `ρ² ∈ [0, 1]`.
const TABLE: usize = 1025;

impl WomersleyTube {
    /// The tube of cycle-mean centre-line speed `v_max` (the Poiseuille profile of the mean flow;
    /// its mean velocity is `v_max/2`) whose mean velocity follows `waveform`, fundamental
    /// Womersley number `alpha`.
    pub fn new(
        origin: DVec3,
        axis: DVec3,
        radius: f64,
        (v_max, omega): (f64, f64),
        alpha: f64,
        waveform: &Waveform,
    ) -> Self {
        let mean = 0.5 * v_max;
        let table = waveform
            .harmonics
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                let a = alpha * ((i + 1) as f64).sqrt();
                (0..TABLE)
                    .map(|j| {
                        let rho = (j as f64 / (TABLE - 1) as f64).sqrt();
                        womersley_profile(a, rho) * s * mean
                    })
                    .collect()
            })
            .collect();
        WomersleyTube { origin, axis, radius, v_max, omega, alpha, waveform: waveform.clone(), table }
    }

    /// The same tube with every velocity multiplied by `k`.
    pub fn scaled(&self, k: f64) -> Self {
        let table = self.table.iter().map(|row| row.iter().map(|z| z * k).collect()).collect();
        WomersleyTube { v_max: k * self.v_max, table, ..self.clone() }
    }

    /// The velocity at `p` at time `t` of the cycle: the mean flow's Poiseuille profile plus every
    /// harmonic's Womersley profile then.
    pub fn velocity_at(&self, p: DVec3, t: f64) -> DVec3 {
        let d = p - self.origin;
        let radial = d - d.dot(self.axis) * self.axis;
        let s = radial.length_squared() / (self.radius * self.radius);
        if s >= 1.0 {
            return DVec3::ZERO;
        }
        // Read at every scattering event of a frozen run: no allocation, one sine and cosine
        // (the harmonics' phasors by recurrence from the fundamental's).
        let x = s * (TABLE - 1) as f64;
        let i = (x as usize).min(TABLE - 2);
        let u = x - i as f64;
        let phase = (t * self.omega / std::f64::consts::TAU).rem_euclid(1.0) * std::f64::consts::TAU;
        let e1 = Complex64::from_polar(1.0, phase);
        let (mut e, mut v) = (e1, self.v_max * (1.0 - s));
        for row in &self.table {
            v += ((row[i] * (1.0 - u) + row[i + 1] * u) * e).re;
            e *= e1;
        }
        self.axis * v
    }

    /// Add `n·(axis·delta)·V_k(p)` to `f` (harmonic `k` at `f[k − 1]`).
    #[inline]
    fn add(&self, f: &mut [Complex64], p: DVec3, n_delta_axial: f64) {
        let d = p - self.origin;
        let radial = d - d.dot(self.axis) * self.axis;
        let s = radial.length_squared() / (self.radius * self.radius);
        if s >= 1.0 {
            return;
        }
        let x = s * (TABLE - 1) as f64;
        let i = (x as usize).min(TABLE - 2);
        let t = x - i as f64;
        for (fk, row) in f.iter_mut().zip(&self.table) {
            *fk += (row[i] * (1.0 - t) + row[i + 1] * t) * n_delta_axial;
        }
    }
}

/// How a population's velocities pulse ([`crate::medium::Population::pulse`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Pulse {
    /// The flow's time dependence (`None`: steady).
    pub flow: Option<FlowPulse>,
    /// The random velocity dispersion's waveform `s_k` (`None`: steady).
    pub dispersion: Option<Arc<Waveform>>,
}

/// How a flow depends on time.
#[derive(Debug, Clone, PartialEq)]
pub enum FlowPulse {
    /// `v(x)·s(t)`.
    Separable(Arc<Waveform>),
    /// Womersley flow in the field's Poiseuille tube.
    Womersley(Arc<WomersleyTube>),
}

impl Pulse {
    /// Whether anything pulses.
    pub fn is_pulsatile(&self) -> bool {
        self.flow.is_some() || self.dispersion.is_some()
    }

    /// The most harmonics its waveforms keep (0 if steady).
    pub fn harmonics(&self) -> usize {
        let flow = match &self.flow {
            None => 0,
            Some(FlowPulse::Separable(w)) => w.harmonics.len(),
            Some(FlowPulse::Womersley(t)) => t.table.len(),
        };
        flow.max(self.dispersion.as_ref().map_or(0, |w| w.harmonics.len()))
    }

    /// The harmonics of a scattering event at `p` with `dir_in − dir_out = delta` in a layer of
    /// index `n`, on a particle whose cycle-mean flow velocity is `flow` and random velocity
    /// `random`, added to `f`.
    #[inline]
    pub fn event(&self, f: &mut [Complex64], p: DVec3, n: f64, flow: DVec3, random: DVec3, delta: DVec3) {
        match &self.flow {
            None => {}
            Some(FlowPulse::Separable(w)) => add_scaled(f, &w.harmonics, n * flow.dot(delta)),
            Some(FlowPulse::Womersley(tube)) => tube.add(f, p, n * tube.axis.dot(delta)),
        }
        if let Some(w) = &self.dispersion {
            add_scaled(f, &w.harmonics, n * random.dot(delta));
        }
    }
}

#[inline]
fn add_scaled(f: &mut [Complex64], s: &[Complex64], x: f64) {
    for (fk, sk) in f.iter_mut().zip(s) {
        *fk += sk * x;
    }
}

/// A path's harmonic Doppler components `F_k` (m/s), `k = 1..=K`.
pub type Harmonics = [Complex64];

/// The rate `dl/dt` at the time whose phasors ([`Cycle::phasors`]) are `e`, of a path whose steady
/// rate is `dldt` and harmonics `f`.
#[inline]
pub fn rate(dldt: f64, f: &Harmonics, e: &[Complex64]) -> f64 {
    dldt + f.iter().zip(e).map(|(a, b)| a.re * b.re - a.im * b.im).sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `J_n(z)` by its power series (independent of the cancellation-free form under test).
    fn bessel(n: u32, z: Complex64) -> Complex64 {
        let mut term = (z / 2.0).powu(n) / (1..=n).map(f64::from).product::<f64>();
        let mut sum = term;
        for m in 1..200 {
            let mf = m as f64;
            term = -term * (z / 2.0) * (z / 2.0) / (mf * (mf + n as f64));
            sum += term;
        }
        sum
    }

    #[test]
    fn bessel_series_matches_kelvin_tables() {
        // J0(x e^{3πi/4}) = ber x + i bei x; Abramowitz & Stegun Table 9.12.
        let z = |x: f64| Complex64::from_polar(x, 0.75 * std::f64::consts::PI);
        for (x, ber, bei) in [(1.0, 0.984_381_781_6, 0.249_566_040_0), (2.0, 0.751_734_182_7, 0.972_291_627_3)] {
            let j = bessel(0, z(x));
            assert!((j.re - ber).abs() < 1e-9 && (j.im - bei).abs() < 1e-9, "x = {x}: {j}");
        }
    }

    #[test]
    fn womersley_profile_is_the_closed_form() {
        for alpha in [0.5, 1.0, 3.0, 7.0, 15.0, 25.0] {
            let lambda = Complex64::from_polar(alpha, 0.75 * std::f64::consts::PI);
            let j0 = bessel(0, lambda);
            let den = 1.0 - 2.0 * bessel(1, lambda) / (lambda * j0);
            for rho in [0.0, 0.3, 0.7, 0.95] {
                let want = (1.0 - bessel(0, lambda * rho) / j0) / den;
                let got = womersley_profile(alpha, rho);
                assert!((got - want).norm() < 1e-9 * want.norm().max(1.0), "α {alpha}, ρ {rho}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn womersley_profile_solves_its_equation_and_carries_the_mean() {
        // u'' + u'/ρ − iα²u is constant over the radius (the pressure gradient), u(1) = 0, and
        // the mean over the cross-section, ∫ 2ρ u dρ, is 1.
        for alpha in [0.01, 2.0, 10.0, 40.0] {
            let u = |r: f64| womersley_profile(alpha, r);
            let h = 1e-3;
            let lhs = |r: f64| {
                let d2 = (u(r + h) - 2.0 * u(r) + u(r - h)) / (h * h);
                let d1 = (u(r + h) - u(r - h)) / (2.0 * h);
                d2 + d1 / r - Complex64::new(0.0, alpha * alpha) * u(r)
            };
            let scale = lhs(0.2).norm();
            for r in [0.1, 0.4, 0.6, 0.8, 0.9] {
                assert!((lhs(r) - lhs(0.2)).norm() < 1e-4 * scale.max(1.0), "α {alpha}, ρ {r}");
            }
            assert!(womersley_profile(alpha, 1.0 - 1e-12).norm() < 1e-9 * scale.max(1.0));
            let n = 20_000;
            let mean: Complex64 = (0..n)
                .map(|i| {
                    let r = (i as f64 + 0.5) / n as f64;
                    u(r) * (2.0 * r / n as f64)
                })
                .sum();
            assert!((mean - 1.0).norm() < 1e-6, "α {alpha}: mean {mean}");
        }
        // α → 0: Poiseuille's 2(1 − ρ²), to α²-order.
        for rho in [0.0, 0.5, 0.9] {
            assert!((womersley_profile(1e-4, rho) - 2.0 * (1.0 - rho * rho)).norm() < 1e-8);
        }
        // α → ∞: a flat core moving at the mean.
        assert!((womersley_profile(MAX_WOMERSLEY, 0.0) - 1.0).norm() < 4.0 / MAX_WOMERSLEY);
    }

    #[test]
    fn a_tube_carries_its_waveform() {
        // The mean velocity over the cross-section at time t is v_max/2·s(t), for every t.
        let w = Waveform::built_in(Shape::Artery, 0.7, 10);
        let (v_max, radius, alpha) = (0.016, 55e-6, 4.0);
        let omega = 7.0;
        let tube = WomersleyTube::new(DVec3::ZERO, DVec3::X, radius, (v_max, omega), alpha, &w);
        let n = 400;
        for t in [0.0, 0.1, 0.37, 0.8] {
            let e: Vec<Complex64> = (1..=10).map(|k| Complex64::from_polar(1.0, k as f64 * omega * t)).collect();
            let mut mean = 0.0;
            for i in 0..n {
                let r = (i as f64 + 0.5) / n as f64;
                let mut f = vec![Complex64::new(0.0, 0.0); 10];
                tube.add(&mut f, DVec3::new(0.3, r * radius, 0.0), 1.0);
                let steady = v_max * (1.0 - r * r);
                mean += rate(steady, &f, &e) * 2.0 * r / n as f64;
            }
            let want = 0.5 * v_max * w.value(omega, t);
            assert!((mean - want).abs() < 1e-4 * v_max, "t = {t}: {mean} vs {want}");
            // Frozen at t, the tube's field is the same profile.
            let p = DVec3::new(0.1, 0.37 * radius, 0.2 * radius);
            let mut f = vec![Complex64::new(0.0, 0.0); 10];
            tube.add(&mut f, p, 1.0);
            let s = 0.37f64.powi(2) + 0.2f64.powi(2);
            let frozen = tube.velocity_at(p, t);
            assert!((frozen.x - rate(v_max * (1.0 - s), &f, &e)).abs() < 1e-15 && frozen.y == 0.0);
        }
    }

    #[test]
    fn waveforms_from_samples_fourier_and_delays() {
        // A sampled 1 + 0.5 cos(ωt) − 0.2 sin(2ωt), scaled by 3, comes back relative to its mean.
        let n = 64;
        let v: Vec<f64> = (0..n)
            .map(|j| {
                let p = std::f64::consts::TAU * j as f64 / n as f64;
                3.0 * (1.0 + 0.5 * p.cos() - 0.2 * (2.0 * p).sin())
            })
            .collect();
        let w = Waveform::from_samples(&v, 4).unwrap();
        let f = Waveform::from_fourier(&[[0.5, 0.0], [0.0, -0.2], [0.0, 0.0], [0.0, 0.0]]);
        for (a, b) in w.harmonics.iter().zip(&f.harmonics) {
            assert!((a - b).norm() < 1e-12, "{a} vs {b}");
        }
        for t in [0.0, 0.3, 1.1] {
            assert!((w.value(1.0, t) - f.value(1.0, t)).abs() < 1e-12);
            assert!((w.delayed(0.2, 1.0).value(1.0, t) - w.value(1.0, t - 0.2)).abs() < 1e-12);
        }
        assert_eq!(Waveform::from_samples(&[1.0, -1.0, 0.0], 1), Err(WaveformError::MeanNotPositive(0.0)));
        assert_eq!(Waveform::from_samples(&[1.0; 4], 2), Err(WaveformError::TooFewSamples(4, 5)));
        // Built-in shapes keep their index to within the truncation's rounding, mean 1.
        for shape in [Shape::Artery, Shape::Vein, Shape::Choroid] {
            let ri = shape.default_resistivity_index();
            let w = Waveform::built_in(shape, ri, 10);
            assert!((w.resistivity_index() - ri).abs() < 0.08, "{shape:?}: {}", w.resistivity_index());
        }
        assert_eq!(Waveform::steady().resistivity_index(), 0.0);
    }
}
