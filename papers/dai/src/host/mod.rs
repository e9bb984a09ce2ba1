//! Seed 004's host side (the orchestrator's; the `host` feature): the run analysis ([`analysis`]),
//! the verdict ([`verdict`]), the measured Tables 2 and 4 with the sampled-data study
//! (`orchestrator dai tables`, [`tables`], [`readings`], over the runs of [`campaign`]), and the
//! hooks and command that declare them ([`hooks`]).

pub mod analysis;
mod campaign;
mod hooks;
pub mod readings;
pub mod tables;
pub mod verdict;
