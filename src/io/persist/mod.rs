//! Persistence of runs in progress: the per-batch tally sums of a part of a run for `ohd merge`
//! ([`shard`]) and the state of a run for `--resume` ([`checkpoint`]), in one binary codec
//! (`binary`). Both carry the [`config_fingerprint`] of the configuration they belong to.

mod binary;
pub mod checkpoint;
pub mod shard;

/// Whether `v` can be a tally sum, mean or sum of squared deviations read back from a shard or a
/// checkpoint: finite and at most 1e100 in magnitude. A batch sums at most 2⁴⁸ paths' weights (of
/// order 1, at most 1/`run.roulette_survival` ≤ 10⁶ after roulette), so no run comes near; a file
/// whose checksum was rewritten over larger values would overflow the standard errors (issue 33's
/// deep sweep: merged and resumed to exit 1 instead of being refused as the corrupt input).
pub(crate) fn plausible(v: f64) -> bool {
    v.is_finite() && v.abs() <= 1e100
}

/// FNV-1a (64 bit) of `text`: the fingerprint of a configuration.
pub fn fingerprint(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The fingerprint of the configuration as run, without `run.threads` (results do not depend
/// on it, so a run may resume, or a shard run, on another thread count).
pub fn config_fingerprint(table: &toml::Table) -> u64 {
    let mut t = table.clone();
    if let Some(toml::Value::Table(run)) = t.get_mut("run") {
        run.remove("threads");
    }
    fingerprint(&toml::to_string(&t).unwrap_or_default())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprints_differ_and_ignore_threads() {
        assert_ne!(fingerprint("a = 1"), fingerprint("a = 2"));
        let t = |s: &str| -> toml::Table { s.parse().unwrap() };
        let a = config_fingerprint(&t("[run]\nseed = 1\nthreads = 1\n"));
        assert_eq!(a, config_fingerprint(&t("[run]\nseed = 1\nthreads = 4\n")));
        assert_ne!(a, config_fingerprint(&t("[run]\nseed = 2\nthreads = 1\n")));
    }
}
