//! The three formation controllers compared in Sec. 4, each a pure `Algorithm`: AEMC
//! (cooperative-game DMPC with the tension forecast, [`aemc`]), DMPC ([`dmpc`]) and SMC ([`smc`]),
//! with what they share ([`common`], the condensed box-constrained QP in [`mpc`]).

pub mod active_set;
pub mod aemc;
pub mod common;
pub mod dmpc;
pub mod mpc;
pub mod smc;
