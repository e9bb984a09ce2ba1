//! Seed 001, the tethered space net robot (Ma et al., Acta Astronautica 2024): the pieces shared by
//! the plant (net mesh), the agents (relative-motion model, desired trajectories, tension
//! predictor) and the orchestrator (training, reports). No transport in here.

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod cw;
pub mod dnn_forecast;
pub mod forecast;
pub mod net;
pub mod predictor;
pub mod trajectory;
