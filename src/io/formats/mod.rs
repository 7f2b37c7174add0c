//! File formats: `.npy` arrays ([`npy`]), OpenEXR images ([`exr`]), PNG encoding ([`png`]),
//! phase-function tables ([`table`]) and the OpenVDB reader ([`vdb`], the only place that reads
//! `.vdb` files).

pub mod exr;
pub mod npy;
pub mod png;
pub mod table;
pub mod vdb;
