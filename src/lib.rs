//! # ohd — Monte Carlo simulation of optical heterodyne detection in participating media
//!
//! `ohd` traces photon packets from a collimated laser through a stack of scattering layers with
//! embedded regions (vessels, boxes, spheres). Each path carries, besides its radiometric weight,
//! its optical path length `l` and the rate of change of that length `dl/dt` (from the velocities
//! of the particles it scattered on). Detectors histogram the weight over the heterodyne beat
//! frequency — the "OHD path integral" of Kim et al., ACM TOG 44(4) 2025 (Eq. 26, 33).
//!
//! ## Conventions (the single place they are stated; tests pin each one)
//!
//! * **Units.** SI inside: m, s, Hz, m/s, m⁻¹ for σa/σs/σt, sr⁻¹ for phase functions. All physics
//!   in `f64`. Configuration keys carry their unit when it is not SI (`wavelength_nm`,
//!   `sigma_s_per_mm`, `speed_mm_per_s`, …); [`config::resolve()`] converts once.
//! * **Frame.** Right-handed, `z` is depth: the layer stack starts at the top surface `z = 0` and
//!   extends towards `+z` (as in MCML). "Top" detectors sit on the `z = 0` side, "bottom" ones
//!   below the last finite layer. Layers are laterally infinite. **In an atmosphere** (wind lidar)
//!   the same axis is the height above the ground: the lidar sits at `z ≤ 0` looking up, `x` is
//!   east and `y` north; azimuths are clockwise from north, elevations above the horizontal, and a
//!   wind direction is where it blows *from* (meteorological: 270° blows toward `+x`). Falling
//!   drops move toward `−z`.
//! * **Directions are propagation directions.** `dir_in` is the direction travelled before an
//!   event, `dir_out` after it; `cos θ = dir_in · dir_out`, `+1` = forward. Henyey–Greenstein `g > 0`
//!   is forward scattering, as published. `cos θ` is sampled directly (never through `acos`).
//! * **Beat-frequency sign.** Positive = the optical path is lengthening (scatterer receding), as in
//!   Kim et al. Eq. 33 and the wind-lidar custom. A *real* scattering event on a particle of velocity
//!   `v` in a medium of refractive index `n` adds `n · v · (dir_in − dir_out)` to `dl/dt`
//!   (Eq. 32 with `u = −dl/dt`). Interfaces and the source and detectors are static; null
//!   collisions are not vertices (their terms telescope away). Coaxial backscatter from a receding
//!   particle at speed `v` gives `f = +2nv/λ0` (test `transport::tests::coaxial_backscatter_sign`).
//!   A path traced from a camera pixel (`estimator = "camera"`, [`transport::camera`]) is the
//!   light's path reversed: each vertex's `dir_in − dir_out` is the same vector both ways, so
//!   `dl/dt`, `l` and the sign are the same whichever end a path is traced from.
//! * **Path length.** `l = Σ n_k |x_{k+1} − x_k|` from the laser's emission point to the plane of
//!   the detector that records the path.
//! * **Beat frequency.** Single-frequency laser: `f = (dl/dt)/λ0`. FMCW with chirp slope
//!   `α = B/T`: up-chirp `f_up = α·l/c + (dl/dt)/λ0`, down-chirp `f_down = α·l/c − (dl/dt)/λ0`.
//! * **Phase functions** are normalised to 1 over the sphere (sr⁻¹); tables in other
//!   normalisations (`four_pi`, `arbitrary`) are renormalised on load and the manifest records the
//!   convention as given. Tables are indexed by the scattering angle θ from forward (θ = 0,
//!   `cos θ = dir_in · dir_out = 1`) and read as linear in `cos θ` between their angles.
//! * **Refractive indices** of particles are `n − ik` with `k ≥ 0` absorbing (Wiscombe's sign);
//!   the Mie size parameter is `x = 2π r n_medium/λ0` and the relative index `m = (n − ik)/n_medium`.
//! * **Spectrum bins.** An explicit signed axis `[f_min, f_max)` cut into `bins` equal bins; bin
//!   `k` covers `[f_min + kΔ, f_min + (k+1)Δ)`, ascending frequency. With `f_min = −f_max` and an
//!   odd bin count the DC bin is the centre bin and the axis is mirror symmetric. A path outside the
//!   axis goes to the `below` / `above` out-of-range tallies, never out of bounds. Spectrum values
//!   are power per bin as a fraction of the emitted power (not per Hz), so a spectrum summed over
//!   its bins plus its out-of-range tallies equals the detected power of the same paths (Parseval).
//! * **Images** in every written format (`.npy`, EXR, PNG): row 0 = the top row = the largest `y`
//!   of the detector plane, columns `x` ascending — as `plt.imshow` and image viewers show them.
//!   With more axes the image rows and columns stay in that order: `[window][row][col]`,
//!   per-pixel spectra `[row][col][bin]`. Tallies keep row 0 at the lowest `y`; the flip is made
//!   once, where an output's values are taken for writing ([`output::Output::values`]).
//! * **Estimates** are means over paths of the fraction of emitted power; every estimate carries
//!   the standard error of the mean over `batches` independent batches of equal size. The FMCW
//!   range and velocity read off the spectra afterwards ([`retrieval::fmcw`]) are the exception:
//!   they come with the range and velocity one bin spans instead (the reason is given there).
//!   Per named output ([`converge`]) a scalar's error is absolute and a spectrum's or image's is the
//!   relative RMS over its bins, `‖x − r‖₂/‖r‖₂`, estimated by a run as `√(Σσ²)/‖x‖₂`.
//! * **Random numbers** are a pure function of `(seed, purpose, element, sample)`
//!   ([`sampling::rng`]); work is split by the configuration, never by the thread count, and batches
//!   are reduced in a fixed order, so output is bit-identical for any number of threads — and for
//!   any number of processes: a run resumed from a checkpoint, or cut into shards (`ohd run
//!   --shard I/N`, contiguous batch ranges) and merged, folds the same batches in the same order.
//!
//! ## Architecture
//!
//! One library and a thin binary. The modules form layers; a module may import from its own layer
//! (without cycles) and from the layers below it, never from above. `validation/architecture.py`
//! checks both on every CI run (its `LAYERS` table is this one). The layers up to the runs are
//! the workspace crate `ohd-core` (`core/`), which this crate re-exports module by module under
//! the same names, so `ohd::transport` is `ohd_core::transport` and the compiler refuses an import
//! from the physics into the configuration, the outputs or the command line. Two crates are
//! optimised on two cores at once; one crate's release build is LLVM on one codegen unit on one
//! core (`core/src/lib.rs`).
//!
//! | layer | modules | role |
//! |---|---|---|
//! | foundations | [`error`], [`numeric`], [`sys`], [`sampling`], [`stats`], [`spectrum`], [`phase`], [`surface`], [`mie`], [`output`], [`retrieval`] | errors; `ln Γ` and quadrature; the process's memory limits; random-number streams and warps; batch statistics; frequency axes, histograms, STFT and speckle synthesis; phase functions; surface BSDFs (Fresnel, GGX microfacets); Lorenz–Mie scattering and particle ensembles; the registry of a run's named outputs (kind, shape, units, tally slots, file, sign); estimators read off spectra (gate moments and fits, VAD wind, FMCW range and velocity) |
//! | scene | [`medium`], [`flow`], [`source`], [`io::formats`] | media, density fields with their majorant grids, shapes and the layer stack; velocity fields; the laser; file formats read and written (`.npy`, EXR, PNG, phase tables, the OpenVDB reader) |
//! | recording | [`detect`] | detectors ([`detect::DetectorKind`]) and the tally a finished path is recorded into; each detector declares its outputs in the registry as it lays out its tallies |
//! | transport | [`transport`] | interfaces, free-flight tracking (analytic, delta and ratio tracking over majorant segments), the random walk (`walk`: the physics of a path, generic over an estimator) and its estimators: forward packets from the laser (`forward`), camera paths from a camera's pixels (`adjoint`), the layered twin of the control variate (`twin`), weight windows and the guide (`steering`) |
//! | runs | [`experiment`], [`pilot`], [`post`], [`scan`], [`converge`], [`describe`] | an experiment and its run loop (batches, the target-error rule); the pilot that decides `estimator = "auto"`; the importance table's pilot (`Experiment::importance_table`); post-processing of a finished run (speckle); the VAD retrieval of a scan; errors of named outputs and the convergence study; the resolved experiment printed in human units |
//! | configuration | [`config`] | TOML schema with typed quantities, `--set` overrides, the one resolve step into SI runtime types |
//! | outputs | [`io`] ([`io::write`], [`io::persist`], [`io::figures`], [`io::outdir`]) | a finished run's files and manifest, read off the registry; shard and checkpoint files; figures; the output directory, held open and locked |
//! | orchestration | [`run`] | running as the command line does: a run or a scan, to a target error, checkpointed and resumed, in shards and merged; the convergence study written |
//! | binary | `cli` (`main.rs`) | argument parsing, the progress bar, printing, exit codes |
//!
//! Closed sets on the per-collision path are enums with `match` (phase functions, media, velocity
//! fields, detectors); trait objects only at cold seams (progress, observers, checkpoints).

pub mod cli;
pub mod config;
pub mod io;
pub mod run;

// The physics (everything below the configuration in the table above) is the workspace crate
// `ohd-core` (core/): it compiles beside this crate's configuration, outputs and command line.
pub use ohd_core::{
    SPEED_OF_LIGHT, converge, describe, detect, error, experiment, flow, medium, mie, numeric, output, phase, pilot,
    post, retrieval, sampling, scan, source, spectrum, stats, surface, sys, transport,
};

/// The built-in default experiment (`ohd run` without a CONFIG): a vessel with Poiseuille flow in
/// scattering tissue. The same file ships as `configs/default.toml`.
pub const DEFAULT_CONFIG: &str = include_str!("../configs/default.toml");
