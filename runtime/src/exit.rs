//! The exit codes of Cohort's binaries and the one mapping from an outcome or an error to its
//! code ([`ToExitCode`]). Every `main` (orchestrator, plant, agent) and every error type that
//! ends one implements it, so a kind of failure has the same code wherever it is met and no
//! caller matches variants to numbers by hand.
//!
//! The orchestrator's codes are 0 done, 1 failed, 2 invalid input and 128 + N stopped by signal
//! N ([`RunStatus::exit_code`]); a child process (plant, agent) adds 3 (built from other
//! sources than the orchestrator) and 4 (stopped on request), which the supervisor reads.

use cohort_scenario::ScenarioError;

use crate::run_status::RunStatus;

/// Done: every step completed (or the work asked for was done).
pub const OK: u8 = 0;
/// The run or the work failed (timeout, crash, transport or I/O error, a failed check).
pub const FAILED: u8 = 1;
/// Bad input: a scenario, argument or file, named on stderr.
pub const INVALID: u8 = 2;
/// A child built from other sources than the orchestrator (build id mismatch).
pub const BUILD_MISMATCH: u8 = 3;
/// A child stopped on request (stop message or SIGTERM) before the end.
pub const STOPPED: u8 = 4;

/// The exit code a binary ends with when this is its outcome.
pub trait ToExitCode {
    fn exit_code(&self) -> u8;

    /// As the `main`'s return value.
    fn to_exit(&self) -> std::process::ExitCode {
        std::process::ExitCode::from(self.exit_code())
    }
}

impl ToExitCode for RunStatus {
    fn exit_code(&self) -> u8 {
        RunStatus::exit_code(*self)
    }
}

/// An invalid scenario is bad input.
impl ToExitCode for ScenarioError {
    fn exit_code(&self) -> u8 {
        INVALID
    }
}

/// Bad `--tls-*`/`--auth-file` settings are bad input.
impl ToExitCode for cohort_wire::transport::zenoh_security::SecurityConfigError {
    fn exit_code(&self) -> u8 {
        INVALID
    }
}

/// A child's end: stopped on request, or failed.
impl ToExitCode for crate::record::ProcessError {
    fn exit_code(&self) -> u8 {
        if self.is_stop() { STOPPED } else { FAILED }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_distinct_and_run_status_agrees() {
        let codes = [OK, FAILED, INVALID, BUILD_MISMATCH, STOPPED];
        for (i, a) in codes.iter().enumerate() {
            assert!(codes[i + 1..].iter().all(|b| a != b), "{a} twice");
        }
        assert_eq!(ToExitCode::exit_code(&RunStatus::Ok), OK);
        assert_eq!(ToExitCode::exit_code(&RunStatus::Failed), FAILED);
        assert_eq!(ToExitCode::exit_code(&RunStatus::Interrupted(15)), 143);
        let stop = crate::record::ProcessError::new(crate::record::ErrorKind::Stopped, "stopped");
        assert_eq!(stop.exit_code(), STOPPED);
        let io = crate::record::ProcessError::new(crate::record::ErrorKind::Io, "disk full");
        assert_eq!(io.exit_code(), FAILED);
    }
}
