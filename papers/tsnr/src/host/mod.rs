//! Seed 001's host side (the orchestrator's; the `host` feature): the run analysis
//! ([`analysis`]), the paper's figures ([`figures`]), the verdict ([`verdict`]), the Tables 1–2
//! analogue (`orchestrator tsnr compare`, [`compare`]), the ablation campaign (`orchestrator tsnr
//! ablation`, [`ablation`]), and the hooks and commands that declare them ([`hooks`]). The
//! trainer is the crate's `train`.

pub mod ablation;
pub mod analysis;
pub mod compare;
pub mod figures;
mod hooks;
pub mod verdict;
