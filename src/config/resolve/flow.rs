//! Velocity fields, `[wind]`, height profiles and particle motion.

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use super::density::{interpolation, resolve_placement};
use super::{GridFiles, R, err, given, join, non_negative, positive, require, require_arr, shown};
use crate::config::schema::*;
use crate::config::units::{Speed, UnitSet};
use crate::error::ConfigError;
use crate::flow::{FallSpeeds, VON_KARMAN, VelocityField, WindProfile, atlas_fall_speed};
use crate::medium::density::{GridField, Placement};
use crate::medium::grid::VoxelGrid;
use crate::medium::{Motion, Shape, stokes_einstein};

/// What a velocity field may draw on besides its own keys: the region's cylinder (Poiseuille), the
/// file's `[wind]` and the particle sizes of the population (terminal fall).
#[derive(Clone, Copy)]
pub(super) struct FlowCtx<'a> {
    /// Where relative file names start, and the grids read so far.
    pub(super) base: &'a Path,
    pub(super) files: &'a GridFiles,
    pub(super) memory: &'a super::Memory,
    pub(super) cylinder: Option<&'a Shape>,
    pub(super) wind: Option<&'a WindProfile>,
    /// Radii (m) with their σs weights.
    pub(super) sizes: &'a [(f64, f64)],
}

/// Speeds are refused at or above the speed of light in vacuum, `c`: a physical bound (no
/// particle reaches it; the Doppler shift `n·v·(d_in − d_out)/λ0` is the first-order formula,
/// valid only far below it).
pub(super) const SPEED_LIMIT: f64 = crate::SPEED_OF_LIGHT;

/// The largest velocity dispersion (standard deviation of each component, m/s): `c/10`, so that a
/// Gaussian draw per event reaches `c` in a component with probability below 10⁻²³.
pub(super) const DISPERSION_LIMIT: f64 = 0.1 * crate::SPEED_OF_LIGHT;

/// Refuse a speed `v` (m/s; `written` as written, in the key's unit) at or above `c`.
fn below_light(path: &str, v: f64, written: &str) -> R<()> {
    if v.is_finite() && v.abs() < SPEED_LIMIT {
        return Ok(());
    }
    let unit = super::unit_of(path);
    err(
        path,
        format!(
            "= {written} {unit}: expected a finite speed below the speed of light, |v| < c = {SPEED_LIMIT} m/s (a physical bound)"
        ),
    )
}

/// The numbers of a velocity section that need nothing else to be checked: finite, and speeds
/// below the speed of light. Run on every velocity section written, used or not (an unused
/// medium's, a medium's overridden by a region's), so that nothing written is accepted unchecked;
/// [`resolve_velocity`] checks the rest (files, the cylinder, the wind, the particles) where it
/// is used.
pub(super) fn check_velocity(path: &str, v: &VelocitySection) -> R<()> {
    match v {
        VelocitySection::None {} | VelocitySection::Wind { .. } | VelocitySection::TerminalFall { .. } => Ok(()),
        // Its placement's numbers (the file is not read for an unused medium).
        VelocitySection::Vdb { scale, translate, .. } => resolve_placement(path, *scale, translate).map(drop),
        VelocitySection::Npy { voxel_size, translate, .. } => {
            super::density::npy_transform(path, voxel_size, translate).map(drop)
        }
        VelocitySection::Uniform { velocity, .. } => {
            let Some(q) = velocity else { return Ok(()) };
            let (v, key) = require_arr(path, "velocity", velocity, "the velocity vector")?;
            below_light(&key, DVec3::from_array(v).length(), &format!("[{}]", q.value.map(shown).join(", ")))
        }
        VelocitySection::RandomDirection { speed, .. } => match given(path, speed)? {
            Some((v, key, as_written)) => below_light(&key, v, &shown(as_written)),
            None => Ok(()),
        },
        VelocitySection::Poiseuille { v_max, mean, .. } => {
            if let Some((v, key, as_written)) = given(path, v_max)? {
                below_light(&key, v, &shown(as_written))?;
            }
            if let Some((v, key, as_written)) = given(path, mean)? {
                // The centre line moves at twice the mean.
                below_light(&key, 2.0 * v, &shown(as_written)).map_err(|e| {
                    ConfigError::new(e.path, format!("{} (the centre line moves at twice the mean)", e.message))
                })?;
            }
            Ok(())
        }
    }
}

pub(super) fn resolve_velocity(path: &str, v: &VelocitySection, fc: FlowCtx) -> R<VelocityField> {
    check_velocity(path, v)?;
    let cylinder = fc.cylinder;
    Ok(match v {
        VelocitySection::None {} => VelocityField::Static,
        VelocitySection::Wind { .. } => match fc.wind {
            Some(w) => VelocityField::Wind(w.clone()),
            None => return err(join(path, "type"), "= \"wind\" needs a [wind] table (the wind profile)"),
        },
        VelocitySection::TerminalFall { .. } => {
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
        VelocitySection::Uniform { velocity, .. } => {
            let (v, _) = require_arr(path, "velocity", velocity, "the velocity vector")?;
            VelocityField::Uniform(DVec3::from_array(v))
        }
        VelocitySection::RandomDirection { speed, .. } => {
            let s = require(path, "speed", speed, "the speed")?;
            VelocityField::RandomDirection { speed: non_negative(s, "a speed")? }
        }
        VelocitySection::Poiseuille { v_max, mean, .. } => {
            let Some(&Shape::Cylinder { center, axis, radius, .. }) = cylinder else {
                return err(
                    join(path, "type"),
                    "= \"poiseuille\": a Poiseuille profile needs a cylinder region (its axis and radius); use it on a region with shape.type = \"cylinder\"",
                );
            };
            // Mean over the cross-section of v_max(1 − r²/R²) is v_max/2 (the factor 2 is exact, so
            // 2·(unit factor) is the factor of the mean's unit to v_max in m/s).
            let v = match (v_max, mean) {
                (Some(_), None) => given(path, v_max)?.expect("given"),
                (None, Some(q)) => {
                    let (_, key, v) = given(path, mean)?.expect("given");
                    (v * (2.0 * q.unit.factor), key, v)
                }
                (Some(a), Some(b)) => return err(path, format!("give only one of {}, {}", a.key, b.key)),
                (None, None) => {
                    let keys = [Speed::keys("v_max"), Speed::keys("mean")].concat();
                    return err(
                        path,
                        format!("missing the centre-line (v_max) or mean speed: give one of {}", keys.join(", ")),
                    );
                }
            };
            if !v.0.is_finite() {
                return err(v.1, "expected a finite speed (negative reverses the flow along the axis)");
            }
            VelocityField::Poiseuille { origin: center, axis, radius, v_max: v.0 }
        }
        VelocitySection::Npy { file, voxel_size, translate, interpolation: i, .. } => {
            let transform = super::density::npy_transform(path, voxel_size, translate)?;
            let g = super::GridFiles::npy::<[f32; 3]>(path, (fc.base, fc.memory), file, transform, 1, |_| None)?;
            grid_velocity(path, file, Arc::new(g), interpolation(*i), Placement::default())?
        }
        VelocitySection::Vdb { file, grid, interpolation: i, scale, translate, .. } => {
            let g = fc.files.vec3(path, (fc.base, fc.memory), file, grid.as_deref())?;
            let place = resolve_placement(path, *scale, translate)?;
            grid_velocity(path, file, g, interpolation(*i), place)?
        }
    })
}

/// A velocity field from the voxel grid `g` of `file` (a `.vdb` or `.npy`; `path` its key),
/// checked: finite, and below the speed of light everywhere.
fn grid_velocity(
    path: &str,
    file: &str,
    g: Arc<VoxelGrid<[f32; 3]>>,
    interp: crate::medium::density::Interpolation,
    place: Placement,
) -> R<VelocityField> {
    if !g.background.iter().all(|c| c.is_finite()) {
        return err(join(path, "file"), format!("{file}: the velocity grid's background is not finite"));
    }
    if let Some(o) = g.data.iter().position(|v| !v.iter().all(|c| c.is_finite())) {
        let ijk = g.index_of(o);
        return err(join(path, "file"), format!("{file}: voxel {ijk:?} of the velocity grid is not finite"));
    }
    let speed = |v: &[f32; 3]| DVec3::new(v[0].into(), v[1].into(), v[2].into()).length();
    if speed(&g.background) >= SPEED_LIMIT {
        return err(
            join(path, "file"),
            format!(
                "{file}: the velocity grid's background, {:?} m/s, is not below the speed of light, c = {SPEED_LIMIT} m/s (a physical bound)",
                g.background
            ),
        );
    }
    if let Some(o) = g.data.iter().position(|v| speed(v) >= SPEED_LIMIT) {
        return err(
            join(path, "file"),
            format!(
                "{file}: voxel {:?} of the velocity grid, {:?} m/s, is not below the speed of light, c = {SPEED_LIMIT} m/s (a physical bound)",
                g.index_of(o),
                g.data[o]
            ),
        );
    }
    Ok(VelocityField::Grid(Arc::new(GridField::new(g, interp, place))))
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
        WindSection::Uniform { velocity } => {
            let velocity_m_per_s = velocity.si();
            let v = DVec3::from_array(velocity_m_per_s);
            if !v.is_finite() || v.length() > 200.0 {
                return err(
                    "wind.velocity_m_per_s",
                    format!("= {velocity_m_per_s:?}: expected finite components, |v| ≤ 200 m/s"),
                );
            }
            WindProfile::Uniform(v)
        }
        WindSection::PowerLaw { speed: u, reference_height: h, exponent, direction_from, vertical: w } => {
            if !(exponent.is_finite() && (0.0..=1.0).contains(exponent)) {
                return err(
                    "wind.exponent",
                    format!("= {exponent}: expected a shear exponent α in [0, 1] (1/7 onshore)"),
                );
            }
            WindProfile::PowerLaw {
                direction: horizontal(direction_from.value)?,
                speed_ref: speed("speed_m_per_s", u.si())?,
                height_ref: height("reference_height_m", h.si())?,
                exponent: *exponent,
                vertical: vertical(w.as_ref().map(|q| q.si()))?,
            }
        }
        WindSection::LogLaw {
            friction_velocity,
            speed: u,
            reference_height,
            roughness_length,
            displacement_height,
            direction_from,
            vertical: w,
        } => {
            let z0 = height("roughness_length_m", roughness_length.si())?;
            let d = displacement_height.as_ref().map_or(0.0, |q| q.si());
            if !(d.is_finite() && d >= 0.0) {
                return err("wind.displacement_height_m", format!("= {d}: expected a height ≥ 0 m"));
            }
            let u_star = match (friction_velocity, u, reference_height) {
                (Some(u), None, None) => speed("friction_velocity_m_per_s", u.si())?,
                (None, Some(u), Some(h)) => {
                    let h = height("reference_height_m", h.si())?;
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
                    speed("speed_m_per_s", u.si())? * VON_KARMAN / ((h - d) / z0).ln()
                }
                _ => {
                    return err(
                        "wind",
                        "a log-law wind needs friction_velocity_m_per_s, or speed_m_per_s with reference_height_m (not both)",
                    );
                }
            };
            WindProfile::LogLaw {
                direction: horizontal(direction_from.value)?,
                friction_velocity: u_star,
                roughness: z0,
                displacement: d,
                vertical: vertical(w.as_ref().map(|q| q.si()))?,
            }
        }
        WindSection::Table { heights, velocities } => {
            // Metres and metres per second: SI as written.
            let (heights_m, velocities_m_per_s) = (&heights.value, &velocities.value);
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
        HeightProfileSection::Exponential { scale_height } => {
            HeightProfile::Exponential { scale: length("scale_height_m", scale_height.si())? }
        }
        HeightProfileSection::BoundaryLayer { top, scale_height } => HeightProfile::BoundaryLayer {
            top: length("top_m", top.si())?,
            scale: length("scale_height_m", scale_height.si())?,
        },
        HeightProfileSection::Table { heights, factors } => {
            // Metres: SI as written.
            let heights_m = &heights.value;
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
    let dispersion = match given(path, &m.dispersion)? {
        None => 0.0,
        Some((v, ..)) if v.is_finite() && (0.0..DISPERSION_LIMIT).contains(&v) => v,
        Some((_, key, as_written)) => {
            let unit = super::unit_of(&key);
            return err(
                key,
                format!(
                    "= {} {unit}: expected a velocity standard deviation in [0, c/10) = [0, {DISPERSION_LIMIT}) m/s (each event draws a Gaussian velocity; the bound keeps its draws below the speed of light, a physical bound)",
                    shown(as_written)
                ),
            );
        }
    };
    let direct = given(path, &m.diffusion)?;
    let radius = given(path, &m.radius)?;
    let temperature = given(path, &m.temperature)?;
    let viscosity = given(path, &m.viscosity)?;
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
