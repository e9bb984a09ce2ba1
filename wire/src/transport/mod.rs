//! The `Transport` abstraction: what a plant or agent process needs of messaging, and nothing
//! more. Two implementations sit behind it: [`iox::IoxTransport`] (iceoryx2 zero-copy
//! publish–subscribe between processes) and [`memory::MemoryTransport`] (threads of one process).
//! The step drivers in `cohort-runtime` are generic over it, so the multi-process run and the
//! in-process reference run execute the same code.

pub mod iox;
pub mod memory;
pub mod udp;

use std::time::Duration;

use crate::msg::{Measurement, RunControl, Share, Status};

/// Which process an endpoint belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Proc {
    Plant,
    /// Agent id, 1..=N.
    Agent(u32),
}

impl Proc {
    /// Stable short name used for files (`telemetry/agent-3.csv`) and iceoryx2 node names.
    pub fn name(self) -> String {
        match self {
            Proc::Plant => "plant".to_string(),
            Proc::Agent(i) => format!("agent-{i}"),
        }
    }
    pub fn sender_id(self) -> u32 {
        match self {
            Proc::Plant => crate::msg::PLANT_ID,
            Proc::Agent(i) => i,
        }
    }
}

/// The communication graph, as far as messaging is concerned: who listens to whom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topology {
    /// `neighbours[i - 1]`: the agents whose shares agent i reads.
    pub neighbours: Vec<Vec<u32>>,
}

impl Topology {
    pub fn n_agents(&self) -> u32 {
        self.neighbours.len() as u32
    }
    pub fn neighbours_of(&self, id: u32) -> &[u32] {
        &self.neighbours[(id - 1) as usize]
    }
    /// The agents that read agent `id`'s share (besides the plant, which reads every share).
    pub fn readers_of(&self, id: u32) -> Vec<u32> {
        (1..=self.n_agents()).filter(|&j| self.neighbours_of(j).contains(&id)).collect()
    }
    /// How many processes send wakeups to `p`.
    pub fn senders_to(&self, p: Proc) -> usize {
        match p {
            Proc::Plant => self.n_agents() as usize,
            Proc::Agent(i) => 1 + self.neighbours_of(i).len(),
        }
    }
}

/// A message handed to the driver by [`Transport::drain`]. `from` is the owner of the service
/// the message arrived on: the driver checks that the header's sender agrees.
pub enum Incoming<'a> {
    Measurement(&'a Measurement),
    Share { from: u32, share: &'a Share },
}

#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    #[error("iceoryx2 {what}: {detail}")]
    Iox { what: String, detail: String },
    #[error("{0}")]
    Other(String),
}

impl TransportError {
    pub fn iox(what: impl Into<String>, detail: impl std::fmt::Debug) -> Self {
        TransportError::Iox { what: what.into(), detail: format!("{detail:?}") }
    }
}

/// One process's messaging endpoint.
pub trait Transport {
    /// Plant only: publish agent `to`'s measurement and wake it.
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError>;
    /// Agent only: publish this agent's share and wake the plant and every reader of it.
    fn send_share(&mut self, s: &Share) -> Result<(), TransportError>;
    /// Hand every message received so far to `f` (FIFO per sender), without blocking.
    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError>;
    /// Block until a wakeup arrives or `timeout` passes; may return early. Callers re-poll with
    /// [`Transport::drain`] after every return, because a wakeup can be lost under heavy
    /// preemption (iceoryx2-notes.md): waits are always short and repeated, never one long one.
    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError>;
    /// Best-effort status to the orchestrator (progress, waiting, done).
    fn report(&mut self, s: &Status);
    /// Whether the orchestrator asked this process to stop.
    fn stop_requested(&mut self) -> bool;
    /// Whether every process of the run is ready, so the first message sent reaches its reader
    /// (iceoryx2 delivers nothing to a subscriber that does not exist yet). The plant polls this
    /// before step 0.
    fn start_granted(&mut self) -> bool;
    /// The plant only: the orchestrator's resume and dead-agent notices received so far
    /// (`CONTROL_RESUME`, `CONTROL_DEAD`), appended to `out`.
    fn control_events(&mut self, out: &mut Vec<RunControl>);
}

/// CLOCK_MONOTONIC in ns: system-wide, so send and receive stamps of two processes compare.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes into the timespec we own; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}
