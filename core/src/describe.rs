//! Human-readable accounts of a resolved experiment (`ohd check`): `impl Display` for the
//! [`Experiment`] and its parts — source, scene (media, layers, regions), phase functions,
//! velocity fields, detectors, run plan.
//!
//! Units are human and chosen by magnitude: each quantity in the largest unit not exceeding it
//! (µm, mm, m, km; Hz, kHz, MHz, GHz; mm/s, m/s; ns, µs, ms, s; coefficients in mm⁻¹, m⁻¹ or
//! km⁻¹), one unit for the values that belong together (a shape's centre and radius, the whole
//! layer stack, a medium's σa and σs). Layers split into sublayers (`air[0]`, `air[1]`, …) and
//! populations split into size classes (`rain[0]`, …) print as one summary line each.
//!
//! The impls live here, not beside their types, because several need the whole scene (a
//! sublayer summary, same-named media across sublayers, the stack's unit) and because one unit
//! policy in one place keeps the account consistent.

use std::fmt::{self, Display, Formatter};
use std::ops::Range;

use glam::DVec3;

use crate::detect::{Area, Detector, DetectorKind, ImageSpec, LdhSpec, LidarSpec, Side, SpectrumSpec};
use crate::experiment::{Experiment, RunPlan};
use crate::flow::{VelocityField, WindProfile};
use crate::medium::density::{DensityInfo, Interpolation, MajorantKind};
use crate::medium::{Medium, Population, Scene, Shape};
use crate::phase::PhaseFunction;
use crate::source::{Chirp, Pointing, Profile, Source};
use crate::spectrum::FrequencyAxis;
use crate::transport::Tracking;
use crate::transport::windows::Importance;

/// A unit: its symbol and its size in SI.
#[derive(Debug, Clone, Copy)]
struct Unit(&'static str, f64);

const LENGTH: &[Unit] = &[Unit("µm", 1e-6), Unit("mm", 1e-3), Unit("m", 1.0), Unit("km", 1e3)];
const COEFFICIENT: &[Unit] = &[Unit("km⁻¹", 1e-3), Unit("m⁻¹", 1.0), Unit("mm⁻¹", 1e3)];
const FREQUENCY: &[Unit] = &[Unit("Hz", 1.0), Unit("kHz", 1e3), Unit("MHz", 1e6), Unit("GHz", 1e9)];
const SPEED: &[Unit] = &[Unit("mm/s", 1e-3), Unit("m/s", 1.0)];
const TIME: &[Unit] = &[Unit("ns", 1e-9), Unit("µs", 1e-6), Unit("ms", 1e-3), Unit("s", 1.0)];
const ENERGY: &[Unit] = &[Unit("nJ", 1e-9), Unit("µJ", 1e-6), Unit("mJ", 1e-3), Unit("J", 1.0)];

/// The unit of `units` (ascending) for values of magnitude up to `scale`: the largest not
/// exceeding it (the smallest below all; `base` for zero or a non-finite scale).
fn unit(units: &[Unit], base: usize, scale: f64) -> Unit {
    let s = scale.abs();
    if !(s.is_finite() && s > 0.0) {
        return units[base];
    }
    units.iter().rev().find(|u| u.1 <= s * (1.0 + 1e-9)).copied().unwrap_or(units[0])
}

impl Unit {
    /// `v` in this unit, as a number.
    fn num(self, v: f64) -> String {
        num(v / self.1)
    }

    /// `v` in this unit, with the symbol.
    fn of(self, v: f64) -> String {
        format!("{} {}", self.num(v), self.0)
    }

    /// `lo–hi` in this unit (one value when they agree), with the symbol.
    fn range(self, lo: f64, hi: f64) -> String {
        let (a, b) = (self.num(lo), self.num(hi));
        if a == b { self.of(lo) } else { format!("{a}–{b} {}", self.0) }
    }

    /// A point in this unit, with the symbol.
    fn point(self, p: DVec3) -> String {
        format!("({}, {}, {}) {}", self.num(p.x), self.num(p.y), self.num(p.z), self.0)
    }
}

/// A value in the unit of `units` that fits it.
fn scaled(units: &[Unit], base: usize, v: f64) -> String {
    unit(units, base, v).of(v)
}

fn length(v: f64) -> String {
    scaled(LENGTH, 2, v)
}

fn speed(v: f64) -> String {
    scaled(SPEED, 1, v)
}

/// An energy in the unit that fits it (`100 µJ`), for figures and reports.
pub fn energy(v: f64) -> String {
    scaled(ENERGY, 3, v)
}

/// A number with up to four significant digits and no trailing zeros; in scientific notation
/// outside 10⁻⁴ … 10⁷.
pub fn num(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return if v.is_nan() {
            "NaN".into()
        } else if v > 0.0 {
            "∞".into()
        } else {
            "−∞".into()
        };
    }
    let trim = |s: &str| {
        if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s.to_string() }
    };
    let a = v.abs();
    if !(1e-4..1e7).contains(&a) {
        let s = format!("{v:.3e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        return format!("{}e{exponent}", trim(mantissa));
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = trim(&format!("{v:.decimals$}"));
    if s == "-0" { "0".into() } else { s }
}

/// A unit vector, to four decimals.
fn direction(d: DVec3) -> String {
    let c = |v: f64| {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" { "0".to_string() } else { s.to_string() }
    };
    format!("({}, {}, {})", c(d.x), c(d.y), c(d.z))
}

/// A velocity vector in the unit that fits its largest component.
fn velocity(v: DVec3) -> String {
    unit(SPEED, 1, v.abs().max_element()).point(v)
}

/// The largest magnitude of `values` (lengths that share a unit).
fn scale(values: impl IntoIterator<Item = f64>) -> f64 {
    values.into_iter().filter(|v| v.is_finite()).fold(0.0, |m, v| m.max(v.abs()))
}

/// `lo–hi` of `values`.
fn span(values: impl IntoIterator<Item = f64>) -> (f64, f64) {
    values.into_iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
}

/// The part before `[k]` of a name split by the resolve step (`air[3]` → `air`), if it is one.
fn split_base(name: &str) -> Option<&str> {
    let (base, rest) = name.split_once('[')?;
    let k = rest.strip_suffix(']')?;
    (!k.is_empty() && k.bytes().all(|b| b.is_ascii_digit())).then_some(base)
}

/// Runs of consecutive items named `base[0]`, `base[1]`, … (one run per split item; every
/// other item a run of its own), with the run's name.
fn runs<T>(items: &[T], name: impl Fn(&T) -> &str) -> Vec<(String, Range<usize>)> {
    let mut out: Vec<(String, Range<usize>)> = Vec::new();
    for (i, it) in items.iter().enumerate() {
        let n = name(it);
        match (split_base(n), out.last_mut()) {
            (Some(b), Some((last, r))) if r.end == i && r.len() > 1 && last == b => r.end = i + 1,
            (Some(b), Some((last, r)))
                if r.end == i && r.len() == 1 && split_base(name(&items[r.start])) == Some(b) =>
            {
                *last = b.to_string();
                r.end = i + 1;
            }
            _ => out.push((n.to_string(), i..i + 1)),
        }
    }
    out
}

impl Display for Profile {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match *self {
            Profile::Pencil => write!(f, "pencil beam"),
            Profile::Disk { radius } => write!(f, "flat-top beam of radius {}", length(radius)),
            Profile::Gaussian { waist } => write!(f, "Gaussian beam of 1/e² radius {}", length(waist)),
        }
    }
}

impl Display for Chirp {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "chirp of {} over {} (slope {} Hz/s)",
            scaled(FREQUENCY, 0, self.bandwidth),
            scaled(TIME, 3, self.duration),
            num(self.slope())
        )
    }
}

impl Display for Pointing {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        write!(f, "({}°, {}°)", num(self.azimuth_deg), num(self.elevation_deg))
    }
}

/// The source: one line, then indented lines for its chirp, divergence and scan.
impl Display for Source {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let u = unit(LENGTH, 1, scale(self.position.to_array()));
        write!(
            f,
            "λ0 = {} nm, {}, from {} along {}",
            num(self.wavelength * 1e9),
            self.profile,
            u.point(self.position),
            direction(self.direction)
        )?;
        if let Some(c) = &self.chirp {
            write!(f, "\n  {c}")?;
        }
        if self.divergence > 0.0 {
            write!(f, "\n  divergence {} µrad (1/e² half-angle)", num(self.divergence * 1e6))?;
        }
        if self.pointings.len() > 1 {
            let list: Vec<String> = self.pointings.iter().map(Pointing::to_string).collect();
            write!(f, "\n  scan of {} pointings (azimuth, elevation): {}", list.len(), list.join(", "))?;
        }
        Ok(())
    }
}

impl Display for PhaseFunction {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            PhaseFunction::Isotropic => write!(f, "isotropic"),
            PhaseFunction::HenyeyGreenstein(hg) => write!(f, "Henyey–Greenstein g = {}", num(hg.g())),
            PhaseFunction::Tabulated(t) => {
                write!(f, "table of {} angles (g = {}) from {}", t.len(), num(t.mean_cosine()), t.origin())
            }
        }
    }
}

/// Where a horizontal wind along `d` (a unit vector, where it blows to) blows from: degrees
/// clockwise from north.
fn from_deg(d: DVec3) -> f64 {
    let deg = (-d.x).atan2(-d.y).to_degrees().rem_euclid(360.0);
    (deg * 1e6).round() / 1e6 % 360.0
}

impl Display for WindProfile {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let vertical = |w: f64| if w == 0.0 { String::new() } else { format!(", vertical {}", speed(w)) };
        match self {
            WindProfile::Uniform(v) => write!(f, "uniform {}", velocity(*v)),
            WindProfile::PowerLaw { direction: d, speed_ref, height_ref, exponent, vertical: w } => write!(
                f,
                "power law from {}°, {} at {}, exponent {}{}",
                num(from_deg(*d)),
                speed(*speed_ref),
                length(*height_ref),
                num(*exponent),
                vertical(*w)
            ),
            WindProfile::LogLaw { direction: d, friction_velocity, roughness, displacement, vertical: w } => {
                write!(
                    f,
                    "log law from {}°, friction velocity {}, roughness {}",
                    num(from_deg(*d)),
                    speed(*friction_velocity),
                    length(*roughness)
                )?;
                if *displacement != 0.0 {
                    write!(f, ", displacement {}", length(*displacement))?;
                }
                let (u10, u100) = (self.at(10.0).length(), self.at(100.0).length());
                write!(f, " ({} at 10 m, {} at 100 m){}", speed(u10), speed(u100), vertical(*w))
            }
            WindProfile::Table { edges, velocities } => {
                let (lo, hi) = span(edges.iter().copied());
                let (slo, shi) = span(velocities.iter().map(|v| v.length()));
                let u = unit(LENGTH, 2, scale([lo, hi]));
                write!(
                    f,
                    "table of {} heights over {}, speeds {}",
                    velocities.len(),
                    u.range(lo, hi),
                    unit(SPEED, 1, shi).range(slo, shi)
                )
            }
        }
    }
}

impl Display for VelocityField {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            VelocityField::Static => write!(f, "static"),
            VelocityField::Uniform(v) => write!(f, "moving at {}", velocity(*v)),
            VelocityField::Poiseuille { origin, axis, radius, v_max } => {
                let u = unit(LENGTH, 1, scale(origin.to_array().into_iter().chain([*radius])));
                write!(
                    f,
                    "Poiseuille flow of {} on the axis, tube of radius {} through {} along {}",
                    speed(*v_max),
                    u.of(*radius),
                    u.point(*origin),
                    direction(*axis)
                )
            }
            VelocityField::RandomDirection { speed: s } => write!(f, "random directions at {}", speed(*s)),
            VelocityField::Wind(w) => write!(f, "wind: {w}"),
            VelocityField::TerminalFall { wind, fall } => {
                write!(f, "falling at {} (σs-weighted mean) in the wind: {wind}", speed(fall.mean()))
            }
            VelocityField::Grid(g) => {
                let lo = DVec3::from_array(g.grid.min.map(f64::from));
                let dims = DVec3::from_array(g.grid.dims.map(|n| n as f64));
                let (lo, hi) = (g.to_world(lo), g.to_world(lo + dims - DVec3::ONE));
                let u = unit(LENGTH, 2, scale(lo.to_array().into_iter().chain(hi.to_array())));
                let [x, y, z] = g.grid.dims;
                write!(
                    f,
                    "velocity grid of {x}×{y}×{z} voxels ({}) over {} – {}, background {}",
                    interpolation(g.interpolation),
                    u.point(lo),
                    u.point(hi),
                    velocity(DVec3::from_array(g.grid.background.map(f64::from)))
                )
            }
            VelocityField::Womersley { tube, t } => {
                let u = unit(LENGTH, 1, scale(tube.origin.to_array().into_iter().chain([tube.radius])));
                write!(
                    f,
                    "Womersley flow (α = {:.3}) frozen at {:.2} ms of its cycle, {} cycle-mean on the axis, tube of radius {} through {} along {}",
                    tube.alpha,
                    1e3 * t,
                    speed(tube.v_max),
                    u.of(tube.radius),
                    u.point(tube.origin),
                    direction(tube.axis)
                )
            }
        }
    }
}

fn interpolation(i: Interpolation) -> &'static str {
    match i {
        Interpolation::Trilinear => "trilinear",
        Interpolation::Nearest => "nearest",
    }
}

/// σa and σs (each a range `lo–hi`) in one coefficient unit, with the albedo.
fn coefficients(sigma_a: (f64, f64), sigma_s: (f64, f64), albedo: (f64, f64)) -> String {
    let u = unit(COEFFICIENT, 1, sigma_a.1 + sigma_s.1);
    // Near 1 the albedo's last digits matter (1 − albedo is the absorption per event).
    let num = |a: f64| if a > 0.99 && a < 1.0 { format!("{a:.6}").trim_end_matches('0').to_string() } else { num(a) };
    let albedo = match (num(albedo.0), num(albedo.1)) {
        (a, b) if a == b => a,
        (a, b) => format!("{a}–{b}"),
    };
    format!("σa {}, σs {} (albedo {albedo})", u.range(sigma_a.0, sigma_a.1), u.range(sigma_s.0, sigma_s.1))
}

/// Random motion beyond the flow, if any.
fn motion(p: &Population) -> String {
    let mut s = String::new();
    if p.motion.dispersion > 0.0 {
        s += &format!(", random velocity {} per component", speed(p.motion.dispersion));
    }
    if p.motion.diffusion > 0.0 {
        s += &format!(", diffusion {} m²/s", num(p.motion.diffusion));
    }
    s + &pulse(&p.pulse)
}

/// How a population's velocities pulse over the cardiac cycle, if they do: each waveform's
/// resistivity index as its harmonics keep it.
fn pulse(p: &crate::flow::pulse::Pulse) -> String {
    use crate::flow::pulse::FlowPulse;
    let mut s = String::new();
    match &p.flow {
        None => {}
        Some(FlowPulse::Separable(w)) => {
            s +=
                &format!(", pulsing over the cycle (RI {:.2}, {} harmonics)", w.resistivity_index(), w.harmonics.len());
        }
        Some(FlowPulse::Womersley(t)) => {
            s += &format!(
                ", pulsing as Womersley flow (α = {:.3} at the heart rate, {} harmonics)",
                t.alpha,
                p.harmonics()
            );
        }
    }
    if let Some(w) = &p.dispersion {
        s += &format!(", random velocity pulsing (RI {:.2})", w.resistivity_index());
    }
    s
}

/// A medium's account after its name and coefficients: phase function and motion, then lines
/// for its populations, density and particle optics (each starting with a newline and `indent`).
fn medium_details(m: &Medium, indent: &str, f: &mut Formatter<'_>) -> fmt::Result {
    let p = m.population();
    if m.populations().len() == 1 {
        write!(f, ", {}, {}{}", p.phase, p.velocity, motion(p))?;
    } else {
        write!(f, ", g = {}, {} populations", num(m.info.g), m.populations().len())?;
        let u = unit(COEFFICIENT, 1, m.sigma_s());
        for (name, r) in runs(m.populations(), |p| p.name.as_str()) {
            let ps = &m.populations()[r.clone()];
            if ps.len() == 1 {
                let p = &ps[0];
                write!(f, "\n{indent}  {name}: σs {}, {}, {}{}", u.of(p.sigma_s), p.phase, p.velocity, motion(p))?;
                continue;
            }
            let total: f64 = ps.iter().map(|p| p.sigma_s).sum();
            let (glo, ghi) = span(ps.iter().map(|p| p.phase.mean_cosine()));
            write!(
                f,
                "\n{indent}  {name}: {} size classes, σs {} in all, g {}–{}",
                ps.len(),
                u.of(total),
                num(glo),
                num(ghi)
            )?;
            let falls: Vec<f64> = ps
                .iter()
                .filter_map(|p| match &p.velocity {
                    VelocityField::TerminalFall { fall, .. } => Some(fall.mean()),
                    _ => None,
                })
                .collect();
            match (&ps[0].velocity, falls.len() == ps.len()) {
                (VelocityField::TerminalFall { wind, .. }, true) => {
                    let (lo, hi) = span(falls);
                    write!(
                        f,
                        ", falling at {} (σs-weighted mean per class) in the wind: {wind}",
                        unit(SPEED, 1, hi).range(lo, hi)
                    )?;
                }
                (v, _) if ps.iter().all(|p| &p.velocity == v) => write!(f, ", {v}")?,
                _ => write!(f, ", velocities per class")?,
            }
            write!(f, "{}", motion(&ps[0]))?;
        }
    }
    if let Some(h) = m.heterogeneity() {
        write!(f, "\n{indent}  ")?;
        density(&h.info, f)?;
    }
    if let Some(p) = &m.info.particles {
        let u = unit(COEFFICIENT, 1, p.sigma_s + p.sigma_a);
        write!(
            f,
            "\n{indent}  Mie: σs {}, σa {}, g = {}, backscatter {} sr⁻¹, lidar ratio {} sr",
            u.of(p.sigma_s),
            u.of(p.sigma_a),
            num(p.g),
            u.of(p.backscatter),
            num(p.lidar_ratio)
        )?;
        for c in &p.components {
            write!(
                f,
                "\n{indent}    {}: {} particles per m³, volume fraction {}, effective radius {}, σs {}, σa {}, g = {}",
                c.name,
                num(c.number_density),
                num(c.volume_fraction),
                length(c.effective_radius),
                u.of(c.sigma_s),
                u.of(c.sigma_a),
                num(c.g)
            )?;
        }
    }
    Ok(())
}

/// A density field: its kind and range, grid and majorant.
fn density(d: &DensityInfo, f: &mut Formatter<'_>) -> fmt::Result {
    write!(f, "density {} from {} to {} (σ above at density 1)", d.kind, num(d.min), num(d.max))?;
    if let Some(s) = &d.source {
        write!(f, " from {s}")?;
    }
    if let Some([x, y, z]) = d.voxels {
        write!(f, ", {x}×{y}×{z} voxels")?;
    }
    if let Some(i) = d.interpolation {
        write!(f, " ({})", interpolation(i))?;
    }
    match (d.majorant, d.majorant_cells) {
        (Some(MajorantKind::Grid), Some([x, y, z])) => write!(f, ", majorant grid of {x}×{y}×{z} cells")?,
        (Some(MajorantKind::Grid), None) => write!(f, ", majorant grid")?,
        (Some(MajorantKind::Global), _) => write!(f, ", one global majorant")?,
        (None, _) => {}
    }
    if d.negative_voxels_clamped > 0 {
        write!(f, ", {} negative voxels clamped to 0", d.negative_voxels_clamped)?;
    }
    if d.albedo_grid {
        write!(f, ", albedo grid")?;
    }
    Ok(())
}

/// A medium: `name: σa …, σs … (albedo …), phase, velocity`, then its populations, density
/// and particle optics on indented lines.
impl Display for Medium {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let (a, s, w) = (self.sigma_a(), self.sigma_s(), self.albedo());
        write!(f, "{}: {}", self.name, coefficients((a, a), (s, s), (w, w)))?;
        medium_details(self, "", f)
    }
}

impl Display for Shape {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match *self {
            Shape::Cylinder { center, axis, radius, half_length } => {
                let u = unit(LENGTH, 1, scale(center.to_array().into_iter().chain([radius, 2.0 * half_length])));
                write!(f, "cylinder of radius {} through {} along {}", u.of(radius), u.point(center), direction(axis))?;
                if half_length.is_finite() {
                    write!(f, ", {} long", u.of(2.0 * half_length))
                } else {
                    write!(f, ", through the layer")
                }
            }
            Shape::Box { min, max } => {
                let u = unit(LENGTH, 1, scale(min.to_array().into_iter().chain(max.to_array())));
                write!(f, "box from {} to {}", u.point(min), u.point(max))
            }
            Shape::Sphere { center, radius } => {
                let u = unit(LENGTH, 1, scale(center.to_array().into_iter().chain([radius])));
                write!(f, "sphere of radius {} about {}", u.of(radius), u.point(center))
            }
        }
    }
}

/// The scene: ambient indices, media (each name once; a medium repeated per sublayer with
/// varying coefficients as ranges), layers (sublayers summarised) and regions, one per line.
impl Display for Scene {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        if self.bottom.is_some() {
            write!(f, "ambient: n = {} above", num(self.n_above))?;
        } else {
            write!(f, "ambient: n = {} above, {} below", num(self.n_above), num(self.n_below))?;
        }
        if let Some(b) = &self.lateral {
            write!(
                f,
                "\nlateral: a box x ∈ [{}, {}] mm, y ∈ [{}, {}] mm, n = {} beside",
                num(b.x.0 * 1e3),
                num(b.x.1 * 1e3),
                num(b.y.0 * 1e3),
                num(b.y.1 * 1e3),
                num(b.n_outside)
            )?;
        }
        if let Some(b) = &self.bottom {
            write!(f, "\nbottom: an opaque surface under the last layer: {b}")?;
        }
        write!(f, "\nmedia:")?;
        let mut names: Vec<&str> = Vec::new();
        for m in &self.media {
            if !names.contains(&m.name.as_str()) {
                names.push(&m.name);
            }
        }
        for name in names {
            let same: Vec<&Medium> = self.media.iter().filter(|m| m.name == name).collect();
            let m = same[0];
            let a = span(same.iter().map(|m| m.sigma_a()));
            let s = span(same.iter().map(|m| m.sigma_s()));
            let w = span(same.iter().map(|m| m.albedo()));
            write!(f, "\n  {name}: {}", coefficients(a, s, w))?;
            if a.0 != a.1 || s.0 != s.1 {
                write!(f, " over its {} uses", same.len())?;
            }
            medium_details(m, "  ", f)?;
        }
        write!(f, "\nlayers:")?;
        let finite = self.layers.iter().flat_map(|l| [l.z_top, l.z_bottom]);
        let u = unit(LENGTH, 1, scale(finite));
        let z = |l: &crate::medium::Layer| {
            if l.z_bottom.is_finite() { u.range(l.z_top, l.z_bottom) } else { format!("{} – ∞", u.of(l.z_top)) }
        };
        for (name, r) in runs(&self.layers, |l| l.name.as_str()) {
            let ls = &self.layers[r.clone()];
            let (first, last) = (&ls[0], &ls[ls.len() - 1]);
            let medium = &self.media[first.medium].name;
            if ls.len() == 1 {
                write!(f, "\n  {name}: {}, n = {}, {medium}", z(first), num(first.n))?;
            } else {
                let sub = length(first.z_bottom - first.z_top);
                let cu = unit(COEFFICIENT, 1, scale(ls.iter().map(|l| self.media[l.medium].sigma_t())));
                let (slo, shi) = span(ls.iter().map(|l| self.media[l.medium].sigma_s()));
                let (alo, ahi) = span(ls.iter().map(|l| self.media[l.medium].sigma_a()));
                write!(
                    f,
                    "\n  {name}: {} in {} sublayers of {sub}, n = {}, {medium}, σs {}, σa {}",
                    u.range(first.z_top, last.z_bottom),
                    ls.len(),
                    num(first.n),
                    cu.range(slo, shi),
                    cu.range(alo, ahi)
                )?;
            }
            if first.face.is_rough() {
                write!(f, ", a rough top face (GGX α = {})", num(first.face.roughness()))?;
            }
            let regions: usize = ls.iter().map(|l| l.regions.len()).sum();
            match regions {
                0 => {}
                1 => write!(f, ", 1 region")?,
                n => write!(f, ", {n} regions")?,
            }
            if ls.iter().any(|l| l.heterogeneous) {
                write!(f, ", heterogeneous")?;
            }
            let (mlo, mhi) = span(ls.iter().map(|l| l.majorant));
            if mhi > 0.0 {
                write!(f, ", majorant {}", unit(COEFFICIENT, 1, mhi).range(mlo, mhi))?;
            }
        }
        if !self.regions.is_empty() {
            write!(f, "\nregions:")?;
            for r in &self.regions {
                write!(
                    f,
                    "\n  {}: in {}, {}, {}",
                    r.name, self.layers[r.layer].name, self.media[r.medium].name, r.shape
                )?;
            }
        }
        if !self.opaque.is_empty() {
            write!(f, "\nopaque solids:")?;
            for o in &self.opaque {
                write!(f, "\n  {}: in {}, {}; {}", o.name, self.layers[o.layer].name, o.shape, o.surface)?;
            }
        }
        Ok(())
    }
}

/// A surface: its BSDF, then its motion if it moves.
impl Display for crate::medium::Surface {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.bsdf)?;
        if self.velocity != glam::DVec3::ZERO {
            let v = self.velocity;
            write!(f, "; moving at ({}, {}, {}) m/s", num(v.x), num(v.y), num(v.z))?;
        }
        if self.angular_velocity != glam::DVec3::ZERO {
            let (w, c) = (self.angular_velocity, self.center);
            write!(
                f,
                "; rotating at ({}, {}, {}) rad/s about ({}, {}, {}) m",
                num(w.x),
                num(w.y),
                num(w.z),
                num(c.x),
                num(c.y),
                num(c.z)
            )?;
        }
        Ok(())
    }
}

impl Display for Area {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match *self {
            Area::All => write!(f, "the whole plane"),
            Area::Disk { center, radius } => {
                let u = unit(LENGTH, 1, scale([center[0], center[1], radius]));
                write!(f, "disk of radius {} about ({}, {}) {}", u.of(radius), u.num(center[0]), u.num(center[1]), u.0)
            }
            Area::Annulus { center, inner, outer } => {
                let u = unit(LENGTH, 1, scale([center[0], center[1], outer]));
                write!(
                    f,
                    "annulus of radii {} to {} about ({}, {}) {}",
                    u.of(inner),
                    u.of(outer),
                    u.num(center[0]),
                    u.num(center[1]),
                    u.0
                )
            }
            Area::Rect { min, max } => {
                let u = unit(LENGTH, 1, scale(min.into_iter().chain(max)));
                write!(
                    f,
                    "rectangle ({}, {}) to ({}, {}) {}",
                    u.num(min[0]),
                    u.num(min[1]),
                    u.num(max[0]),
                    u.num(max[1]),
                    u.0
                )
            }
        }
    }
}

impl Display for FrequencyAxis {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let u = unit(FREQUENCY, 0, scale([self.f_min, self.f_max]));
        write!(
            f,
            "{} bins over [{}, {}) {} ({} per bin)",
            self.bins,
            u.num(self.f_min),
            u.num(self.f_max),
            u.0,
            scaled(FREQUENCY, 0, self.bin_width())
        )
    }
}

/// `0…k−1, ≥k` of a split into `k + 1` channels.
fn split(k: u32) -> String {
    if k == 0 { "≥0".into() } else { format!("0…{}, ≥{k}", k - 1) }
}

impl Display for SpectrumSpec {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        write!(f, "spectrum of {}", self.axis)?;
        if let Some(k) = self.by_order {
            write!(f, ", by scattering order ({})", split(k))?;
        }
        if let Some(e) = self.by_doppler_events {
            write!(f, ", by Doppler events ({})", split(e))?;
        }
        if let Some(a) = &self.acquisition {
            write!(f, ", {}", windows(a))?;
        }
        Ok(())
    }
}

/// An acquisition's windows over the cardiac cycle, in words.
fn windows(a: &crate::detect::ldh::Acquisition) -> String {
    let n = a.times.len();
    format!(
        "acquisition over the cardiac cycle: {n} windows centred {:.1}–{:.1} ms, every {:.2} ms",
        1e3 * a.times[0],
        1e3 * a.times[n - 1],
        1e3 * a.hop
    )
}

impl Display for ImageSpec {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let area = Area::Rect { min: self.min, max: self.max };
        write!(f, "image of {}×{} px over the {area}", self.nx, self.ny)
    }
}

impl Display for LdhSpec {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let u = unit(FREQUENCY, 0, self.band.1);
        write!(f, "LDH: M0± over the band {}", u.range(self.band.0, self.band.1))?;
        if self.m1 {
            write!(f, ", M1")?;
        }
        if self.by_class {
            write!(f, ", by class")?;
        }
        if self.flip_sign {
            write!(f, ", frequencies sign-flipped")?;
        }
        if !self.rois.is_empty() {
            let names: Vec<&str> = self.rois.iter().map(|r| r.name.as_str()).collect();
            write!(f, ", spectra of {} in {}", names.join(", "), self.spectrum_axis)?;
        }
        if self.pixel_spectra {
            write!(f, ", per-pixel spectra")?;
        }
        if let Some(s) = self.speckle {
            write!(f, ", speckle in {} windows", s.windows)?;
            if s.pixels {
                write!(f, " (and per pixel)")?;
            }
        }
        if let Some(a) = &self.acquisition {
            let (first, last) = (a.times[0], a.times[a.times.len() - 1]);
            let half = 0.5 * self.stft.samples() as f64 / self.stft.sample_rate();
            write!(
                f,
                ", acquisition over the cardiac cycle: {} windows of {:.2} ms every {:.2} ms, {:.1}–{:.1} ms",
                a.times.len(),
                2e3 * half,
                1e3 * a.hop,
                1e3 * (first - half),
                1e3 * (last + half)
            )?;
        }
        Ok(())
    }
}

/// A lidar receiver: where it is and looks, then (on a second line) its gates and noise floor.
impl Display for LidarSpec {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let floor = self.noise_floor_per_bin();
        let u = unit(LENGTH, 1, scale(self.position.to_array().into_iter().chain([self.aperture_radius])));
        write!(
            f,
            "lidar receiver at {} along {}, aperture radius {}, field of view {} µrad (half-angle)",
            u.point(self.position),
            direction(self.axis),
            u.of(self.aperture_radius),
            num(self.cos_fov.clamp(-1.0, 1.0).acos() * 1e6)
        )?;
        write!(
            f,
            "\n{} gates of {} samples at {} from {}, {}-point DFT, pulse {} of {}, η = {} × {}: shot-noise floor {} per bin ({:.1} dB)",
            self.gates,
            self.gate_points,
            scaled(FREQUENCY, 0, self.sample_rate),
            length(0.5 * crate::SPEED_OF_LIGHT * self.first_sample_time),
            self.fft_points,
            scaled(TIME, 3, self.pulse_fwhm),
            scaled(ENERGY, 3, self.pulse_energy),
            num(self.quantum_efficiency),
            num(self.heterodyne_efficiency),
            num(floor),
            10.0 * floor.log10()
        )
    }
}

/// A detector: `name: side, area, acceptance, plane`, then what it records on indented lines.
impl Display for Detector {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let d = match &self.kind {
            DetectorKind::Surface(d) => d,
            DetectorKind::Lidar(l) => {
                let text = l.to_string();
                let (first, rest) = text.split_once('\n').unwrap_or((&text, ""));
                write!(f, "{}: {first}", self.name)?;
                return rest.lines().try_for_each(|line| write!(f, "\n  {line}"));
            }
        };
        let side = match d.side {
            Side::Top => "top",
            Side::Bottom => "bottom",
        };
        let half_angle = d.cos_acceptance.clamp(-1.0, 1.0).acos().to_degrees();
        write!(
            f,
            "{}: {side}, {}, acceptance {}° about {}{}, plane {}",
            self.name,
            d.area,
            num((half_angle * 1e4).round() / 1e4),
            direction(d.axis),
            if d.monostatic { " (back along the beam)" } else { "" },
            if d.distance == 0.0 {
                "at the surface".to_string()
            } else {
                format!("{} from the surface", length(d.distance))
            }
        )?;
        if d.choice == crate::detect::EstimatorChoice::Auto {
            // As configured: a pilot decides before the CLI's run (`crate::pilot::decide`); a run
            // without its decision estimates it forward ([`crate::detect::Surface::estimator`]).
            write!(f, ", estimator auto (a pilot before the run chooses camera-side or forward estimation)")?;
        } else if d.estimator() == crate::detect::Estimator::Camera {
            write!(f, ", camera-side estimation (paths from its pixels, at least one per pixel and batch)")?;
        } else if let Some(fp) = &d.footprints {
            write!(
                f,
                ", footprints: camera paths from {} pixels (the regions' footprints with a {} halo, and the ROIs'; {} camera paths per forward path), next-event estimation elsewhere",
                fp.pixels.len(),
                length(fp.halo),
                fp.camera_paths
            )?;
            if let Some(paths) = fp.light_field {
                write!(
                    f,
                    "; below the regions they connect to the layered scene's light field (a table from {paths} forward paths)"
                )?;
            }
        } else if d.next_event {
            write!(f, ", next-event estimation")?;
        }
        if d.include_specular {
            write!(f, ", specular reflection included")?;
        }
        if let Some(s) = d.spectrum() {
            write!(f, "\n  {s}")?;
        }
        if let Some(i) = d.image() {
            write!(f, "\n  {i}")?;
        }
        if let Some(t) = d.time() {
            let u = unit(TIME, 0, t.axis.f_max);
            write!(f, "\n  TPSF: {} time-of-flight bins over {}", t.axis.bins, u.range(t.axis.f_min, t.axis.f_max))?;
            if t.image {
                write!(f, ", and a time-gated image")?;
            }
        }
        if let Some(c) = d.correlation() {
            let (lo, hi) = (c.tau[0], c.tau[c.tau.len() - 1]);
            let (ul, uh) = (unit(TIME, 0, lo), unit(TIME, 0, hi));
            write!(
                f,
                "\n  g1, g2 at {} delays from {} to {} (log-spaced), β = {}",
                c.tau.len(),
                ul.of(lo),
                uh.of(hi),
                num(c.beta)
            )?;
            if !c.exposures.is_empty() {
                let times: Vec<String> = c.exposures.iter().map(|&t| unit(TIME, 0, t).of(t)).collect();
                write!(f, "; speckle contrast K at T = {}", times.join(", "))?;
                if c.pixels {
                    write!(f, ", per pixel")?;
                }
            }
            if !c.rois.is_empty() {
                write!(f, "; also per ROI ({})", c.rois.len())?;
            }
        }
        if let Some(l) = d.ldh() {
            write!(f, "\n  {l}")?;
        }
        Ok(())
    }
}

impl Display for Tracking {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match *self {
            Tracking::Analytic => write!(f, "analytic free flights"),
            Tracking::Delta { majorant_scale: 1.0 } => write!(f, "delta tracking"),
            Tracking::Delta { majorant_scale } => write!(f, "delta tracking (majorant × {})", num(majorant_scale)),
        }
    }
}

impl Display for RunPlan {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let threads = self.effective_threads();
        write!(
            f,
            "{} paths ({} batches × {}), seed {}, {threads} thread{}, {}",
            self.samples(),
            self.batches,
            self.paths_per_batch,
            self.seed,
            if threads == 1 { "" } else { "s" },
            self.walk.tracking
        )
    }
}

/// The resolved experiment, one part per line (parts with details on indented lines).
impl Display for Experiment {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        writeln!(f, "source: {}", self.source)?;
        writeln!(f, "{}", self.scene)?;
        writeln!(f, "detectors:")?;
        for d in &self.detectors {
            let text = d.to_string();
            for line in text.lines() {
                writeln!(f, "  {line}")?;
            }
        }
        if self.detectors.is_empty() {
            writeln!(f, "  (none: only the scalar tallies)")?;
        }
        // The outputs as declared: what the run will write, its shape, axes and units.
        let layout = self.output_layout();
        let outputs: Vec<&crate::output::Output> =
            layout.registry.outputs.iter().filter(|o| o.kind != crate::output::Kind::Internal).collect();
        let scalars = outputs.iter().filter(|o| o.is_scalar()).count();
        writeln!(f, "outputs: {} arrays, {scalars} scalars (manifest.json: estimates)", outputs.len() - scalars)?;
        for o in outputs.iter().filter(|o| !o.is_scalar()) {
            let axes: Vec<&str> = o.axes.iter().map(|a| a.name.as_str()).collect();
            let shape: Vec<String> = o.shape.iter().map(|n| n.to_string()).collect();
            writeln!(f, "  {}: {} ({}), {}", o.file, shape.join(" × "), axes.join(" × "), o.units)?;
        }
        writeln!(
            f,
            "run: {}, walk with{} Doppler, with{} path length",
            self.plan,
            if self.needs_doppler() { "" } else { "out" },
            if self.needs_length() { "" } else { "out" }
        )?;
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        // The interfaces' unscattered reflections: how the detectors get them (`run.reflections`).
        let deterministic = crate::transport::policy::deterministic_reflections(
            &self.scene,
            &self.source,
            &self.plan.walk,
            &self.detectors,
        );
        let moment = crate::transport::policy::reflection_second_moment(&self.scene, &self.source);
        writeln!(
            f,
            "unscattered reflections below the surface: {} (second moment per path along the beam {}, auto threshold {})",
            if deterministic { "deterministic" } else { "sampled by the walk" },
            num(moment),
            num(crate::transport::policy::AUTO_REFLECTIONS)
        )?;
        // Where the forward paths start (`run.launches`).
        match self.plan.walk.launches {
            None => writeln!(f, "launches: from the beam's profile")?,
            Some(l) => match l.launches(&self.scene, &self.source) {
                None => writeln!(f, "launches: from the beam's profile (nothing near the regions to favour)")?,
                Some(n) => writeln!(
                    f,
                    "launches: {:.0} % from the profile, the rest within {} µm of the regions, which hold {:.2} % of the profile",
                    100.0 * l.profile_share,
                    num(l.margin * 1e6),
                    100.0 * n.p_near
                )?,
            },
        }
        if let Some(c) = self.scene.cycle {
            writeln!(
                f,
                "cardiac cycle: {:.1} bpm ({:.1} ms), paths carry {} harmonics of their Doppler rate",
                60.0 / c.period(),
                1e3 * c.period(),
                c.harmonics
            )?;
        }
        // The cameras' layered control variate (`run.control_variate`).
        let obstacle = crate::transport::control_variate_obstacle(&self.scene, &self.source, &self.detectors);
        match (self.plan.walk.control_variate, obstacle) {
            (crate::transport::ControlVariate::Off, _) => writeln!(f, "layered control variate: off")?,
            (_, Some(why)) => writeln!(f, "layered control variate: none ({why})")?,
            (_, None) => {
                let layout = self.tally_layout();
                for (d, lay) in self.detectors.iter().zip(&layout.detectors) {
                    let Some(t) = &lay.twin else { continue };
                    let ((kx, ky), (fx, fy)) = t.sizes();
                    writeln!(
                        f,
                        "layered control variate of {}: {} maps, kernels of {kx}×{ky} offsets ({:.1} MiB per batch), FFT {fx}×{fy}",
                        d.name,
                        t.blocks.len(),
                        mib(8 * t.kernel_len() as u64)
                    )?;
                }
            }
        }
        // The importance table (`run.importance`).
        if self.plan.importance != Importance::Off {
            let windows = match self.plan.importance {
                Importance::Windows => {
                    "the forward walk's weight windows follow it (split above, roulette below a window of width 5 about R/I*)"
                        .to_string()
                }
                Importance::Guided => {
                    "the forward walk's weight windows follow it, and where its importance varies over the directions \
                     a scattering reaches, each continuation is one of 4 phase-function directions resampled on it"
                        .to_string()
                }
                Importance::Auto => format!(
                    "the forward walk follows its weight windows, or its windows and guided directions, where a pilot \
                     of 1/{} of the paths, without, with the windows and with both, measures a lower squared relative \
                     error × work of the main output",
                    crate::pilot::PILOT_SHARE
                ),
                Importance::Off | Importance::Table => "written, not used by the walk".to_string(),
            };
            match (self.importance_obstacle(), self.main_output().detector) {
                (Some(why), _) => writeln!(f, "importance table: none ({why})")?,
                (None, None) => {}
                (None, Some(d)) => writeln!(
                    f,
                    "importance table of {}: a pilot of {} paths through the layered stack, {}; {windows}",
                    self.detectors[d].name,
                    crate::detect::importance::pilot_paths(self.plan.samples()),
                    self.importance_grid(d).describe(&self.scene),
                )?,
            }
        }
        let parts: String = self.plan.memory.iter().map(|b| format!(", {} {:.1} MiB", b.what, mib(b.bytes))).collect();
        writeln!(
            f,
            "memory estimate: {:.1} MiB: {:.1} MiB of tallies{parts} (budget {:.1} GiB{})",
            mib(self.memory_total()),
            mib(self.memory_estimate()),
            self.plan.memory_budget as f64 / (1u64 << 30) as f64,
            self.plan.memory_limited_by.map_or(String::new(), |l| format!(", lowered by {l}"))
        )
    }
}

/// A surface's BSDF in words: its model, roughness and index (with the reflectance at normal
/// incidence a metal's index gives).
impl Display for crate::surface::Bsdf {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        use crate::surface::Bsdf;
        match self {
            Bsdf::Lambertian { albedo } => write!(f, "Lambertian, albedo {}", num(*albedo)),
            Bsdf::Conductor { alpha, eta } => {
                let r = crate::surface::conductor_reflectance(*eta, 1.0);
                if *alpha == 0.0 {
                    write!(f, "a smooth mirror")?;
                } else {
                    write!(f, "a rough conductor (GGX α = {})", num(*alpha))?;
                }
                write!(
                    f,
                    ", index {} + {}i relative to the medium above (reflectance {} at normal incidence)",
                    num(eta.re),
                    num(eta.im),
                    num(r)
                )
            }
            Bsdf::Mixture(parts) => {
                write!(f, "a mixture of")?;
                for (i, (w, p)) in parts.iter().enumerate() {
                    write!(f, "{} {} × ({p})", if i == 0 { "" } else { " +" }, num(*w))?;
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_units() {
        assert_eq!(num(0.12000000000000001), "0.12");
        assert_eq!(num(1500.0), "1500");
        assert_eq!(num(-0.25), "-0.25");
        assert_eq!(num(3.9111e-17), "3.911e-17");
        assert_eq!(num(3.0e9), "3e9");
        assert_eq!(num(0.998004), "0.998");
        assert_eq!(length(0.00025), "250 µm");
        assert_eq!(length(0.0025), "2.5 mm");
        assert_eq!(length(5.5e-5), "55 µm");
        assert_eq!(length(60.0), "60 m");
        assert_eq!(length(0.0), "0 m");
        assert_eq!(speed(0.034), "34 mm/s");
        assert_eq!(scaled(FREQUENCY, 0, 50_000.0), "50 kHz");
        assert_eq!(unit(COEFFICIENT, 1, 15_030.0).of(30.0), "0.03 mm⁻¹");
        assert_eq!(unit(COEFFICIENT, 1, 2.2e-3).of(2.0e-3), "2 km⁻¹");
        assert_eq!(direction(DVec3::new(0.9961942927598858, -1e-17, 0.08716037558794171)), "(0.9962, 0, 0.0872)");
        assert_eq!(num(from_deg(DVec3::new(1.0, 1.8e-16, 0.0))), "270");
    }

    #[test]
    fn split_names_run_together() {
        let names = ["a", "air[0]", "air[1]", "air[2]", "b[0]", "c"];
        let r = runs(&names, |s| s);
        let got: Vec<(&str, Range<usize>)> = r.iter().map(|(n, r)| (n.as_str(), r.clone())).collect();
        assert_eq!(got, vec![("a", 0..1), ("air", 1..4), ("b[0]", 4..5), ("c", 5..6)]);
    }
}
