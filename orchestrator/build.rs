//! Sets `COHORT_GIT_COMMIT`: the commit the orchestrator was built from (12 hex digits, or
//! `unknown` outside a git checkout), for `--version` beside the build id of the sources.
use std::process::Command;

// The run path of libpython (kind = "python"), shared with the other packages that link it.
#[path = "../kinds/python/rpath.rs"]
mod rpath;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    rpath::emit();
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=COHORT_GIT_COMMIT={commit}");
    // Rebuild when HEAD moves: HEAD itself (a checkout) and the branch it names (a commit), as
    // a loose ref or in packed-refs. Only files that exist: cargo reruns a script on every build
    // while a path it watches is missing (a worktree keeps its refs in the common directory,
    // which `--git-path` resolves).
    let mut watched = vec!["HEAD".to_string(), "packed-refs".to_string()];
    watched.extend(git(&["symbolic-ref", "-q", "HEAD"]));
    for name in watched {
        if let Some(path) = git(&["rev-parse", "--path-format=absolute", "--git-path", &name])
            && std::path::Path::new(&path).exists()
        {
            println!("cargo:rerun-if-changed={path}");
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
