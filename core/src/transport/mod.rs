//! Light transport: Fresnel interfaces, free-flight tracking, the random walk of a path and the
//! estimators that score it.

pub mod adjoint;
pub mod camera;
pub mod carried;
pub mod event;
pub mod features;
pub mod field;
pub mod field_pass;
pub mod forward;
pub use crate::surface::fresnel;
pub mod guide;
pub mod nee;
pub mod policy;
pub mod steering;
pub mod tracking;
pub mod twin;
pub mod walk;
pub mod windows;

pub use camera::CameraTarget;
pub use features::{Features, PATHS_PER_TICK};
pub use nee::NeeTarget;
pub use policy::{ControlVariate, LaunchSettings, Reflections, WalkSettings, control_variate_obstacle};
pub use tracking::{Flight, LayerRay, Tracking, free_flight};
pub use walk::WalkContext;
