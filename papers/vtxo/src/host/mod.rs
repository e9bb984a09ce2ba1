//! Seed 002 on the host side, after and around the runs ("Explainable AI-Enhanced Supervisory
//! Control for High-Precision Spacecraft Formation", Secs. 2.3 and 7): the telemetry join and
//! summary ([`analysis`]), the figures ([`figures`]), the verdict against the mission requirements
//! ([`verdict`]), the Sec. 7 table campaign ([`sec7`]), and the paper's host hooks and
//! `orchestrator vtxo …` command line ([`hooks`]).

pub(crate) mod analysis;
pub(crate) mod figures;
mod hooks;
pub(crate) mod sec7;
pub(crate) mod verdict;
