//! Test support shared by the modules of the integration-test binary: [`stats`] (the statistics
//! harness), [`run`] (running experiments from inline TOML and reading their tallies),
//! [`scenes`] (the shared test scenes, as TOML fragments) and [`lidar`] (lidar physics for the
//! wind-lidar tests); [`analog`] is an analog tracer of a slab written apart from the library (the
//! estimators' independent reference); [`alloc`] counts what each thread allocates; [`files`] runs the built binary and reads what it
//! writes; [`special`] makes the FIFOs and device nodes the tests use, in a directory of their own.

pub mod alloc;
pub mod analog;
pub mod files;
pub mod lidar;
pub mod run;
pub mod scenes;
pub mod special;
pub mod stats;
