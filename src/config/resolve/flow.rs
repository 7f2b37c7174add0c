//! Velocity fields, `[wind]`, height profiles and particle motion.

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use super::density::{interpolation, resolve_placement};
use super::{GridFiles, R, err, join, non_negative, pick, positive, require, require_arr};
use crate::config::schema::*;
use crate::error::ConfigError;
use crate::flow::{FallSpeeds, VON_KARMAN, VelocityField, WindProfile, atlas_fall_speed};
use crate::medium::density::GridField;
use crate::medium::{Motion, Shape, stokes_einstein};

/// What a velocity field may draw on besides its own keys: the region's cylinder (Poiseuille), the
/// file's `[wind]` and the particle sizes of the population (terminal fall).
#[derive(Clone, Copy)]
pub(super) struct FlowCtx<'a> {
    /// Where relative file names start, and the grids read so far.
    pub(super) base: &'a Path,
    pub(super) files: &'a GridFiles,
    pub(super) cylinder: Option<&'a Shape>,
    pub(super) wind: Option<&'a WindProfile>,
    /// Radii (m) with their σs weights.
    pub(super) sizes: &'a [(f64, f64)],
}

pub(super) fn resolve_velocity(path: &str, v: &VelocitySection, fc: FlowCtx) -> R<VelocityField> {
    let cylinder = fc.cylinder;
    Ok(match v {
        VelocitySection::None {} => VelocityField::Static,
        VelocitySection::Wind {} => match fc.wind {
            Some(w) => VelocityField::Wind(w.clone()),
            None => return err(join(path, "type"), "= \"wind\" needs a [wind] table (the wind profile)"),
        },
        VelocitySection::TerminalFall {} => {
            if fc.sizes.is_empty() {
                return err(
                    join(path, "type"),
                    "= \"terminal_fall\" needs the medium's particles: the drop sizes give the fall speeds",
                );
            }
            let pairs: Vec<(f64, f64)> = fc.sizes.iter().map(|&(r, w)| (atlas_fall_speed(2.0 * r), w)).collect();
            let fall = FallSpeeds::new(&pairs)
                .ok_or_else(|| ConfigError::new(path, "the particles scatter nothing: no drop sizes to fall"))?;
            let wind = fc.wind.cloned().unwrap_or(WindProfile::Uniform(DVec3::ZERO));
            VelocityField::TerminalFall { wind, fall: Arc::new(fall) }
        }
        VelocitySection::Uniform { velocity_mm_per_s, velocity_m_per_s } => {
            let (v, _) = require_arr(
                path,
                &[("velocity_mm_per_s", *velocity_mm_per_s, 1e-3), ("velocity_m_per_s", *velocity_m_per_s, 1.0)],
                "the velocity vector",
            )?;
            VelocityField::Uniform(DVec3::from_array(v))
        }
        VelocitySection::RandomDirection { speed_mm_per_s, speed_m_per_s } => {
            let s = require(
                path,
                &[("speed_mm_per_s", *speed_mm_per_s, 1e-3), ("speed_m_per_s", *speed_m_per_s, 1.0)],
                "the speed",
            )?;
            VelocityField::RandomDirection { speed: non_negative(s, "a speed")? }
        }
        VelocitySection::Poiseuille { v_max_mm_per_s, v_max_m_per_s, mean_mm_per_s, mean_m_per_s } => {
            let Some(&Shape::Cylinder { center, axis, radius, .. }) = cylinder else {
                return err(
                    join(path, "type"),
                    "= \"poiseuille\": a Poiseuille profile needs a cylinder region (its axis and radius); use it on a region with shape.type = \"cylinder\"",
                );
            };
            let v = require(
                path,
                &[
                    ("v_max_mm_per_s", *v_max_mm_per_s, 1e-3),
                    ("v_max_m_per_s", *v_max_m_per_s, 1.0),
                    // Mean over the cross-section of v_max(1 − r²/R²) is v_max/2.
                    ("mean_mm_per_s", *mean_mm_per_s, 2e-3),
                    ("mean_m_per_s", *mean_m_per_s, 2.0),
                ],
                "the centre-line (v_max) or mean speed",
            )?;
            if !v.0.is_finite() {
                return err(v.1, "expected a finite speed (negative reverses the flow along the axis)");
            }
            VelocityField::Poiseuille { origin: center, axis, radius, v_max: v.0 }
        }
        VelocitySection::Vdb { file, grid, interpolation: i, scale, translate_um, translate_mm, translate_m } => {
            let g = fc.files.vec3(path, fc.base, file, grid.as_deref())?;
            let place = resolve_placement(path, *scale, *translate_um, *translate_mm, *translate_m)?;
            if !g.background.iter().all(|c| c.is_finite()) {
                return err(join(path, "file"), format!("{file}: the velocity grid's background is not finite"));
            }
            if let Some(o) = g.data.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
                let ijk = g.index_of(o);
                return err(join(path, "file"), format!("{file}: voxel {ijk:?} of the velocity grid is not finite"));
            }
            VelocityField::Grid(Arc::new(GridField::new(g, interpolation(*i), place)))
        }
    })
}

/// `[wind]`: the wind profile.
pub(super) fn resolve_wind(w: &WindSection) -> R<WindProfile> {
    let finite = |key: &str, v: f64, what: &str| -> R<f64> {
        if v.is_finite() { Ok(v) } else { err(join("wind", key), format!("= {v}: expected a finite {what}")) }
    };
    let horizontal = |deg: f64| -> R<DVec3> {
        let d = finite("direction_from_deg", deg, "direction in degrees clockwise from north")?.to_radians();
        // Blowing *from* azimuth d, i.e. toward d + 180°: (−sin d, −cos d, 0) in (east, north, up).
        Ok(DVec3::new(-d.sin(), -d.cos(), 0.0))
    };
    let speed = |key: &str, v: f64| -> R<f64> {
        if v.is_finite() && (0.0..=200.0).contains(&v) {
            Ok(v)
        } else {
            err(join("wind", key), format!("= {v}: expected a wind speed from 0 to 200 m/s"))
        }
    };
    let vertical = |v: Option<f64>| -> R<f64> {
        let v = v.unwrap_or(0.0);
        if v.is_finite() && v.abs() <= 100.0 {
            Ok(v)
        } else {
            err("wind.vertical_m_per_s", format!("= {v}: expected a vertical velocity within ±100 m/s"))
        }
    };
    let height = |key: &str, v: f64| -> R<f64> {
        if v.is_finite() && v > 0.0 { Ok(v) } else { err(join("wind", key), format!("= {v}: expected a height > 0 m")) }
    };
    Ok(match w {
        WindSection::Uniform { velocity_m_per_s } => {
            let v = DVec3::from_array(*velocity_m_per_s);
            if !v.is_finite() || v.length() > 200.0 {
                return err(
                    "wind.velocity_m_per_s",
                    format!("= {velocity_m_per_s:?}: expected finite components, |v| ≤ 200 m/s"),
                );
            }
            WindProfile::Uniform(v)
        }
        WindSection::PowerLaw { speed_m_per_s, reference_height_m, exponent, direction_from_deg, vertical_m_per_s } => {
            if !(exponent.is_finite() && (0.0..=1.0).contains(exponent)) {
                return err(
                    "wind.exponent",
                    format!("= {exponent}: expected a shear exponent α in [0, 1] (1/7 onshore)"),
                );
            }
            WindProfile::PowerLaw {
                direction: horizontal(*direction_from_deg)?,
                speed_ref: speed("speed_m_per_s", *speed_m_per_s)?,
                height_ref: height("reference_height_m", *reference_height_m)?,
                exponent: *exponent,
                vertical: vertical(*vertical_m_per_s)?,
            }
        }
        WindSection::LogLaw {
            friction_velocity_m_per_s,
            speed_m_per_s,
            reference_height_m,
            roughness_length_m,
            displacement_height_m,
            direction_from_deg,
            vertical_m_per_s,
        } => {
            let z0 = height("roughness_length_m", *roughness_length_m)?;
            let d = displacement_height_m.unwrap_or(0.0);
            if !(d.is_finite() && d >= 0.0) {
                return err("wind.displacement_height_m", format!("= {d}: expected a height ≥ 0 m"));
            }
            let u_star = match (friction_velocity_m_per_s, speed_m_per_s, reference_height_m) {
                (Some(u), None, None) => speed("friction_velocity_m_per_s", *u)?,
                (None, Some(u), Some(h)) => {
                    let h = height("reference_height_m", *h)?;
                    if h - d <= z0 {
                        return err(
                            "wind.reference_height_m",
                            format!(
                                "= {h}: the reference height must lie above displacement + roughness ({} m)",
                                d + z0
                            ),
                        );
                    }
                    // u(h) = (u*/κ) ln((h − d)/z0), solved for u*.
                    speed("speed_m_per_s", *u)? * VON_KARMAN / ((h - d) / z0).ln()
                }
                _ => {
                    return err(
                        "wind",
                        "a log-law wind needs friction_velocity_m_per_s, or speed_m_per_s with reference_height_m (not both)",
                    );
                }
            };
            WindProfile::LogLaw {
                direction: horizontal(*direction_from_deg)?,
                friction_velocity: u_star,
                roughness: z0,
                displacement: d,
                vertical: vertical(*vertical_m_per_s)?,
            }
        }
        WindSection::Table { heights_m, velocities_m_per_s } => {
            if velocities_m_per_s.is_empty() || heights_m.len() != velocities_m_per_s.len() + 1 {
                return err(
                    "wind.heights_m",
                    format!(
                        "{} heights for {} velocities: give the n + 1 layer edges of n ≥ 1 velocities",
                        heights_m.len(),
                        velocities_m_per_s.len()
                    ),
                );
            }
            if heights_m.iter().any(|h| !h.is_finite()) || heights_m.windows(2).any(|w| w[1] <= w[0]) {
                return err("wind.heights_m", "expected finite heights in strictly increasing order (m)");
            }
            if let Some(i) = velocities_m_per_s
                .iter()
                .position(|v| !DVec3::from_array(*v).is_finite() || DVec3::from_array(*v).length() > 200.0)
            {
                return err(
                    format!("wind.velocities_m_per_s[{i}]"),
                    format!("= {:?}: expected finite components, |v| ≤ 200 m/s", velocities_m_per_s[i]),
                );
            }
            WindProfile::Table {
                edges: heights_m.as_slice().into(),
                velocities: velocities_m_per_s.iter().map(|v| DVec3::from_array(*v)).collect(),
            }
        }
    })
}

/// A factor on σs and σa as a function of height.
pub(super) enum HeightProfile {
    Exponential { scale: f64 },
    BoundaryLayer { top: f64, scale: f64 },
    Table { heights: Vec<f64>, factors: Vec<f64> },
}

impl HeightProfile {
    pub(super) fn factor(&self, h: f64) -> f64 {
        match self {
            HeightProfile::Exponential { scale } => (-h / scale).exp(),
            HeightProfile::BoundaryLayer { top, scale } => {
                if h <= *top {
                    1.0
                } else {
                    (-(h - top) / scale).exp()
                }
            }
            HeightProfile::Table { heights, factors } => {
                let i = heights.partition_point(|&x| x <= h);
                if i == 0 {
                    factors[0]
                } else if i == heights.len() {
                    factors[i - 1]
                } else {
                    let t = (h - heights[i - 1]) / (heights[i] - heights[i - 1]);
                    factors[i - 1] + t * (factors[i] - factors[i - 1])
                }
            }
        }
    }
}

pub(super) fn resolve_height_profile(path: &str, h: &HeightProfileSection) -> R<HeightProfile> {
    let length = |key: &str, v: f64| -> R<f64> {
        if v.is_finite() && v > 0.0 { Ok(v) } else { err(join(path, key), format!("= {v}: expected a length > 0 m")) }
    };
    Ok(match h {
        HeightProfileSection::Exponential { scale_height_m } => {
            HeightProfile::Exponential { scale: length("scale_height_m", *scale_height_m)? }
        }
        HeightProfileSection::BoundaryLayer { top_m, scale_height_m } => HeightProfile::BoundaryLayer {
            top: length("top_m", *top_m)?,
            scale: length("scale_height_m", *scale_height_m)?,
        },
        HeightProfileSection::Table { heights_m, factors } => {
            if heights_m.is_empty() || heights_m.len() != factors.len() {
                return err(
                    join(path, "factors"),
                    format!(
                        "{} factors for {} heights: expected one factor per height",
                        factors.len(),
                        heights_m.len()
                    ),
                );
            }
            if heights_m.iter().any(|h| !h.is_finite()) || heights_m.windows(2).any(|w| w[1] <= w[0]) {
                return err(join(path, "heights_m"), "expected finite heights in strictly increasing order (m)");
            }
            if let Some(f) = factors.iter().find(|f| !(f.is_finite() && **f >= 0.0 && **f <= 1e6)) {
                return err(join(path, "factors"), format!("contains {f}: expected factors in [0, 1e6]"));
            }
            HeightProfile::Table { heights: heights_m.clone(), factors: factors.clone() }
        }
    })
}

/// `[media.X.motion]`: a per-event velocity dispersion and a diffusion coefficient, given directly
/// or by Stokes–Einstein from radius, temperature and viscosity.
pub(super) fn resolve_motion(path: &str, m: &MotionSection) -> R<Motion> {
    let dispersion = pick(
        path,
        &[("dispersion_mm_per_s", m.dispersion_mm_per_s, 1e-3), ("dispersion_m_per_s", m.dispersion_m_per_s, 1.0)],
    )?
    .map_or(Ok(0.0), |v| non_negative(v, "a velocity standard deviation"))?;
    let direct = pick(
        path,
        &[("diffusion_m2_per_s", m.diffusion_m2_per_s, 1.0), ("diffusion_um2_per_s", m.diffusion_um2_per_s, 1e-12)],
    )?;
    let radius = pick(path, &[("radius_um", m.radius_um, 1e-6), ("radius_nm", m.radius_nm, 1e-9)])?;
    let temperature = pick(path, &[("temperature_k", m.temperature_k, 1.0)])?;
    let viscosity =
        pick(path, &[("viscosity_mpa_s", m.viscosity_mpa_s, 1e-3), ("viscosity_pa_s", m.viscosity_pa_s, 1.0)])?;
    let stokes = radius.is_some() || temperature.is_some() || viscosity.is_some();
    let diffusion = match (direct, stokes) {
        (Some(d), false) => non_negative(d, "a diffusion coefficient")?,
        (None, false) => 0.0,
        (Some(d), true) => {
            return err(d.1, "give either the diffusion coefficient or radius, temperature and viscosity, not both");
        }
        (None, true) => {
            let missing = |what: &str, keys: &str| {
                ConfigError::new(
                    path,
                    format!("missing {what} for the Stokes–Einstein diffusion coefficient: give {keys}"),
                )
            };
            let r =
                positive(radius.ok_or_else(|| missing("the particle radius", "radius_um or radius_nm"))?, "a radius")?;
            let t = positive(temperature.ok_or_else(|| missing("the temperature", "temperature_k"))?, "a temperature")?;
            let eta = positive(
                viscosity.ok_or_else(|| missing("the fluid viscosity", "viscosity_mpa_s or viscosity_pa_s"))?,
                "a viscosity",
            )?;
            stokes_einstein(r, t, eta)
        }
    };
    Ok(Motion { dispersion, diffusion })
}
