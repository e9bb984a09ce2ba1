//! The Python loader (`python/`): its tests launch a short run of the runtime's smoke scenario (and a three-case campaign, read with `cohort.load_campaign`)
//! and read it with `cohort.load`, in Parquet and in CSV; fig1's example (`papers/fig1/python/`) redraws Fig. 4 from a short fig1 run with it. Skipped,
//! with the reason printed, when python3 or pyarrow is missing (scripts/test installs them when
//! it can).

use std::process::Command;

use cohort::OutputWithin;
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

/// Run the Python unit tests in `dir` (from the repository root); returns their stderr.
fn unittest(dir: &str, tests: usize) -> Option<String> {
    // The Python tests launch runs of their own.
    let _g = cohort::heavy();
    if let Err(why) = python_with_pyarrow() {
        eprintln!("SKIPPED the Python tests in {dir}: {why} (python3 -m pip install ./python)");
        return None;
    }
    let o = Command::new("python3")
        .args(["-m", "unittest", "discover", "-v", "-s", dir, "-p", "test_*.py"])
        .current_dir(repo_root())
        .output_within(cohort::RUN_LIMIT, "the Python loader's unit tests");
    assert!(o.status.success(), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    // The release binaries are built before the tests (scripts/test): the run tests must have run.
    assert!(err.contains(&format!("Ran {tests} tests")) && !err.contains("not built"), "{err}");
    Some(err)
}

#[test]
fn the_python_loader_reads_a_run_in_either_format() {
    unittest("python/tests", 3);
}

#[test]
fn the_fig1_python_example_redraws_fig4() {
    if let Some(err) = unittest("papers/fig1/python", 2)
        && err.contains("matplotlib is not installed")
    {
        eprintln!("the example drew no PNG: matplotlib is not installed");
    }
}
