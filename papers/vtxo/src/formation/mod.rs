//! Seed 002's formation flight as the registry sees it ("Explainable AI-Enhanced Supervisory
//! Control for High-Precision Spacecraft Formation", Sec. 7): the `vtxo` plant kind and the
//! `vtxo-formation` algorithm kind ([`kinds`]), the builders of the plant and of each agent from
//! validated sections ([`build`]), and an in-process lockstep loop in the drivers' order for tests
//! and studies ([`sim`]).

pub(crate) mod build;
pub(crate) mod kinds;
pub mod sim;

pub use build::{build_agent, build_follower, build_leader, build_plant};
