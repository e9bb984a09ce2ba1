//! The Python loader (`python/`): its tests launch a short fig1 run and read it with
//! `cohort.load`, in Parquet and in CSV, and redraw Fig. 4 with the example script. Skipped, with
//! the reason printed, when python3 or pyarrow is missing (scripts/test installs them when it can).

use std::process::Command;

use cohort::{describe_output, repo_root};

fn python_with_pyarrow() -> Result<(), String> {
    match Command::new("python3").args(["-c", "import pyarrow"]).output() {
        Err(e) => Err(format!("no python3 ({e})")),
        Ok(o) if !o.status.success() => {
            Err(format!("python3 has no pyarrow: {}", String::from_utf8_lossy(&o.stderr).trim()))
        }
        Ok(_) => Ok(()),
    }
}

#[test]
fn the_python_loader_reads_a_run_and_redraws_fig4() {
    if let Err(why) = python_with_pyarrow() {
        eprintln!("SKIPPED the Python loader test: {why} (python3 -m pip install ./python)");
        return;
    }
    let o = Command::new("python3")
        .args(["-m", "unittest", "discover", "-v", "-s", "python/tests"])
        .current_dir(repo_root())
        .output()
        .expect("running python3");
    assert!(o.status.success(), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    // The release binaries are built before the tests (scripts/test): the run tests must have run.
    assert!(err.contains("Ran 3 tests") && !err.contains("not built"), "{err}");
    if err.contains("matplotlib is not installed") {
        eprintln!("the example drew no PNG: matplotlib is not installed");
    }
}
