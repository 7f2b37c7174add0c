//! `[source]`: the laser (wavelength, profile, position, pointing or scan, divergence, chirp).

use glam::DVec3;

use super::{Given, R, err, factor, given, given_arr, non_negative, positive, require, shown, unit_vector};
use crate::config::schema::*;
use crate::config::units::unit_of;
use crate::error::ConfigError;
use crate::source::{Chirp, Pointing, Profile, Source};

pub(super) fn resolve_source(s: &SourceSection) -> R<Source> {
    let wl = require("source", "wavelength", &s.wavelength, "the vacuum wavelength")?;
    if !(wl.0.is_finite() && (1e-8..=1e-3).contains(&wl.0)) {
        return err(wl.1, format!("= {}: expected a vacuum wavelength from 10 nm to 1 mm", wl.2));
    }
    let radius = given("source", &s.radius)?;
    let waist = given("source", &s.waist)?;
    let profile = match s.profile.unwrap_or(ProfileKind::Pencil) {
        ProfileKind::Pencil => {
            if let Some(r) = radius.as_ref().or(waist.as_ref()) {
                return err(r.1.clone(), "only applies to profile = \"disk\" (radius) or \"gaussian\" (waist)");
            }
            Profile::Pencil
        }
        ProfileKind::Disk => {
            if let Some(w) = waist {
                return err(w.1, "only applies to profile = \"gaussian\"; a disk has a radius");
            }
            let r = radius.ok_or_else(|| {
                ConfigError::new("source", "profile = \"disk\" needs radius_um, radius_mm or radius_m")
            })?;
            Profile::Disk { radius: positive(r, "a beam radius")? }
        }
        ProfileKind::Gaussian => {
            if let Some(r) = radius {
                return err(r.1, "only applies to profile = \"disk\"; a Gaussian beam has a waist (1/e² radius)");
            }
            let w = waist.ok_or_else(|| {
                ConfigError::new(
                    "source",
                    "profile = \"gaussian\" needs waist_um, waist_mm or waist_m (1/e² intensity radius)",
                )
            })?;
            Profile::Gaussian { waist: positive(w, "a 1/e² beam radius")? }
        }
    };
    let position = given_arr("source", &s.position)?;
    let position = match position {
        Some((p, path)) => {
            if p[2] > 0.0 {
                return err(path, format!("= {p:?} m: the laser must start above or on the top surface (z ≤ 0)"));
            }
            DVec3::from_array(p)
        }
        None => DVec3::ZERO,
    };
    let pointings = resolve_pointings(s)?;
    let direction = match pointings.first() {
        Some(p) => p.direction,
        None => unit_vector("source.direction", s.direction.unwrap_or([0.0, 0.0, 1.0]))?,
    };
    if direction.z < 1e-6 {
        return err(
            "source.direction",
            format!(
                "= {:?}: the beam must point into the stack, not graze it (z component of the unit vector > 1e-6; +z is depth)",
                direction.to_array()
            ),
        );
    }
    let divergence = match given("source", &s.divergence)? {
        None => 0.0,
        Some(d) => {
            if !(d.0.is_finite() && (0.0..=0.1).contains(&d.0)) {
                return err(d.1, format!("= {}: expected a 1/e² half-angle divergence from 0 to 0.1 rad", d.2));
            }
            if direction.z < 5.0 * d.0 {
                return err(
                    d.1,
                    format!(
                        "= {}: too wide for a beam {:.2}° above the surface (the beam's z component must exceed 5× the divergence)",
                        d.2,
                        direction.z.asin().to_degrees()
                    ),
                );
            }
            d.0
        }
    };
    let chirp = match &s.chirp {
        None => None,
        Some(c) => {
            let b = require("source.chirp", "bandwidth", &c.bandwidth, "the chirp bandwidth B")?;
            let t = require("source.chirp", "duration", &c.duration, "the chirp duration T")?;
            // B = 0 is accepted: a chirp of zero bandwidth is a single-frequency laser, and its up-
            // and down-chirp spectra are the CW Doppler spectrum and its mirror (f = ±(dl/dt)/λ0).
            // Only the range retrieval needs B > 0, and says so (`retrieval::fmcw`).
            let bandwidth = non_negative(b.clone(), "a bandwidth")?;
            let duration = positive(t.clone(), "a chirp duration")?;
            check_chirp(&b, &t, bandwidth, duration)?;
            Some(Chirp { bandwidth, duration })
        }
    };
    let mut source = Source::new(wl.0, profile, position, direction, chirp);
    source.divergence = divergence;
    source.pointings = pointings;
    Ok(source)
}

/// Every number derived from a chirp of bandwidth `bandwidth` (key `b`) swept in `duration` (key
/// `t`) finite (issue 33, item 8: B = 1 Hz over T = 1e300 s ran and wrote a range of null): the
/// slope `B/T` of the beat `B/T·l/c`, `c·T`, and with `B > 0` a non-zero slope and the range of one
/// hertz of beat, `c·T/(2B)` (the range conversions of [`crate::retrieval::fmcw`]).
fn check_chirp(b: &Given, t: &Given, bandwidth: f64, duration: f64) -> R<()> {
    let c = crate::SPEED_OF_LIGHT;
    let (bu, tu) = (unit_of(&b.1), unit_of(&t.1));
    let (bf, tf) = (factor(&b.1), factor(&t.1));
    if !(c * duration).is_finite() {
        return err(
            t.1.clone(),
            format!(
                "= {} {tu}: expected a chirp duration of at most {} {tu} (c·T, which converts beat frequencies to ranges, must be a finite number)",
                shown(t.2),
                shown(f64::MAX / c / tf)
            ),
        );
    }
    if !(bandwidth / duration).is_finite() {
        return err(
            b.1.clone(),
            format!(
                "= {} {bu}: expected a bandwidth of at most {} {bu} over the chirp duration T = {} s (the slope B/T must be a finite number)",
                shown(b.2),
                shown(f64::MAX * duration / bf),
                shown(duration)
            ),
        );
    }
    if bandwidth > 0.0 && !(bandwidth / duration >= f64::MIN_POSITIVE && (c * duration / (2.0 * bandwidth)).is_finite())
    {
        return err(
            b.1.clone(),
            format!(
                "= {} {bu}: expected 0 (a single frequency) or a bandwidth of at least {} {bu} over the chirp duration T = {} s (the slope B/T must be non-zero and the range of one hertz of beat, c·T/(2B), a finite number)",
                shown(b.2),
                shown((duration * f64::MIN_POSITIVE).max(c * duration / (2.0 * f64::MAX)) / bf),
                shown(duration)
            ),
        );
    }
    Ok(())
}

/// The pointing of the beam by azimuth and elevation (degrees), or a scan of several.
fn resolve_pointings(s: &SourceSection) -> R<Vec<Pointing>> {
    let angles = |path: &str, az: f64, el: f64| -> R<Pointing> {
        if !(az.is_finite() && (-360.0..=360.0).contains(&az)) {
            return err(path, format!("azimuth = {az}°: expected −360 to 360 degrees clockwise from north"));
        }
        if !(el.is_finite() && el > 0.0 && el <= 90.0) {
            return err(
                path,
                format!("elevation = {el}°: expected above 0 and at most 90 degrees (the beam must point up, +z)"),
            );
        }
        Ok(Pointing::new(az, el))
    };
    // Degrees as written.
    let (azimuth, elevation) = (s.azimuth.as_ref().map(|q| q.value), s.elevation.as_ref().map(|q| q.value));
    let single = azimuth.is_some() || elevation.is_some();
    if single && s.direction.is_some() {
        return err("source", "give the pointing as direction or as azimuth_deg/elevation_deg, not both");
    }
    if let Some(list) = s.pointings.as_ref().map(|q| &q.value) {
        if single || s.direction.is_some() {
            return err(
                "source.pointings_deg",
                "a scan replaces direction, azimuth_deg and elevation_deg: remove them",
            );
        }
        if list.is_empty() || list.len() > 10_000 {
            return err("source.pointings_deg", format!("{} pointings: expected 1 to 10000", list.len()));
        }
        return list
            .iter()
            .enumerate()
            .map(|(i, p)| angles(&format!("source.pointings_deg[{i}]"), p[0], p[1]))
            .collect();
    }
    if single {
        let el = elevation.unwrap_or(90.0);
        return Ok(vec![angles("source", azimuth.unwrap_or(0.0), el)?]);
    }
    Ok(Vec::new())
}
