//! `[lateral]`: the layer stack cut to a box phantom ([`crate::medium::Lateral`]).

use super::{R, err, index_of_refraction, require_arr};
use crate::config::schema::LateralSection;
use crate::detect::{Detector, DetectorKind, EstimatorChoice};
use crate::medium::Lateral;
use crate::source::{Profile, Source};

/// The bounds, checked against what the walk in a box supports: the beam must enter the top
/// face inside the box (every path then starts inside it), and no estimator may trace shadow
/// rays or camera connections (they cross the layers as infinite slabs).
pub(super) fn resolve_lateral(
    l: Option<&LateralSection>,
    n_above: f64,
    source: &Source,
    detectors: &[Detector],
) -> R<Option<Lateral>> {
    let Some(l) = l else { return Ok(None) };
    let p = "lateral";
    let mut bounds = [(0.0, 0.0); 2];
    for (k, (name, q)) in [("x", &l.x), ("y", &l.y)].into_iter().enumerate() {
        let (v, path) = require_arr(p, name, q, &format!("the box's extent along {name}"))?;
        if v[0] >= v[1] {
            return err(path, format!("= {v:?} m: expected [{name}0, {name}1] with {name}0 < {name}1"));
        }
        bounds[k] = (v[0], v[1]);
    }
    let n_outside = index_of_refraction("lateral.n_outside", l.n_outside.unwrap_or(n_above))?;
    let lateral = Lateral { x: bounds[0], y: bounds[1], n_outside };
    // Where the beam meets the top surface (z = 0), and how far its footprint reaches from
    // there: a disk of radius r perpendicular to the beam is an ellipse within r/cos θ on z = 0.
    let reach = match source.profile {
        Profile::Pencil => 0.0,
        Profile::Disk { radius } => radius / source.direction.z,
        Profile::Gaussian { .. } => {
            return err(
                "source.profile",
                "= \"gaussian\": its tails reach past any [lateral] bounds; use \"pencil\" or \"disk\" in a box phantom",
            );
        }
    };
    if source.divergence > 0.0 {
        return err("source.divergence", "a diverging beam may miss a box phantom ([lateral]): remove it");
    }
    if !source.pointings.is_empty() {
        return err("source.pointings", "a scan is not supported in a box phantom ([lateral]): remove it");
    }
    let t0 = -source.position.z / source.direction.z;
    let hit = source.position + t0 * source.direction;
    let inside = lateral.contains(hit.x - reach, hit.y - reach) && lateral.contains(hit.x + reach, hit.y + reach);
    if !inside {
        return err(
            p,
            format!(
                "the beam enters the top surface at x = {:.6} m, y = {:.6} m (± {reach:.3e} m), outside the box x ∈ [{}, {}] m, y ∈ [{}, {}] m: the source must start inside or above the box",
                hit.x, hit.y, lateral.x.0, lateral.x.1, lateral.y.0, lateral.y.1
            ),
        );
    }
    for (i, d) in detectors.iter().enumerate() {
        let key = match &d.kind {
            DetectorKind::Lidar(_) => "lidar",
            DetectorKind::Surface(s) if s.choice != EstimatorChoice::Forward => "estimator",
            DetectorKind::Surface(s) if s.ldh().is_some() => "ldh",
            DetectorKind::Surface(s) if s.next_event => "next_event",
            DetectorKind::Surface(_) => continue,
        };
        return err(
            format!("detectors[{i}].{key}"),
            "shadow rays, lidar receivers and camera-side paths cross the layers as infinite slabs, which a box phantom ([lateral]) is not: use a forward surface detector (estimator = \"forward\", next_event = false, no ldh)",
        );
    }
    Ok(Some(lateral))
}
