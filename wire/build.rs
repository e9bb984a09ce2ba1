//! Computes `COHORT_BUILD_ID`: a hash of the package version and of every source file of the
//! workspace's crates. The orchestrator refuses to launch a `plant` or `agent` binary whose build
//! id differs from its own, so a stale binary left beside a fresh orchestrator is caught in the
//! handshake instead of producing a run with mismatched message layouts or algorithms.
use std::path::{Path, PathBuf};

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else { return };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            collect(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs" || x == "toml") {
            out.push(p);
        }
    }
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut files = Vec::new();
    for krate in ["wire", "scenario", "runtime", "plant", "agent", "orchestrator"] {
        let src = root.join(krate).join("src");
        println!("cargo:rerun-if-changed={}", src.display());
        collect(&src, &mut files);
        let manifest = root.join(krate).join("Cargo.toml");
        println!("cargo:rerun-if-changed={}", manifest.display());
        files.push(manifest);
    }
    files.sort();
    // FNV-1a 64: stable across Rust versions (unlike DefaultHasher).
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= u64::from(*b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(env!("CARGO_PKG_VERSION").as_bytes());
    for f in &files {
        eat(f.strip_prefix(&root).unwrap_or(f).to_string_lossy().as_bytes());
        eat(&std::fs::read(f).unwrap_or_default());
    }
    println!("cargo:rustc-env=COHORT_BUILD_ID={}-{h:016x}", env!("CARGO_PKG_VERSION"));
}
