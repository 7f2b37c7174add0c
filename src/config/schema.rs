//! The experiment file as written: serde structs mirroring the TOML, with `deny_unknown_fields`
//! everywhere. Quantities whose natural unit is not SI carry it in the key (`thickness_mm`,
//! `sigma_s_per_cm`, `speed_mm_per_s`, `f_max_khz`); a quantity may be given in any one of its
//! listed units. Each is one [`Quantity`] field whose unit set names the suffixes it accepts, and
//! whose serde name and aliases are the same keys (see [`super::units`]). Nothing here is
//! validated: [`super::resolve()`] does that, once.

use std::collections::BTreeMap;

use serde::Deserialize;

use super::units::{
    AngularSpeed, Aperture, CameraFrequency, ChirpBandwidth, ChirpDuration, Coefficient, Degrees, Delay, Diffusivity,
    FieldOfView, Frequency, Length, Metres, MetresPerSecond, NumberDensity, PulseEnergy, PulseWidth, Quantity,
    RainRate, SampleRate, SmallAngle, SmallRadius, Speed, Temperature, TimeOfFlight, Viscosity, Wavelength,
};

/// The schema version this build reads.
pub const SCHEMA_VERSION: i64 = 1;

/// The largest count a float can give exactly (2⁵³).
const EXACT_FLOAT_COUNT: f64 = 9_007_199_254_740_992.0;

/// `v` as a count, if it is a whole number in [0, 2⁵³].
pub fn whole(v: f64) -> Option<u64> {
    (v >= 0.0 && v.fract() == 0.0 && v <= EXACT_FLOAT_COUNT).then_some(v as u64)
}

/// A count (`run.samples`) from an integer or a float of a whole value (`1e6`, `2.5e5`): what the
/// field's users write (pmcx takes `1e6`); a fraction, a negative value or one beyond 2⁵³ is
/// refused with what is expected.
fn whole_count<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
    struct Count;
    impl serde::de::Visitor<'_> for Count {
        type Value = u64;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a whole number of paths such as 1000000 or 1e6")
        }
        fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<u64, E> {
            Ok(v)
        }
        fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<u64, E> {
            u64::try_from(v).map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(v), &self))
        }
        fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<u64, E> {
            whole(v).ok_or_else(|| E::invalid_value(serde::de::Unexpected::Float(v), &self))
        }
    }
    d.deserialize_any(Count).map(Some)
}

#[derive(Debug, Clone, Deserialize)]
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
    /// A voxel grid scoring absorbed power and fluence inside the scene.
    pub volume: Option<VolumeSection>,
    /// Lateral bounds: the stack cut to a box phantom.
    pub lateral: Option<LateralSection>,
    /// An opaque surface closing the stack from below.
    pub bottom: Option<BottomSection>,
    /// The cardiac cycle of pulsatile flows: the heart rate and the named waveforms that
    /// velocities follow (`velocity.waveform`, `motion.waveform`).
    pub cardiac: Option<CardiacSection>,
    /// Opaque solids inside the layers: reflectors with a surface BSDF.
    #[serde(default)]
    pub opaque: Vec<OpaqueSection>,
}

/// `[cardiac]`: one heart rate for every pulsatile flow of the scene, and its waveforms.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CardiacSection {
    pub heart_rate_bpm: Option<f64>,
    /// The kinematic viscosity of blood for Womersley profiles (default 3.3·10⁻⁶ m²/s).
    #[serde(rename = "blood_kinematic_viscosity_m2_per_s", alias = "blood_kinematic_viscosity_um2_per_s")]
    pub kinematic_viscosity: Option<Quantity<Diffusivity>>,
    #[serde(default)]
    pub waveforms: BTreeMap<String, WaveformSection>,
    /// Every flow steady at this time of the cycle (its velocities then): the steady run a
    /// window of an acquisition is compared with.
    #[serde(rename = "frozen_at_ms", alias = "frozen_at_s")]
    pub frozen_at: Option<Quantity<Delay>>,
}

/// `[cardiac.waveforms.NAME]`: a waveform over the cycle, relative to its mean; exactly one of
/// `shape`, `fourier`, `samples` or `table`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaveformSection {
    /// A built-in shape: "artery", "vein" or "choroid" (illustrative; see configs/README.md).
    pub shape: Option<String>,
    /// `(max − min)/max` of a built-in shape (default the shape's).
    pub resistivity_index: Option<f64>,
    /// `[[a1, b1], [a2, b2], …]`: `s(t) = 1 + Σ a_k cos(kωt) + b_k sin(kωt)`.
    pub fourier: Option<Vec<[f64; 2]>>,
    /// Values at equally spaced times over one cycle (the first at t = 0; not closed).
    pub samples: Option<Vec<f64>>,
    /// A CSV file (relative to the config) of `time_s,value` or `phase,value` rows over one
    /// closed cycle: from 0 to the period (or phase 1), the last value the first's.
    pub table: Option<String>,
    /// Harmonics kept (default 10 for shapes, samples and tables; the coefficients given for
    /// `fourier`), at most 32.
    pub harmonics: Option<i64>,
    /// The waveform arrives this late (default 0).
    #[serde(rename = "delay_ms", alias = "delay_s", alias = "delay_us")]
    pub delay: Option<Quantity<Delay>>,
}

/// `[bottom]`: an opaque surface under the last layer (which must be finite): a reflector with a
/// BSDF, which may move (a belt: `velocity`; a wheel or disk: `angular_velocity` about `center`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BottomSection {
    pub surface: Option<SurfaceSection>,
    #[serde(rename = "velocity_mm_per_s", alias = "velocity_m_per_s")]
    pub velocity: Option<Quantity<Speed, [f64; 3]>>,
    #[serde(rename = "angular_velocity_rad_per_s", alias = "angular_velocity_rpm")]
    pub angular_velocity: Option<Quantity<AngularSpeed, [f64; 3]>>,
    /// A point on the rotation axis (default the origin).
    #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
    pub center: Option<Quantity<Length, [f64; 3]>>,
}

/// `[[opaque]]`: an opaque solid inside a layer (a plate, a wall, a belt): its shape, its
/// surface's BSDF and its motion (as `[bottom]`'s).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpaqueSection {
    pub name: Option<String>,
    pub layer: Option<String>,
    pub shape: Option<ShapeSection>,
    pub surface: Option<SurfaceSection>,
    #[serde(rename = "velocity_mm_per_s", alias = "velocity_m_per_s")]
    pub velocity: Option<Quantity<Speed, [f64; 3]>>,
    #[serde(rename = "angular_velocity_rad_per_s", alias = "angular_velocity_rpm")]
    pub angular_velocity: Option<Quantity<AngularSpeed, [f64; 3]>>,
    /// A point on the rotation axis (default the shape's centre).
    #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
    pub center: Option<Quantity<Length, [f64; 3]>>,
}

/// A surface's BSDF.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SurfaceSection {
    /// The ideal diffuse reflector.
    Lambertian { albedo: Option<f64> },
    /// A rough metal (GGX microfacets): a measured `material` ("copper", "gold", "aluminium") at
    /// the source's wavelength, or its index `n` and extinction `k`.
    Conductor { roughness: Option<f64>, material: Option<String>, n: Option<f64>, k: Option<f64> },
    /// A weighted sum of surfaces (weights > 0, summing to 1).
    Mixture { parts: Option<Vec<MixturePart>> },
}

/// One part of a `type = "mixture"` surface.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixturePart {
    pub weight: Option<f64>,
    pub surface: Option<SurfaceSection>,
}

/// `[lateral]`: the layer stack cut to `x ∈ [x0, x1]`, `y ∈ [y0, y1]`, its side faces against
/// a clear medium of index `n_outside` (default `ambient.n_above`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LateralSection {
    #[serde(rename = "x_um", alias = "x_mm", alias = "x_m")]
    pub x: Option<Quantity<Length, [f64; 2]>>,
    #[serde(rename = "y_um", alias = "y_mm", alias = "y_m")]
    pub y: Option<Quantity<Length, [f64; 2]>>,
    pub n_outside: Option<f64>,
}

/// `[volume]`: a box of the scene (`z` = depth) cut into `voxels = [nx, ny, nz]` voxels.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VolumeSection {
    #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
    pub center: Option<Quantity<Length, [f64; 3]>>,
    #[serde(rename = "size_um", alias = "size_mm", alias = "size_m")]
    pub size: Option<Quantity<Length, [f64; 3]>>,
    pub voxels: Option<[i64; 3]>,
    /// The fluence estimator(s): `"track_length"` (default), `"collision"` or `"both"`.
    pub fluence: Option<FluenceKind>,
    /// `[volume.time]`: time-of-flight bins, the keys of `[detectors.time]` (`image` refused).
    pub time: Option<TimeSection>,
    /// Also write the untimed volumes as an OpenVDB file (`volume.vdb`).
    pub vdb: Option<bool>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FluenceKind {
    TrackLength,
    Collision,
    Both,
}

/// A `[reference]` value: a number for a scalar output, an array for a spectrum or image
/// (in the order of its `.npy` file).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum ReferenceValue {
    Scalar(f64),
    Array(Vec<f64>),
}

/// `[wind]`: horizontal wind as a function of height, plus a vertical velocity. Directions are
/// meteorological: `direction_from_deg` is where the wind blows *from*, clockwise from north
/// (270 = a westerly, blowing toward +x = east); `y` is north, `z` up.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum WindSection {
    Uniform {
        #[serde(rename = "velocity_m_per_s")]
        velocity: Quantity<MetresPerSecond, [f64; 3]>,
    },
    /// `u(h) = u_ref·(h/h_ref)^α`.
    PowerLaw {
        #[serde(rename = "speed_m_per_s")]
        speed: Quantity<MetresPerSecond>,
        #[serde(rename = "reference_height_m")]
        reference_height: Quantity<Metres>,
        exponent: f64,
        #[serde(rename = "direction_from_deg")]
        direction_from: Quantity<Degrees>,
        #[serde(rename = "vertical_m_per_s")]
        vertical: Option<Quantity<MetresPerSecond>>,
    },
    /// `u(h) = (u*/κ)·ln((h − d)/z0)`; give u* or the speed at a reference height.
    LogLaw {
        #[serde(rename = "friction_velocity_m_per_s")]
        friction_velocity: Option<Quantity<MetresPerSecond>>,
        #[serde(rename = "speed_m_per_s")]
        speed: Option<Quantity<MetresPerSecond>>,
        #[serde(rename = "reference_height_m")]
        reference_height: Option<Quantity<Metres>>,
        #[serde(rename = "roughness_length_m")]
        roughness_length: Quantity<Metres>,
        #[serde(rename = "displacement_height_m")]
        displacement_height: Option<Quantity<Metres>>,
        #[serde(rename = "direction_from_deg")]
        direction_from: Quantity<Degrees>,
        #[serde(rename = "vertical_m_per_s")]
        vertical: Option<Quantity<MetresPerSecond>>,
    },
    /// One velocity per layer of height: `velocities_m_per_s[i]` for
    /// `heights_m[i] ≤ h < heights_m[i + 1]`.
    Table {
        #[serde(rename = "heights_m")]
        heights: Quantity<Metres, Vec<f64>>,
        #[serde(rename = "velocities_m_per_s")]
        velocities: Quantity<MetresPerSecond, Vec<[f64; 3]>>,
    },
}

/// How a medium's coefficients change with height (`z`, m, above the ground at `z = 0`):
/// a factor on σs and σa, taken at the middle of each layer the medium fills.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum HeightProfileSection {
    /// `exp(−h/H)`.
    Exponential {
        #[serde(rename = "scale_height_m")]
        scale_height: Quantity<Metres>,
    },
    /// 1 up to the boundary-layer top, then `exp(−(h − top)/H)`.
    BoundaryLayer {
        #[serde(rename = "top_m")]
        top: Quantity<Metres>,
        #[serde(rename = "scale_height_m")]
        scale_height: Quantity<Metres>,
    },
    /// Piecewise linear through `(heights_m[i], factors[i])`, constant beyond the ends.
    Table {
        #[serde(rename = "heights_m")]
        heights: Quantity<Metres, Vec<f64>>,
        factors: Vec<f64>,
    },
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSection {
    /// Paths: a whole number, also written as a float (`1e6`, as pmcx takes it).
    #[serde(default, deserialize_with = "whole_count")]
    pub samples: Option<u64>,
    pub seed: Option<u64>,
    pub batches: Option<u64>,
    pub threads: Option<u64>,
    pub tracking: Option<TrackingKind>,
    pub majorant_scale: Option<f64>,
    pub roulette_threshold: Option<f64>,
    pub roulette_survival: Option<f64>,
    pub max_scattering_events: Option<u64>,
    /// How the laser's unscattered reflections at the interfaces below the surface reach the
    /// detectors: `"auto"` (default), `"deterministic"` or `"sampled"`.
    pub reflections: Option<ReflectionsKind>,
    /// The layered control variate of forward-estimated cameras: `"auto"` (default: wherever it
    /// applies), `"layered"` (refused where it does not) or `"off"`.
    pub control_variate: Option<ControlVariateKind>,
    /// Where forward paths start: `"profile"` (default) or `"near_regions"` (a share
    /// `launch_profile_share` from the profile, the rest from within `launch_margin_um` of the
    /// regions, weighted).
    pub launches: Option<LaunchesKind>,
    #[serde(rename = "launch_margin_um", alias = "launch_margin_mm")]
    pub launch_margin: Option<Quantity<Length>>,
    pub launch_profile_share: Option<f64>,
    /// The importance table of the main output's detector (`detect::importance`): `"off"`
    /// (default), `"table"` (a pilot computes it and the run writes it) or `"windows"` (and the
    /// forward walk's weight windows follow it, `transport::windows`), `"guided"` (the windows
    /// and directions guided by it, `transport::guide`) or `"auto"` (the table, and the windows
    /// or the windows and guided directions where a pilot measures that they pay, `pilot`).
    pub importance: Option<ImportanceKind>,
    /// Largest memory the tallies may take (GiB); configurations above it are refused.
    pub memory_budget_gib: Option<f64>,
    /// A global time gate `[t0, t1]` on the forward paths (time of flight = optical path length
    /// / c from the emission point).
    #[serde(rename = "time_gate_ns", alias = "time_gate_us")]
    pub time_gate: Option<Quantity<PulseWidth, [f64; 2]>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LaunchesKind {
    Profile,
    NearRegions,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImportanceKind {
    Off,
    Table,
    Windows,
    Guided,
    Auto,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlVariateKind {
    Auto,
    Layered,
    Off,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReflectionsKind {
    Auto,
    Deterministic,
    Sampled,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackingKind {
    Analytic,
    Delta,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceSection {
    #[serde(rename = "wavelength_nm", alias = "wavelength_um")]
    pub wavelength: Option<Quantity<Wavelength>>,
    #[serde(default)]
    pub profile: Option<ProfileKind>,
    /// Disk radius.
    #[serde(rename = "radius_um", alias = "radius_mm", alias = "radius_m")]
    pub radius: Option<Quantity<Length>>,
    /// Gaussian 1/e² intensity radius.
    #[serde(rename = "waist_um", alias = "waist_mm", alias = "waist_m")]
    pub waist: Option<Quantity<Length>>,
    #[serde(rename = "position_um", alias = "position_mm", alias = "position_m")]
    pub position: Option<Quantity<Length, [f64; 3]>>,
    pub direction: Option<[f64; 3]>,
    /// Pointing by angles instead of `direction`, in the frame x = east, y = north, z = up (the
    /// depth axis of the stack): azimuth clockwise from north, elevation above the horizontal.
    #[serde(rename = "azimuth_deg")]
    pub azimuth: Option<Quantity<Degrees>>,
    #[serde(rename = "elevation_deg")]
    pub elevation: Option<Quantity<Degrees>>,
    /// A scan: `[[azimuth, elevation], …]` in degrees, one run per pointing (a VAD scan).
    #[serde(rename = "pointings_deg")]
    pub pointings: Option<Quantity<Degrees, Vec<[f64; 2]>>>,
    /// Far-field divergence of the Gaussian beam: the 1/e² intensity half-angle.
    #[serde(rename = "divergence_urad", alias = "divergence_mrad")]
    pub divergence: Option<Quantity<SmallAngle>>,
    pub chirp: Option<ChirpSection>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProfileKind {
    Pencil,
    Disk,
    Gaussian,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChirpSection {
    #[serde(rename = "bandwidth_hz", alias = "bandwidth_mhz", alias = "bandwidth_ghz")]
    pub bandwidth: Option<Quantity<ChirpBandwidth>>,
    #[serde(rename = "duration_s", alias = "duration_ms", alias = "duration_us")]
    pub duration: Option<Quantity<ChirpDuration>>,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmbientSection {
    pub n_above: Option<f64>,
    pub n_below: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumSection {
    /// The preset this medium was expanded from (see [`super::preset`]); for the record.
    pub preset: Option<String>,
    pub description: Option<String>,
    pub references: Option<Vec<String>>,
    /// The vacuum wavelength the medium's values are for; checked against the source.
    #[serde(rename = "wavelength_nm", alias = "wavelength_um")]
    pub wavelength: Option<Quantity<Wavelength>>,
    /// Particles whose Mie optics give σs, σa and the phase function (explicit σs, σa win).
    pub particles: Option<OneOrMany<ParticlesSection>>,
    /// Factor applied to σs after everything else (≥ 0; e.g. to calibrate a sphere model to a
    /// measured σs, or to thin a medium for tractability).
    pub sigma_s_scale: Option<f64>,
    #[serde(rename = "sigma_a_per_m", alias = "sigma_a_per_cm", alias = "sigma_a_per_mm")]
    pub sigma_a: Option<Quantity<Coefficient>>,
    #[serde(rename = "sigma_s_per_m", alias = "sigma_s_per_cm", alias = "sigma_s_per_mm")]
    pub sigma_s: Option<Quantity<Coefficient>>,
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
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum DensitySection {
    /// Linear along `axis` ("x", "y" or "z") from `density_from` at the plane `from_*` to
    /// `density_to` at the plane `to_*`, constant beyond the planes.
    Ramp {
        axis: String,
        #[serde(rename = "from_um", alias = "from_mm", alias = "from_m")]
        from: Option<Quantity<Length>>,
        #[serde(rename = "to_um", alias = "to_mm", alias = "to_m")]
        to: Option<Quantity<Length>>,
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
        #[serde(rename = "translate_um", alias = "translate_mm", alias = "translate_m")]
        translate: Option<Quantity<Length, [f64; 3]>>,
        /// "grid" (default: per-cell bounds) or "global" (one bound for the whole grid).
        majorant: Option<MajorantSection>,
        /// Edge of a majorant cell in voxels (default 4).
        majorant_cell_voxels: Option<u64>,
    },
    /// A float volume from a NumPy `.npy` file: `array[i, j, k]` is voxel `(i, j, k)` along x, y
    /// and z (shape `(nx, ny, nz)`, float32 or float64, C or Fortran order), 0 outside it; read
    /// as an OpenVDB grid is (the same majorant grid and lookup).
    Npy {
        /// The `.npy` file, relative to the config file.
        file: String,
        /// The voxels' edge (cubic voxels).
        #[serde(rename = "voxel_size_um", alias = "voxel_size_mm", alias = "voxel_size_m")]
        voxel_size: Option<Quantity<Length>>,
        /// Where the centre of voxel (0, 0, 0) lies (default the origin).
        #[serde(rename = "translate_um", alias = "translate_mm", alias = "translate_m")]
        translate: Option<Quantity<Length, [f64; 3]>>,
        /// "trilinear" (default) or "nearest".
        interpolation: Option<InterpolationSection>,
        /// "grid" (default: per-cell bounds) or "global" (one bound for the whole grid).
        majorant: Option<MajorantSection>,
        /// Edge of a majorant cell in voxels (default: chosen per grid).
        majorant_cell_voxels: Option<u64>,
    },
}

/// How a grid is read between its voxel points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InterpolationSection {
    Trilinear,
    Nearest,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MajorantSection {
    Grid,
    Global,
}

/// `[media.X.motion]`: a per-event random velocity and Brownian diffusion.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSection {
    /// Standard deviation of each velocity component, drawn per scattering event.
    #[serde(rename = "dispersion_mm_per_s", alias = "dispersion_m_per_s")]
    pub dispersion: Option<Quantity<Speed>>,
    /// The diffusion coefficient D, or the particle radius, temperature and viscosity that give it.
    #[serde(rename = "diffusion_m2_per_s", alias = "diffusion_um2_per_s")]
    pub diffusion: Option<Quantity<Diffusivity>>,
    #[serde(rename = "radius_um", alias = "radius_nm")]
    pub radius: Option<Quantity<SmallRadius>>,
    #[serde(rename = "temperature_k")]
    pub temperature: Option<Quantity<Temperature>>,
    #[serde(rename = "viscosity_mpa_s", alias = "viscosity_pa_s")]
    pub viscosity: Option<Quantity<Viscosity>>,
    /// The name of a `[cardiac.waveforms]` entry the dispersion follows over the cycle (a
    /// perfused bed's pulsatility; the dispersion given is its cycle mean).
    pub waveform: Option<String>,
}

#[derive(Debug, Clone, Deserialize)]
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
#[derive(Debug, Clone)]
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
#[derive(Debug, Clone, Deserialize)]
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
    #[serde(rename = "number_density_per_m3", alias = "number_density_per_cm3")]
    pub number_density: Option<Quantity<NumberDensity>>,
    /// Fraction of the volume the particles fill (the hematocrit, for red blood cells).
    pub volume_fraction: Option<f64>,
    pub packing: Option<PackingKind>,
    /// Nodes of the size quadrature.
    pub size_points: Option<u64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PackingKind {
    None,
    Twersky,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SizeSection {
    Monodisperse {
        #[serde(rename = "diameter_um", alias = "diameter_mm", alias = "diameter_m")]
        diameter: Option<Quantity<Length>>,
        #[serde(rename = "radius_um", alias = "radius_mm", alias = "radius_m")]
        radius: Option<Quantity<Length>>,
    },
    /// Number distribution log-normal in radius (OPAC): median radius, geometric standard deviation.
    LogNormal {
        #[serde(rename = "median_radius_um", alias = "median_radius_mm", alias = "median_radius_m")]
        median_radius: Option<Quantity<Length>>,
        sigma_g: f64,
        #[serde(rename = "min_radius_um", alias = "min_radius_mm", alias = "min_radius_m")]
        min_radius: Option<Quantity<Length>>,
        #[serde(rename = "max_radius_um", alias = "max_radius_mm", alias = "max_radius_m")]
        max_radius: Option<Quantity<Length>>,
    },
    /// Deirmendjian's modified gamma, n(r) ∝ r^α exp(−(α/γ)(r/r_c)^γ), mode radius r_c.
    ModifiedGamma {
        #[serde(rename = "mode_radius_um", alias = "mode_radius_mm", alias = "mode_radius_m")]
        mode_radius: Option<Quantity<Length>>,
        alpha: f64,
        gamma: f64,
        #[serde(rename = "min_radius_um", alias = "min_radius_mm", alias = "min_radius_m")]
        min_radius: Option<Quantity<Length>>,
        #[serde(rename = "max_radius_um", alias = "max_radius_mm", alias = "max_radius_m")]
        max_radius: Option<Quantity<Length>>,
    },
    /// Marshall–Palmer raindrops, N(D) = 8000 m⁻³ mm⁻¹ exp(−4.1 R^−0.21 D): absolute concentration.
    MarshallPalmer {
        #[serde(rename = "rain_rate_mm_per_h")]
        rain_rate: Quantity<RainRate>,
        #[serde(rename = "min_diameter_um", alias = "min_diameter_mm", alias = "min_diameter_m")]
        min_diameter: Option<Quantity<Length>>,
        #[serde(rename = "max_diameter_um", alias = "max_diameter_mm", alias = "max_diameter_m")]
        max_diameter: Option<Quantity<Length>>,
    },
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum VelocitySection {
    None {},
    Uniform {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
        #[serde(rename = "velocity_mm_per_s", alias = "velocity_m_per_s")]
        velocity: Option<Quantity<Speed, [f64; 3]>>,
    },
    Poiseuille {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
        /// With a waveform: Womersley's pulsatile profile in the rigid tube (default false: the
        /// Poiseuille profile times the waveform, Womersley's limit at α → 0).
        womersley: Option<bool>,
        #[serde(rename = "v_max_mm_per_s", alias = "v_max_m_per_s")]
        v_max: Option<Quantity<Speed>>,
        #[serde(rename = "mean_mm_per_s", alias = "mean_m_per_s")]
        mean: Option<Quantity<Speed>>,
    },
    RandomDirection {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
        #[serde(rename = "speed_mm_per_s", alias = "speed_m_per_s")]
        speed: Option<Quantity<Speed>>,
    },
    /// Carried by the `[wind]` at the particle's height.
    Wind {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
    },
    /// Falling drops: the `[wind]` (calm without one) plus each drop size's terminal fall speed
    /// (Atlas et al. 1973) downward; the drop sizes are the medium's particles.
    TerminalFall {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
    },
    /// A Vec3SGrid (m/s) from an OpenVDB file.
    Vdb {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
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
        #[serde(rename = "translate_um", alias = "translate_mm", alias = "translate_m")]
        translate: Option<Quantity<Length, [f64; 3]>>,
    },
    /// A velocity volume (m/s) from a NumPy `.npy` file of shape `(nx, ny, nz, 3)`, placed as a
    /// `density = { type = "npy" }` is.
    Npy {
        /// The name of a `[cardiac.waveforms]` entry: the velocities follow it over the cycle
        /// (the field given is the cycle-mean flow).
        waveform: Option<String>,
        /// The `.npy` file, relative to the config file.
        file: String,
        /// The voxels' edge (cubic voxels).
        #[serde(rename = "voxel_size_um", alias = "voxel_size_mm", alias = "voxel_size_m")]
        voxel_size: Option<Quantity<Length>>,
        /// Where the centre of voxel (0, 0, 0) lies (default the origin).
        #[serde(rename = "translate_um", alias = "translate_mm", alias = "translate_m")]
        translate: Option<Quantity<Length, [f64; 3]>>,
        /// "trilinear" (default) or "nearest".
        interpolation: Option<InterpolationSection>,
    },
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSection {
    pub name: Option<String>,
    /// `inf` (a TOML float) for a semi-infinite last layer.
    #[serde(rename = "thickness_um", alias = "thickness_mm", alias = "thickness_m")]
    pub thickness: Option<Quantity<Length>>,
    pub n: Option<f64>,
    /// The GGX roughness α of the layer's top face (its interface with what lies above; default 0,
    /// smooth).
    pub roughness: Option<f64>,
    pub medium: String,
    /// Split the layer into this many equal layers (named `NAME[i]`), e.g. 100 layers of 10 m for
    /// an atmosphere with a wind or density profile.
    pub sublayers: Option<u64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSection {
    pub name: Option<String>,
    pub layer: String,
    pub medium: String,
    /// Overrides the medium's velocity field inside this region.
    pub velocity: Option<VelocitySection>,
    pub shape: ShapeSection,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSection {
    Cylinder {
        #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
        center: Option<Quantity<Length, [f64; 3]>>,
        axis: [f64; 3],
        #[serde(rename = "radius_um", alias = "radius_mm", alias = "radius_m")]
        radius: Option<Quantity<Length>>,
        #[serde(rename = "length_um", alias = "length_mm", alias = "length_m")]
        length: Option<Quantity<Length>>,
    },
    Box {
        #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
        center: Option<Quantity<Length, [f64; 3]>>,
        #[serde(rename = "size_um", alias = "size_mm", alias = "size_m")]
        size: Option<Quantity<Length, [f64; 3]>>,
    },
    Sphere {
        #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
        center: Option<Quantity<Length, [f64; 3]>>,
        #[serde(rename = "radius_um", alias = "radius_mm", alias = "radius_m")]
        radius: Option<Quantity<Length>>,
    },
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorSection {
    pub name: String,
    pub side: Option<SideKind>,
    pub area: Option<AreaSection>,
    #[serde(rename = "acceptance_half_angle_deg")]
    pub acceptance_half_angle: Option<Quantity<Degrees>>,
    pub axis: Option<[f64; 3]>,
    /// A monostatic transceiver's receiver: it looks back along the beam (its axis the reverse of
    /// the source's direction), turned with each pointing of a scan.
    pub monostatic: Option<bool>,
    #[serde(rename = "distance_um", alias = "distance_mm", alias = "distance_m")]
    pub distance: Option<Quantity<Length>>,
    pub include_specular: Option<bool>,
    /// Score the detector by next-event estimation (a shadow ray from every scattering vertex into
    /// its cone) as well as by the paths that escape into it; top detectors only. Always on for
    /// LDH cameras and lidar receivers.
    pub next_event: Option<bool>,
    /// How the detector's scattered light is estimated: `"forward"` (paths from the laser, the
    /// default), `"camera"` (paths from its pixels, connected to the laser at every
    /// scattering vertex; a top detector with an image, under a disk or Gaussian beam) or
    /// `"auto"` (where `"camera"` could run: whichever a pilot before the run finds lower in
    /// variance × work). `"footprints"`: camera paths from the pixels of the regions'
    /// footprints (grown by a halo) and of the ROIs, the forward paths (with the layered control
    /// variate) everywhere else ([`FootprintsSection`]).
    pub estimator: Option<EstimatorKind>,
    /// With `estimator = "footprints"`: the halo and the number of camera paths.
    pub footprints: Option<FootprintsSection>,
    pub spectrum: Option<SpectrumSection>,
    pub image: Option<ImageSection>,
    /// A time axis: the temporal point-spread function (and time-gated images).
    pub time: Option<TimeSection>,
    /// g1(τ), g2(τ) and the speckle contrast K(T).
    pub correlation: Option<CorrelationSection>,
    /// A laser Doppler holography camera over the image's pixels.
    pub ldh: Option<LdhSection>,
    /// A pulsed lidar receiver at the source (monostatic), with range gates.
    pub lidar: Option<LidarSection>,
}

/// `estimator = "…"` of a detector.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorKind {
    Forward,
    Camera,
    Footprints,
    Auto,
}

/// `[detectors.footprints]`: the camera pixels of `estimator = "footprints"`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FootprintsSection {
    /// Pixels whose centre lies within this distance of a footprint pixel's are camera pixels too
    /// (default 20 µm: a vessel's light leaves the surface within ≈ 20 µm of where it last
    /// scattered in the blood).
    #[serde(rename = "halo_um", alias = "halo_mm")]
    pub halo: Option<Quantity<Length>>,
    /// Camera paths per forward path, spread evenly over the camera pixels (default 1).
    pub camera_paths: Option<f64>,
    /// Camera paths connect to the layered scene's light field below the regions (default
    /// false).
    pub light_field: Option<bool>,
    /// Forward paths of the light field's pre-pass (default 2·10⁶).
    pub field_paths: Option<u64>,
}

/// `[detectors.lidar]`: a monostatic pulsed coherent lidar receiver at the source's position,
/// looking along the source's direction, and its range gates.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarSection {
    #[serde(rename = "aperture_radius_mm", alias = "aperture_radius_m")]
    pub aperture_radius: Option<Quantity<Aperture>>,
    /// Field-of-view half-angle.
    #[serde(rename = "field_of_view_urad", alias = "field_of_view_mrad", alias = "field_of_view_deg")]
    pub field_of_view: Option<Quantity<FieldOfView>>,
    /// Intensity FWHM of the Gaussian pulse.
    #[serde(rename = "pulse_fwhm_ns", alias = "pulse_fwhm_us")]
    pub pulse_fwhm: Option<Quantity<PulseWidth>>,
    #[serde(rename = "sample_rate_hz", alias = "sample_rate_mhz")]
    pub sample_rate: Option<Quantity<SampleRate>>,
    /// Range of the start of the first gate.
    #[serde(rename = "first_gate_m")]
    pub first_gate: Option<Quantity<Metres>>,
    /// Samples per gate (gate length = points·c/(2 f_s)).
    pub gate_points: Option<u64>,
    pub gates: Option<u64>,
    /// Length of the (zero-padded) DFT of a gate.
    pub fft_points: Option<u64>,
    /// Transmitted pulse energy (sets the shot-noise floor; default 100 µJ).
    #[serde(rename = "pulse_energy_uj", alias = "pulse_energy_mj")]
    pub pulse_energy: Option<Quantity<PulseEnergy>>,
    /// Detector quantum efficiency in (0, 1] (default 0.8).
    pub quantum_efficiency: Option<f64>,
    /// Heterodyne (mixing, mode-matching) efficiency in (0, 1] (default 0.4).
    pub heterodyne_efficiency: Option<f64>,
}

/// `[detectors.ldh]`: the LDH acquisition (camera rate, STFT window, band) and its outputs.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LdhSection {
    #[serde(rename = "frame_rate_hz", alias = "frame_rate_khz")]
    pub frame_rate: Option<Quantity<CameraFrequency>>,
    /// Samples N_w of one short-time Fourier transform window.
    pub window_samples: Option<u64>,
    pub window: Option<WindowKind>,
    /// `[f1, f2]` of the M0± band.
    #[serde(rename = "band_hz", alias = "band_khz")]
    pub band: Option<Quantity<CameraFrequency, [f64; 2]>>,
    /// Report frequencies (M0−, spectra) with the opposite sign.
    pub flip_sign: Option<bool>,
    /// Also accumulate the first moment M1.
    pub m1: Option<bool>,
    /// Also the band moments M1±, M2± and the mean and RMS frequency images, per pixel and ROI.
    pub moments: Option<bool>,
    /// Also accumulate M0± per path class (static, one Doppler event, several).
    pub by_class: Option<bool>,
    /// Axis of the ROI spectra (and of per-pixel spectra).
    pub spectrum: Option<LdhSpectrumSection>,
    /// Full spectra in every pixel (memory: pixels × bins).
    pub pixel_spectra: Option<bool>,
    #[serde(default)]
    pub roi: Vec<RoiSection>,
    pub speckle: Option<SpeckleSection>,
    /// Windows over the cardiac cycle of a scene whose flows pulse (`[cardiac]`).
    pub acquisition: Option<AcquisitionSection>,
}

/// `[detectors.ldh.acquisition]`: HoloDoppler's windows over the cardiac cycle, each of the
/// camera's `window_samples` frames.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AcquisitionSection {
    /// Frames between the windows' starts (default `window_samples`: back to back).
    pub hop_samples: Option<u64>,
    /// How long the acquisition lasts (default one cardiac cycle).
    #[serde(rename = "duration_s", alias = "duration_ms")]
    pub duration: Option<Quantity<Delay>>,
    /// When it starts in the cycle (default 0).
    #[serde(rename = "start_ms", alias = "start_s")]
    pub start: Option<Quantity<Delay>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowKind {
    Rect,
    Hann,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LdhSpectrumSection {
    #[serde(rename = "f_min_hz", alias = "f_min_khz")]
    pub f_min: Option<Quantity<CameraFrequency>>,
    #[serde(rename = "f_max_hz", alias = "f_max_khz")]
    pub f_max: Option<Quantity<CameraFrequency>>,
    pub bins: Option<u64>,
}

/// `[[detectors.ldh.roi]]`: a named rectangle of the detector plane.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoiSection {
    pub name: String,
    #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
    pub center: Option<Quantity<Length, [f64; 2]>>,
    #[serde(rename = "size_um", alias = "size_mm", alias = "size_m")]
    pub size: Option<Quantity<Length, [f64; 2]>>,
}

/// `[detectors.ldh.speckle]`: single-window speckle of the ROI spectra, Algorithms 1 and 2, and
/// optionally of every pixel (Algorithm 1 from the per-pixel spectra).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeckleSection {
    /// Independent windows (speckle realisations) per ROI, and per pixel with `pixels`; default 16.
    pub windows: Option<u64>,
    /// Also a single-window speckled M0± in every pixel (Algorithm 1, drawn from the per-pixel
    /// spectra: needs `pixel_spectra = true`); default false.
    pub pixels: Option<bool>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SideKind {
    Top,
    Bottom,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum AreaSection {
    All {},
    Disk {
        #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
        center: Option<Quantity<Length, [f64; 2]>>,
        #[serde(rename = "radius_um", alias = "radius_mm", alias = "radius_m")]
        radius: Option<Quantity<Length>>,
    },
    Rect {
        #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
        center: Option<Quantity<Length, [f64; 2]>>,
        #[serde(rename = "size_um", alias = "size_mm", alias = "size_m")]
        size: Option<Quantity<Length, [f64; 2]>>,
    },
    /// A ring (a fibre bundle at a source–detector separation).
    Annulus {
        #[serde(rename = "center_um", alias = "center_mm", alias = "center_m")]
        center: Option<Quantity<Length, [f64; 2]>>,
        #[serde(rename = "inner_radius_um", alias = "inner_radius_mm", alias = "inner_radius_m")]
        inner_radius: Option<Quantity<Length>>,
        #[serde(rename = "outer_radius_um", alias = "outer_radius_mm", alias = "outer_radius_m")]
        outer_radius: Option<Quantity<Length>>,
    },
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpectrumSection {
    #[serde(rename = "f_min_hz", alias = "f_min_khz", alias = "f_min_mhz", alias = "f_min_ghz")]
    pub f_min: Option<Quantity<Frequency>>,
    #[serde(rename = "f_max_hz", alias = "f_max_khz", alias = "f_max_mhz", alias = "f_max_ghz")]
    pub f_max: Option<Quantity<Frequency>>,
    pub bins: Option<u64>,
    pub by_order: Option<u64>,
    pub by_doppler_events: Option<u64>,
    /// Spectra in windows over the cardiac cycle of a scene whose flows pulse.
    pub acquisition: Option<SpectrumAcquisitionSection>,
}

/// `[detectors.spectrum.acquisition]`: a point detector's spectra in windows over the cardiac
/// cycle (laser Doppler flowmetry).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpectrumAcquisitionSection {
    /// Each window's length (required).
    #[serde(rename = "window_ms", alias = "window_s", alias = "window_us")]
    pub window: Option<Quantity<Delay>>,
    /// Between the windows' starts (default the window: back to back).
    #[serde(rename = "hop_ms", alias = "hop_s", alias = "hop_us")]
    pub hop: Option<Quantity<Delay>>,
    /// How long the acquisition lasts (default one cardiac cycle).
    #[serde(rename = "duration_s", alias = "duration_ms")]
    pub duration: Option<Quantity<Delay>>,
    /// When it starts in the cycle (default 0).
    #[serde(rename = "start_ms", alias = "start_s")]
    pub start: Option<Quantity<Delay>>,
}

/// `[detectors.time]`: time-of-flight bins over `[t_min, t_max)`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSection {
    #[serde(rename = "t_min_ns")]
    pub t_min: Option<Quantity<TimeOfFlight>>,
    #[serde(rename = "t_max_ns")]
    pub t_max: Option<Quantity<TimeOfFlight>>,
    pub bins: Option<u64>,
    /// Also gate the detector's image by the bins (`[bin, y, x]`).
    pub image: Option<bool>,
}

/// `[detectors.correlation]`: delays log-spaced over `[tau_min, tau_max]`, β, exposure times.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CorrelationSection {
    #[serde(rename = "tau_min_s", alias = "tau_min_ms", alias = "tau_min_us")]
    pub tau_min: Option<Quantity<Delay>>,
    #[serde(rename = "tau_max_s", alias = "tau_max_ms", alias = "tau_max_us")]
    pub tau_max: Option<Quantity<Delay>>,
    pub points: Option<u64>,
    pub beta: Option<f64>,
    #[serde(rename = "exposures_s", alias = "exposures_ms", alias = "exposures_us")]
    pub exposures: Option<Quantity<Delay, Vec<f64>>>,
    /// Also per pixel of the image (the speckle contrast image).
    pub pixels: Option<bool>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageSection {
    pub pixels: [u64; 2],
}
