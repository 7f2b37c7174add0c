//! A surface detector's spectra: the detected power over the beat frequency, per chirp (one, or up
//! and down with FMCW), as a total and optionally split by scattering order and by the number of
//! Doppler-shifting events. Each channel's bins are followed by its below/above out-of-range
//! tallies, so a path outside the axis is counted, never lost (`DESIGN.md` §2).

use super::{BeatModel, Hit, Place, detector_output};
use crate::output::{Kind, Output, PER_BIN, Registry, Slots};
use crate::spectrum::FrequencyAxis;
use crate::stats::RunStats;

/// A spectrum recorded by a detector.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectrumSpec {
    pub axis: FrequencyAxis,
    /// Split by scattering order 0, 1, …, K−1 and ≥ K (`Some(K)`).
    pub by_order: Option<u32>,
    /// Split by number of Doppler-shifting events 0, 1, …, E−1 and ≥ E (`Some(E)`).
    pub by_doppler_events: Option<u32>,
    /// Windows over the cardiac cycle (a scene whose flows pulse): the total spectrum per window.
    pub acquisition: Option<super::ldh::Acquisition>,
}

/// Where a detector's spectra lie: `chirps × channels × stride` slots from `start`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpectrumLayout {
    pub start: usize,
    /// Slots of one channel: the bins, then the below/above tallies.
    pub stride: usize,
    pub channels: usize,
    /// Channels of the split by scattering order (0 without it): the split by Doppler events
    /// follows them.
    pub order_channels: usize,
    /// With an acquisition: its total spectra `[window][slot]` from here.
    pub windows: Option<usize>,
}

/// The chirp of a detector's spectra in file and output names: `""` without a chirp (one
/// spectrum), `"up"` and `"down"` with one.
pub fn chirp_name(chirps: usize, chirp: usize) -> &'static str {
    match (chirps, chirp) {
        (1, _) => "",
        (_, 0) => "up",
        _ => "down",
    }
}

/// The split of a spectrum into channels by the scattering order, in file and output names.
pub const BY_ORDER: &str = "by_order";
/// The split by the number of Doppler events, likewise.
pub const BY_DOPPLER_EVENTS: &str = "by_doppler_events";

impl SpectrumLayout {
    /// The slots of every chirp's spectra (`chirps` of them).
    pub fn slots(&self, chirps: usize) -> std::ops::Range<usize> {
        self.start..self.start + chirps * self.channels * self.stride
    }

    /// What the output starting at tally slot `slot` (one of these spectra) holds: its chirp
    /// ([`chirp_name`] of it) and its split ([`BY_ORDER`], [`BY_DOPPLER_EVENTS`]; `None`: the
    /// total).
    pub fn role(&self, slot: usize, chirps: usize) -> (&'static str, Option<&'static str>) {
        let block = self.channels * self.stride;
        let (chirp, channel) = ((slot - self.start) / block, (slot - self.start) % block / self.stride);
        let split = match channel {
            0 => None,
            c if c <= self.order_channels => Some(BY_ORDER),
            _ => Some(BY_DOPPLER_EVENTS),
        };
        (chirp_name(chirps, chirp), split)
    }
}

impl SpectrumSpec {
    /// Channels: the total, then the order split, then the Doppler-event split.
    pub fn channels(&self) -> usize {
        1 + self.by_order.map_or(0, |k| k as usize + 1) + self.by_doppler_events.map_or(0, |e| e as usize + 1)
    }

    /// Lay out the spectra of every chirp from `reg`'s end and declare them: per chirp its total
    /// (`NAME[_up|_down]_spectrum.npy`), then each split as one array of rows.
    pub fn declare(&self, at: &Place, reg: &mut Registry) -> SpectrumLayout {
        let (i, name, beat) = (at.i, at.name, at.beat);
        let (bins, stride, channels) = (self.axis.bins, self.axis.bins + 2, self.channels());
        let start = reg.take(beat.chirps() * channels * stride);
        let budget = Some((format!("detectors[{i}].spectrum.bins"), format!("= {bins}")));
        let mut groups: Vec<(&str, usize, Vec<String>)> = Vec::new();
        if let Some(k) = self.by_order {
            let names = (0..=k).map(|i| if i == k { format!("order>={k}") } else { format!("order={i}") });
            groups.push((BY_ORDER, 1, names.collect()));
        }
        if let Some(e) = self.by_doppler_events {
            let first = 1 + self.by_order.map_or(0, |k| k as usize + 1);
            let names =
                (0..=e).map(|i| if i == e { format!("doppler_events>={e}") } else { format!("doppler_events={i}") });
            groups.push((BY_DOPPLER_EVENTS, first, names.collect()));
        }
        for c in 0..beat.chirps() {
            let base = start + c * channels * stride;
            let chirp = match chirp_name(beat.chirps(), c) {
                "" => String::new(),
                n => format!("_{n}"),
            };
            let what = format!("spectrum{chirp}");
            let kind = |channels: Vec<String>| Kind::Spectrum { axis: self.axis, channels, mirrored: false };
            reg.declare(Output {
                file: format!("{name}{chirp}_spectrum.npy"),
                units: PER_BIN,
                primary: true,
                budget_key: budget.clone(),
                ..detector_output(
                    i,
                    format!("{name}.{what}"),
                    kind(vec!["total".into()]),
                    Slots::row(base, bins, stride),
                    vec![bins],
                )
            });
            for (suffix, first, names) in &groups {
                let rows = names.len();
                reg.declare(Output {
                    file: format!("{name}{chirp}_spectrum_{suffix}.npy"),
                    units: PER_BIN,
                    budget_key: budget.clone(),
                    ..detector_output(
                        i,
                        format!("{name}.{what}_{suffix}"),
                        kind(names.clone()),
                        Slots { start: base + first * stride, rows, stride, len: bins },
                        vec![rows, bins],
                    )
                });
            }
        }
        // (Resolve refuses a chirp with pulsing flows: one spectrum per window.)
        let windows = self.acquisition.as_ref().map(|acq| {
            let w = acq.times.len();
            let o = reg.take(w * stride);
            let labels = (0..w).map(|m| format!("window_{m}")).collect();
            let mut out = Output {
                file: format!("{name}_spectrum_windows.npy"),
                units: PER_BIN,
                budget_key: Some((format!("detectors[{i}].spectrum.acquisition"), format!("= {w} windows"))),
                ..detector_output(
                    i,
                    format!("{name}.spectrum_windows"),
                    Kind::Spectrum { axis: self.axis, channels: labels, mirrored: false },
                    Slots { start: o, rows: w, stride, len: bins },
                    vec![w, bins],
                )
            };
            out.axes[0] = acq.axis();
            reg.declare(out);
            o
        });
        SpectrumLayout { start, stride, channels, order_channels: self.by_order.map_or(0, |k| k as usize + 1), windows }
    }

    /// Record `hit` (its harmonics `pulse`) into the acquisition's windows at `start`: its line
    /// at its frequency in each window, integrated over the bins as the spectrum's own (a point
    /// detector's hits are few beside a camera's: the windows' lines are not drawn into slots
    /// here, so that each window's far Lorentzian tails are the steady spectrum's).
    #[allow(clippy::too_many_arguments)]
    pub fn record_windows(
        &self,
        start: usize,
        stride: usize,
        acc: &mut [f64],
        beat: &BeatModel,
        hit: &Hit,
        pulse: &[num_complex::Complex64],
        rates: &mut Vec<f64>,
    ) {
        let Some(acq) = &self.acquisition else { return };
        acq.rates(hit.dldt, pulse, rates);
        for (m, &rate) in rates.iter().enumerate() {
            let f = beat.frequency(0, hit.l, rate);
            let s = start + m * stride;
            self.axis.add_line(&mut acc[s..s + stride], hit.weight, f, hit.gamma);
        }
    }

    /// Record `hit` into every chirp's total and its split channels (a non-finite beat frequency
    /// is counted in `stats.non_finite`).
    #[inline]
    pub fn record(&self, lay: &SpectrumLayout, acc: &mut [f64], stats: &mut RunStats, beat: &BeatModel, hit: &Hit) {
        let (w, gamma, stride) = (hit.weight, hit.gamma, lay.stride);
        let order_channel = self.by_order.map(|k| 1 + hit.order.min(k) as usize);
        let event_channel = self
            .by_doppler_events
            .map(|k| 1 + self.by_order.map_or(0, |k| k as usize + 1) + hit.doppler_events.min(k) as usize);
        for chirp in 0..beat.chirps() {
            let f = beat.frequency(chirp, hit.l, hit.dldt);
            let base = lay.start + chirp * lay.channels * stride;
            if !self.axis.add_line(&mut acc[base..base + stride], w, f, gamma) {
                stats.non_finite += 1;
                continue;
            }
            for c in [order_channel, event_channel].into_iter().flatten() {
                let o = base + c * stride;
                self.axis.add_line(&mut acc[o..o + stride], w, f, gamma);
            }
        }
    }
}
