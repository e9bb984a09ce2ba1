//! Seed 003: Neural-Rendezvous (Tsukamoto, Chung et al., "Neural-Rendezvous: Provably Robust
//! Guidance and Control to Encounter Interstellar Objects", arXiv:2208.04883).
//!
//! The `iso-encounter` plant ([`plant`]) flies one ISO and K spacecraft about the Sun and gives
//! each spacecraft noisy estimates ([`navigation`], [`messages`]); each spacecraft's
//! [`agent::NrAgent`] flies Algorithm 1 or one of the baselines ([`config::Method`]): the SN-DNN
//! guidance ([`sn_dnn`], [`features`]) trained by imitation of the SCP global solution
//! ([`scp`], [`train`]), then min-norm tracking ([`min_norm`], [`tracking`]) of the desired
//! trajectory ([`desired`]) with the delivery-error bound ([`bound`]). Every controller predicts
//! with the relative model (2) ([`relative`]). [`sim`] and [`campaign`] run and evaluate it in
//! one process. The crate README gives the set-up, the measured results and every departure.

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
