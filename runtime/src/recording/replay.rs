//! Replaying one agent against its recording (`orchestrator replay RUN_DIR --agent I`): the
//! debugging loop for one spacecraft's software. Agent i's algorithm is built from the run's
//! scenario as the agent process builds it and driven by the same driver (`drive::run_agent`),
//! over a transport ([`ReplayTransport`]) that hands it the recorded measurements and neighbour
//! shares and compares every share it sends with the one the live agent sent.
//!
//! **Pacing.** The recorded inputs are handed over in step order (stable, so the order the live
//! agent saw is kept within a step), gated like lockstep: messages of steps up to one past the
//! last share the agent sent (step 0 at the start). That is what the live agent could have had
//! at each wait; the driver's results never depend on which of those arrived first, which the
//! multi-process runs' bit-identity with the in-process reference shows. When the agent waits
//! for more than the gate lets through (a roster change after a fault skips steps), the gate
//! opens to the next recorded message; when nothing is left, the replay ends there (a recording
//! of an agent that stopped early ends so).
//!
//! **A relaunched agent** (`restart` fault) records to a file of its own, `agent-<i>.<n>.mcap`,
//! carrying the checkpoint it resumed from as the attachment [`super::RESTORED_FROM`]. Its replay
//! restores that state into a freshly built algorithm and hands it to the driver as the process
//! did (`run_agent(.., Some(checkpoint))`), so every incarnation replays on its own.
//!
//! **Comparison.** Every share sent is compared with the recorded one at the same place, byte for
//! byte over the whole wire payload except the header's `mac` (a tag under the run's key, which is
//! never stored; the replay sends unsealed). Sent shares were recorded before the transport stamps
//! `sent_wall_ns`, so that is 0 on both sides.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use cohort_wire::layout::{self, Payload};
use cohort_wire::msg::{Measurement, RunControl, Share, Status};
use cohort_wire::transport::{DataPath, Incoming, RunControlPort, TransportError};

use super::Direction;
use super::reader::{Msg, ReadError, Recorded, RecordingFile};
use crate::checkpoint::Checkpoint;
use crate::drive::{DriveParams, SpinPolicy, run_agent};
use crate::model::Algorithm;
use crate::paper::Setup;
use crate::record::RunDirs;

/// The first share that differs from its recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Mismatch {
    /// Its place among the shares the agent sent (0-based).
    pub index: usize,
    pub step: u64,
    /// The differing element (`values[3]`, `header.step`) and its first differing byte.
    pub field: String,
    pub offset: usize,
    pub recorded: String,
    pub replayed: String,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "share of step {} (share #{} sent) differs at byte {} ({}): recorded {}, replayed {}",
            self.step,
            self.index + 1,
            self.offset,
            self.field,
            self.recorded,
            self.replayed
        )
    }
}

/// What a replay found.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayOutcome {
    /// Steps the replayed agent completed.
    pub steps: u64,
    /// Shares the live agent sent (data shares and step tokens), and the replay.
    pub recorded_sent: usize,
    pub replayed_sent: usize,
    /// Of the shares sent at the same place, how many were identical.
    pub identical: usize,
    pub first: Option<Mismatch>,
    /// How the replayed agent ended when not by finishing every step or running out of recorded
    /// input (a timeout, a divergence).
    pub error: Option<String>,
    /// A relaunched agent's recording: the step of the checkpoint the replay resumed from.
    pub restored_from: Option<u64>,
}

impl ReplayOutcome {
    /// Every share identical and none missing or extra.
    pub fn identical(&self) -> bool {
        self.first.is_none() && self.error.is_none() && self.recorded_sent == self.replayed_sent
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error("{}: written by {who}, not agent {want}", path.display())]
    NotThisAgent { path: std::path::PathBuf, who: String, want: u32 },
    #[error("{}: cannot create the replay's output directory: {source}", path.display())]
    Out { path: std::path::PathBuf, source: std::io::Error },
    #[error("{}: its attachment {}: {reason}", path.display(), super::RESTORED_FROM)]
    Checkpoint { path: std::path::PathBuf, reason: String },
}

/// Replay agent `id` of `setup` against `rec`; the replayed agent's telemetry, timing and
/// checkpoints go to `out`.
pub fn replay_agent(setup: &Setup, rec: &RecordingFile, id: u32, out: &RunDirs) -> Result<ReplayOutcome, ReplayError> {
    let run_id = rec.run_id()?;
    let who = rec.id()?;
    if who != id {
        let who = super::proc_of(who).name();
        return Err(ReplayError::NotThisAgent { path: rec.path.clone(), who, want: id });
    }
    out.create_all().map_err(|source| ReplayError::Out { path: out.root.clone(), source })?;
    let params = DriveParams::from_setup(setup, run_id, out.clone(), Arc::new(AtomicBool::new(false)), Instant::now());
    // The same construction as the agent process's (`agent/src/main.rs`).
    let mut algo = setup.algorithm.build(setup, id);
    let neighbours = setup.agent(id).neighbours.clone();
    let restore = match rec.attachment(super::RESTORED_FROM) {
        Some(a) => {
            let bad = |reason: String| ReplayError::Checkpoint { path: rec.path.clone(), reason };
            let c = Checkpoint::decode(&a.data, run_id, id, &params.algorithm_kind).map_err(|e| bad(e.to_string()))?;
            algo.restore_state(&c.state.algorithm).map_err(|e| bad(format!("algorithm state: {e}")))?;
            Some(c)
        }
        None => None,
    };
    Ok(replay_with(algo.as_mut(), id, &neighbours, params, rec, restore.as_ref()))
}

/// Replay agent `id` running `algo` with the settings `params` (its run id must be the
/// recording's) against `rec`; `restore`: the checkpoint `algo` was restored from (a relaunched
/// agent's recording), which the driver resumes after as the agent process does.
pub fn replay_with(
    algo: &mut dyn Algorithm,
    id: u32,
    neighbours: &[u32],
    mut params: DriveParams,
    rec: &RecordingFile,
    restore: Option<&Checkpoint>,
) -> ReplayOutcome {
    // Every wait that is not complete at once asks the transport for more (see `wait`).
    params.spin = SpinPolicy::Fixed(Duration::ZERO);
    params.key = None;
    let mut t = ReplayTransport::new(rec);
    let report = run_agent(&mut t, algo, id, neighbours, &params, restore);
    let error = match &report.error {
        Some(_) if t.exhausted && t.replayed_sent >= t.recorded_sent.len() => None,
        Some(e) => Some(e.to_string()),
        None => None,
    };
    ReplayOutcome {
        steps: report.steps_completed,
        recorded_sent: t.recorded_sent.len(),
        replayed_sent: t.replayed_sent,
        identical: t.identical,
        first: t.first,
        error,
        restored_from: restore.map(|c| c.step),
    }
}

/// The transport of a replay: recorded inputs in, shares compared on the way out.
pub struct ReplayTransport<'r> {
    /// Received messages, stably sorted by step.
    inputs: Vec<&'r Recorded>,
    cursor: usize,
    /// Messages of steps up to this one may be handed over.
    gate: u64,
    recorded_sent: Vec<&'r Share>,
    replayed_sent: usize,
    identical: usize,
    first: Option<Mismatch>,
    /// The agent waited with nothing left to hand over.
    exhausted: bool,
}

impl<'r> ReplayTransport<'r> {
    pub fn new(rec: &'r RecordingFile) -> Self {
        let mut inputs: Vec<&Recorded> = rec.messages.iter().filter(|m| m.dir == Direction::Received).collect();
        inputs.sort_by_key(|m| m.msg.step());
        let recorded_sent = rec
            .messages
            .iter()
            .filter(|m| m.dir == Direction::Sent)
            .filter_map(|m| match &m.msg {
                Msg::Share { share, .. } => Some(&**share),
                Msg::Measurement(_) => None,
            })
            .collect();
        Self {
            inputs,
            cursor: 0,
            gate: 0,
            recorded_sent,
            replayed_sent: 0,
            identical: 0,
            first: None,
            exhausted: false,
        }
    }

    fn compare(&mut self, s: &Share) {
        let index = self.replayed_sent;
        self.replayed_sent += 1;
        let Some(recorded) = self.recorded_sent.get(index) else { return };
        match first_difference(layout::share_bytes(recorded), layout::share_bytes(s)) {
            None => self.identical += 1,
            Some(offset) if self.first.is_none() => {
                let (field, prim, start) = layout::locate(Payload::Share, offset).expect("inside the payload");
                let end = start + prim.size();
                self.first = Some(Mismatch {
                    index,
                    step: recorded.header.step,
                    field,
                    offset,
                    recorded: prim.show(&layout::share_bytes(recorded)[start..end]),
                    replayed: prim.show(&layout::share_bytes(s)[start..end]),
                });
            }
            Some(_) => {}
        }
    }
}

/// The first byte where two shares differ, the `mac` left out.
fn first_difference(a: &[u8], b: &[u8]) -> Option<usize> {
    let mac = layout::mac_range();
    a.iter().zip(b).enumerate().find(|(i, (x, y))| x != y && !mac.contains(i)).map(|(i, _)| i)
}

impl DataPath for ReplayTransport<'_> {
    fn send_measurement(&mut self, _to: u32, _m: &Measurement) -> Result<(), TransportError> {
        Err(TransportError::Other("a replayed agent sends no measurement".into()))
    }
    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        self.compare(s);
        self.gate = self.gate.max(s.header.step.saturating_add(1));
        Ok(())
    }
    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        while let Some(r) = self.inputs.get(self.cursor).filter(|r| r.msg.step() <= self.gate) {
            match &r.msg {
                Msg::Measurement(m) => f(Incoming::Measurement(m)),
                Msg::Share { from, share } => f(Incoming::Share { from: *from, share }),
            }
            self.cursor += 1;
        }
        Ok(())
    }
    fn wait(&mut self, _timeout: Duration) -> Result<(), TransportError> {
        match self.inputs.get(self.cursor) {
            Some(next) => {
                self.gate = self.gate.max(next.msg.step());
                Ok(())
            }
            None => {
                self.exhausted = true;
                Err(TransportError::Other("the recording holds no more input for this agent".into()))
            }
        }
    }
}

impl RunControlPort for ReplayTransport<'_> {
    fn report(&mut self, _s: &Status) {}
    fn stop_requested(&mut self) -> bool {
        false
    }
    fn start_granted(&mut self) -> bool {
        true
    }
    fn control_events(&mut self, _out: &mut Vec<RunControl>) {}
}
