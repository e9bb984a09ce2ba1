//! How a run ended: one type for the supervisor, the orchestrator, the verdict and the papers'
//! campaigns, written to `summary.json` (`"status"`) under the names users' scripts and the
//! Python loader read.

use serde::{Serialize, Serializer};

/// How a run ended, with the orchestrator's exit code for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunStatus {
    /// Every step completed, nothing lost.
    Ok,
    /// An agent was lost unplanned and the run went on without it to the end
    /// (`run.on_agent_loss = "degrade"`).
    Degraded,
    /// A process's model went non-finite; `expected` when the scenario is a divergence study
    /// (`scenario.expect = "diverge"`), which ends so by design.
    Diverged { expected: bool },
    /// A process failed (crash, timeout, invalid message, …) or the run could not start.
    Failed,
    /// The orchestrator was stopped by this signal; every child was stopped in order.
    Interrupted(i32),
    /// The orchestrator was killed; `orchestrator salvage` wrote the summary afterwards from
    /// what the processes left.
    Salvaged,
}

impl RunStatus {
    /// The name in `summary.json` and in messages: "ok", "degraded", "diverged", "failed",
    /// "interrupted" or "salvaged".
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Degraded => "degraded",
            Self::Diverged { .. } => "diverged",
            Self::Failed => "failed",
            Self::Interrupted(_) => "interrupted",
            Self::Salvaged => "salvaged",
        }
    }

    /// The orchestrator's exit code: 0 a completed run (or an expected divergence), 128 + N a
    /// run stopped by signal N, 1 any other end (a salvaged run did not end in order).
    pub fn exit_code(self) -> u8 {
        match self {
            Self::Ok | Self::Diverged { expected: true } => 0,
            Self::Interrupted(sig) => 128u8.wrapping_add(sig as u8),
            Self::Degraded | Self::Diverged { expected: false } | Self::Failed | Self::Salvaged => 1,
        }
    }

    /// Stopped by a signal.
    pub fn is_interrupted(self) -> bool {
        matches!(self, Self::Interrupted(_))
    }
}

impl std::fmt::Display for RunStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for RunStatus {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::RunStatus;

    #[test]
    fn names_in_summary_json_and_exit_codes() {
        let cases = [
            (RunStatus::Ok, "\"ok\"", 0),
            (RunStatus::Degraded, "\"degraded\"", 1),
            (RunStatus::Diverged { expected: false }, "\"diverged\"", 1),
            (RunStatus::Diverged { expected: true }, "\"diverged\"", 0),
            (RunStatus::Failed, "\"failed\"", 1),
            (RunStatus::Interrupted(2), "\"interrupted\"", 130),
            (RunStatus::Interrupted(15), "\"interrupted\"", 143),
            (RunStatus::Interrupted(1), "\"interrupted\"", 129),
            (RunStatus::Salvaged, "\"salvaged\"", 1),
        ];
        for (status, json, code) in cases {
            assert_eq!(serde_json::to_string(&status).unwrap(), json, "{status:?}");
            assert_eq!(format!("\"{status}\""), json, "{status:?}");
            assert_eq!(status.exit_code(), code, "{status:?}");
        }
    }
}
