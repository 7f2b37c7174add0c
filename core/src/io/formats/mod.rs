//! File formats: `.npy` arrays ([`npy`]), OpenEXR images ([`exr`]), PNG encoding ([`png`]),
//! phase-function tables ([`table`]), the OpenVDB reader ([`vdb`], the only place that reads
//! `.vdb` files) and writer ([`vdb_write`]: float grids, for the volume tallies), cardiac
//! waveform tables ([`waveform`]).

pub mod exr;
pub mod npy;
pub mod png;
pub mod table;
pub mod vdb;
pub mod vdb_write;
pub mod waveform;
