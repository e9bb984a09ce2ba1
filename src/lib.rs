//! The root package holds Cohort's tests that launch real processes (`tests/`); this library only
//! gives them shared helpers.

use std::path::PathBuf;

/// The workspace root (where `topologies/` lives), fixed at compile time.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Path of a workspace binary (e.g. `"orchestrator"`) built with the same profile as the running
/// test. A test executable runs from `<target dir>/<profile>/deps/`, and binaries sit one level
/// up, in `<target dir>/<profile>/`. Run the tests as `cargo test --workspace --release` so
/// cargo builds them. This function does not check that the binary exists.
pub fn bin_path(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("cannot find the running test executable");
    let profile_dir = exe
        .parent() // deps/
        .and_then(|deps| deps.parent())
        .expect("test executable is not in <target dir>/<profile>/deps/");
    profile_dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}
