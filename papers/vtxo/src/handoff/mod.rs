//! The hand-off scenario of "Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation" (Secs. 2.11, 3.2.1, 3.2.2 and 8): one visit of the supervisor through s1
//! stabilisation → s2 transient → s3 science with the full dynamics, each spacecraft's flight
//! agent with the supervisor riding along and the controllers switching with its location
//! ([`agent`]); the science law at the entry to s3 ([`science`]); the `vtxo-handoff` algorithm
//! kind ([`kind`]) and its section ([`config`]); the run's summary from the telemetry
//! ([`analysis`]).

pub(crate) mod agent;
#[cfg(feature = "host")]
pub(crate) mod analysis;
pub(crate) mod config;
pub(crate) mod kind;
pub(crate) mod science;
