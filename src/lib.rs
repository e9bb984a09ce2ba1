//! The root package holds Cohort's tests that launch real processes (`tests/`); this library only
//! gives them shared helpers.

use std::path::PathBuf;
use std::time::Duration;

mod within;
pub use within::{OutputWithin, finish_within};

/// The longest a test waits for one launch (a whole run, on a loaded 2-core machine) before it
/// fails naming what it waited for.
pub const RUN_LIMIT: Duration = Duration::from_secs(600);
/// The longest a test waits for a command that reads and checks but runs nothing (`check`,
/// `report`, `replay`, a refused launch).
pub const QUICK_LIMIT: Duration = Duration::from_secs(120);

/// The workspace root (where `topologies/` lives), fixed at compile time.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `*.toml` file names in `rel` (a directory under the repository root), sorted.
pub fn tomls_in(rel: &str) -> Vec<String> {
    let dir = repo_root().join(rel);
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|e| e.expect("readable directory entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    names.sort();
    names
}

/// Path of a workspace binary (e.g. `"orchestrator"`) built with the same profile as the running
/// test. A test executable runs from `<target dir>/<profile>/deps/`, and binaries sit one level
/// up, in `<target dir>/<profile>/`. `cargo test` does not build them: run the tests with
/// `scripts/test`, which does. This function does not check that the binary exists.
pub fn bin_path(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("cannot find the running test executable");
    let profile_dir = exe
        .parent() // deps/
        .and_then(|deps| deps.parent())
        .expect("test executable is not in <target dir>/<profile>/deps/");
    profile_dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}

/// The lock every test that launches a run holds while it runs. A run already puts several
/// processes on the machine's cores; two at once in one test harness would slow both past their
/// timeouts on a loaded 2-core machine. Tests of one harness share it (the test files of a
/// package are modules of one harness, which saves linking one per file). A test that panicked
/// holding it does not poison the others.
pub fn heavy() -> std::sync::MutexGuard<'static, ()> {
    static HEAVY: std::sync::Mutex<()> = std::sync::Mutex::new(());
    HEAVY.lock().unwrap_or_else(|p| p.into_inner())
}

/// A test's scratch directory ([`scratch_dir`]): removed when it goes out of scope, unless the
/// test is failing (then it stays, and its path is printed, for a look at what the run left).
#[derive(Debug)]
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for Scratch {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for Scratch {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept for a look: {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A fresh, empty scratch directory under the system temp dir, unique per call.
pub fn scratch_dir(tag: &str) -> Scratch {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "cohort-test-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::SeqCst)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("creating a scratch directory");
    Scratch(dir)
}

/// What a test that launches runs starts with: the [`heavy`] lock and its [`scratch_dir`] (the
/// directory goes first when both drop at the end of the test).
pub fn heavy_scratch(tag: &str) -> (std::sync::MutexGuard<'static, ()>, Scratch) {
    (heavy(), scratch_dir(tag))
}

/// Pids of live processes whose command line mentions `needle` (e.g. a run directory), other
/// than the calling process.
pub fn processes_mentioning(needle: &str) -> Vec<(u32, String)> {
    let me = std::process::id();
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir("/proc") else { return out };
    for e in rd.flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else { continue };
        if pid == me {
            continue;
        }
        let Ok(raw) = std::fs::read(e.path().join("cmdline")) else { continue };
        let cmd = String::from_utf8_lossy(&raw).replace('\0', " ");
        // A zombie has an empty command line; it is not running.
        if cmd.contains(needle) {
            out.push((pid, cmd.trim().to_string()));
        }
    }
    out
}

/// iceoryx2 entries of run `run_id_hex` left in /dev/shm or under its root directory.
pub fn iceoryx2_leftovers(run_id_hex: &str) -> Vec<String> {
    let prefix = format!("cohort_{run_id_hex}_");
    let mut left: Vec<String> = std::fs::read_dir("/dev/shm")
        .map(|rd| {
            rd.flatten()
                .map(|e| e.file_name().to_string_lossy().to_string())
                .filter(|n| n.starts_with(&prefix))
                .collect()
        })
        .unwrap_or_default();
    let root = cohort_wire::transport::iox::user_base().join(run_id_hex);
    if root.exists() {
        left.push(root.display().to_string());
    }
    left
}

/// Every telemetry value of a run directory as (file, row, column, bits), in file order: read by
/// the one telemetry reader (`cohort_report::Table`, Parquet or CSV); column 0 is the step `k`
/// itself, rows count from 2 (the first data line of a CSV).
pub fn telemetry_bits(run_dir: &std::path::Path) -> Vec<(String, usize, usize, u64)> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(run_dir.join("telemetry"))
        .expect("telemetry directory")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv" || e == "parquet"))
        .collect();
    files.sort();
    let mut out = Vec::new();
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let table = cohort_report::Table::read(&f).unwrap_or_else(|e| panic!("{e}"));
        for (row, k) in table.k.iter().enumerate() {
            out.push((name.clone(), row + 2, 0, *k));
            out.push((name.clone(), row + 2, 1, table.t[row].to_bits()));
            for (col, c) in table.columns.iter().enumerate() {
                out.push((name.clone(), row + 2, col + 2, c.values[row].to_bits()));
            }
        }
    }
    out
}

/// The telemetry file of process `stem` (`plant`, `agent-3`) in a run directory: the Parquet
/// file, or the CSV file when the run wrote CSV.
pub fn telemetry_path(run_dir: &std::path::Path, stem: &str) -> PathBuf {
    cohort_report::table::resolve(&run_dir.join("telemetry").join(format!("{stem}.parquet")))
}

/// A run's telemetry of process `stem` (`plant`, `agent-3`), whichever format it was written in.
pub fn telemetry_table(run_dir: &std::path::Path, stem: &str) -> cohort_report::Table {
    let path = run_dir.join("telemetry").join(format!("{stem}.parquet"));
    cohort_report::Table::read(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Column `name` (or `t_s`) of a run's telemetry of process `stem`.
pub fn telemetry_column(run_dir: &std::path::Path, stem: &str, name: &str) -> Vec<f64> {
    let table = telemetry_table(run_dir, stem);
    table.get(name).unwrap_or_else(|| panic!("{stem}: no column {name}")).to_vec()
}

/// A command running the orchestrator from the repository root (asserting it was built).
pub fn orchestrator_command() -> std::process::Command {
    let bin = bin_path("orchestrator");
    assert!(bin.is_file(), "{} not found: run the tests with scripts/test (it builds the binaries)", bin.display());
    let mut c = std::process::Command::new(bin);
    c.current_dir(repo_root());
    c
}

/// Exit status, stdout and stderr of a finished command, for assertion messages.
pub fn describe_output(o: &std::process::Output) -> String {
    format!(
        "exit: {:?}\n--- stdout ---\n{}\n--- stderr ---\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// `orchestrator launch FILE --out OUT --no-plots EXTRA...` from the repository root (`file` may
/// be relative to it), waited for.
pub fn launch_scenario(file: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    orchestrator_command()
        .arg("launch")
        .arg(file)
        .arg("--out")
        .arg(out)
        .arg("--no-plots")
        .args(extra)
        .output_within(RUN_LIMIT, &format!("orchestrator launch {} {}", file.display(), extra.join(" ")))
}

/// A JSON file (a summary, a process report), parsed.
pub fn read_json(path: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A run directory's `summary.json`.
pub fn summary(run_dir: &std::path::Path) -> serde_json::Value {
    read_json(&run_dir.join("summary.json"))
}

/// Column `name` (or `t_s`) of a telemetry CSV's text, as numbers (read by the one telemetry
/// reader, `cohort_report::Table`).
pub fn csv_column(csv: &str, name: &str) -> Vec<f64> {
    let table = cohort_report::Table::parse(csv, std::path::Path::new("(csv text)")).expect("a telemetry CSV");
    table.get(name).unwrap_or_else(|| panic!("no column {name}")).to_vec()
}

/// `topologies/<file>` to be written elsewhere: the files it names are relative to it (`"../…"`),
/// so they are made absolute.
pub fn scenario_text_with_absolute_paths(file: &str) -> String {
    let text = std::fs::read_to_string(repo_root().join("topologies").join(file)).unwrap();
    text.replace("\"../", &format!("\"{}/", repo_root().display()))
}

/// Run a command of the network lab's setup (`ip netns …`, `openssl …`): Ok, or an error with
/// the command line and its stderr.
pub fn sh(args: &[&str]) -> Result<(), String> {
    let o = std::process::Command::new(args[0])
        .args(&args[1..])
        .output()
        .map_err(|e| format!("{}: {e}", args.join(" ")))?;
    if o.status.success() {
        Ok(())
    } else {
        Err(format!("{}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr).trim()))
    }
}
