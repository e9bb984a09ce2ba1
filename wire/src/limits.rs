//! Open-file limits: every iceoryx2 port holds several descriptors (service files, shared-memory
//! segments, port tags), so a run's descriptor count grows with its number of agents, the plant's
//! fastest. iceoryx2 reports running out of them as an opaque `InternalFailure`; these helpers let
//! the run say "too many open files" instead, and let the orchestrator raise its soft limit and
//! refuse up front a scenario that cannot fit.

/// (soft, hard) `RLIMIT_NOFILE` of this process.
pub fn nofile_limit() -> (u64, u64) {
    let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: getrlimit writes into the struct we own.
    unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut r) };
    (r.rlim_cur, r.rlim_max)
}

/// Raise the soft `RLIMIT_NOFILE` to the hard limit (children inherit it). Returns the soft limit
/// in force afterwards.
pub fn raise_nofile_to_hard() -> u64 {
    let (soft, hard) = nofile_limit();
    if soft < hard {
        let r = libc::rlimit { rlim_cur: hard, rlim_max: hard };
        // SAFETY: setrlimit with a struct we own; raising the soft limit up to the hard one is
        // always permitted.
        unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &r) };
    }
    nofile_limit().0
}

/// Descriptors this process has open now (0 if /proc is not there).
pub fn open_fds() -> u64 {
    std::fs::read_dir("/proc/self/fd").map_or(0, |d| d.count() as u64)
}

/// When this process is at (or within a few descriptors of) its open-file limit, the sentence
/// that says so; an opaque failure of a library that needed a descriptor is then most likely
/// EMFILE.
pub fn fd_exhaustion_note() -> Option<String> {
    let (soft, _) = nofile_limit();
    let open = open_fds();
    (open + 16 >= soft).then(|| {
        format!("too many open files: this process has {open} open and the limit is {soft}; raise it with ulimit -n")
    })
}

/// Descriptors the busiest process of a run with `n_agents` agents needs, about: the plant holds
/// a measurement publisher, a share subscriber and a wakeup notifier per agent, ≈ 18 descriptors
/// per agent (measured with iceoryx2 0.10: 395 at N = 20, 935 at N = 50),
/// plus a fixed part; `spare` relaunch slots add little. A 5 % margin on top.
pub fn descriptors_needed(n_agents: u32, spare: u32) -> u64 {
    let per_process = 18 * u64::from(n_agents) + 40 + 4 * u64::from(spare);
    per_process + per_process / 20
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_estimate_grows_with_n_and_fits_the_default_soft_limit_only_for_small_runs() {
        assert!(descriptors_needed(6, 0) < 1024);
        assert!(descriptors_needed(50, 0) < 1024);
        assert!(descriptors_needed(100, 0) > 1024, "N = 100 failed at ulimit -n 1024 (issue 18)");
        assert!(descriptors_needed(200, 0) > descriptors_needed(100, 0));
    }

    #[test]
    fn limits_and_counts_are_read() {
        let (soft, hard) = nofile_limit();
        assert!(soft > 0 && soft <= hard);
        assert!(open_fds() >= 3);
    }
}
