//! The truth of seed 002 ("Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation", Sec. 2 and Apps. C–E): what the plant process integrates for both
//! spacecraft — the orbits (16)–(17), (21)–(22) from Table D.9's elements, the rigid-body attitude
//! (13)–(15) with the gravity gradient (23), the reaction wheels and thrusters (28)–(33), the
//! sensors of App. C, and the exponentially correlated biases — as [`plant::VtxoPlant`], its
//! telemetry row and summary metrics, and the `[plant]` section of a scenario ([`config`]).
//! The quaternion convention (Markley–Crassidis, scalar last) is here too; both sides use it.

pub(crate) mod actuators;
pub(crate) mod attitude;
pub mod config;
pub(crate) mod ecrv;
pub mod metrics;
pub mod orbit;
pub mod orbit_setup;
pub(crate) mod plant;
pub(crate) mod plant_row;
pub mod quaternion;
pub(crate) mod sensors;
