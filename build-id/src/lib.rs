//! The build id of this checkout (see `build.rs`): a digest of the package version, of every
//! source file of every workspace member and of every patched crate in `vendor/`.
//!
//! Only the binaries (`orchestrator`, `plant`, `agent`) and the process tests depend on this
//! crate; each binary hands the id to `cohort_wire::set_build_id` as its first act. The library
//! crates read it at run time through `cohort_wire::build_id`, so an edit to one paper rebuilds
//! that paper and the binaries, not every crate below them (when the id was a constant of the
//! wire crate, every edit anywhere recompiled the whole workspace).

/// Identifies the exact sources every binary was built from.
pub const BUILD_ID: &str = env!("COHORT_BUILD_ID");

/// The workspace member directories [`BUILD_ID`] covers (relative to the root, `.` for the root
/// package), comma-separated: every member, or a stale binary could pass the handshake.
pub const BUILD_ID_MEMBERS: &str = env!("COHORT_BUILD_ID_MEMBERS");
