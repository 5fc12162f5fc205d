//! CPU time of the calling thread, shared by the cost examples.

/// CPU time of this thread, ns (scheduler accounting: exact over many steps, coarse for one); 0 where
/// `/proc/thread-self/schedstat` does not exist (not Linux).
pub fn cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(0)
}
