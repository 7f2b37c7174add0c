//! `[media.NAME]`: optics (coefficients, phase function), Mie particle ensembles and size classes,
//! mixtures, and the populations a medium becomes.

use std::collections::BTreeMap;
use std::sync::Arc;

use super::flow::{FlowCtx, check_velocity, resolve_height_profile, resolve_motion, resolve_velocity};
use super::{Ctx, Given, R, err, given, index_of_refraction, join, positive};
use crate::config::schema::*;
use crate::config::units::{Coefficient, Length, Quantity, UnitSet};
use crate::error::ConfigError;
use crate::flow::{VelocityField, WindProfile};
use crate::io::formats::table::read_phase_table;
use crate::medium::{MediumInfo, Motion, ParticleOptics, Population, Shape, TableInfo, mixture_optics};
use crate::mie::{Concentration, DEFAULT_SIZE_POINTS, EnsembleSpec, Packing, SizeDistribution};
use crate::phase::{HenyeyGreenstein, PhaseFunction, TabulatedPhase};

/// The optics of a named medium (everything but its velocity), resolved once per name however many
/// layers and regions use it.
#[derive(Debug, Clone)]
pub(super) struct Optics {
    sigma_a: f64,
    sigma_s: f64,
    phase: PhaseFunction,
    info: MediumInfo,
    /// Particle radii (m) with the σs (m⁻¹) each contributes, when the medium has particles.
    sizes: Vec<(f64, f64)>,
    /// With `size_classes`: one population per class (then the fields above are their sums).
    classes: Vec<ClassOptics>,
}

/// The optics of one size class of a medium's particles.
#[derive(Debug, Clone)]
struct ClassOptics {
    sigma_s: f64,
    phase: PhaseFunction,
    sizes: Vec<(f64, f64)>,
}

/// Default number of angles of a Mie phase table, and the grid used when only σ and g are needed.
const MIE_ANGLES: u64 = 1000;
const MIE_ANGLES_UNUSED: usize = 16;

/// Values computed for one wavelength must not be used at another (1 % tolerance).
fn check_wavelength(path: &str, what: &str, given: f64, source: f64) -> R<()> {
    if (given / source - 1.0).abs() > 0.01 {
        return err(
            path,
            format!(
                "{what} λ0 = {:.1} nm but source.wavelength is {:.1} nm: use values for the source wavelength",
                given * 1e9,
                source * 1e9
            ),
        );
    }
    Ok(())
}

fn resolve_optics(path: &str, m: &MediumSection, ctx: &Ctx) -> R<Optics> {
    if let Some(wl) = given(path, &m.wavelength)? {
        check_wavelength(&wl.1, "this medium's values are for", wl.0, ctx.wavelength)?;
    }
    // Only a Mie phase function needs the full angle grid; σ and g alone need very few angles.
    let mie_angles = match &m.phase {
        None => Some(MIE_ANGLES),
        Some(PhaseSection::Mie { angles }) => Some(angles.unwrap_or(MIE_ANGLES)),
        _ => None,
    };
    if let Some(a) = mie_angles.filter(|a| !(16..=100_000).contains(a)) {
        return err(join(path, "phase.angles"), format!("= {a}: expected 16 to 100000 angles"));
    }
    if let Some(classes) = m.size_classes {
        return resolve_classes(path, m, classes, mie_angles, ctx);
    }
    let particles = match &m.particles {
        None => None,
        Some(list) => {
            let angles = mie_angles.map_or(MIE_ANGLES_UNUSED, |a| a as usize);
            Some(resolve_particles(&join(path, "particles"), list, angles, ctx)?)
        }
    };
    let coeff = |key: &str, q: &Option<Quantity<Coefficient>>, mie: Option<f64>| -> R<f64> {
        let Some(v) = given(path, q)? else {
            return mie.ok_or_else(|| {
                ConfigError::new(
                    path,
                    format!(
                        "missing {key} (a coefficient): give one of {}, or particles",
                        Coefficient::keys(key).join(", ")
                    ),
                )
            });
        };
        if !(v.0.is_finite() && (0.0..=1e12).contains(&v.0)) {
            return err(v.1, format!("= {} m⁻¹: expected a coefficient in [0, 1e12] m⁻¹", v.0));
        }
        Ok(v.0)
    };
    let sigma_a = coeff("sigma_a", &m.sigma_a, particles.as_ref().map(|p| p.sigma_a))?;
    let sigma_s = coeff("sigma_s", &m.sigma_s, particles.as_ref().map(|p| p.sigma_s))?;
    let scale = m.sigma_s_scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return err(join(path, "sigma_s_scale"), format!("= {scale}: expected a factor ≥ 0"));
    }
    let needs_particles = |what: &str| {
        ConfigError::new(
            join(path, "phase"),
            format!("{what} needs the medium's particles (add a particles table, or give the phase function)"),
        )
    };
    let mut table = None;
    let (phase, kind) = match &m.phase {
        None if particles.is_none() => (PhaseFunction::Isotropic, "isotropic"),
        Some(PhaseSection::Isotropic {}) => (PhaseFunction::Isotropic, "isotropic"),
        Some(PhaseSection::Hg { g }) => {
            let g = match (g, &particles) {
                (Some(g), _) => *g,
                (None, Some(p)) => p.g,
                (None, None) => return Err(needs_particles("type = \"hg\" without g")),
            };
            let hg = HenyeyGreenstein::new(g).ok_or_else(|| {
                ConfigError::new(
                    join(path, "phase.g"),
                    format!("= {g}: expected an asymmetry parameter with −1 < g < 1"),
                )
            })?;
            (PhaseFunction::HenyeyGreenstein(hg), "hg")
        }
        Some(PhaseSection::Table { file }) => {
            let key = join(path, "phase.file");
            let loaded = read_phase_table(&ctx.base.join(file)).map_err(|e| ConfigError::new(&key, e))?;
            if let Some(nm) = loaded.file.optics.wavelength_nm {
                check_wavelength(&key, &format!("the table `{file}` is for"), nm * 1e-9, ctx.wavelength)?;
            }
            table = Some(TableInfo {
                origin: loaded.phase.origin().to_string(),
                angles: loaded.phase.len(),
                source_normalisation: Some(loaded.file.normalisation.name().to_string()),
                source_integral: loaded.phase.source_integral(),
                provenance: loaded.file.provenance.clone(),
            });
            (PhaseFunction::Tabulated(Arc::new(loaded.phase)), "table")
        }
        None | Some(PhaseSection::Mie { .. }) => {
            let p = particles.as_ref().ok_or_else(|| needs_particles("type = \"mie\""))?;
            let origin = format!("Mie, {} component(s), λ0 = {:.1} nm", p.components.len(), ctx.wavelength * 1e9);
            let t = TabulatedPhase::from_angles(&p.theta, &p.phase, origin).map_err(|e| {
                ConfigError::new(join(path, "particles"), format!("the Mie phase function is not a distribution: {e}"))
            })?;
            table = Some(TableInfo {
                origin: t.origin().to_string(),
                angles: t.len(),
                source_normalisation: None,
                source_integral: t.source_integral(),
                provenance: Default::default(),
            });
            (PhaseFunction::Tabulated(Arc::new(t)), "mie")
        }
    };
    let sizes = particles.as_ref().map_or(Vec::new(), |p| p.sizes.iter().map(|&(r, s)| (r, s * scale)).collect());
    let info = MediumInfo {
        preset: m.preset.clone(),
        phase: kind.to_string(),
        g: phase.mean_cosine(),
        table,
        particles,
        sigma_s_scale: scale,
    };
    Ok(Optics { sigma_a, sigma_s: sigma_s * scale, phase, info, sizes, classes: Vec::new() })
}

/// A medium whose particles are split into `classes` size classes, each its own population with
/// its own Mie phase function (σs, σa and the phase functions all come from Mie theory).
fn resolve_classes(path: &str, m: &MediumSection, classes: u64, mie_angles: Option<u64>, ctx: &Ctx) -> R<Optics> {
    let key = join(path, "size_classes");
    if !(2..=64).contains(&classes) {
        return err(key, format!("= {classes}: expected 2 to 64 size classes"));
    }
    let Some(list) = &m.particles else {
        return err(key, "splits the medium's particles into size classes: add a particles table");
    };
    if let Some((k, _)) = coefficient_keys(m).iter().find(|(_, given)| *given) {
        return err(join(path, k), "with size_classes σs and σa come from the Mie classes: remove this key");
    }
    let Some(angles) = mie_angles else {
        return err(
            join(path, "phase"),
            "with size_classes each class has its Mie phase function: remove phase or give type = \"mie\"",
        );
    };
    let scale = m.sigma_s_scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale >= 0.0) {
        return err(join(path, "sigma_s_scale"), format!("= {scale}: expected a factor ≥ 0"));
    }
    let optics = particle_classes(&join(path, "particles"), list, classes as usize, angles as usize, ctx)?;
    let mut out = Vec::with_capacity(optics.len());
    for (i, o) in optics.iter().enumerate() {
        let origin = format!("Mie, size class {i} of {classes}, λ0 = {:.1} nm", ctx.wavelength * 1e9);
        let t = TabulatedPhase::from_angles(&o.theta, &o.phase, origin).map_err(|e| {
            ConfigError::new(
                join(path, "particles"),
                format!("size class {i}: the Mie phase function is not a distribution: {e}"),
            )
        })?;
        out.push(ClassOptics {
            sigma_s: o.sigma_s * scale,
            phase: PhaseFunction::Tabulated(Arc::new(t)),
            sizes: o.sizes.iter().map(|&(r, s)| (r, s * scale)).collect(),
        });
    }
    // The whole ensemble, for the record: sums over the classes.
    let sigma_s: f64 = optics.iter().map(|o| o.sigma_s).sum();
    let sigma_a: f64 = optics.iter().map(|o| o.sigma_a).sum();
    let backscatter: f64 = optics.iter().map(|o| o.backscatter).sum();
    let g = optics.iter().map(|o| o.sigma_s * o.g).sum::<f64>() / sigma_s;
    let whole = ParticleOptics {
        sigma_s,
        sigma_a,
        g,
        backscatter,
        lidar_ratio: (sigma_s + sigma_a) / backscatter,
        components: optics.iter().flat_map(|o| o.components.clone()).collect(),
        theta: Vec::new(),
        phase: Vec::new(),
        sizes: optics.iter().flat_map(|o| o.sizes.clone()).collect(),
    };
    let info = MediumInfo {
        preset: m.preset.clone(),
        phase: format!("mie, {} size classes", out.len()),
        g,
        table: None,
        particles: Some(whole),
        sigma_s_scale: scale,
    };
    Ok(Optics { sigma_a, sigma_s: sigma_s * scale, phase: out[0].phase.clone(), info, sizes: Vec::new(), classes: out })
}

/// A positive length `name`, if given.
fn positive_length(prefix: &str, name: &str, q: &Option<Quantity<Length>>) -> R<Option<Given>> {
    let Some(v) = given(prefix, q)? else { return Ok(None) };
    positive(v.clone(), &format!("a {}", name.replace('_', " ")))?;
    Ok(Some(v))
}

/// A size range `[lo, hi]` (m) from its two lengths (named `names`), with defaults when both are
/// optional.
fn size_range(
    prefix: &str,
    names: (&str, &str),
    lo: &Option<Quantity<Length>>,
    hi: &Option<Quantity<Length>>,
    default: Option<(f64, f64)>,
) -> R<(f64, f64)> {
    let lo = positive_length(prefix, names.0, lo)?;
    let hi = positive_length(prefix, names.1, hi)?;
    let (lo, hi) = match (lo, hi, default) {
        (Some(a), Some(b), _) => (a, b),
        (a, b, Some((da, db))) => {
            (a.unwrap_or((da, join(prefix, names.0), da)), b.unwrap_or((db, join(prefix, names.1), db)))
        }
        _ => {
            return err(prefix, format!("missing the size range: give {}_um and {}_um (or _mm, _m)", names.0, names.1));
        }
    };
    if lo.0 >= hi.0 {
        let key = |p: &str| p.rsplit('.').next().unwrap_or(p).to_string();
        return err(
            lo.1.clone(),
            format!("= {} is not below {} = {}: the size range is empty", lo.2, key(&hi.1), hi.2),
        );
    }
    Ok((lo.0, hi.0))
}

fn resolve_particles(path: &str, list: &OneOrMany<ParticlesSection>, angles: usize, ctx: &Ctx) -> R<ParticleOptics> {
    let specs = particle_specs(path, list, ctx)?;
    mixture_optics(&specs, angles).map_err(|e| ConfigError::new(path, e.to_string()))
}

/// The Mie optics of each of `classes` size classes of one Marshall–Palmer component, with
/// diameters log-spaced over its range and the quadrature nodes shared among them. Classes that
/// hold essentially no drops (far in the tail) are left out.
fn particle_classes(
    path: &str,
    list: &OneOrMany<ParticlesSection>,
    classes: usize,
    angles: usize,
    ctx: &Ctx,
) -> R<Vec<ParticleOptics>> {
    let specs = particle_specs(path, list, ctx)?;
    let [(name, spec)] = specs.as_slice() else {
        return err(path, "size_classes splits one particle component: give a single particles table");
    };
    let SizeDistribution::MarshallPalmer { rain_rate_mm_per_h, d_min, d_max } = spec.distribution else {
        return err(
            join(path, "size.type"),
            "size_classes needs an absolute size distribution: use type = \"marshall_palmer\" (the others are normalised to their whole range)",
        );
    };
    let size_points = (spec.size_points / classes).max(16);
    let mut out = Vec::with_capacity(classes);
    let edge = |j: usize| d_min * (d_max / d_min).powf(j as f64 / classes as f64);
    for i in 0..classes {
        let class = EnsembleSpec {
            distribution: SizeDistribution::MarshallPalmer { rain_rate_mm_per_h, d_min: edge(i), d_max: edge(i + 1) },
            size_points,
            ..*spec
        };
        match mixture_optics(&[(format!("{name}[{i}]"), class)], angles) {
            Ok(o) if o.sigma_s > 0.0 => out.push(o),
            Ok(_) | Err(crate::mie::MieError::EmptyDistribution(_)) => {}
            Err(e) => return err(path, format!("size class {i}: {e}")),
        }
    }
    if out.is_empty() {
        return err(path, "no size class holds any drops");
    }
    Ok(out)
}

/// The ensemble specification of every particle component.
fn particle_specs(path: &str, list: &OneOrMany<ParticlesSection>, ctx: &Ctx) -> R<Vec<(String, EnsembleSpec)>> {
    let items = list.items();
    if items.is_empty() {
        return err(path, "an empty list: give at least one particle component");
    }
    let mut specs = Vec::with_capacity(items.len());
    for (suffix, p) in items {
        let here = format!("{path}{suffix}");
        let name = p.name.clone().unwrap_or_else(|| format!("component{}", specs.len()));
        let k = p.k_particle.unwrap_or(0.0);
        if !(p.n_particle.is_finite() && p.n_particle > 0.0 && p.n_particle <= 20.0) {
            return err(
                join(&here, "n_particle"),
                format!("= {}: expected a real refractive index in (0, 20]", p.n_particle),
            );
        }
        if !(k.is_finite() && (0.0..=20.0).contains(&k)) {
            return err(
                join(&here, "k_particle"),
                format!("= {k}: expected an absorption index k in [0, 20] (index n − ik, k ≥ 0 absorbs)"),
            );
        }
        let n_medium = index_of_refraction(&join(&here, "n_medium"), p.n_medium)?;
        let sp = join(&here, "size");
        let distribution = match &p.size {
            SizeSection::Monodisperse { diameter, radius } => {
                let d = positive_length(&sp, "diameter", diameter)?;
                let r = positive_length(&sp, "radius", radius)?;
                let radius = match (d, r) {
                    (Some(d), None) => 0.5 * d.0,
                    (None, Some(r)) => r.0,
                    (Some(_), Some(_)) => return err(&sp, "give the diameter or the radius, not both"),
                    (None, None) => {
                        return err(&sp, "missing the particle size: give diameter_um or radius_um (or _mm, _m)");
                    }
                };
                SizeDistribution::Monodisperse { radius }
            }
            SizeSection::LogNormal { median_radius, sigma_g, min_radius, max_radius } => {
                let median_radius = positive_length(&sp, "median_radius", median_radius)?
                    .ok_or_else(|| ConfigError::new(&sp, "missing median_radius_um (or _mm, _m)"))?;
                if !(sigma_g.is_finite() && *sigma_g > 1.0 && *sigma_g <= 10.0) {
                    return err(
                        join(&sp, "sigma_g"),
                        format!("= {sigma_g}: expected a geometric standard deviation in (1, 10]"),
                    );
                }
                let (r_min, r_max) = size_range(&sp, ("min_radius", "max_radius"), min_radius, max_radius, None)?;
                SizeDistribution::LogNormal { median_radius: median_radius.0, sigma_g: *sigma_g, r_min, r_max }
            }
            SizeSection::ModifiedGamma { mode_radius, alpha, gamma, min_radius, max_radius } => {
                let mode_radius = positive_length(&sp, "mode_radius", mode_radius)?
                    .ok_or_else(|| ConfigError::new(&sp, "missing mode_radius_um (or _mm, _m)"))?;
                if !(alpha.is_finite() && *alpha > 0.0 && *alpha <= 100.0) {
                    return err(join(&sp, "alpha"), format!("= {alpha}: expected a shape exponent α in (0, 100]"));
                }
                if !(gamma.is_finite() && *gamma > 0.0 && *gamma <= 100.0) {
                    return err(join(&sp, "gamma"), format!("= {gamma}: expected an exponent γ in (0, 100]"));
                }
                let (r_min, r_max) = size_range(&sp, ("min_radius", "max_radius"), min_radius, max_radius, None)?;
                SizeDistribution::ModifiedGamma {
                    alpha: *alpha,
                    gamma: *gamma,
                    mode_radius: mode_radius.0,
                    r_min,
                    r_max,
                }
            }
            SizeSection::MarshallPalmer { rain_rate, min_diameter, max_diameter } => {
                // mm/h as written: the distribution's own unit.
                let rain_rate_mm_per_h = &rain_rate.value;
                if !(rain_rate_mm_per_h.is_finite() && *rain_rate_mm_per_h > 0.0 && *rain_rate_mm_per_h <= 500.0) {
                    return err(
                        join(&sp, "rain_rate_mm_per_h"),
                        format!("= {rain_rate_mm_per_h} mm/h: expected a rain rate in (0, 500] mm/h"),
                    );
                }
                // Defaults: 0.05–6 mm, the range of media/references.md §B4.
                let (d_min, d_max) = size_range(
                    &sp,
                    ("min_diameter", "max_diameter"),
                    min_diameter,
                    max_diameter,
                    Some((0.05e-3, 6e-3)),
                )?;
                SizeDistribution::MarshallPalmer { rain_rate_mm_per_h: *rain_rate_mm_per_h, d_min, d_max }
            }
        };
        let conc = match (&p.number_density, p.volume_fraction) {
            (Some(n), Some(_)) => return err(&here, format!("give only one of {}, volume_fraction", n.key)),
            (_, None) => given(&here, &p.number_density)?,
            (None, Some(v)) => {
                let path = join(&here, "volume_fraction");
                if v.is_nan() {
                    return err(path, "= nan: expected a number");
                }
                Some((v, path, v))
            }
        };
        let concentration = match (&distribution, conc) {
            (SizeDistribution::MarshallPalmer { .. }, Some(c)) => {
                return err(c.1, "Marshall–Palmer fixes the drop concentration (N0 = 8000 m⁻³ mm⁻¹); remove this key");
            }
            (SizeDistribution::MarshallPalmer { .. }, None) => None,
            (_, None) => {
                return err(
                    &here,
                    "missing the concentration: give number_density_per_cm3, number_density_per_m3 or volume_fraction",
                );
            }
            (_, Some(c)) if c.1.ends_with("volume_fraction") => {
                if !(c.0 > 0.0 && c.0 < 1.0) {
                    return err(c.1, format!("= {}: expected a volume fraction in (0, 1)", c.2));
                }
                Some(Concentration::VolumeFraction(c.0))
            }
            (_, Some(c)) => Some(Concentration::NumberDensity(positive(c, "a number density")?)),
        };
        let packing = match p.packing.unwrap_or(PackingKind::None) {
            PackingKind::None => None,
            PackingKind::Twersky => Some(Packing::Twersky),
        };
        let size_points = p.size_points.unwrap_or(DEFAULT_SIZE_POINTS as u64);
        if !(8..=4096).contains(&size_points) {
            return err(join(&here, "size_points"), format!("= {size_points}: expected 8 to 4096 quadrature nodes"));
        }
        specs.push((
            name,
            EnsembleSpec {
                n_particle: p.n_particle,
                k_particle: k,
                n_medium,
                wavelength: ctx.wavelength,
                distribution,
                concentration,
                packing,
                size_points: size_points as usize,
            },
        ));
    }
    Ok(specs)
}

/// The explicit σa and σs keys of a medium (as written), with whether each is given.
fn coefficient_keys(m: &MediumSection) -> [(&str, bool); 2] {
    fn key(q: &Option<Quantity<Coefficient>>) -> (&str, bool) {
        q.as_ref().map_or(("", false), |q| (q.key.as_str(), true))
    }
    [key(&m.sigma_a), key(&m.sigma_s)]
}

/// Check a medium that no layer or region uses (issue 21: an unused medium with σa = NaN and
/// g = 7 was accepted): everything written is validated, used or not. Its optics are resolved
/// (Mie included, once per name into `optics`), its height profile and motion resolved, its
/// velocity's numbers checked ([`check_velocity`]: what a velocity needs from where it is used —
/// a cylinder, the wind, the particles — is not asked of an unused medium) and its density's keys
/// checked (a VDB file is not read). A mixture's populations must be known media that are not
/// mixtures themselves and carry no density, as when it is used; they are checked as media of
/// their own.
pub(super) fn check_unused(
    optics: &mut BTreeMap<String, Optics>,
    ctx: &Ctx,
    name: &str,
    ms: &MediumSection,
    media: &BTreeMap<String, MediumSection>,
) -> R<()> {
    let path = format!("media.{name}");
    let sigma_t = match &ms.populations {
        Some(list) => {
            check_mixture(&path, ms)?;
            if list.is_empty() {
                return err(join(&path, "populations"), "an empty list: name at least one medium");
            }
            let mut sigma_t = 0.0;
            for (j, pname) in list.iter().enumerate() {
                let key = format!("{}[{j}]", join(&path, "populations"));
                let Some(pms) = media.get(pname) else {
                    let known = media.keys().cloned().collect::<Vec<_>>().join(", ");
                    return err(key, format!("= \"{pname}\": unknown medium; defined media: {known}"));
                };
                check_population(&key, pname, pms, name)?;
                let o = optics_of(optics, ctx, &format!("media.{pname}"), pname, pms)?;
                sigma_t += o.sigma_a + o.sigma_s;
            }
            sigma_t
        }
        None => {
            let o = optics_of(optics, ctx, &path, name, ms)?;
            let sigma_t = o.sigma_a + o.sigma_s;
            if let Some(h) = &ms.height_profile {
                resolve_height_profile(&join(&path, "height_profile"), h)?;
            }
            if let Some(m) = &ms.motion {
                resolve_motion(&join(&path, "motion"), m)?;
            }
            if let Some(v) = &ms.velocity {
                check_velocity(&join(&path, "velocity"), v)?;
            }
            sigma_t
        }
    };
    if let Some(d) = &ms.density {
        super::density::check_density_keys(&join(&path, "density"), d, sigma_t, ctx)?;
    }
    Ok(())
}

/// The optics of the medium `name`, resolved once.
fn optics_of<'o>(
    optics: &'o mut BTreeMap<String, Optics>,
    ctx: &Ctx,
    path: &str,
    name: &str,
    ms: &MediumSection,
) -> R<&'o Optics> {
    if !optics.contains_key(name) {
        let o = resolve_optics(path, ms, ctx)?;
        optics.insert(name.to_string(), o);
    }
    Ok(&optics[name])
}

/// A mixture medium (`populations`) takes everything from its populations.
pub(super) fn check_mixture(path: &str, ms: &MediumSection) -> R<()> {
    let particles = [("particles", ms.particles.is_some())];
    let others = [
        ("sigma_s_scale", ms.sigma_s_scale.is_some()),
        ("phase", ms.phase.is_some()),
        ("velocity", ms.velocity.is_some()),
        ("motion", ms.motion.is_some()),
        ("size_classes", ms.size_classes.is_some()),
        ("height_profile", ms.height_profile.is_some()),
    ];
    match particles.iter().chain(&coefficient_keys(ms)).chain(&others).find(|g| g.1) {
        Some((key, _)) => err(
            join(path, key),
            "a mixture medium (populations) takes its optics, velocity and profile from its populations: give this key there",
        ),
        None => Ok(()),
    }
}

/// Where a medium is used, as far as its populations depend on it.
pub(super) struct Placement<'a> {
    /// The scene's wind profile, if any.
    pub wind: Option<&'a WindProfile>,
    /// The velocity section that applies (the medium's own or a region's), with its key.
    pub velocity: Option<(String, &'a VelocitySection)>,
    /// The region's shape if it is a cylinder.
    pub cylinder: Option<&'a Shape>,
    /// Height of the medium, for its height profile.
    pub height: f64,
}

/// The populations of a medium that is not a mixture: one, or one per size class; with its total
/// σa and its provenance. σs and σa are scaled by the height profile at `at.height`.
pub(super) fn populations_of(
    optics: &mut BTreeMap<String, Optics>,
    ctx: &Ctx,
    path: &str,
    name: &str,
    ms: &MediumSection,
    at: Placement,
) -> R<(f64, Vec<Population>, MediumInfo)> {
    let Placement { wind, velocity, cylinder, height } = at;
    let o = optics_of(optics, ctx, path, name, ms)?;
    let factor = match &ms.height_profile {
        Some(h) => resolve_height_profile(&join(path, "height_profile"), h)?.factor(height),
        None => 1.0,
    };
    let motion = match &ms.motion {
        Some(m) => resolve_motion(&join(path, "motion"), m)?,
        None => Motion::default(),
    };
    let field = |sizes: &[(f64, f64)]| -> R<VelocityField> {
        match &velocity {
            None => Ok(VelocityField::Static),
            Some((p, v)) => resolve_velocity(
                p,
                v,
                FlowCtx { base: ctx.base, files: &ctx.files, memory: &ctx.memory, cylinder, wind, sizes },
            ),
        }
    };
    use super::cardiac::frozen;
    let motion_waveform = ms.motion.as_ref().map(|m| (join(path, "motion"), m.waveform.as_deref()));
    let pulse = |field: &VelocityField| {
        super::cardiac::resolve_pulse(
            ctx.cardiac.as_ref(),
            velocity.as_ref().map(|(p, v)| (p.as_str(), *v)),
            field,
            motion_waveform.as_ref().map(|(p, w)| (p.as_str(), *w)),
            motion.dispersion,
        )
    };
    if o.classes.is_empty() {
        let velocity = field(&o.sizes)?;
        let (pulse, velocity, motion) = frozen(ctx.cardiac.as_ref(), pulse(&velocity)?, velocity, motion);
        let population = Population {
            name: name.to_string(),
            phase: o.phase.clone(),
            pulse,
            velocity,
            motion,
            sigma_s: o.sigma_s * factor,
        };
        return Ok((o.sigma_a * factor, vec![population], o.info.clone()));
    }
    let mut populations = Vec::with_capacity(o.classes.len());
    for (i, c) in o.classes.iter().enumerate() {
        let velocity = field(&c.sizes)?;
        let (pulse, velocity, motion) = frozen(ctx.cardiac.as_ref(), pulse(&velocity)?, velocity, motion);
        populations.push(Population {
            name: format!("{name}[{i}]"),
            phase: c.phase.clone(),
            pulse,
            velocity,
            motion,
            sigma_s: c.sigma_s * factor,
        });
    }
    Ok((o.sigma_a * factor, populations, o.info.clone()))
}

/// A mixture's population `pname` (listed at `key` in mixture `name`) is a plain medium: not a
/// mixture itself, and without a density of its own (the mixture's applies).
pub(super) fn check_population(key: &str, pname: &str, pms: &MediumSection, name: &str) -> R<()> {
    if pms.populations.is_some() {
        return err(key, format!("= \"{pname}\" is itself a mixture: list its populations here instead"));
    }
    if pms.density.is_some() {
        return err(
            format!("media.{pname}.density"),
            format!("medium \"{pname}\" is a population of the mixture \"{name}\": give the density on the mixture"),
        );
    }
    Ok(())
}
