//! Writing a surface detector's parts ([`crate::detect::part`]): each part's files beyond what
//! its declared outputs give by themselves (axis files, figures, its table in the manifest's
//! `detectors.NAME`), in the order of its parts. What a part declares and nothing more is written
//! by [`Writer::rest`] after its parts.

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::Value;

use super::{Entry, IMAGE_LAYOUT, Writer, estimate};
use crate::detect::{Placed, SpectrumSpec, Surface};
use crate::error::Result;
use crate::output::{Kind, Output};
use crate::post::Finished;

/// What the parts of surface detector `i` (`name`) write into besides files.
pub struct Context<'a, 'f> {
    pub i: usize,
    pub name: &'a str,
    pub surface: &'a Surface,
    pub finished: &'a Finished<'f>,
    /// The detector's estimates (`estimates.detectors.NAME`).
    pub detector: &'a mut BTreeMap<String, Entry>,
    /// The manifest's top-level estimates (an LDH camera's ROI values).
    pub estimates: &'a mut BTreeMap<String, Entry>,
    /// The detector's tables in the manifest, by part.
    pub entries: &'a mut BTreeMap<&'static str, Value>,
    /// The weight its spectra's total channels put outside their axes (every chirp).
    pub out_of_range: f64,
}

/// Write `part` of `cx`'s detector.
pub fn write_part(w: &mut Writer, part: &Placed, cx: &mut Context) -> Result<()> {
    let (exp, out, name) = (cx.finished.exp, cx.finished.out, cx.name);
    match part {
        Placed::Spectrum(spec, lay) => {
            let spectra: Vec<&Output> = w.registry.within(lay.slots(out.beat.chirps())).collect();
            let roles: Vec<_> = spectra.iter().map(|o| lay.role(o.slots.start, out.beat.chirps())).collect();
            let (entry, oor) = write_spectra(w, name, spec, &spectra, &roles, cx.detector)?;
            let fmcw = exp.fmcw_estimates(out, cx.i).and_then(|r| r.ok());
            super::figures::spectra_figures(w, name, &spectra, &roles, fmcw.as_ref())?;
            cx.entries.insert(part.name(), to_value(entry));
            cx.out_of_range += oor;
            if let Some(entry) = super::fmcw::detector_entry(exp, out, cx.i, cx.detector) {
                let rows: Vec<String> = entry.row.into_iter().collect();
                w.put(super::fmcw::csv_file(name), super::fmcw::csv(&rows).into_bytes())?;
                cx.entries.insert("fmcw", entry.info);
            }
        }
        Placed::Image(im, slot) => {
            let o = w.registry.at(*slot);
            let (v, e) = w.image(o, "intensity")?;
            w.image_figure(o, &v, &e, &format!("{name}: intensity image"), "fraction of emitted power")?;
            let entry = ImageEntry {
                pixels: [im.nx, im.ny],
                x_range_m: [im.min[0], im.max[0]],
                y_range_m: [im.min[1], im.max[1]],
                layout: IMAGE_LAYOUT,
                units: o.units,
            };
            cx.entries.insert(part.name(), to_value(entry));
        }
        Placed::Time(t, lay) => {
            let entry = super::tcorr::write_time(w, name, t, lay, cx.detector)?;
            cx.entries.insert(part.name(), entry);
        }
        Placed::Correlation(c, lay) => {
            let entry = super::tcorr::write_correlation(w, name, c, lay)?;
            cx.entries.insert(part.name(), entry);
        }
        Placed::Ldh(spec, lay) => {
            let im = cx.surface.image().expect("an LDH camera has an image (checked when resolving)");
            let entry = super::ldh::write_ldh(w, name, im, spec, lay, cx.finished, cx.estimates)?;
            cx.entries.insert(part.name(), entry);
        }
    }
    Ok(())
}

/// A manifest table as a JSON value.
fn to_value(entry: impl Serialize) -> Value {
    serde_json::to_value(entry).expect("a manifest entry serialises")
}

/// A surface detector's spectra `spectra` (every chirp, the total and its splits; `roles`: each
/// one's chirp and split, [`crate::detect::SpectrumLayout::role`]) with their frequency axis, and
/// its out-of-range tallies into `de`; returns the manifest entry and the total channels'
/// out-of-range weight.
fn write_spectra(
    w: &mut Writer,
    name: &str,
    spec: &SpectrumSpec,
    spectra: &[&Output],
    roles: &[(&str, Option<&str>)],
    de: &mut BTreeMap<String, Entry>,
) -> Result<(SpectrumEntry, f64)> {
    let (mean, se) = (w.mean, w.stderr);
    let bins = spec.axis.bins;
    let centres: Vec<f64> = (0..bins).map(|k| spec.axis.center(k)).collect();
    let frequency_file = format!("{name}_frequency_hz.npy");
    w.axis_file(frequency_file.clone(), "frequency_hz", "Hz", &centres)?;
    let mut channel_names: Vec<String> = Vec::new();
    let mut chirps = BTreeMap::new();
    let mut out_of_range_total = 0.0;
    // Each chirp's outputs: its total, then its splits.
    let totals = spectra.iter().enumerate().filter(|(_, o)| o.primary).map(|(k, _)| k);
    let starts: Vec<usize> = totals.chain(std::iter::once(spectra.len())).collect();
    for bounds in starts.windows(2) {
        let group = &spectra[bounds[0]..bounds[1]];
        let chirp = roles[bounds[0]].0;
        let (key, infix) = if chirp.is_empty() { ("single", String::new()) } else { (chirp, format!("_{chirp}")) };
        let mut oor = BTreeMap::new();
        let mut names = Vec::new();
        for o in group {
            w.array(o)?;
            let Kind::Spectrum { channels, .. } = &o.kind else { unreachable!("{} is declared a spectrum", o.name) };
            for (r, ch) in channels.iter().enumerate() {
                let ((below, above), (below_se, above_se)) = (o.tails(mean, r), o.tails(se, r));
                let tails = [("below", estimate(below, below_se)), ("above", estimate(above, above_se))];
                oor.insert(ch.clone(), Entry::Group(tails.map(|(k, e)| (k.to_string(), Entry::Estimate(e))).into()));
                names.push(ch.clone());
            }
        }
        let (below, above) = group[0].tails(mean, 0);
        out_of_range_total += below + above;
        de.insert(format!("out_of_range_{key}"), Entry::Group(oor));
        chirps.insert(key.to_string(), infix);
        channel_names = names;
    }
    Ok((
        SpectrumEntry {
            f_min_hz: spec.axis.f_min,
            f_max_hz: spec.axis.f_max,
            bins,
            bin_width_hz: spec.axis.bin_width(),
            frequency_file,
            channels: channel_names,
            chirps,
            units: crate::output::PER_BIN,
        },
        out_of_range_total,
    ))
}

#[derive(Debug, Clone, Serialize)]
pub struct SpectrumEntry {
    pub f_min_hz: f64,
    pub f_max_hz: f64,
    pub bins: usize,
    pub bin_width_hz: f64,
    pub frequency_file: String,
    pub channels: Vec<String>,
    /// Chirp (`single`, or `up` and `down`) → its file-name infix.
    pub chirps: BTreeMap<String, String>,
    pub units: &'static str,
}

/// An image's pixel grid.
#[derive(Debug, Clone, Serialize)]
pub struct ImageEntry {
    pub pixels: [usize; 2],
    pub x_range_m: [f64; 2],
    pub y_range_m: [f64; 2],
    pub layout: &'static str,
    pub units: &'static str,
}
