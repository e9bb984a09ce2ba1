//! The flight software of seed 002's two spacecraft ("Explainable AI-Enhanced Supervisory Control
//! for High-Precision Spacecraft Formation", Secs. 2.10–2.11 and 7): the MEKF on the gyro and the
//! star tracker, the attitude laws (Lyapunov (57), PD (54), SMC (58)–(60)), the follower's relative
//! navigation and the relative-position laws ((56), (64)–(67), (70)), assembled into the
//! [`leader::Leader`] and [`follower::Follower`] agents; the plant ↔ agent and agent ↔ agent
//! message layouts, and the `[algorithm]` section of a scenario ([`config`]).

pub(crate) mod acs;
pub mod attitude_control;
pub mod config;
pub(crate) mod follower;
pub mod layout;
pub(crate) mod leader;
pub mod mekf;
pub mod relative_control;
pub mod relative_filter;
pub(crate) mod relative_nav;
pub mod share;
