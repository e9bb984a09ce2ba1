//! Fixed-size `#[repr(C)]` message payloads. No heap, no pointers: every type here can be placed
//! in iceoryx2 shared memory as is. Variable-length content sits in a bounded array with an
//! explicit length; the bound is checked when a scenario is validated, never discovered mid-run.
//!
//! Names say the direction: [`Measurement`] goes plant → agent, [`Share`] goes agent → plant and
//! neighbours, [`RunControl`] goes orchestrator → every process, [`Status`] goes process →
//! orchestrator.

use iceoryx2::prelude::ZeroCopySend;

/// Bumped whenever a payload's layout or meaning changes.
pub const SCHEMA_VERSION: u32 = 5;

/// Sender id of the plant. Agents are numbered 1..=N as in the scenario; the orchestrator is
/// [`ORCHESTRATOR_ID`].
pub const PLANT_ID: u32 = 0;
pub const ORCHESTRATOR_ID: u32 = u32::MAX;

/// Most sensor readings one measurement can carry.
pub const MAX_READINGS: usize = 64;
/// Most command components one share can carry (what the plant applies).
pub const MAX_COMMAND: usize = 8;
/// Most values one share can carry for the neighbours (e.g. gᵢuᵢ and θ̂ᵢ, or Uᵢ and Xᵢ).
pub const MAX_SHARE_VALUES: usize = 512;
/// Most agents in one scenario (service limits and ids are sized from the scenario below this).
/// A roster is a bit per agent in every measurement and run-control notice (2 × 128 bytes).
pub const MAX_AGENTS: usize = 1024;
/// Most neighbours whose links one measurement describes (`[links]` model `geometric`).
pub const MAX_LINKS_IN: usize = 64;
/// A link code of [`Measurement::links`]: below [`LINK_BLOCKED`], the whole steps the share the
/// neighbour sends at this step takes to arrive (0: within the step, as on an ideal link).
/// The line of sight is blocked by the occulting body.
pub const LINK_BLOCKED: u32 = u32::MAX;
/// The neighbour is farther than the link's maximum range.
pub const LINK_OUT_OF_RANGE: u32 = u32::MAX - 1;
/// In view, but the share is lost (the loss law's draw).
pub const LINK_LOST_IN_TRANSIT: u32 = u32::MAX - 2;
/// The link is still sending the neighbour's previous share (the data-rate cap): this one is
/// not sent.
pub const LINK_BUSY: u32 = u32::MAX - 3;

/// Common header of every payload (design.md "Messages").
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("cohort::Header")]
pub struct Header {
    pub version: u32,
    pub sender: u32,
    pub run_id: u64,
    pub step: u64,
    pub t_s: f64,
    /// CLOCK_MONOTONIC at send, ns; shared by all processes of one machine, used only for
    /// latency histograms (never for anything that reaches telemetry).
    pub sent_wall_ns: u64,
    /// Keyed MAC of the message (`run.authenticate`, see [`crate::auth`]); zero otherwise.
    pub mac: [u64; 2],
}

impl Header {
    pub fn new(run_id: u64, sender: u32, step: u64, t_s: f64) -> Self {
        Self { version: SCHEMA_VERSION, sender, run_id, step, t_s, sent_wall_ns: 0, mac: [0; 2] }
    }
}

/// Plant → agent i at step k: that agent's sensor readings (never the truth).
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("cohort::Measurement")]
pub struct Measurement {
    pub header: Header,
    pub len: u32,
    pub _pad: u32,
    pub readings: [f64; MAX_READINGS],
    /// The roster as of this step: bit (id − 1) set when agent id is live. It rides with the
    /// measurement rather than on a service of its own so that it is ordered with the step clock
    /// (the plant decides who is live while it closes a step; a separate service would race).
    pub live: Roster,
    /// Agents the plant declared dead while closing the previous step: their share of step − 1
    /// was not used (the plant waited it out or learnt that the process died). Every other
    /// roster change in `live` took effect at this step.
    pub lost_at_close: Roster,
    /// `[links]` model `geometric`: how many entries of `links` are used (0: ideal links).
    pub links_len: u32,
    pub _pad2: u32,
    /// Per neighbour of the receiving agent, in its scenario order: what becomes of the share
    /// that neighbour sends at this step (a delay in steps, or a `LINK_*` code). Decided by the
    /// plant from the truth, so it rides with the step clock like the roster.
    pub links: [u32; MAX_LINKS_IN],
}

/// A set of agent ids 1..=MAX_AGENTS as a bit mask.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("cohort::Roster")]
pub struct Roster(pub [u64; MAX_AGENTS / 64]);

impl Roster {
    pub const EMPTY: Roster = Roster([0; MAX_AGENTS / 64]);
    pub fn all(n: u32) -> Self {
        let mut r = Self::EMPTY;
        for id in 1..=n {
            r.set(id, true);
        }
        r
    }
    pub fn contains(&self, id: u32) -> bool {
        let b = (id as usize).wrapping_sub(1);
        b < MAX_AGENTS && self.0[b / 64] >> (b % 64) & 1 == 1
    }
    pub fn set(&mut self, id: u32, on: bool) {
        let b = (id as usize).wrapping_sub(1);
        if b < MAX_AGENTS {
            if on {
                self.0[b / 64] |= 1 << (b % 64);
            } else {
                self.0[b / 64] &= !(1 << (b % 64));
            }
        }
    }
    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|w| *w == 0)
    }
    pub fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        (1..=MAX_AGENTS as u32).filter(|&id| self.contains(id))
    }
}

impl Measurement {
    pub fn new(header: Header, readings: &[f64]) -> Self {
        assert!(readings.len() <= MAX_READINGS, "bound checked at scenario validation");
        let mut m = Self {
            header,
            len: readings.len() as u32,
            _pad: 0,
            readings: [0.0; MAX_READINGS],
            live: Roster::EMPTY,
            lost_at_close: Roster::EMPTY,
            links_len: 0,
            _pad2: 0,
            links: [0; MAX_LINKS_IN],
        };
        m.readings[..readings.len()].copy_from_slice(readings);
        m
    }
    /// The link codes (see [`Measurement::links`]); empty on ideal links or when `links_len` is
    /// out of bounds (validation rejects such a message first).
    pub fn links(&self) -> &[u32] {
        self.links.get(..self.links_len as usize).unwrap_or(&[])
    }
    /// Set the link codes (at most [`MAX_LINKS_IN`], checked when the scenario was validated).
    pub fn set_links(&mut self, codes: &[u32]) {
        assert!(codes.len() <= MAX_LINKS_IN, "bound checked at scenario validation");
        self.links_len = codes.len() as u32;
        self.links[..codes.len()].copy_from_slice(codes);
    }
    /// The readings; empty when `len` is out of bounds (validation rejects such a message first).
    pub fn readings(&self) -> &[f64] {
        self.readings.get(..self.len as usize).unwrap_or(&[])
    }
}

/// Agent i → plant and i's subscribers at step k: the command the plant applies over
/// [tₖ, tₖ₊₁) and the values the neighbours' algorithms need.
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("cohort::Share")]
pub struct Share {
    pub header: Header,
    pub command_len: u32,
    pub values_len: u32,
    /// [`LINK_DATA`], or [`LINK_LOST`]: a step token with nothing in it.
    pub link: u32,
    pub _pad: u32,
    pub command: [f64; MAX_COMMAND],
    pub values: [f64; MAX_SHARE_VALUES],
}

impl Share {
    pub fn new(header: Header, command: &[f64], values: &[f64]) -> Self {
        assert!(command.len() <= MAX_COMMAND && values.len() <= MAX_SHARE_VALUES);
        let mut s = Self {
            header,
            command_len: command.len() as u32,
            values_len: values.len() as u32,
            link: LINK_DATA,
            _pad: 0,
            command: [0.0; MAX_COMMAND],
            values: [0.0; MAX_SHARE_VALUES],
        };
        s.command[..command.len()].copy_from_slice(command);
        s.values[..values.len()].copy_from_slice(values);
        s
    }
    pub fn command(&self) -> &[f64] {
        self.command.get(..self.command_len as usize).unwrap_or(&[])
    }
    pub fn values(&self) -> &[f64] {
        self.values.get(..self.values_len as usize).unwrap_or(&[])
    }
}

/// Orchestrator → every process.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("cohort::RunControl")]
pub struct RunControl {
    pub version: u32,
    /// One of the `CONTROL_*` constants.
    pub command: u32,
    pub run_id: u64,
    /// CONTROL_RESUME: the step the plant holds at.
    pub step: u64,
    /// CONTROL_RESUME, CONTROL_DEAD: agents to mark dead.
    pub dead: Roster,
    /// CONTROL_RESUME: agents to mark live again (relaunched or thawed).
    pub alive: Roster,
    /// Keyed MAC (`run.authenticate`); zero otherwise.
    pub mac: [u64; 2],
}

impl RunControl {
    pub fn new(command: u32, run_id: u64) -> Self {
        Self {
            version: SCHEMA_VERSION,
            command,
            run_id,
            step: 0,
            dead: Roster::EMPTY,
            alive: Roster::EMPTY,
            mac: [0; 2],
        }
    }
}

/// A share that carries data.
pub const LINK_DATA: u32 = 0;
/// A step token: the sender finished computing this step, but the link lost (or delayed) its
/// share. Lockstep needs it — without it the plant could not tell "lost" from "not yet sent" and
/// would either wait out a timeout per lost share or run ahead of the sender. Receivers use it to
/// close the step and never read numbers from it (a `drop`, `corrupt` or `delay` fault).
pub const LINK_LOST: u32 = 1;

/// Stop: finish nothing more, write what you have, exit.
pub const CONTROL_STOP: u32 = 1;
/// Start: every process reported ready (all ports exist), the plant may send step 0.
pub const CONTROL_START: u32 = 2;
/// The orchestrator has carried out the process faults due at `step`: the plant, holding before
/// that step's measurements, applies `dead`/`alive` to the roster and goes on.
pub const CONTROL_RESUME: u32 = 3;
/// Agents in `dead` died outside the fault plan (the orchestrator reaped them): the plant marks
/// them dead at the step it is closing instead of waiting out the step timeout.
pub const CONTROL_DEAD: u32 = 4;

/// Process → orchestrator: lifecycle and progress (never on the step's critical path).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("cohort::Status")]
pub struct Status {
    pub version: u32,
    pub sender: u32,
    pub run_id: u64,
    /// One of the `STATUS_*` constants.
    pub kind: u32,
    /// For `STATUS_WAITING`: the process being waited for.
    pub waiting_for: u32,
    pub step: u64,
    pub t_s: f64,
    /// Build id hash (see `build_id_hash`) so the orchestrator can check it in the handshake.
    pub build_hash: u64,
    /// For `STATUS_WAITING`: 0, or 1 + the [`crate::validate::Rejection`] of the latest message
    /// from the process waited for, when that message was rejected (damaged or forged).
    pub detail: u32,
    pub _pad: u32,
    /// Keyed MAC (`run.authenticate`); zero otherwise.
    pub mac: [u64; 2],
}

/// All ports exist; the process is ready for step 0.
pub const STATUS_READY: u32 = 1;
/// The plant completed `step` (sent at most every few ms).
pub const STATUS_PROGRESS: u32 = 2;
/// The sender has been waiting noticeably long in `step` for `waiting_for`.
pub const STATUS_WAITING: u32 = 3;
/// The process finished every step.
pub const STATUS_DONE: u32 = 4;
/// The plant holds before sending the measurements of `step` (a process fault is due).
pub const STATUS_HOLDING: u32 = 5;
/// The plant marked agent `waiting_for` dead from `step` on (it coasts from then).
pub const STATUS_DEAD: u32 = 6;
/// The plant marked agent `waiting_for` live again from `step` on.
pub const STATUS_ALIVE: u32 = 7;
/// Agent `sender` finished every step before `step` and flushed its telemetry: a process fault
/// due at `step` (a hold step) finds it in a known state.
pub const STATUS_IDLE: u32 = 8;
