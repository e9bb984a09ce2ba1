//! Seed 001, the tethered space net robot (Ma et al., Acta Astronautica 2024): the pieces shared by
//! the plant (net mesh), the agents (relative-motion model, desired trajectories, tension
//! predictor) and the orchestrator (training, reports). No transport in here.

pub mod cw;
pub mod net;
pub mod predictor;
pub mod trajectory;
