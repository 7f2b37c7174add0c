//! What the operating system allows this process, read when an experiment is resolved: the
//! memory it may still take (issue 33: under `ulimit -v` a 2048² image aborted in the allocator,
//! because the default budget of 8 GiB ignored the process's limit).

/// The memory this process may still take under its tightest limit, and that limit's name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryLimit {
    /// Bytes that may be budgeted: [`SHARE`] of what is left under the limit.
    pub available: u64,
    /// The limit, as a user would look it up.
    pub source: &'static str,
}

/// Share of the memory left under a limit that a run's budget may take: the rest is for what the
/// budget does not count (the program, thread stacks, the allocator's arenas).
pub const SHARE: f64 = 0.75;

/// The tightest of the address-space limit (`ulimit -v`), the data limit (`ulimit -d`) and the
/// memory limit of the process's cgroup (v2, `memory.max` of it and its ancestors), as what is
/// left under it; `None` without any.
pub fn memory_limit() -> Option<MemoryLimit> {
    use rustix::process::{Resource, getrlimit};
    let page = rustix::param::page_size() as u64;
    // /proc/self/statm: sizes in pages, the first the address space, the sixth data + stack.
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let field = |i: usize| statm.split_whitespace().nth(i).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0) * page;
    let mut limits = vec![];
    if let Some(max) = getrlimit(Resource::As).current {
        limits.push((max.saturating_sub(field(0)), "the address-space limit (ulimit -v, RLIMIT_AS)"));
    }
    if let Some(max) = getrlimit(Resource::Data).current {
        limits.push((max.saturating_sub(field(5)), "the data limit (ulimit -d, RLIMIT_DATA)"));
    }
    if let Some(left) = cgroup_left() {
        limits.push((left, "the memory limit of this process's cgroup (memory.max)"));
    }
    let (left, source) = limits.into_iter().min_by_key(|l| l.0)?;
    Some(MemoryLimit { available: (left as f64 * SHARE) as u64, source })
}

/// What is left under `memory.max` of this process's cgroup (v2) and its ancestors, bytes.
fn cgroup_left() -> Option<u64> {
    let own = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let path = own.lines().find_map(|l| l.strip_prefix("0::"))?.trim();
    let mut dir = std::path::PathBuf::from("/sys/fs/cgroup").join(path.trim_start_matches('/'));
    let mut left: Option<u64> = None;
    loop {
        let read = |name: &str| std::fs::read_to_string(dir.join(name)).ok();
        let max = read("memory.max").and_then(|m| m.trim().parse::<u64>().ok());
        let current = read("memory.current").and_then(|c| c.trim().parse::<u64>().ok()).unwrap_or(0);
        if let Some(max) = max {
            let here = max.saturating_sub(current);
            left = Some(left.map_or(here, |l| l.min(here)));
        }
        if dir == std::path::Path::new("/sys/fs/cgroup") || !dir.pop() {
            return left;
        }
    }
}
