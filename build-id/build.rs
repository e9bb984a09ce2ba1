//! Computes `COHORT_BUILD_ID`: a hash of the package version and of every source file of every
//! workspace member (read from the root `Cargo.toml`'s `[workspace] members`, globs expanded, so a
//! new paper is covered without an edit here) and of every patched crate in `vendor/`. The orchestrator refuses to launch a `plant` or
//! `agent` binary whose build id differs from its own, so a stale binary left beside a fresh
//! orchestrator is caught in the handshake instead of producing a run with mismatched message
//! layouts or algorithms. `COHORT_BUILD_ID_MEMBERS` lists the member directories it covered (a
//! test compares it with `cargo metadata`).
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

/// The `[workspace] members` entries of the root manifest (a small reader: one `members = [...]`
/// array of strings, possibly over several lines).
fn members(manifest: &str) -> Vec<String> {
    let Some(start) = manifest.find("\nmembers") else { return Vec::new() };
    let rest = &manifest[start..];
    let (Some(open), Some(close)) = (rest.find('['), rest.find(']')) else { return Vec::new() };
    rest[open + 1..close].split(',').map(|m| m.trim().trim_matches('"').to_string()).filter(|m| !m.is_empty()).collect()
}

/// A member entry as directories: `papers/*` is every directory of `papers/` with a Cargo.toml.
fn expand(root: &Path, member: &str) -> Vec<PathBuf> {
    match member.strip_suffix("/*") {
        Some(parent) => {
            let Ok(rd) = std::fs::read_dir(root.join(parent)) else { return Vec::new() };
            let mut dirs: Vec<PathBuf> =
                rd.flatten().map(|e| e.path()).filter(|p| p.join("Cargo.toml").is_file()).collect();
            dirs.sort();
            dirs
        }
        None => vec![root.join(member)],
    }
}

fn main() {
    // Read when the script runs, not when it was compiled: a target directory moved to another
    // checkout must not hash the old one.
    let manifest_dir = std::env::var_os("CARGO_MANIFEST_DIR").map(PathBuf::from).unwrap_or_default();
    let root = manifest_dir.join("..");
    let root_manifest = root.join("Cargo.toml");
    println!("cargo:rerun-if-changed={}", root_manifest.display());
    let text = std::fs::read_to_string(&root_manifest).unwrap_or_default();
    let mut files = Vec::new();
    let mut covered = Vec::new();
    // The patched third-party crates of `vendor/` (`[patch.crates-io]`) are built into the
    // binaries as much as a member is: an edit to one is a different build.
    let vendored = std::iter::once("vendor/*".to_string());
    for member in members(&text).into_iter().chain(vendored) {
        if let Some(parent) = member.strip_suffix("/*") {
            // A new paper folder changes the expansion.
            println!("cargo:rerun-if-changed={}", root.join(parent).display());
        }
        for dir in expand(&root, &member) {
            let src = dir.join("src");
            println!("cargo:rerun-if-changed={}", src.display());
            collect(&src, &mut files);
            let manifest = dir.join("Cargo.toml");
            println!("cargo:rerun-if-changed={}", manifest.display());
            files.push(manifest);
            let rel = dir.strip_prefix(&root).unwrap_or(&dir).to_string_lossy().into_owned();
            covered.push(if rel.is_empty() { ".".to_string() } else { rel });
        }
    }
    // The root package (the process tests' helpers) is a member too.
    let root_src = root.join("src");
    println!("cargo:rerun-if-changed={}", root_src.display());
    collect(&root_src, &mut files);
    files.push(root_manifest.clone());
    covered.push(".".to_string());
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
    covered.sort();
    covered.dedup();
    println!("cargo:rustc-env=COHORT_BUILD_ID_MEMBERS={}", covered.join(","));
}
