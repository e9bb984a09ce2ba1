//! The build id (the stale-binary check of every launch) must cover every workspace member: a
//! changed paper crate that it missed would let an old `plant` or `agent` binary pass the
//! handshake. `cargo metadata` is the independent list.

use cohort::OutputWithin;
use std::path::Path;
use std::process::Command;

#[test]
fn the_build_id_covers_every_workspace_member() {
    let root = cohort::repo_root();
    let out = Command::new(env!("CARGO"))
        .args(["metadata", "--no-deps", "--format-version", "1", "--offline"])
        .current_dir(&root)
        .output_within(cohort::QUICK_LIMIT, "cargo metadata");
    assert!(out.status.success(), "cargo metadata: {}", String::from_utf8_lossy(&out.stderr));
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON");
    let mut members: Vec<String> = meta["packages"]
        .as_array()
        .expect("a package list")
        .iter()
        .map(|p| {
            let manifest = Path::new(p["manifest_path"].as_str().expect("a manifest path"));
            let dir = manifest.parent().expect("a directory");
            let rel = dir.strip_prefix(&root).expect("a member inside the workspace").to_string_lossy().into_owned();
            if rel.is_empty() { ".".to_string() } else { rel }
        })
        .collect();
    members.sort();
    let covered: Vec<&str> = cohort_build_id::BUILD_ID_MEMBERS.split(',').collect();
    let missing: Vec<&String> = members.iter().filter(|m| !covered.contains(&m.as_str())).collect();
    assert!(missing.is_empty(), "members the build id does not cover: {missing:?} (covered: {covered:?})");
    assert!(covered.iter().any(|c| c.starts_with("papers/")), "no paper covered: {covered:?}");
}
