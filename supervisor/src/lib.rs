//! `cohort-supervisor`: the processes of a multi-process run — starting, watching and stopping
//! them on this machine or, for a multi-host run, through a host daemon on each machine — and the
//! multi-host machinery around that (the daemon, its protocol, the preflight check, the bench's
//! network lab and zenoh round trip).
//!
//! - [`supervise`]: [`supervise::launch`] spawns the plant and every agent, releases the start
//!   barrier, watches them, carries out the fault plan, stops them in order (the shutdown ladder)
//!   and removes every resource of the run; [`supervise::SIGNALLED`] and
//!   [`supervise::install_signal_handlers`] turn Ctrl-C, SIGTERM and SIGHUP into an orderly stop.
//! - [`preflight`]: before a multi-host run starts, every daemon of `[[hosts]]` is reachable,
//!   answers to its name and has this build's id.
//! - [`daemon`]: the host daemon (`orchestrator host`) that starts one machine's processes for an
//!   orchestrator elsewhere, relays its signals and sends the run's files back.
//! - [`farm`]: a campaign's cases sent to the host daemons' worker pools (`orchestrator
//!   campaign --hosts`), a lost host's unanswered cases sent again to the others.
//! - [`netlab`] and [`zping`]: four network namespaces with host daemons and a delay on their
//!   links, and a zenoh ping-pong, both for `orchestrator bench`.
//! - [`observe`]: each timeline event as it happens, for the live view (`launch --live`).
//! - [`linkemu`]: a user-space `tc netem` (a TAP pair with a pump that delays, jitters and drops
//!   frames) for kernels without `sch_netem`; the lab's links and the multi-host test use it.
//!
//! Why a crate apart: this is the part of the orchestrator that deals in processes, signals and
//! hosts rather than in scenarios and reports, and it grew with the multi-host transport; kept
//! apart it has an API of its own and the orchestrator binary stays small (it keeps the CLI,
//! launch, the reference run, summary, report, sweep, soak and bench). Like the other generic
//! crates it knows no paper, and it depends on the orchestrator for nothing: the caller passes
//! what it needs (the configured scenario, the run directories, a progress hook) and maps the
//! errors it returns to exit codes.

pub mod daemon;
pub mod farm;
pub mod gateway;
mod hostproto;
pub use hostproto::ProcRows;
pub mod linkemu;
pub mod netlab;
pub mod observe;
mod remote;
pub mod supervise;
pub mod zping;

pub use remote::{PreflightError, PreflightProblem, preflight};
