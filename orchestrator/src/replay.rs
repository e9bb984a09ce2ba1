//! `orchestrator replay RUN_DIR --agent I`: re-run agent I of a recorded run (`launch --record`)
//! against its recorded inputs and compare its shares with the recorded ones (the runtime's
//! `recording::replay` does the work; this reads the run directory and reports).
//!
//! Exit codes: 0 every share identical; 1 a share differs (or one is missing or extra); 2 invalid
//! input (no such run directory, no recording, an agent out of range, a damaged recording).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use cohort_runtime::record::RunDirs;
use cohort_runtime::recording::{self, reader, replay};
use cohort_scenario::Overrides;
use cohort_wire::transport::Proc;

use crate::{EXIT_FAILED, EXIT_INVALID};

/// Run the command; prints its result and returns its exit code.
pub fn command(run_dir: &Path, agent: u32, out: Option<&Path>) -> ExitCode {
    let (outcome, out, cut_short) = match run(run_dir, agent, out) {
        Ok(x) => x,
        Err(e) => {
            tracing::error!("{e}");
            return ExitCode::from(EXIT_INVALID);
        }
    };
    tracing::info!("replayed agent's telemetry: {}", out.join("telemetry").display());
    if outcome.identical() {
        outln!("replayed {} steps of agent {agent}: all {} shares identical", outcome.steps, outcome.identical);
        return ExitCode::SUCCESS;
    }
    // A recording cut short ends inside a step: the replayed agent goes on to send the share the
    // recording stops before. Every share recorded is compared; the ones past its end cannot be.
    if cut_short
        && outcome.first.is_none()
        && outcome.error.is_none()
        && outcome.identical == outcome.recorded_sent
        && outcome.replayed_sent > outcome.recorded_sent
    {
        outln!(
            "replayed {} steps of agent {agent}: all {} recorded shares identical (the recording stops there; \
             {} share(s) sent past its end)",
            outcome.steps,
            outcome.identical,
            outcome.replayed_sent - outcome.recorded_sent
        );
        return ExitCode::SUCCESS;
    }
    if let Some(m) = &outcome.first {
        outln!("first mismatch: agent {agent}'s {m}");
    }
    if outcome.recorded_sent != outcome.replayed_sent {
        outln!(
            "agent {agent} sent {} shares in the replay, {} in the recording",
            outcome.replayed_sent,
            outcome.recorded_sent
        );
    }
    if let Some(e) = &outcome.error {
        outln!("the replayed agent ended early: {e}");
    }
    let compared = outcome.recorded_sent.min(outcome.replayed_sent);
    outln!(
        "replayed {} steps of agent {agent}: {} of {compared} shares differ",
        outcome.steps,
        compared - outcome.identical
    );
    ExitCode::from(EXIT_FAILED)
}

/// Read the run directory and replay; every error names what and where.
fn run(run_dir: &Path, agent: u32, out: Option<&Path>) -> Result<(replay::ReplayOutcome, PathBuf, bool), String> {
    if !run_dir.is_dir() {
        return Err(format!("{}: no such run directory", run_dir.display()));
    }
    let file = run_dir.join("scenario.toml");
    if !file.is_file() {
        return Err(format!("{}: missing: not a run directory written by `launch`", file.display()));
    }
    let s = crate::load(&file, &Overrides::default()).map_err(|e| e.to_string())?;
    if let Some(c) = s.algorithm.coupled() {
        return Err(format!(
            "{}: the scenario is {}: no agent processes, no messages to replay",
            run_dir.display(),
            c.describe()
        ));
    }
    if agent == 0 || agent > s.n_agents() {
        return Err(format!(
            "--agent {agent}: out of range, the run {} has agents 1..={}",
            run_dir.display(),
            s.n_agents()
        ));
    }
    let rec = reader::read(&recording::path_for(run_dir, Proc::Agent(agent))).map_err(|e| e.to_string())?;
    if let Some(c) = &rec.cut_short {
        tracing::warn!("{c}");
    }
    if let Some(b) = rec.meta.get("build_id").filter(|b| b.as_str() != cohort_wire::BUILD_ID) {
        tracing::warn!("recorded by build {b}, replayed with build {}", cohort_wire::BUILD_ID);
    }
    let out = out.map_or_else(|| run_dir.join("replay").join(Proc::Agent(agent).name()), Path::to_path_buf);
    let outcome = replay::replay_agent(&s, &rec, agent, &RunDirs::new(&out)).map_err(|e| e.to_string())?;
    Ok((outcome, out, rec.cut_short.is_some()))
}
