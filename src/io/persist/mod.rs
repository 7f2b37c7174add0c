//! Persistence of runs in progress: the per-batch tally sums of a part of a run for `ohd merge`
//! ([`shard`]) and the state of a run for `--resume` ([`checkpoint`]), in one binary codec
//! ([`binary`]).

mod binary;
pub mod checkpoint;
pub mod shard;
