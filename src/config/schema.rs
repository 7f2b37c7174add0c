//! The experiment file as written: serde structs mirroring the TOML, with `deny_unknown_fields`
//! everywhere. Quantities whose natural unit is not SI carry it in the key (`thickness_mm`,
//! `sigma_s_per_cm`, `speed_mm_per_s`, `f_max_khz`); a quantity may be given in any one of its
//! listed units. Nothing here is validated: [`super::resolve()`] does that, once.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// The schema version this build reads.
pub const SCHEMA_VERSION: i64 = 1;

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentFile {
    pub schema_version: i64,
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub description: Option<String>,
    #[serde(default)]
    pub run: RunSection,
    pub source: SourceSection,
    #[serde(default)]
    pub ambient: AmbientSection,
    pub media: BTreeMap<String, MediumSection>,
    pub layers: Vec<LayerSection>,
    #[serde(default)]
    pub regions: Vec<RegionSection>,
    #[serde(default)]
    pub detectors: Vec<DetectorSection>,
    /// The wind of an atmosphere (`z` = height above the ground), used by media with
    /// `velocity = { type = "wind" }` or `{ type = "terminal_fall" }`.
    pub wind: Option<WindSection>,
    /// Analytic values of named outputs (`reflectance_diffuse = 0.0974`,
    /// `"camera.spectrum" = [...]`) that `ohd converge` measures errors against.
    #[serde(default)]
    pub reference: BTreeMap<String, ReferenceValue>,
}

/// A `[reference]` value: a number for a scalar output, an array for a spectrum or image
/// (in the order of its `.npy` file).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(untagged)]
pub enum ReferenceValue {
    Scalar(f64),
    Array(Vec<f64>),
}

/// `[wind]`: horizontal wind as a function of height, plus a vertical velocity. Directions are
/// meteorological: `direction_from_deg` is where the wind blows *from*, clockwise from north
/// (270 = a westerly, blowing toward +x = east); `y` is north, `z` up.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum WindSection {
    Uniform {
        velocity_m_per_s: [f64; 3],
    },
    /// `u(h) = u_ref·(h/h_ref)^α`.
    PowerLaw {
        speed_m_per_s: f64,
        reference_height_m: f64,
        exponent: f64,
        direction_from_deg: f64,
        vertical_m_per_s: Option<f64>,
    },
    /// `u(h) = (u*/κ)·ln((h − d)/z0)`; give u* or the speed at a reference height.
    LogLaw {
        friction_velocity_m_per_s: Option<f64>,
        speed_m_per_s: Option<f64>,
        reference_height_m: Option<f64>,
        roughness_length_m: f64,
        displacement_height_m: Option<f64>,
        direction_from_deg: f64,
        vertical_m_per_s: Option<f64>,
    },
    /// One velocity per layer of height: `velocities_m_per_s[i]` for
    /// `heights_m[i] ≤ h < heights_m[i + 1]`.
    Table {
        heights_m: Vec<f64>,
        velocities_m_per_s: Vec<[f64; 3]>,
    },
}

/// How a medium's coefficients change with height (`z`, m, above the ground at `z = 0`):
/// a factor on σs and σa, taken at the middle of each layer the medium fills.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum HeightProfileSection {
    /// `exp(−h/H)`.
    Exponential { scale_height_m: f64 },
    /// 1 up to the boundary-layer top, then `exp(−(h − top)/H)`.
    BoundaryLayer { top_m: f64, scale_height_m: f64 },
    /// Piecewise linear through `(heights_m[i], factors[i])`, constant beyond the ends.
    Table { heights_m: Vec<f64>, factors: Vec<f64> },
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RunSection {
    pub samples: Option<u64>,
    pub seed: Option<u64>,
    pub batches: Option<u64>,
    pub threads: Option<u64>,
    pub tracking: Option<TrackingKind>,
    pub majorant_scale: Option<f64>,
    pub roulette_threshold: Option<f64>,
    pub roulette_survival: Option<f64>,
    pub max_scattering_events: Option<u64>,
    /// Largest memory the tallies may take (GiB); configurations above it are refused.
    pub memory_budget_gib: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackingKind {
    Analytic,
    Delta,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SourceSection {
    pub wavelength_nm: Option<f64>,
    pub wavelength_um: Option<f64>,
    #[serde(default)]
    pub profile: Option<ProfileKind>,
    /// Disk radius.
    pub radius_um: Option<f64>,
    pub radius_mm: Option<f64>,
    pub radius_m: Option<f64>,
    /// Gaussian 1/e² intensity radius.
    pub waist_um: Option<f64>,
    pub waist_mm: Option<f64>,
    pub waist_m: Option<f64>,
    pub position_um: Option<[f64; 3]>,
    pub position_mm: Option<[f64; 3]>,
    pub position_m: Option<[f64; 3]>,
    pub direction: Option<[f64; 3]>,
    /// Pointing by angles instead of `direction`, in the frame x = east, y = north, z = up (the
    /// depth axis of the stack): azimuth clockwise from north, elevation above the horizontal.
    pub azimuth_deg: Option<f64>,
    pub elevation_deg: Option<f64>,
    /// A scan: `[[azimuth, elevation], …]` in degrees, one run per pointing (a VAD scan).
    pub pointings_deg: Option<Vec<[f64; 2]>>,
    /// Far-field divergence of the Gaussian beam: the 1/e² intensity half-angle.
    pub divergence_urad: Option<f64>,
    pub divergence_mrad: Option<f64>,
    pub chirp: Option<ChirpSection>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ProfileKind {
    Pencil,
    Disk,
    Gaussian,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ChirpSection {
    pub bandwidth_hz: Option<f64>,
    pub bandwidth_mhz: Option<f64>,
    pub bandwidth_ghz: Option<f64>,
    pub duration_s: Option<f64>,
    pub duration_ms: Option<f64>,
    pub duration_us: Option<f64>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AmbientSection {
    pub n_above: Option<f64>,
    pub n_below: Option<f64>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MediumSection {
    /// The preset this medium was expanded from (see [`super::preset`]); for the record.
    pub preset: Option<String>,
    pub description: Option<String>,
    pub references: Option<Vec<String>>,
    /// The vacuum wavelength the medium's values are for; checked against the source.
    pub wavelength_nm: Option<f64>,
    pub wavelength_um: Option<f64>,
    /// Particles whose Mie optics give σs, σa and the phase function (explicit σs, σa win).
    pub particles: Option<OneOrMany<ParticlesSection>>,
    /// Factor applied to σs after everything else (≥ 0; e.g. to calibrate a sphere model to a
    /// measured σs, or to thin a medium for tractability).
    pub sigma_s_scale: Option<f64>,
    pub sigma_a_per_m: Option<f64>,
    pub sigma_a_per_cm: Option<f64>,
    pub sigma_a_per_mm: Option<f64>,
    pub sigma_s_per_m: Option<f64>,
    pub sigma_s_per_cm: Option<f64>,
    pub sigma_s_per_mm: Option<f64>,
    #[serde(default)]
    pub phase: Option<PhaseSection>,
    #[serde(default)]
    pub velocity: Option<VelocitySection>,
    /// Random motion of the particles beyond the flow.
    pub motion: Option<MotionSection>,
    /// A mixture of other media: each named medium becomes one particle population of this one
    /// (σs and σa add; at a scattering event the population is drawn in proportion to its σs and
    /// its phase function and velocity are used). Nothing else may then be given.
    pub populations: Option<Vec<String>>,
    /// Split the (single) particle size distribution into this many size classes (diameters
    /// log-spaced), each a population with its own Mie phase function (and, with
    /// `velocity.type = "terminal_fall"`, its own drop sizes' fall speeds).
    pub size_classes: Option<u64>,
    /// σs and σa scaled with height.
    pub height_profile: Option<HeightProfileSection>,
    /// A density field `d(x) ≥ 0` scaling σa and σs in space (`σ(x) = d(x)·σ`).
    pub density: Option<DensitySection>,
}

/// `density = {…}` of a medium: a heterogeneous medium.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum DensitySection {
    /// Linear along `axis` ("x", "y" or "z") from `density_from` at the plane `from_*` to
    /// `density_to` at the plane `to_*`, constant beyond the planes.
    Ramp {
        axis: String,
        from_um: Option<f64>,
        from_mm: Option<f64>,
        from_m: Option<f64>,
        to_um: Option<f64>,
        to_mm: Option<f64>,
        to_m: Option<f64>,
        density_from: f64,
        density_to: f64,
        /// "grid" (default: bounds per piece of the ray between the planes) or "global" (one
        /// bound, the larger end value).
        majorant: Option<MajorantSection>,
    },
    /// A FloatGrid from an OpenVDB file (our own reader, `io::formats::vdb`).
    Vdb {
        /// The `.vdb` file, relative to the config file.
        file: String,
        /// The grid's name (default: the file's first float grid).
        grid: Option<String>,
        /// A second float grid of the same file: the single-scattering albedo per voxel (0 to 1),
        /// overriding σs/σt at a collision.
        albedo_grid: Option<String>,
        /// "trilinear" (default) or "nearest".
        interpolation: Option<InterpolationSection>,
        /// The file's length unit in metres: multiplies its voxel size and translation (default
        /// 1; 1e-3 for a file in millimetres).
        scale: Option<f64>,
        /// Moves the grid after scaling.
        translate_um: Option<[f64; 3]>,
        translate_mm: Option<[f64; 3]>,
        translate_m: Option<[f64; 3]>,
        /// "grid" (default: per-cell bounds) or "global" (one bound for the whole grid).
        majorant: Option<MajorantSection>,
        /// Edge of a majorant cell in voxels (default 4).
        majorant_cell_voxels: Option<u64>,
    },
}

/// How a grid is read between its voxel points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum InterpolationSection {
    Trilinear,
    Nearest,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MajorantSection {
    Grid,
    Global,
}

/// `[media.X.motion]`: a per-event random velocity and Brownian diffusion.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSection {
    /// Standard deviation of each velocity component, drawn per scattering event.
    pub dispersion_mm_per_s: Option<f64>,
    pub dispersion_m_per_s: Option<f64>,
    /// The diffusion coefficient D, or the particle radius, temperature and viscosity that give it.
    pub diffusion_m2_per_s: Option<f64>,
    pub diffusion_um2_per_s: Option<f64>,
    pub radius_um: Option<f64>,
    pub radius_nm: Option<f64>,
    pub temperature_k: Option<f64>,
    pub viscosity_mpa_s: Option<f64>,
    pub viscosity_pa_s: Option<f64>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum PhaseSection {
    Isotropic {},
    /// `g` may be left out when the medium has `particles`: then it is their Mie asymmetry.
    #[serde(alias = "henyey_greenstein")]
    Hg {
        g: Option<f64>,
    },
    /// A phase-table file (format in `media/README.md`), relative to the config file.
    Table {
        file: String,
    },
    /// Tabulated from the Mie solution of the medium's `particles` (the default when it has them).
    Mie {
        angles: Option<u64>,
    },
}

/// A single table or an array of them (`particles = {…}` or `[[media.x.particles]]`).
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum OneOrMany<T> {
    One(T),
    Many(Vec<T>),
}

/// By hand rather than `#[serde(untagged)]`, so that an error inside an item keeps its message
/// and key path instead of becoming "did not match any variant".
impl<'de, T: Deserialize<'de>> Deserialize<'de> for OneOrMany<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::value::{MapAccessDeserializer, SeqAccessDeserializer};
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> serde::de::Visitor<'de> for V<T> {
            type Value = OneOrMany<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a table or an array of tables")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, a: A) -> Result<Self::Value, A::Error> {
                T::deserialize(MapAccessDeserializer::new(a)).map(OneOrMany::One)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, a: A) -> Result<Self::Value, A::Error> {
                Vec::<T>::deserialize(SeqAccessDeserializer::new(a)).map(OneOrMany::Many)
            }
        }
        d.deserialize_any(V(std::marker::PhantomData))
    }
}

impl<T> OneOrMany<T> {
    /// The items with their key paths relative to the field (`""` for a single one, `[i]` else).
    pub fn items(&self) -> Vec<(String, &T)> {
        match self {
            OneOrMany::One(t) => vec![(String::new(), t)],
            OneOrMany::Many(v) => v.iter().enumerate().map(|(i, t)| (format!("[{i}]"), t)).collect(),
        }
    }
}

/// One kind of particle in a medium: optical constants, size distribution and concentration.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ParticlesSection {
    /// A label (e.g. an OPAC component name), for messages and the manifest.
    pub name: Option<String>,
    /// Real part of the particle's refractive index.
    pub n_particle: f64,
    /// Imaginary part, k ≥ 0 absorbing (index n − ik); default 0.
    pub k_particle: Option<f64>,
    /// Refractive index of the host the particles sit in (1 for air).
    pub n_medium: f64,
    pub size: SizeSection,
    pub number_density_per_m3: Option<f64>,
    pub number_density_per_cm3: Option<f64>,
    /// Fraction of the volume the particles fill (the hematocrit, for red blood cells).
    pub volume_fraction: Option<f64>,
    pub packing: Option<PackingKind>,
    /// Nodes of the size quadrature.
    pub size_points: Option<u64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PackingKind {
    None,
    Twersky,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SizeSection {
    Monodisperse {
        diameter_um: Option<f64>,
        diameter_mm: Option<f64>,
        diameter_m: Option<f64>,
        radius_um: Option<f64>,
        radius_mm: Option<f64>,
        radius_m: Option<f64>,
    },
    /// Number distribution log-normal in radius (OPAC): median radius, geometric standard deviation.
    LogNormal {
        median_radius_um: Option<f64>,
        median_radius_mm: Option<f64>,
        median_radius_m: Option<f64>,
        sigma_g: f64,
        min_radius_um: Option<f64>,
        min_radius_mm: Option<f64>,
        min_radius_m: Option<f64>,
        max_radius_um: Option<f64>,
        max_radius_mm: Option<f64>,
        max_radius_m: Option<f64>,
    },
    /// Deirmendjian's modified gamma, n(r) ∝ r^α exp(−(α/γ)(r/r_c)^γ), mode radius r_c.
    ModifiedGamma {
        mode_radius_um: Option<f64>,
        mode_radius_mm: Option<f64>,
        mode_radius_m: Option<f64>,
        alpha: f64,
        gamma: f64,
        min_radius_um: Option<f64>,
        min_radius_mm: Option<f64>,
        min_radius_m: Option<f64>,
        max_radius_um: Option<f64>,
        max_radius_mm: Option<f64>,
        max_radius_m: Option<f64>,
    },
    /// Marshall–Palmer raindrops, N(D) = 8000 m⁻³ mm⁻¹ exp(−4.1 R^−0.21 D): absolute concentration.
    MarshallPalmer {
        rain_rate_mm_per_h: f64,
        min_diameter_um: Option<f64>,
        min_diameter_mm: Option<f64>,
        min_diameter_m: Option<f64>,
        max_diameter_um: Option<f64>,
        max_diameter_mm: Option<f64>,
        max_diameter_m: Option<f64>,
    },
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum VelocitySection {
    None {},
    Uniform {
        velocity_mm_per_s: Option<[f64; 3]>,
        velocity_m_per_s: Option<[f64; 3]>,
    },
    Poiseuille {
        v_max_mm_per_s: Option<f64>,
        v_max_m_per_s: Option<f64>,
        mean_mm_per_s: Option<f64>,
        mean_m_per_s: Option<f64>,
    },
    RandomDirection {
        speed_mm_per_s: Option<f64>,
        speed_m_per_s: Option<f64>,
    },
    /// Carried by the `[wind]` at the particle's height.
    Wind {},
    /// Falling drops: the `[wind]` (calm without one) plus each drop size's terminal fall speed
    /// (Atlas et al. 1973) downward; the drop sizes are the medium's particles.
    TerminalFall {},
    /// A Vec3SGrid (m/s) from an OpenVDB file.
    Vdb {
        /// The `.vdb` file, relative to the config file.
        file: String,
        /// The grid's name (default: the file's first vec3 grid).
        grid: Option<String>,
        /// "trilinear" (default) or "nearest".
        interpolation: Option<InterpolationSection>,
        /// The file's length unit in metres: multiplies its voxel size and translation (default
        /// 1; 1e-3 for a file in millimetres).
        scale: Option<f64>,
        /// Moves the grid after scaling.
        translate_um: Option<[f64; 3]>,
        translate_mm: Option<[f64; 3]>,
        translate_m: Option<[f64; 3]>,
    },
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSection {
    pub name: Option<String>,
    /// `inf` (a TOML float) for a semi-infinite last layer.
    pub thickness_um: Option<f64>,
    pub thickness_mm: Option<f64>,
    pub thickness_m: Option<f64>,
    pub n: Option<f64>,
    pub medium: String,
    /// Split the layer into this many equal layers (named `NAME[i]`), e.g. 100 layers of 10 m for
    /// an atmosphere with a wind or density profile.
    pub sublayers: Option<u64>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSection {
    pub name: Option<String>,
    pub layer: String,
    pub medium: String,
    /// Overrides the medium's velocity field inside this region.
    pub velocity: Option<VelocitySection>,
    pub shape: ShapeSection,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSection {
    Cylinder {
        center_um: Option<[f64; 3]>,
        center_mm: Option<[f64; 3]>,
        center_m: Option<[f64; 3]>,
        axis: [f64; 3],
        radius_um: Option<f64>,
        radius_mm: Option<f64>,
        radius_m: Option<f64>,
        length_um: Option<f64>,
        length_mm: Option<f64>,
        length_m: Option<f64>,
    },
    Box {
        center_um: Option<[f64; 3]>,
        center_mm: Option<[f64; 3]>,
        center_m: Option<[f64; 3]>,
        size_um: Option<[f64; 3]>,
        size_mm: Option<[f64; 3]>,
        size_m: Option<[f64; 3]>,
    },
    Sphere {
        center_um: Option<[f64; 3]>,
        center_mm: Option<[f64; 3]>,
        center_m: Option<[f64; 3]>,
        radius_um: Option<f64>,
        radius_mm: Option<f64>,
        radius_m: Option<f64>,
    },
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorSection {
    pub name: String,
    pub side: Option<SideKind>,
    pub area: Option<AreaSection>,
    pub acceptance_half_angle_deg: Option<f64>,
    pub axis: Option<[f64; 3]>,
    pub distance_um: Option<f64>,
    pub distance_mm: Option<f64>,
    pub distance_m: Option<f64>,
    pub include_specular: Option<bool>,
    /// Score the detector by next-event estimation (a shadow ray from every scattering vertex into
    /// its cone) as well as by the paths that escape into it; top detectors only. Always on for
    /// LDH cameras and lidar receivers.
    pub next_event: Option<bool>,
    pub spectrum: Option<SpectrumSection>,
    pub image: Option<ImageSection>,
    /// A laser Doppler holography camera over the image's pixels.
    pub ldh: Option<LdhSection>,
    /// A pulsed lidar receiver at the source (monostatic), with range gates.
    pub lidar: Option<LidarSection>,
}

/// `[detectors.lidar]`: a monostatic pulsed coherent lidar receiver at the source's position,
/// looking along the source's direction, and its range gates.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LidarSection {
    pub aperture_radius_mm: Option<f64>,
    pub aperture_radius_m: Option<f64>,
    /// Field-of-view half-angle.
    pub field_of_view_urad: Option<f64>,
    pub field_of_view_mrad: Option<f64>,
    pub field_of_view_deg: Option<f64>,
    /// Intensity FWHM of the Gaussian pulse.
    pub pulse_fwhm_ns: Option<f64>,
    pub pulse_fwhm_us: Option<f64>,
    pub sample_rate_mhz: Option<f64>,
    pub sample_rate_hz: Option<f64>,
    /// Range of the start of the first gate.
    pub first_gate_m: Option<f64>,
    /// Samples per gate (gate length = points·c/(2 f_s)).
    pub gate_points: Option<u64>,
    pub gates: Option<u64>,
    /// Length of the (zero-padded) DFT of a gate.
    pub fft_points: Option<u64>,
    /// Transmitted pulse energy (sets the shot-noise floor; default 100 µJ).
    pub pulse_energy_uj: Option<f64>,
    pub pulse_energy_mj: Option<f64>,
    /// Detector quantum efficiency in (0, 1] (default 0.8).
    pub quantum_efficiency: Option<f64>,
    /// Heterodyne (mixing, mode-matching) efficiency in (0, 1] (default 0.4).
    pub heterodyne_efficiency: Option<f64>,
}

/// `[detectors.ldh]`: the LDH acquisition (camera rate, STFT window, band) and its outputs.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LdhSection {
    pub frame_rate_hz: Option<f64>,
    pub frame_rate_khz: Option<f64>,
    /// Samples N_w of one short-time Fourier transform window.
    pub window_samples: Option<u64>,
    pub window: Option<WindowKind>,
    /// `[f1, f2]` of the M0± band.
    pub band_hz: Option<[f64; 2]>,
    pub band_khz: Option<[f64; 2]>,
    /// Report frequencies (M0−, spectra) with the opposite sign.
    pub flip_sign: Option<bool>,
    /// Also accumulate the first moment M1.
    pub m1: Option<bool>,
    /// Also accumulate M0± per path class (static, one Doppler event, several).
    pub by_class: Option<bool>,
    /// Axis of the ROI spectra (and of per-pixel spectra).
    pub spectrum: Option<LdhSpectrumSection>,
    /// Full spectra in every pixel (memory: pixels × bins).
    pub pixel_spectra: Option<bool>,
    #[serde(default)]
    pub roi: Vec<RoiSection>,
    pub speckle: Option<SpeckleSection>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowKind {
    Rect,
    Hann,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LdhSpectrumSection {
    pub f_min_hz: Option<f64>,
    pub f_min_khz: Option<f64>,
    pub f_max_hz: Option<f64>,
    pub f_max_khz: Option<f64>,
    pub bins: Option<u64>,
}

/// `[[detectors.ldh.roi]]`: a named rectangle of the detector plane.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RoiSection {
    pub name: String,
    pub center_um: Option<[f64; 2]>,
    pub center_mm: Option<[f64; 2]>,
    pub center_m: Option<[f64; 2]>,
    pub size_um: Option<[f64; 2]>,
    pub size_mm: Option<[f64; 2]>,
    pub size_m: Option<[f64; 2]>,
}

/// `[detectors.ldh.speckle]`: single-window speckle of the ROI spectra, Algorithms 1 and 2.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SpeckleSection {
    /// Independent windows (speckle realisations) per ROI; default 16.
    pub windows: Option<u64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SideKind {
    Top,
    Bottom,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum AreaSection {
    All {},
    Disk {
        center_um: Option<[f64; 2]>,
        center_mm: Option<[f64; 2]>,
        center_m: Option<[f64; 2]>,
        radius_um: Option<f64>,
        radius_mm: Option<f64>,
        radius_m: Option<f64>,
    },
    Rect {
        center_um: Option<[f64; 2]>,
        center_mm: Option<[f64; 2]>,
        center_m: Option<[f64; 2]>,
        size_um: Option<[f64; 2]>,
        size_mm: Option<[f64; 2]>,
        size_m: Option<[f64; 2]>,
    },
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SpectrumSection {
    pub f_min_hz: Option<f64>,
    pub f_min_khz: Option<f64>,
    pub f_min_mhz: Option<f64>,
    pub f_min_ghz: Option<f64>,
    pub f_max_hz: Option<f64>,
    pub f_max_khz: Option<f64>,
    pub f_max_mhz: Option<f64>,
    pub f_max_ghz: Option<f64>,
    pub bins: Option<u64>,
    pub by_order: Option<u64>,
    pub by_doppler_events: Option<u64>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSection {
    pub pixels: [u64; 2],
}
