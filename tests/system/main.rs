//! Cohort's system tests: each module launches real processes (plant, agents, orchestrator,
//! host daemons) from the release binaries `scripts/test` builds, and checks what a user would:
//! scenario validation, launches, faults, replays, multi-host runs, logs and summaries.
//!
//! One test harness for all of them (a harness per file cost a link of the whole binary per
//! file); the tests that launch runs share [`cohort::heavy`], so two never run at once.
//! `cargo test --release --test system faults::` runs one module.

mod build_id;
mod campaign;
mod check;
mod cli;
mod every_scenario;
mod faults;
mod flight_split;
mod hardening;
mod launch;
mod links;
mod live;
mod logging;
mod multihost;
mod python;
mod python_loader;
mod reliability;
mod replay;
mod runtime_options;
mod summary;
mod zenoh_tls;
