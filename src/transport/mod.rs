//! Light transport: Fresnel interfaces, free-flight tracking and the random walk of a path.

pub mod camera;
pub mod features;
pub use crate::surface::fresnel;
pub mod guide;
pub mod nee;
pub mod tracking;
pub mod walk;
pub mod windows;

pub use camera::CameraTarget;
pub use features::{Features, PATHS_PER_TICK};
pub use nee::NeeTarget;
pub use tracking::{Flight, LayerRay, Tracking, free_flight};
pub use walk::{ControlVariate, LaunchSettings, Reflections, WalkContext, WalkSettings, control_variate_obstacle};
