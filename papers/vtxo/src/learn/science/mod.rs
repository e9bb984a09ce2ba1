//! The science phase of "Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation" (Secs. 3.1, 3.2.2 and 6.1): one attitude flight under the PD (54) or SMC
//! (58)–(60) with the vector loss χ = [E, e] (72) ([`sim`]), the seeded NSGA-II Pareto search
//! ([`moga`]), the Pareto tables ([`data`]), the DNN's inference ([`dnn`]) and training
//! ([`train`]), the Table 3 analogue ([`stats`]), and the trainers' command lines ([`trainer`]).

#[cfg(feature = "host")]
pub(crate) mod data;
pub mod dnn;
#[cfg(feature = "host")]
pub(crate) mod moga;
pub mod sim;
#[cfg(feature = "host")]
pub mod stats;
#[cfg(feature = "host")]
pub mod train;
#[cfg(feature = "host")]
pub(crate) mod trainer;
