//! The transient phase of "Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation" (Secs. 3.1, 3.2.1, 5 and 5.1): one flight under the Lyapunov law (57)
//! with its objectives ([`sim`]), simulated annealing of (k₁, k₂, T) per point ([`sa`]), the
//! optimisation table ([`data`]) and its Table 2 statistics ([`stats`]), the DNN's inference
//! ([`dnn`]) and training ([`train`]), the predictor interface the supervisor asks for u2 = T and
//! the gains ([`gains`]), the closed-loop Monte Carlo ([`mc`]), and the trainers' and the Monte
//! Carlo's command lines ([`trainer`]).

#[cfg(feature = "host")]
pub(crate) mod data;
pub mod dnn;
pub mod gains;
#[cfg(feature = "host")]
pub(crate) mod mc;
#[cfg(feature = "host")]
pub(crate) mod sa;
pub(crate) mod sim;
#[cfg(feature = "host")]
pub(crate) mod stats;
#[cfg(feature = "host")]
pub(crate) mod train;
#[cfg(feature = "host")]
pub(crate) mod trainer;
