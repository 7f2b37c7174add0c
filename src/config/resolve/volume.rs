//! `[volume]`: the voxel grid of a volume tally ([`crate::detect::volume`]).

use glam::DVec3;

use super::detectors::resolve_time;
use super::{R, err, require_arr};
use crate::config::schema::{FluenceKind, VolumeSection};
use crate::detect::volume::{FluenceEstimator, VolumeGrid};

/// The most voxels a grid may have, time bins included (each estimate is 8 bytes a voxel and bin
/// in the tallies, times the batches in flight; the memory budget counts them too).
const MAX_VOXELS: i64 = 1 << 28;

pub(super) fn resolve_volume(v: Option<&VolumeSection>) -> R<Option<VolumeGrid>> {
    let Some(v) = v else { return Ok(None) };
    let p = "volume";
    let (c, _) = require_arr(p, "center", &v.center, "the box's center")?;
    let (sz, sp) = require_arr(p, "size", &v.size, "the box's edge lengths")?;
    if sz.iter().any(|&x| x <= 0.0) {
        return err(sp, format!("= {sz:?} m: expected three edge lengths > 0"));
    }
    let Some(n) = v.voxels else {
        return err(p, "missing voxels: give voxels = [nx, ny, nz] (voxels along x, y and z)");
    };
    if n.iter().any(|&k| k < 1) || n.iter().try_fold(1i64, |a, &k| a.checked_mul(k)).is_none_or(|t| t > MAX_VOXELS) {
        return err(
            "volume.voxels",
            format!("= {n:?}: expected three counts ≥ 1 with a product of at most {MAX_VOXELS} (2^28)"),
        );
    }
    let fluence = match v.fluence.unwrap_or(FluenceKind::TrackLength) {
        FluenceKind::TrackLength => FluenceEstimator::TrackLength,
        FluenceKind::Collision => FluenceEstimator::Collision,
        FluenceKind::Both => FluenceEstimator::Both,
    };
    let (c, h) = (DVec3::from_array(c), DVec3::from_array(sz) * 0.5);
    // The box's corners, its voxels' edges, their inverses and the inverse voxel volume finite
    // and non-zero (issue 33, item 8).
    let (lo, hi) = (c - h, c + h);
    let counts = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    let edge = (hi - lo) / counts;
    let inverse = counts / (hi - lo);
    if !(lo.is_finite()
        && hi.is_finite()
        && edge.is_finite()
        && inverse.is_finite()
        && (lo + edge).cmpgt(lo).all()
        && (1.0 / edge.element_product()).is_finite())
    {
        return err(
            sp,
            format!(
                "= {sz:?} m around center {:?} m: expected a box whose corners, voxel edges ({n:?} voxels) and voxel volume are finite, non-zero numbers",
                c.to_array()
            ),
        );
    }
    let mut grid = VolumeGrid::new(c - h, c + h, [n[0] as usize, n[1] as usize, n[2] as usize], fluence);
    grid.vdb = v.vdb.unwrap_or(false);
    let Some(t) = &v.time else { return Ok(Some(grid)) };
    if t.image.is_some() {
        return err("volume.time.image", "is a detector's key (its time-gated image): a volume tally has no image");
    }
    let spec = resolve_time("volume.time", t, false)?;
    let total = grid.count() as i64 * spec.axis.bins as i64;
    if total > MAX_VOXELS {
        return err(
            "volume.time.bins",
            format!(
                "= {}: {} voxels × {} bins = {total} exceeds {MAX_VOXELS} (2^28) values per estimate: fewer bins or voxels",
                spec.axis.bins,
                grid.count(),
                spec.axis.bins
            ),
        );
    }
    Ok(Some(grid.with_time(spec.axis)))
}
