//! Seed 003: Neural-Rendezvous (Tsukamoto, Chung et al., "Neural-Rendezvous: Provably Robust
//! Guidance and Control to Encounter Interstellar Objects", arXiv:2208.04883).

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod agent;
pub mod baselines;
pub mod bound;
pub mod campaign;
pub mod config;
pub mod constants;
pub mod desired;
pub mod features;
pub mod iso_set;
pub mod lvlh;
pub mod messages;
pub mod min_norm;
pub mod navigation;
pub mod plant;
pub mod qp;
pub mod relative;
pub mod scp;
pub mod sim;
pub mod sn_dnn;
pub mod tracking;
pub mod train;
pub mod two_body;
