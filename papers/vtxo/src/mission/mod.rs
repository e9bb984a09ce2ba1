//! The whole VTXO mission, Id 0 → 9, of Sec. 8 and Table 6 of "Explainable AI-Enhanced Supervisory
//! Control for High-Precision Spacecraft Formation": the supervisor ([`crate::automaton`]) run as
//! discrete events with the dynamics abstracted by timers ([`discrete`]), the `vtxo-mission`
//! algorithm kind ([`kind`]) and its section ([`config`]), the orbit period taken from the plant
//! ([`period`]), and the timeline figure ([`figure`]).

pub(crate) mod config;
pub mod discrete;
#[cfg(feature = "host")]
pub(crate) mod figure;
pub(crate) mod kind;
pub(crate) mod period;
