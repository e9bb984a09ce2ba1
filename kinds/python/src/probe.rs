//! The import check of `orchestrator check` and `launch`: the user's module imported in a child
//! interpreter (the one pyo3 was built against), its class and methods looked up and their
//! signatures compared with what the runtime will call, so that each mistake is a named problem at
//! the section's key path before any process starts. A module that crashes its interpreter on
//! import, or never finishes importing, is a problem too, not a dead or hung orchestrator.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long an import may take.
const IMPORT_TIMEOUT: Duration = Duration::from_secs(60);

/// The interpreter to run the check in: the one the build linked (its `site-packages` is the
/// embedded interpreter's), else `python3` on the PATH.
fn python() -> &'static str {
    option_env!("COHORT_PYTHON_EXE").unwrap_or("python3")
}

/// What the class needs (see probe.py).
#[derive(Debug, Clone, Copy)]
pub enum Role {
    Algorithm,
    Plant,
}

/// None if `class` in `file` can fly as a `role`; else what is wrong, in words.
pub fn check(file: &Path, class: &str, role: Role) -> Option<String> {
    let role = match role {
        Role::Algorithm => "algorithm",
        Role::Plant => "plant",
    };
    let mut child = match Command::new(python())
        .args(["-c", include_str!("probe.py")])
        .arg(file)
        .args([class, role])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
    {
        Ok(c) => c,
        Err(e) => return Some(format!("cannot run {} to check the module ({e}): is Python 3 installed?", python())),
    };
    // Read both pipes while it runs: a module that prints much must not block on a full pipe.
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_string(&mut text);
            }
            text
        })
    };
    let out = drain(child.stdout.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let err = drain(child.stderr.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break s,
            Ok(None) if start.elapsed() > IMPORT_TIMEOUT => {
                let _ = child.kill();
                let _ = child.wait();
                return Some(format!("importing it did not finish in {} s", IMPORT_TIMEOUT.as_secs()));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(10)),
            Err(e) => return Some(format!("waiting for the check: {e}")),
        }
    };
    let (out, err) = (out.join().unwrap_or_default(), err.join().unwrap_or_default());
    let answer: Option<serde_json::Value> = out.lines().last().and_then(|l| serde_json::from_str(l).ok());
    match answer {
        Some(v) if v.get("ok").is_some() => None,
        Some(v) => Some(v.get("error").and_then(|e| e.as_str()).unwrap_or("the check failed").to_string()),
        None => {
            let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no output").trim();
            Some(format!("importing it ended the interpreter ({status}): {last}"))
        }
    }
}
