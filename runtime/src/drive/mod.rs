//! The lockstep step protocol (design.md "One step"), once for the plant and once for an agent,
//! generic over the transport. The multi-process binaries and the in-process reference run call
//! exactly these functions; only the `Transport` differs.
//!
//! For step k:
//! 1. plant → agent i: `Measurement{k}`;
//! 2. agent i: `Algorithm::share`, publishes `Share{k}` (command + values for neighbours);
//! 3. agent i waits for `Share{k}` of every neighbour, then `Algorithm::step` (tₖ → tₖ₊₁);
//! 4. plant waits for every `Share{k}`, applies the commands, integrates to tₖ₊₁.
//!
//! Every wait is a loop of short timed waits that re-polls (a wakeup can be lost under heavy
//! preemption) and ends with [`RunError::Timeout`] naming the silent peer after the step timeout.
//!
//! Each loop is a driver with one method per phase of a step ([`plant`]'s `PlantDriver`,
//! [`agent`]'s `AgentDriver`: `open`, `step`, `finish`); the files:
//! - `plant.rs`, `plant_inbox.rs`: the plant's loop, its inbox and roster;
//! - `agent.rs`, `agent_inbox.rs`: an agent's loop, its inbox and how it steps from the shares;
//!   `checkpoint_writer.rs`: its checkpoints, written by a thread off the step path;
//! - `wait.rs`: the waits and their spin policy, `wait_trial.rs` adaptive waiting's trials of
//!   spinning against blocking; `params.rs`: the settings; `files.rs`: the
//!   telemetry and timing files; `status.rs`: status messages and reports; `error.rs`: how a run
//!   ends in error.

mod agent;
mod agent_inbox;
mod checkpoint_writer;
mod error;
mod files;
mod params;
mod plant;
mod plant_inbox;
mod status;
mod wait;
mod wait_trial;

#[cfg(test)]
pub(crate) mod tests;

pub use agent::run_agent;
pub use error::RunError;
pub use params::{DriveParams, spin_budget};
pub use plant::run_plant;
pub use status::report_ready;
pub use wait::{ADAPTIVE_CAP_US, ADAPTIVE_FLOOR_US, Contention, SpinPolicy, YIELD_STALL};
