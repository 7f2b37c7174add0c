//! Run helpers: experiments from inline TOML with `--set`-style overrides, a finished run with
//! accessors for its tallies (scalars, detector powers, spectrum channels, LDH ROIs).

use ohd::detect::Scalar;
use ohd::experiment::{Experiment, RunOutput, Silent};

/// Load an experiment from inline TOML with `--set`-style overrides; panics with the message.
pub fn experiment(text: &str, sets: &[&str]) -> Experiment {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    match ohd::config::load(text, "test", &sets) {
        Ok((_, e)) => e,
        Err(e) => panic!("config: {e}"),
    }
}

/// A finished run with accessors.
pub struct Run {
    pub exp: Experiment,
    pub out: RunOutput,
}

pub fn run(text: &str, sets: &[&str]) -> Run {
    let exp = experiment(text, sets);
    let out = exp.run(&Silent);
    Run { exp, out }
}

/// One spectrum channel of one detector and chirp: (values, stderrs, below, above).
pub struct Channel {
    pub values: Vec<f64>,
    pub stderr: Vec<f64>,
    pub below: f64,
    pub above: f64,
}

impl Run {
    pub fn scalar(&self, s: Scalar) -> (f64, f64) {
        (self.out.estimates.mean()[s as usize], self.out.estimates.stderr()[s as usize])
    }

    pub fn power(&self, detector: usize) -> (f64, f64) {
        let i = self.out.layout.detectors[detector].power;
        (self.out.estimates.mean()[i], self.out.estimates.stderr()[i])
    }

    /// Channel 0 is the total; then orders 0…K (if split), then Doppler-event counts.
    pub fn channel(&self, detector: usize, chirp: usize, channel: usize) -> Channel {
        let lay = &self.out.layout.detectors[detector];
        let s = lay.spectrum().expect("detector has a spectrum");
        let (start, stride) = (s.start, s.stride);
        let bins = stride - 2;
        self.slots(start + (chirp * s.channels + channel) * stride, bins)
    }

    /// The `bins` values at `o` of the tally vector and the two out-of-range slots after them.
    pub fn slots(&self, o: usize, bins: usize) -> Channel {
        let m = self.out.estimates.mean();
        let se = self.out.estimates.stderr();
        Channel {
            values: m[o..o + bins].to_vec(),
            stderr: se[o..o + bins].to_vec(),
            below: m[o + bins],
            above: m[o + bins + 1],
        }
    }

    /// Paths traced.
    pub fn paths(&self) -> f64 {
        self.exp.plan.samples() as f64
    }
}

/// One channel of an LDH ROI spectrum (0 = total, then static, single Doppler, multiple Doppler).
pub fn roi_channel(r: &Run, detector: usize, roi: usize, channel: usize) -> Channel {
    let ll = r.out.layout.detectors[detector].ldh().expect("an LDH camera");
    r.slots(ll.rois[roi].spectrum + channel * ll.stride, ll.stride - 2)
}

/// An LDH ROI's M0+ and M0− with their standard errors: ((m0+, σ), (m0−, σ)).
pub fn roi_m0(r: &Run, detector: usize, roi: usize) -> ((f64, f64), (f64, f64)) {
    let ll = r.out.layout.detectors[detector].ldh().expect("an LDH camera");
    let (m, se) = (r.out.estimates.mean(), r.out.estimates.stderr());
    let rl = &ll.rois[roi];
    ((m[rl.m0_plus], se[rl.m0_plus]), (m[rl.m0_minus], se[rl.m0_minus]))
}
