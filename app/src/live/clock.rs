//! The host's wall clock, which live frames and the fake cameras are
//! stamped with.

/// The host's wall clock: ns since the Unix epoch.
pub(crate) fn host_now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}
