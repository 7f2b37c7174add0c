//! Shared test scenes, as TOML fragments that each read like a short physical description: the
//! start of a scene and its `[run]`, the wind lidar's upward beam and receiver, a 785 nm beam into
//! an index-matched water layer holding a vessel, a camera looking back along the beam, a
//! Brownian half-space, a pencil backscattered into a narrow cone, and a thin tube in a clear
//! layer. A test composes
//! them with `format!`, adds its own sections, and overrides what it varies with `--set`-style
//! keys ([`super::run::experiment`]).

use std::fmt::Display;

/// The start of a scene: the schema version and a `[run]` of `samples` paths from `seed` in
/// `batches` batches.
pub fn header(samples: u64, seed: u64, batches: u64) -> String {
    format!("\nschema_version = 1\n[run]\nsamples = {samples}\nseed = {seed}\nbatches = {batches}\n")
}

/// A 1550 nm lidar beam pointing straight up from 1 m below the scene's surface.
pub const UPWARD_1550: &str = "[source]\nwavelength_nm = 1550\nposition_m = [0, 0, -1]\ndirection = [0, 0, 1]\n";

/// The range gates of a lidar receiver: `gates` gates of `gate_points` samples, the first at
/// `first_gate_m`, each transformed on `fft_points` points.
pub struct Gates {
    pub first_gate_m: u32,
    pub gate_points: u32,
    pub gates: u32,
    pub fft_points: u32,
}

/// The wind lidar's monostatic receiver, detector "lidar": 40 mm aperture radius, a field of view
/// of `fov_mrad`, a 200 ns pulse sampled at 50 MHz, on `gates`.
pub fn lidar_receiver(fov_mrad: impl Display, gates: Gates) -> String {
    let Gates { first_gate_m, gate_points, gates, fft_points } = gates;
    format!(
        r#"[[detectors]]
name = "lidar"
[detectors.lidar]
aperture_radius_mm = 40
field_of_view_mrad = {fov_mrad}
pulse_fwhm_ns = 200
sample_rate_mhz = 50
first_gate_m = {first_gate_m}
gate_points = {gate_points}
gates = {gates}
fft_points = {fft_points}
"#
    )
}

/// A 785 nm beam from 0.1 mm above the surface: a pencil, unless more `[source]` keys follow.
pub const BEAM_785: &str = "[source]\nwavelength_nm = 785\nposition_mm = [0, 0, -0.1]\n";

/// Water (n = 1.33) above and below: a scene of n = 1.33 refracts and reflects nothing at its faces.
pub const WATER_AROUND: &str = "[ambient]\nn_above = 1.33\nn_below = 1.33\n";

/// A 1 mm layer of water (n = 1.33, medium "clear", scattering `clear_sigma_s` per mm) holding a
/// vessel of radius 100 µm at 45° to the beam through its mid-depth: isotropic scatterers
/// (medium "blood", `blood_sigma_s` per mm) in Poiseuille flow, 10 mm/s on the axis. Nothing
/// absorbs.
pub fn vessel_in_water(clear_sigma_s: f64, blood_sigma_s: f64) -> String {
    format!(
        r#"[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = {clear_sigma_s}
[media.blood]
sigma_a_per_mm = 0
sigma_s_per_mm = {blood_sigma_s}
phase = {{ type = "isotropic" }}
[[layers]]
thickness_mm = 1
n = 1.33
medium = "clear"
[[regions]]
layer = "layer0"
medium = "blood"
shape = {{ type = "cylinder", center_um = [0, 0, 500], axis = [0.7071067811865476, 0, 0.7071067811865476], radius_um = 100 }}
velocity = {{ type = "poiseuille", v_max_mm_per_s = 10 }}
"#
    )
}

/// A square camera "camera" of side `side_mm` and `pixels` × `pixels` pixels centred over the
/// beam, taking what leaves within `acceptance_deg` of the normal, scattered light only (no
/// specular reflection). More keys of the detector may follow.
pub fn camera(side_mm: f64, acceptance_deg: f64, pixels: u32) -> String {
    format!(
        r#"[[detectors]]
name = "camera"
area = {{ type = "rect", size_mm = [{side_mm}, {side_mm}] }}
acceptance_half_angle_deg = {acceptance_deg}
include_specular = false
image = {{ pixels = [{pixels}, {pixels}] }}
"#
    )
}

/// A pencil beam at 785 nm from the origin, straight down.
pub const PENCIL_785: &str =
    "[source]\nwavelength_nm = 785\nprofile = \"pencil\"\nposition_mm = [0, 0, 0]\ndirection = [0, 0, 1]\n";

/// A DCS detector "ring" between `inner_mm` and `outer_mm` from the axis, with a time axis of
/// `time_bins` bins over 0–2 ns and g1 at `points` delays over 1e-7–1e-2 s (β = 0.5).
pub fn dcs_ring(inner_mm: f64, outer_mm: f64, time_bins: u32, points: u32) -> String {
    format!(
        r#"[[detectors]]
name = "ring"
area = {{ type = "annulus", inner_radius_mm = {inner_mm:?}, outer_radius_mm = {outer_mm:?} }}
[detectors.time]
t_min_ns = 0
t_max_ns = 2
bins = {time_bins}
[detectors.correlation]
tau_min_s = 1e-7
tau_max_s = 1e-2
points = {points}
beta = 0.5
"#
    )
}

/// A semi-infinite medium "tissue" of n = 1 under air (no Fresnel anywhere): isotropic
/// scattering, `sigma_s` and `sigma_a` per mm, every scatterer Brownian with D = 1e-12 m²/s.
pub fn brownian_half_space(sigma_a: f64, sigma_s: f64) -> String {
    format!(
        r#"[ambient]
n_above = 1.0
[media.tissue]
sigma_a_per_mm = {sigma_a:?}
sigma_s_per_mm = {sigma_s:?}
phase = {{ type = "isotropic" }}
motion = {{ diffusion_m2_per_s = 1e-12 }}
[[layers]]
name = "tissue"
thickness_mm = inf
n = 1.0
medium = "tissue"
"#
    )
}

/// An 800 nm pencil into a 2 mm layer of n = 1 of the isotropic scatterers `medium` (the keys of
/// `[media.m]` besides its phase function), seen straight back through a 0.5° cone by next-event
/// estimation, scattered light only: detector "back".
pub fn backscatter_800(medium: &str) -> String {
    format!(
        r#"[source]
wavelength_nm = 800
profile = "pencil"
position_mm = [0, 0, 0]
direction = [0, 0, 1]
[media.m]
{medium}
phase = {{ type = "isotropic" }}
[[layers]]
name = "m"
thickness_mm = 2
n = 1.0
medium = "m"
[[detectors]]
name = "back"
acceptance_half_angle_deg = 0.5
next_event = true
include_specular = false
"#
    )
}

/// A thin tube at 45° in a transparent layer, lit uniformly and seen in near-backscatter (HG
/// g = −0.99 scatterers, 3° acceptance; the flat-spectrum scene of validation-values §4.4), its
/// velocity given by `velocity` (a TOML inline table), 3·10⁶ paths in 16 batches.
pub fn tube_scene(velocity: &str) -> String {
    format!(
        r#"
schema_version = 1
[run]
samples = 3000000
batches = 16
[source]
wavelength_nm = 1000
profile = "disk"
radius_mm = 0.35
position_mm = [0, 0, -0.1]
[media.clear]
sigma_a_per_mm = 0
sigma_s_per_mm = 0
[media.blood]
sigma_a_per_mm = 0
sigma_s_per_mm = 0.2
phase = {{ type = "hg", g = -0.99 }}
[[layers]]
name = "clear"
thickness_mm = 0.4
n = 1.0
medium = "clear"
[[regions]]
layer = "clear"
medium = "blood"
shape = {{ type = "cylinder", center_mm = [0, 0, 0.2], axis = [1, 0, 1], radius_mm = 0.05 }}
velocity = {velocity}
[[detectors]]
name = "top"
acceptance_half_angle_deg = 3
[detectors.spectrum]
f_min_hz = 0
f_max_hz = 1555.634918610405   # 1.1 f_max
bins = 22
by_order = 2
"#
    )
}
