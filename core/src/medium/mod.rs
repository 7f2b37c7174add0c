//! Media and the scene they fill: media (homogeneous, or scaled by a density field), region
//! shapes, the layer stack.

pub mod density;
pub mod grid;
pub mod majorant;
mod particles;
mod scene;
mod shape;

pub use density::{Density, Heterogeneity};
pub use particles::{ComponentOptics, ParticleOptics, mixture_optics, relative_sphere};
pub use scene::{Lateral, Layer, MAX_REGIONS_PER_LAYER, Opaque, Region, Scene, Surface};
pub use shape::Shape;

use glam::DVec3;
use serde::Serialize;

use std::sync::Arc;

use crate::flow::VelocityField;
use crate::phase::PhaseFunction;
use crate::sampling::{Discrete, PathRng};

/// What the allocator adds to each block on the heap, bytes (glibc: a 16-byte header and
/// rounding), for the estimates of [`Medium::footprint`].
const HEAP_BLOCK: usize = 16;

/// Where a medium's optics came from, for the manifest (nothing here is read by the walk).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MediumInfo {
    /// The preset it was expanded from.
    pub preset: Option<String>,
    /// The phase function in words ("hg", "table", "mie", "isotropic").
    pub phase: String,
    /// Mean cosine of the phase function as sampled.
    pub g: f64,
    /// A phase table's origin and how its values were normalised as given.
    pub table: Option<TableInfo>,
    /// Mie optics of the particles, before explicit σ values and `sigma_s_scale` were applied.
    pub particles: Option<ParticleOptics>,
    pub sigma_s_scale: f64,
}

impl MediumInfo {
    /// Bytes the record owns on the heap (strings, a table's provenance, the Mie tables of the
    /// particles), an estimate for the memory budget.
    pub fn heap_bytes(&self) -> usize {
        let table = self.table.as_ref().map_or(0, |t| {
            let provenance: usize = t.provenance.iter().map(|(k, v)| k.len() + v.len() + 64).sum();
            t.origin.len() + t.source_normalisation.as_ref().map_or(0, String::len) + provenance
        });
        let particles = self.particles.as_ref().map_or(0, |p| {
            let components: usize = p.components.iter().map(|c| std::mem::size_of_val(c) + c.name.len()).sum();
            components
                + std::mem::size_of_val(p.theta.as_slice())
                + std::mem::size_of_val(p.phase.as_slice())
                + std::mem::size_of_val(p.sizes.as_slice())
        });
        self.preset.as_ref().map_or(0, String::len) + self.phase.len() + table + particles
    }
}

/// A phase table as loaded.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TableInfo {
    pub origin: String,
    pub angles: usize,
    /// Declared normalisation of a table file (`per_sr`, `four_pi`, `arbitrary`).
    pub source_normalisation: Option<String>,
    /// `∫ p dΩ` of the values as given (renormalised to 1 on load).
    pub source_integral: f64,
    pub provenance: std::collections::BTreeMap<String, String>,
}

/// Random motion of a medium's particles beyond the mean flow of its [`VelocityField`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Motion {
    /// Standard deviation of each Cartesian component of a random velocity drawn afresh at every
    /// scattering event and added to the flow (shear-induced dispersion, tumbling), m/s.
    pub dispersion: f64,
    /// Translational diffusion coefficient `D` of the particles (Brownian motion), m²/s. Not drawn
    /// per event: a path collects `D·q²` per event, and its line is broadened into a Lorentzian of
    /// half-width `Σ D_k q_k² / 2π` Hz (see `detect`).
    pub diffusion: f64,
}

impl Motion {
    /// Whether the particles move at random at all.
    pub fn is_random(&self) -> bool {
        self.dispersion > 0.0 || self.diffusion > 0.0
    }
}

/// Stokes–Einstein diffusion coefficient `D = k_B T / (6π η r)` (m²/s) of a sphere of radius `r`
/// (m) in a fluid of viscosity `η` (Pa·s) at temperature `T` (K).
pub fn stokes_einstein(radius: f64, temperature: f64, viscosity: f64) -> f64 {
    const BOLTZMANN: f64 = 1.380_649e-23; // J/K, exact (SI 2019)
    BOLTZMANN * temperature / (6.0 * std::f64::consts::PI * viscosity * radius)
}

/// One population of particles in a medium: how it scatters and how it moves. A medium holds one
/// (most media) or several (air with aerosol and raindrops, each raindrop size class with its own
/// phase function and fall speed).
#[derive(Debug, Clone, PartialEq)]
pub struct Population {
    /// Name in the configuration (the medium's own name for a single population).
    pub name: String,
    pub phase: PhaseFunction,
    pub velocity: VelocityField,
    /// Random motion beyond the flow (none by default).
    pub motion: Motion,
    /// This population's scattering coefficient, m⁻¹.
    pub sigma_s: f64,
    /// How its velocities pulse over the cardiac cycle (steady by default): `velocity` and
    /// `motion.dispersion` are then the cycle means ([`crate::flow::pulse`]).
    pub pulse: crate::flow::pulse::Pulse,
}

impl Population {
    /// Whether scattering on these particles changes `dl/dt` or broadens the line (a "Doppler
    /// event").
    #[inline(always)]
    pub fn is_dynamic(&self) -> bool {
        self.velocity.is_moving() || self.motion.is_random()
    }
}

/// A homogeneous participating medium: one or several particle populations.
///
/// The coefficients are fixed at construction so that the derived constants the random walk
/// uses at every collision (σt, 1/σt, albedo) are computed once. At a scattering event the
/// scatterer's population is drawn in proportion to its σs ([`Medium::pick`]); its phase
/// function, velocity and motion then serve the event, and the next-event estimate from it.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// Name in the configuration (for messages and the manifest).
    pub name: String,
    /// At least one; several make a mixture (an external mixture: coefficients add).
    populations: Box<[Population]>,
    /// A copy of `populations[0]` held inline, so that a medium of one population serves its
    /// collisions without following the pointer to the list. (Callgrind, configs/default.toml,
    /// 5·10⁴ paths, one thread: 1469.2M instructions before populations existed, 1534.7M with
    /// the list and a per-collision `is_dynamic` call, 1416.6M with this copy and `dynamic_of`.)
    primary: Population,
    /// The populations' shares of σs, for a mixture (`None` for one population).
    choice: Option<Discrete>,
    /// Provenance of the optics, for the manifest.
    pub info: MediumInfo,
    sigma_a: f64,
    sigma_s: f64,
    sigma_t: f64,
    inv_sigma_t: f64,
    albedo: f64,
    dynamic: bool,
    /// [`Population::is_dynamic`] of each population, computed once (the velocity field's own
    /// test is a match the walk would otherwise call per collision).
    dynamic_of: Box<[bool]>,
    /// A density field (and albedo grid) scaling σa and σs in space; `None` for a homogeneous
    /// medium, which then never looks anything up.
    heterogeneity: Option<Arc<Heterogeneity>>,
}

impl Medium {
    /// A medium of one population with absorption σa and scattering σs (m⁻¹, finite and ≥ 0).
    pub fn new(
        name: impl Into<String>,
        sigma_a: f64,
        sigma_s: f64,
        phase: PhaseFunction,
        velocity: VelocityField,
    ) -> Self {
        let name = name.into();
        let population = Population {
            name: name.clone(),
            phase,
            velocity,
            motion: Motion::default(),
            sigma_s,
            pulse: Default::default(),
        };
        Medium::mixture(name, sigma_a, vec![population])
    }

    /// A medium of the given populations (at least one; their σs add) and total absorption σa.
    pub fn mixture(name: impl Into<String>, sigma_a: f64, populations: Vec<Population>) -> Self {
        assert!(!populations.is_empty(), "a medium needs at least one particle population");
        let sigma_s: f64 = populations.iter().map(|p| p.sigma_s).sum();
        // One population needs no draw; a mixture that scatters nothing never draws.
        let choice = if populations.len() == 1 { None } else { Discrete::new(populations.iter().map(|p| p.sigma_s)) };
        let sigma_t = sigma_a + sigma_s;
        let mut m = Medium {
            name: name.into(),
            primary: populations[0].clone(),
            populations: populations.into(),
            choice,
            info: MediumInfo::default(),
            sigma_a,
            sigma_s,
            sigma_t,
            inv_sigma_t: if sigma_t > 0.0 { 1.0 / sigma_t } else { f64::INFINITY },
            albedo: if sigma_t > 0.0 { sigma_s / sigma_t } else { 0.0 },
            dynamic: false,
            dynamic_of: Box::new([]),
            heterogeneity: None,
        };
        m.update();
        m
    }

    fn update(&mut self) {
        self.dynamic_of = self.populations.iter().map(Population::is_dynamic).collect();
        self.dynamic = self.dynamic_of.iter().any(|&d| d);
        self.primary = self.populations[0].clone();
    }

    /// Bytes this medium occupies, the struct and what it owns on the heap — what a copy of it
    /// copies: its populations and their names, its provenance (the Mie tables of its
    /// particles). An estimate for the memory budget (issue 21: a medium per sublayer, 10⁵
    /// sublayers of rain took 2.1 GB). What it holds through an `Arc` is not counted here: tables
    /// made for it alone ([`Medium::own_tables`]) and what media share (tabulated phase
    /// functions, a density field, a velocity grid, a wind table: made once, counted where made).
    pub fn footprint(&self) -> usize {
        let populations: usize =
            self.populations.iter().map(|p| std::mem::size_of::<Population>() + p.name.len() + HEAP_BLOCK).sum();
        // Blocks: the populations, the names of the medium and its inline population, the
        // shares and the dynamic flags.
        5 * HEAP_BLOCK
            + std::mem::size_of::<Medium>()
            + self.name.len()
            + populations
            + self.primary.name.len()
            + self.choice.as_ref().map_or(0, Discrete::heap_bytes)
            + self.dynamic_of.len()
            + self.info.heap_bytes()
    }

    /// Bytes of the tables made for this medium alone but held through an `Arc` (its populations'
    /// fall speeds), which copies of the medium share.
    pub fn own_tables(&self) -> usize {
        // Blocks of a fall-speed table: the `Arc`, the speeds, the shares.
        let blocks = |v: &VelocityField| if v.owned_bytes() > 0 { 3 * HEAP_BLOCK } else { 0 };
        self.populations.iter().map(|p| p.velocity.owned_bytes() + blocks(&p.velocity)).sum()
    }

    /// The populations (one for most media).
    pub fn populations(&self) -> &[Population] {
        &self.populations
    }

    /// The first (for most media the only) population.
    pub fn population(&self) -> &Population {
        &self.primary
    }

    /// Change the populations' motion and velocity fields (not their σs) through `f`.
    pub fn update_populations(&mut self, mut f: impl FnMut(&mut Population)) {
        for p in self.populations.iter_mut() {
            let sigma_s = p.sigma_s;
            f(p);
            p.sigma_s = sigma_s;
        }
        self.update();
    }

    /// The population a scattering event happens on: drawn in proportion to σs (one uniform
    /// number, only for a mixture).
    #[inline(always)]
    pub fn pick(&self, rng: &mut PathRng) -> &Population {
        self.pick_dynamic(rng).0
    }

    /// [`Medium::pick`] with whether the population drawn is dynamic.
    #[inline(always)]
    pub fn pick_dynamic(&self, rng: &mut PathRng) -> (&Population, bool) {
        match &self.choice {
            None => (&self.primary, self.dynamic),
            Some(c) => {
                let i = c.index(rng.uniform());
                (&self.populations[i], self.dynamic_of[i])
            }
        }
    }

    /// The population of the uniform number `u ∈ [0, 1)` (the first whose cumulative share
    /// exceeds `u`).
    pub fn pick_with(&self, u: f64) -> &Population {
        self.choice.as_ref().map_or(&self.primary, |c| &self.populations[c.index(u)])
    }

    /// Whether scattering on any of this medium's particles changes `dl/dt` or broadens the line.
    #[inline(always)]
    pub fn is_dynamic(&self) -> bool {
        self.dynamic
    }

    /// Absorption coefficient σa, m⁻¹.
    pub fn sigma_a(&self) -> f64 {
        self.sigma_a
    }

    /// Scattering coefficient σs, m⁻¹.
    pub fn sigma_s(&self) -> f64 {
        self.sigma_s
    }

    /// Extinction coefficient σt = σa + σs, m⁻¹.
    #[inline(always)]
    pub fn sigma_t(&self) -> f64 {
        self.sigma_t
    }

    /// Mean free path 1/σt, m (∞ in a vacuum).
    #[inline(always)]
    pub fn inv_sigma_t(&self) -> f64 {
        self.inv_sigma_t
    }

    /// Single-scattering albedo σs/σt (0 for a vacuum).
    #[inline(always)]
    pub fn albedo(&self) -> f64 {
        self.albedo
    }

    /// Give the medium a density (σa and σs become `d(x)·σa`, `d(x)·σs`) and possibly an albedo
    /// grid.
    pub fn set_heterogeneity(&mut self, h: Heterogeneity) {
        self.set_shared_heterogeneity(Arc::new(h));
    }

    /// [`Medium::set_heterogeneity`] with a density (and majorant grid) shared by several media:
    /// the layers and regions that use one named medium.
    pub fn set_shared_heterogeneity(&mut self, h: Arc<Heterogeneity>) {
        self.heterogeneity = Some(h);
    }

    /// The medium's density and albedo grid (`None`: homogeneous).
    #[inline(always)]
    pub fn heterogeneity(&self) -> Option<&Heterogeneity> {
        self.heterogeneity.as_deref()
    }

    /// The density field, if any.
    #[inline(always)]
    pub fn density(&self) -> Option<&Density> {
        self.heterogeneity.as_deref().map(|h| &h.density)
    }

    /// The density everywhere, if it is the same everywhere and the medium has no albedo grid:
    /// 1 for a homogeneous medium, `c` for a constant density field (a grid or ramp holding one
    /// value, background included). Such a medium's free flights are plain exponentials of rate
    /// `c·σt` (see `transport::walk`). `None` otherwise.
    #[inline]
    pub fn uniform_density(&self) -> Option<f64> {
        match self.heterogeneity.as_deref() {
            None => Some(1.0),
            Some(Heterogeneity { density, albedo: None, .. }) => {
                let (lo, hi) = density.range();
                (lo == hi).then_some(lo)
            }
            Some(_) => None,
        }
    }

    /// Whether the medium's albedo is a field of its own (an albedo grid).
    pub fn has_albedo_field(&self) -> bool {
        matches!(self.heterogeneity.as_deref(), Some(Heterogeneity { albedo: Some(_), .. }))
    }

    /// σt at `p`, m⁻¹.
    pub fn sigma_t_at(&self, p: DVec3) -> f64 {
        self.density().map_or(self.sigma_t, |d| self.sigma_t * d.at(p))
    }

    /// The albedo at a collision at `p`: the albedo grid's value where there is one.
    #[inline(always)]
    pub fn albedo_at(&self, p: DVec3) -> f64 {
        match self.heterogeneity.as_deref() {
            Some(Heterogeneity { albedo: Some(a), .. }) => a.value(p).clamp(0.0, 1.0),
            _ => self.albedo,
        }
    }

    /// Smallest and largest σt anywhere in the medium, m⁻¹.
    pub fn sigma_t_range(&self) -> (f64, f64) {
        match self.density() {
            None => (self.sigma_t, self.sigma_t),
            Some(d) => {
                let (lo, hi) = d.range();
                (lo * self.sigma_t, hi * self.sigma_t)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::HenyeyGreenstein;
    use crate::sampling::Purpose;

    fn population(name: &str, sigma_s: f64, g: f64) -> Population {
        Population {
            name: name.into(),
            phase: PhaseFunction::HenyeyGreenstein(HenyeyGreenstein::new(g).unwrap()),
            velocity: VelocityField::Static,
            motion: Motion::default(),
            sigma_s,
            pulse: Default::default(),
        }
    }

    #[test]
    fn populations_are_drawn_in_proportion_to_sigma_s() {
        let m = Medium::mixture("air", 0.5, vec![population("a", 1.0, 0.1), population("b", 3.0, 0.2)]);
        assert_eq!((m.sigma_s(), m.sigma_t()), (4.0, 4.5));
        assert_eq!((m.pick_with(0.0).name.as_str(), m.pick_with(0.2499).name.as_str()), ("a", "a"));
        assert_eq!((m.pick_with(0.25).name.as_str(), m.pick_with(0.999_999).name.as_str()), ("b", "b"));
        let mut rng = PathRng::new(2, Purpose::Test, 0, 0);
        let n = 400_000;
        let a = (0..n).filter(|_| m.pick(&mut rng).name == "a").count() as f64 / n as f64;
        // Binomial: σ = √(0.25·0.75/n) = 6.8e-4.
        assert!((a - 0.25).abs() < 5.0 * (0.1875 / n as f64).sqrt(), "{a}");
        // One population: no draw at all.
        let one = Medium::new("x", 0.0, 1.0, PhaseFunction::Isotropic, VelocityField::Static);
        let before = rng.clone().uniform();
        one.pick(&mut rng);
        assert_eq!(rng.uniform(), before);
    }

    #[test]
    fn a_mixture_is_dynamic_if_any_population_moves() {
        let mut m = Medium::mixture("air", 0.0, vec![population("a", 1.0, 0.0), population("b", 1.0, 0.0)]);
        assert!(!m.is_dynamic());
        m.update_populations(|p| {
            if p.name == "b" {
                p.velocity = VelocityField::Uniform(DVec3::Z)
            }
        });
        assert!(m.is_dynamic() && !m.populations()[0].is_dynamic());
    }
}
