//! Process supervision and the multi-host machinery (moved out of the orchestrator binary).

/// `eprintln!` that never panics (a closed or full stderr): a failed write must not end a run
/// early or change its exit code.
macro_rules! errln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

pub mod daemon;
pub mod hostproto;
pub mod netlab;
pub mod remote;
pub mod supervise;
pub mod zping;

// The orchestrator's exit codes, which the host daemon returns.
const EXIT_FAILED: u8 = 1;
const EXIT_INVALID: u8 = 2;
