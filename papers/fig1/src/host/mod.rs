//! Seed 000's host side (the orchestrator's; the `host` feature): the run analysis — ζ̃ᵢ joined
//! from truth and estimates, the fault effects ([`analysis`]) — the paper's Figs. 2–4
//! ([`figures`]), the verdict ([`verdict`]), the sweep criterion ([`sweep`]), and the hooks that
//! declare them on the servicing run's kinds ([`hooks`]).

pub mod analysis;
pub mod figures;
mod hooks;
pub mod sweep;
pub mod verdict;
