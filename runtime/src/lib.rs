//! Cohort's runtime: the traits a plant model and an algorithm implement ([`model`]), how a paper
//! provides them ([`paper`]), the
//! lockstep step drivers generic over the transport ([`drive`]), what a process records
//! ([`record`]), per-process random generators ([`rng`]), and the message recordings of
//! `run.record` with the replay of one agent against them ([`recording`]), every process's
//! logging ([`logging`]) and exit codes ([`exit`]), the checked weights files of learned models
//! ([`weights`]), and the in-process lockstep loop of campaigns and studies, without a transport
//! ([`lockstep`]), and the reading of a process's telemetry while it is written ([`tail`]: the
//! live view's, on this machine and through a host daemon).

pub mod checkpoint;
pub mod coop;
pub mod drive;
pub mod exit;
pub mod links;
pub mod lockstep;
pub mod logging;
pub mod model;
pub mod paper;
pub mod parquet_out;
pub mod process;
pub mod record;
pub mod recording;
pub mod rng;
pub mod run_status;
pub mod solver_stats;
pub mod tail;
pub mod units;
pub mod weights;
