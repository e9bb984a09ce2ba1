//! Seed 003: Neural-Rendezvous (Tsukamoto, Chung et al., "Neural-Rendezvous: Provably Robust
//! Guidance and Control to Encounter Interstellar Objects", arXiv:2208.04883).

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod constants;
pub mod iso_set;
pub mod lvlh;
pub mod messages;
pub mod navigation;
pub mod plant;
pub mod relative;
pub mod two_body;
