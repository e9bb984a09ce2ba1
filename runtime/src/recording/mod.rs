//! Recording a process's messages (`run.record`, `launch --record`) and replaying one agent against
//! them (`orchestrator replay`).
//!
//! **Who writes.** Every agent process writes its own file, `record/agent-<i>.mcap`, from a
//! thread of its own ([`writer`]): the step path only copies each message's bytes into a bounded
//! queue. One file per process because the processes of a run share no memory and may sit on
//! different machines (zenoh), and one file per agent is also what a replay of that agent needs,
//! complete on its own. The agents' files together hold every message with data in the run: each
//! measurement is received by one agent and each share sent by one. The plant writes none: its
//! file would repeat every agent's stream (the plant sends every measurement and reads every
//! share) at twice the disk, from the process every step waits for. A message a faulty link
//! garbled is recorded as its sender sent it and as its receivers received it.
//!
//! **Format.** MCAP (profile none, zstd chunks). A metadata record `cohort` says what the file is
//! ([`META_FORMAT`], process, agent id, neighbours, run id, wire schema version, build, scenario,
//! seed, `dt_s`). One channel per (kind, sender): `/measurement/plant`, `/share/agent-<j>` for each
//! neighbour j, and `/share/agent-<i>` for the agent's own shares; each channel's metadata gives
//! `kind`, `sender`, `receiver` and `direction` (`received` or `sent`). A message's data are the
//! payload's exact wire bytes — the whole `#[repr(C)]` struct, unused array tails included (zstd
//! makes them nearly free) — with message encoding `ros1` and a `ros1msg` schema
//! (`cohort/Measurement`, `cohort/Share`, see `cohort_wire::layout`) that describes those bytes
//! field by field, so Foxglove decodes and plots them as they are. Received messages are stored as
//! they arrived (with the sender's `sent_wall_ns` stamp); sent shares as this process handed them
//! to the transport, before it stamps `sent_wall_ns` (0 in the file). `log_time` and
//! `publish_time` are the message's sim time, step × `dt_s` in ns (wall clock is in the bytes);
//! `sequence` is the message's place in the file, which is the order the process saw them.
//!
//! **Replay** ([`replay`]) builds agent i's algorithm as the agent process does and runs it through
//! the same driver (`drive::run_agent`) over a transport that hands it the recorded measurements
//! and neighbour shares step by step, then compares every share it sends with the recorded one,
//! byte for byte (all but the `mac`, a tag under a per-run key that is never stored).

pub mod reader;
pub mod replay;
#[cfg(test)]
mod tests;
pub mod walk;
pub mod writer;

use cohort_wire::msg::PLANT_ID;
use cohort_wire::transport::Proc;

/// The `format` value of a recording's `cohort` metadata record; a reader refuses any other.
pub const META_FORMAT: &str = "cohort-record-1";
/// The attachment of a relaunched agent's recording (`restart` fault): the checkpoint file it
/// resumed from, byte for byte, so that a replay resumes from the same state.
pub const RESTORED_FROM: &str = "restored-from.ckpt";
/// Its media type.
pub const CHECKPOINT_MEDIA_TYPE: &str = "application/x-cohort-checkpoint";
/// The name of the metadata record.
pub const META_NAME: &str = "cohort";
/// Message encoding of every channel (the bytes are ROS 1 serialisation of the `ros1msg` schema).
pub const MESSAGE_ENCODING: &str = "ros1";
/// Schema encoding of the two schemas.
pub const SCHEMA_ENCODING: &str = "ros1msg";

/// The directory of a run's recordings.
pub fn dir(run_dir: &std::path::Path) -> std::path::PathBuf {
    run_dir.join("record")
}

/// Where process `me`'s recording goes in a run directory.
pub fn path_for(run_dir: &std::path::Path, me: Proc) -> std::path::PathBuf {
    dir(run_dir).join(format!("{}.mcap", me.name()))
}

/// Where incarnation `n` of process `me` records: `record/<proc>.mcap` for the first process
/// (n = 0), `record/<proc>.<n>.mcap` for its n-th relaunch (`restart` fault).
pub fn incarnation_path(run_dir: &std::path::Path, me: Proc, n: u32) -> std::path::PathBuf {
    match n {
        0 => path_for(run_dir, me),
        n => dir(run_dir).join(format!("{}.{n}.mcap", me.name())),
    }
}

/// The incarnations of `me` that left a recording in a run directory, in order (0, 1, …, up to
/// the first missing one).
pub fn incarnations(run_dir: &std::path::Path, me: Proc) -> Vec<u32> {
    (0..).take_while(|&n| incarnation_path(run_dir, me, n).is_file()).collect()
}

/// Whether a message was received or sent by the recording process.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    Received,
    Sent,
}

impl Direction {
    pub fn name(self) -> &'static str {
        match self {
            Direction::Received => "received",
            Direction::Sent => "sent",
        }
    }
}

/// A process name from a sender id (the plant is 0).
pub fn proc_of(id: u32) -> Proc {
    if id == PLANT_ID { Proc::Plant } else { Proc::Agent(id) }
}
