//! Cohort's wire layer: the messages processes exchange ([`msg`]), how a receiver validates them
//! ([`validate`]), and the [`transport::Transport`] abstraction with its iceoryx2 and in-memory
//! implementations, the keyed MAC of `run.authenticate` ([`auth`]), and the payloads' byte layout
//! that a recording describes ([`layout`]).

pub mod auth;
pub mod layout;
pub mod limits;
pub mod msg;
pub mod transport;
pub mod validate;

/// Identifies the exact sources every binary was built from (see `build.rs`).
pub const BUILD_ID: &str = env!("COHORT_BUILD_ID");

/// A 64-bit digest of [`BUILD_ID`], small enough for a status message.
pub fn build_id_hash() -> u64 {
    BUILD_ID.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The workspace member directories [`BUILD_ID`] covers (relative to the root, `.` for the root
/// package), comma-separated: every member, or a stale binary could pass the handshake.
pub const BUILD_ID_MEMBERS: &str = env!("COHORT_BUILD_ID_MEMBERS");
