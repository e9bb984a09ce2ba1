//! The `Transport` abstraction: what a plant or agent process needs of messaging, and nothing
//! more, in two parts: the [`DataPath`] (measurements and shares, and waiting for them) and the
//! [`RunControlPort`] (the orchestrator's start, stop and roster notices in, this process's status
//! out). A [`Transport`] is both; [`Split`] joins a data path and a control port of different
//! kinds. Implementations: iceoryx2 zero-copy publish–subscribe ([`iox`], both parts), UDP
//! loopback datagrams ([`udp`], data path only, with iceoryx2 run control) and in-memory inboxes
//! for threads of one process ([`memory`], both parts), and zenoh publish–subscribe over TCP for runs
//! across machines ([`zenoh`], both parts). The orchestrator's side of run control is a
//! [`ControlHub`] (iceoryx2's `IoxServices`, zenoh's `ZenohHub`). The step drivers in `cohort-runtime` are
//! generic over it, so the multi-process run and the in-process reference run execute the same
//! code; `tests/conformance.rs` runs one suite against every implementation.

mod doorbell;
pub mod gateway;
pub mod iox;
pub mod memory;
pub mod udp;
pub mod zenoh;
pub mod zenoh_security;

use std::time::Duration;

use crate::msg::{Measurement, Roster, RunControl, Share, Status};

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
    /// Stopped on request (a signal) while opening, before any step: not a failure.
    #[error("stopped on request while {0}")]
    Stopped(String),
}

impl TransportError {
    /// An iceoryx2 failure. iceoryx2 reports running out of descriptors as an opaque internal
    /// failure, so when this process is at its open-file limit the detail says that instead.
    pub fn iox(what: impl Into<String>, detail: impl std::fmt::Debug) -> Self {
        let detail = match crate::limits::fd_exhaustion_note() {
            Some(note) => format!("{detail:?} ({note})"),
            None => format!("{detail:?}"),
        };
        TransportError::Iox { what: what.into(), detail }
    }
}

/// The data path of one process: measurements plant → agent, shares agent → plant and readers.
pub trait DataPath {
    /// Plant only: publish agent `to`'s measurement and wake it.
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError>;
    /// Agent only: publish this agent's share and wake the plant and every reader of it.
    fn send_share(&mut self, s: &Share) -> Result<(), TransportError>;
    /// Hand every message received so far to `f` (FIFO per sender), without blocking.
    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError>;
    /// Block until a wakeup arrives or `timeout` passes; may return early. Callers re-poll with
    /// [`Transport::drain`] after every return, because a wakeup can be lost (a sender that dies
    /// between its message and its wakeup): waits are bounded and repeated, never one long one.
    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError>;
    /// Whether a [`DataPath::drain`] may find something new: `false` only where the transport
    /// knows that nobody rang since the last drain (iceoryx2's doorbells, one line of this
    /// process's own), so a spinning process can yield again without draining; any other always
    /// says yes.
    fn rung(&self) -> bool {
        true
    }
    /// Whether a process must keep its ports open after its last step until the orchestrator's
    /// stop request (it sends one as soon as the plant has finished), because a message it sent
    /// can still be lost when it leaves: an iceoryx2 sample lives in its publisher's segment,
    /// which a reader that has not mapped it yet (in a one-step run, the plant at its first
    /// receive) can no longer reach once the publisher is gone.
    fn keeps_ports_until_stopped(&self) -> bool {
        false
    }
    /// Whether [`DataPath::wait`] also returns as soon as the orchestrator publishes a run-control
    /// notice (a stop, a resume, a roster change), not only when a message arrives: then a
    /// process waiting for its peers need not wake up every few milliseconds to look at the
    /// control port. iceoryx2: the orchestrator rings every doorbell after a notice. A thousand
    /// agent processes on two cores each re-polling every 10 ms of a 150 ms step woke ≈ 8 times
    /// per step instead of ≈ 2, and that was most of the step.
    fn woken_by_control(&self) -> bool {
        false
    }
    /// Whether the run-control port may hold something new since the last call. A data path
    /// [`woken_by_control`](DataPath::woken_by_control) knows (run control rang its doorbell,
    /// or a wait ended without any ring), so a process that wakes for its peers' messages need
    /// not also read the control service each time; any other always says yes.
    fn control_rung(&mut self) -> bool {
        true
    }
    /// A word the plant publishes to every process of its host, and through the gateways to
    /// the other hosts' (adaptive waiting's choice, encoded by the runtime), 0 when none was
    /// published or the transport has no such place.
    fn wait_advice(&self) -> u64 {
        0
    }
    /// The plant only: publish [`DataPath::wait_advice`] (non-zero); a no-op where there is no
    /// such place.
    fn set_wait_advice(&self, _advice: u64) {}
}

/// The run-control port of one process: the orchestrator's requests in, its status out.
pub trait RunControlPort {
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

/// The orchestrator's side of run control: requests out to every process, status in. One per
/// run; `IoxServices` (iceoryx2) and `zenoh::ZenohHub` implement it.
pub trait ControlHub {
    /// Ask every process to stop (a process that opens its ports later still sees it where the
    /// transport keeps history: iceoryx2 does, zenoh does not, and the supervisor signals anyway).
    fn request_stop(&self) -> Result<(), TransportError>;
    /// Tell the plant that every process is ready (see [`RunControlPort::start_granted`]).
    fn grant_start(&self) -> Result<(), TransportError>;
    /// Let the plant go on past the hold at `step`, with these roster changes.
    fn resume(&self, step: u64, dead: Roster, alive: Roster) -> Result<(), TransportError>;
    /// Tell the plant these agents died outside the fault plan.
    fn report_dead(&self, dead: Roster) -> Result<(), TransportError>;
    /// Hand every status received so far to `f`; messages of another version or run, or with a
    /// wrong tag when the run has a key, are skipped and counted ([`ControlHub::rejected`]).
    fn poll_status(&self, f: &mut dyn FnMut(&Status)) -> Result<(), TransportError>;
    /// Status messages dropped so far.
    fn rejected(&self) -> u64;
}

/// One process's messaging endpoint: a data path and a run-control port.
pub trait Transport: DataPath + RunControlPort {}

impl<T: DataPath + RunControlPort + ?Sized> Transport for T {}

/// A data path and a run-control port of different kinds as one [`Transport`] (UDP data with
/// iceoryx2 run control). `data` is dropped before `control`, which may own what the data ports
/// were opened on (an iceoryx2 node).
pub struct Split<D, C> {
    pub data: D,
    pub control: C,
}

impl<D: DataPath, C> DataPath for Split<D, C> {
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError> {
        self.data.send_measurement(to, m)
    }
    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        self.data.send_share(s)
    }
    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        self.data.drain(f)
    }
    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        self.data.wait(timeout)
    }
    fn rung(&self) -> bool {
        self.data.rung()
    }
    fn keeps_ports_until_stopped(&self) -> bool {
        self.data.keeps_ports_until_stopped()
    }
    fn woken_by_control(&self) -> bool {
        self.data.woken_by_control()
    }
    fn control_rung(&mut self) -> bool {
        self.data.control_rung()
    }
    fn wait_advice(&self) -> u64 {
        self.data.wait_advice()
    }
    fn set_wait_advice(&self, advice: u64) {
        self.data.set_wait_advice(advice);
    }
}

impl<D, C: RunControlPort> RunControlPort for Split<D, C> {
    fn report(&mut self, s: &Status) {
        self.control.report(s);
    }
    fn stop_requested(&mut self) -> bool {
        self.control.stop_requested()
    }
    fn start_granted(&mut self) -> bool {
        self.control.start_granted()
    }
    fn control_events(&mut self, out: &mut Vec<RunControl>) {
        self.control.control_events(out);
    }
}

/// The bytes of a plain-old-data payload (datagrams and zenoh samples carry them as they are).
pub(crate) fn bytes_of<T: Copy>(x: &T) -> &[u8] {
    // SAFETY: T is one of the `#[repr(C)]` payloads of `msg`, made only of integers and floats;
    // every byte is initialised (constructors fill every field, padding included, as they build
    // from zeroed arrays and the headers have no padding).
    unsafe { std::slice::from_raw_parts((x as *const T).cast::<u8>(), std::mem::size_of::<T>()) }
}

/// A payload read back from received bytes (`bytes.len() == size_of::<T>()`, checked by callers).
pub(crate) fn read_payload<T: Copy>(bytes: &[u8]) -> T {
    assert_eq!(bytes.len(), std::mem::size_of::<T>());
    // SAFETY: the length matches, and every bit pattern is a valid value of these payloads
    // (integers and floats only); read_unaligned copes with any alignment.
    unsafe { std::ptr::read_unaligned(bytes.as_ptr().cast::<T>()) }
}

/// A payload from the first `bytes.len()` of its bytes, the rest zero (`bytes.len() <=
/// size_of::<T>()`, checked by callers): the gateways send a message without its zero tail.
pub(crate) fn read_payload_prefix<T: Copy>(bytes: &[u8]) -> T {
    assert!(bytes.len() <= std::mem::size_of::<T>());
    let mut out = std::mem::MaybeUninit::<T>::zeroed();
    // SAFETY: at most size_of::<T>() bytes are copied into the zeroed value, and every bit
    // pattern is a valid value of these payloads (integers and floats only).
    unsafe {
        std::ptr::copy_nonoverlapping(bytes.as_ptr(), out.as_mut_ptr().cast::<u8>(), bytes.len());
        out.assume_init()
    }
}

/// CLOCK_MONOTONIC in ns: system-wide, so send and receive stamps of two processes compare.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes into the timespec we own; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}
