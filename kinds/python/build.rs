//! See rpath.rs. Also the build script of the packages that name this file as theirs.
#[path = "rpath.rs"]
mod rpath;

fn main() {
    rpath::emit();
    println!("cargo:rerun-if-changed=build.rs");
}
