//! The only place random-number generators are built.
//!
//! A stream is a pure function of `(seed, purpose, element, sample)`: `element` is the batch (or a
//! pixel, in later applications) and `sample` the path index inside it, so any path can be
//! replayed from those four numbers, independently of threads and scheduling.
//! The key is mixed with the SplitMix64 finaliser and, xored with the sample index, seeds a
//! xoshiro256++ generator through SplitMix64 (see [`StreamKey::path`]).

use rand::rngs::Xoshiro256PlusPlus;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Exp1, StandardNormal};

/// What a stream is used for; different purposes never share numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Purpose {
    /// Random walks of photon paths.
    Path = 0x5041_5448,
    /// Camera paths ([`crate::transport::camera`]): element = batch and detector, sample = the
    /// path's index in the batch (pixel-major).
    Camera = 0x4341_4d52,
    /// Anything a test needs.
    Test = 0x5445_5354,
    /// Speckle of single measurements: Algorithm 2's random phases and Cauchy frequencies,
    /// Algorithm 1's per-bin `Exp(1)` draws ([`crate::spectrum::synth`]).
    Speckle = 0x5350_4543,
    /// The slots camera paths' broadened spectral lines are drawn into
    /// ([`crate::spectrum::FrequencyAxis::drawn_slot`]): element = batch and detector.
    Lines = 0x4c49_4e45,
    /// The light field's pre-pass ([`crate::transport::field`]): element 0, sample = the path.
    Field = 0x4649_454c,
    /// The slots of the broadened lines of an acquisition's windows over the cardiac cycle
    /// ([`crate::detect::ldh::LdhSpec::record_windows`]): element = batch, one stream.
    Windows = 0x5749_4e44,
}

/// SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mixer.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The key of all streams of one `(seed, purpose, element)`; [`StreamKey::path`] gives the stream
/// of one sample. Hoisting it out of the per-path loop saves three mixing rounds per path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamKey(u64);

impl StreamKey {
    pub fn new(seed: u64, purpose: Purpose, element: u64) -> Self {
        StreamKey(mix64(mix64(mix64(seed) ^ purpose as u64) ^ element))
    }

    /// The stream of sample `sample`: xoshiro256++ seeded by `seed_from_u64(key ^ sample)`, i.e.
    /// with the four SplitMix64 outputs `mix64(key ^ sample + k·φ)`, `k = 0..4` (the seeding the
    /// xoshiro authors recommend).
    ///
    /// `key ^ sample` is not mixed again first (that was a fifth `mix64` per path, ~19
    /// instructions, 1.5% of a van de Hulst path): the key is already a SplitMix64 output, and
    /// the inputs `(key ^ s) + k·φ` are pairwise distinct over all samples `s < 2⁶⁰` and all `k`
    /// (a coincidence needs `(key ^ s) − (key ^ s′) ≡ j·φ` with `0 < |j| ≤ 3`; the left side is
    /// below 2⁶⁰ in magnitude, every such `j·φ` is above it), so every state word is the bijective
    /// finaliser of its own input, as in SplitMix64's own output sequence. Mixing first would
    /// only relabel those distinct inputs.
    #[inline]
    pub fn path(self, sample: u64) -> PathRng {
        PathRng(Xoshiro256PlusPlus::seed_from_u64(self.0 ^ sample))
    }
}

/// A per-path random-number stream.
///
/// Performance: the walk keeps the 32-byte state in four registers only as long as no outlined
/// function receives `&mut PathRng` (once its address escapes, every draw loads and stores the
/// state from the stack; measured: 217.3M → 201.6M instructions per 200k van de Hulst paths).
/// Outlined callees are therefore given the numbers they need, or the generator by value: that
/// is what `Clone` is for, and a clone repeats the numbers of its original, so it must replace
/// it (as in `free_flight`), never run beside it.
#[derive(Clone)]
pub struct PathRng(Xoshiro256PlusPlus);

impl PathRng {
    /// The stream for `(seed, purpose, element, sample)`.
    pub fn new(seed: u64, purpose: Purpose, element: u64, sample: u64) -> Self {
        StreamKey::new(seed, purpose, element).path(sample)
    }

    /// A uniform number in `[0, 1)` with 53 random bits.
    #[inline(always)]
    pub fn uniform(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }

    /// A unit-rate exponential variate (an optical depth), by the ziggurat method of Marsaglia &
    /// Tsang (2000) as implemented in `rand_distr`: ~98% of draws need one random number, a table
    /// lookup and a comparison, no logarithm (measured: ~12% fewer instructions per photon on the
    /// van de Hulst slab than `−ln(1 − u)`).
    #[inline(always)]
    pub fn exponential(&mut self) -> f64 {
        Exp1.sample(&mut self.0)
    }

    /// A standard normal variate (ziggurat, `rand_distr`).
    #[inline(always)]
    pub fn normal(&mut self) -> f64 {
        StandardNormal.sample(&mut self.0)
    }

    /// Two uniforms in `[0, 1)` with 32 random bits each, from one draw: the input of the reference
    /// [`azimuth`](super::warp::azimuth), against which the walk's integer form is tested.
    #[cfg(test)]
    pub fn uniform_pair32(&mut self) -> (f64, f64) {
        let r = self.0.next_u64();
        const SCALE: f64 = 1.0 / 4_294_967_296.0;
        ((r >> 32) as f64 * SCALE, (r & 0xFFFF_FFFF) as f64 * SCALE)
    }

    /// A draw from which the streams of a split's copies are made ([`PathRng::copy`]).
    #[inline(always)]
    pub fn split_key(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// The stream of copy `k` of a path split with the key `key` ([`PathRng::split_key`], drawn
    /// from the path's own stream: the same whatever the threads).
    pub fn copy(key: u64, k: u64) -> PathRng {
        PathRng(Xoshiro256PlusPlus::seed_from_u64(mix64(key ^ mix64(k))))
    }

    /// Two independent signed 32-bit integers, uniform on `[−2³¹, 2³¹)`, from one draw (the two
    /// halves reinterpreted; for [`warp::azimuth_i32`](super::warp::azimuth_i32)).
    #[inline(always)]
    pub fn pair_i32(&mut self) -> (i32, i32) {
        let r = self.0.next_u64();
        ((r >> 32) as i32, r as i32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f64> = {
            let mut r = PathRng::new(7, Purpose::Path, 3, 11);
            (0..4).map(|_| r.uniform()).collect()
        };
        let b: Vec<f64> = {
            let mut r = PathRng::new(7, Purpose::Path, 3, 11);
            (0..4).map(|_| r.uniform()).collect()
        };
        let c: Vec<f64> = {
            let mut r = PathRng::new(7, Purpose::Path, 3, 12);
            (0..4).map(|_| r.uniform()).collect()
        };
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|&u| (0.0..1.0).contains(&u)));
    }

    #[test]
    fn uniform_mean_and_variance() {
        // 1e6 draws across many streams: mean 1/2 (σ = 0.289/1000), variance 1/12.
        let n = 1_000_000u64;
        let (mut s, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let u = PathRng::new(1, Purpose::Test, i / 100, i % 100).uniform();
            s += u;
            s2 += u * u;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!((mean - 0.5).abs() < 4.0 * (1.0f64 / 12.0).sqrt() / (n as f64).sqrt());
        assert!((var - 1.0 / 12.0).abs() < 4.0 * (1.0f64 / 180.0).sqrt() / (n as f64).sqrt());
    }
}
