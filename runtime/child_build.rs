//! The build script of the run's child binaries, `agent` and `plant` (their `build = …`): what the
//! shared libpython build script does (kinds/python/rpath.rs), and a position-dependent executable.
//!
//! A position-independent executable is loaded at a random address, so the dynamic loader writes
//! its ≈ 73 000 relative relocations into every process's own copy of the pages that hold them:
//! about a megabyte of private memory per process, and CPU at each start (`perf stat agent
//! --version`: 3.7–3.9 → 2.4–3.7 ms, 739 → 442 page faults). With a thousand agent processes
//! that was a gigabyte, and `_dl_relocate_object` an eighth of a start-up's CPU (`perf record -a`
//! of the first 24 s). Linked without PIE the pages stay shared with the file: a 1 000-agent
//! ring's total PSS 7.71 / 7.70 GB → 6.54 / 6.54 GB (two interleaved pairs of launches; start-up
//! 25.8 / 23.7 s → 23.7 / 26.5 s, within the noise). The cost: these two executables' own code and
//! data sit at a fixed address (their libraries, heap, stacks and mappings are still placed at
//! random); the orchestrator, which serves the network as `orchestrator host`, stays PIE. Only
//! the final link changes: the objects are compiled position-independent as before.

#[path = "../kinds/python/rpath.rs"]
mod rpath;

fn main() {
    rpath::emit();
    println!("cargo:rustc-link-arg-bins=-no-pie");
    // The script's own edits rerun it anyway; its output depends only on the Python found.
    println!("cargo:rerun-if-changed=Cargo.toml");
}
