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

/// The build id this process runs with, set once by its binary ([`set_build_id`]).
static BUILD_ID: std::sync::OnceLock<&'static str> = std::sync::OnceLock::new();

/// Records the build id of this process (`cohort_build_id::BUILD_ID`, which only the binaries
/// depend on: see that crate for why the id is not a constant of this one). The first call wins.
pub fn set_build_id(id: &'static str) {
    let _ = BUILD_ID.set(id);
}

/// The build id the process's binary set: what the handshakes compare, the recordings carry and
/// `--version` prints. `"unset"` in a library's own unit tests, where no binary set it (both ends
/// of any handshake in one process then agree on it).
pub fn build_id() -> &'static str {
    BUILD_ID.get().copied().unwrap_or("unset")
}

/// A 64-bit digest of [`build_id`], small enough for a status message.
pub fn build_id_hash() -> u64 {
    fnv1a(build_id().as_bytes())
}

/// FNV-1a (64-bit) of `bytes`: a stable digest (unlike `DefaultHasher`, the same in every build
/// and Rust version) for tags, names and cache keys; not a defence against anyone.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}
