//! See rpath.rs. Also the build script of the packages that name this file as theirs.
#[path = "rpath.rs"]
mod rpath;

fn main() {
    rpath::emit();
    // Not `build.rs`: the packages that share this script (the registry; agent and plant through
    // runtime/child_build.rs) have no file of that name, and a missing watched path reruns the
    // script, and rebuilds them, every time.
    // The script's own edits rebuild it anyway; its output depends only on the Python found.
    println!("cargo:rerun-if-changed=Cargo.toml");
}
