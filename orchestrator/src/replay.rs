//! `orchestrator replay RUN_DIR --agent I [--incarnation N]`: re-run agent I of a recorded run
//! (`launch --record`) against its recorded inputs and compare its shares with the recorded ones
//! (the runtime's `recording::replay` does the work; this reads the run directory and reports).
//! An agent relaunched by a `restart` fault has one recording per process (`agent-<I>.mcap`,
//! `agent-<I>.1.mcap`, …); each is replayed on its own, the relaunches from the checkpoint their
//! recording carries, and all of them unless `--incarnation` picks one.
//!
//! Exit codes: 0 every share identical; 1 a share differs (or one is missing or extra); 2 invalid
//! input (no such run directory, no recording, an agent out of range, a damaged recording).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;
use cohort_runtime::recording::{self, reader, replay};
use cohort_scenario::Overrides;
use cohort_wire::transport::Proc;

use crate::{EXIT_FAILED, EXIT_INVALID};

/// Run the command; prints its result and returns its exit code (the worst incarnation's).
pub fn command(run_dir: &Path, agent: u32, incarnation: Option<u32>, out: Option<&Path>) -> ExitCode {
    let s = match setup(run_dir, agent) {
        Ok(s) => s,
        Err(e) => {
            tracing::error!("{e}");
            return ExitCode::from(EXIT_INVALID);
        }
    };
    let me = Proc::Agent(agent);
    let chosen = match incarnation {
        Some(n) => vec![n],
        None => recording::incarnations(run_dir, me),
    };
    // No recording at all: name the first process's file (the reader says "no recording here").
    let chosen = if chosen.is_empty() { vec![0] } else { chosen };
    let single = chosen.len() == 1;
    let mut worst = 0u8;
    for n in chosen {
        // Named like the recordings: replay/agent-<I>, replay/agent-<I>.<N>; `--out` is the one
        // replay's directory, or the first's with the relaunches' beside it.
        let out = match out {
            Some(dir) if single || n == 0 => dir.to_path_buf(),
            Some(dir) => PathBuf::from(format!("{}.{n}", dir.display())),
            None if n == 0 => run_dir.join("replay").join(me.name()),
            None => run_dir.join("replay").join(format!("{}.{n}", me.name())),
        };
        let code = match incarnation_run(&s, run_dir, agent, n, &out) {
            Ok((outcome, cut_short)) => verdict(agent, n, &outcome, cut_short),
            Err(e) => {
                tracing::error!("{e}");
                EXIT_INVALID
            }
        };
        worst = worst.max(code);
    }
    ExitCode::from(worst)
}

/// Print what the replay of incarnation `n` found; its exit code.
fn verdict(agent: u32, n: u32, outcome: &replay::ReplayOutcome, cut_short: bool) -> u8 {
    let who = match outcome.restored_from {
        Some(step) if n > 0 => format!("agent {agent} (relaunch {n}, resumed from its checkpoint of step {step})"),
        _ => format!("agent {agent}"),
    };
    if outcome.identical() {
        outln!("replayed {} steps of {who}: all {} shares identical", outcome.steps, outcome.identical);
        return 0;
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
            "replayed {} steps of {who}: all {} recorded shares identical (the recording stops there; \
             {} share(s) sent past its end)",
            outcome.steps,
            outcome.identical,
            outcome.replayed_sent - outcome.recorded_sent
        );
        return 0;
    }
    if let Some(m) = &outcome.first {
        outln!("first mismatch: {who}'s {m}");
    }
    if outcome.recorded_sent != outcome.replayed_sent {
        outln!("{who} sent {} shares in the replay, {} in the recording", outcome.replayed_sent, outcome.recorded_sent);
    }
    if let Some(e) = &outcome.error {
        outln!("the replayed agent ended early: {e}");
    }
    let compared = outcome.recorded_sent.min(outcome.replayed_sent);
    outln!("replayed {} steps of {who}: {} of {compared} shares differ", outcome.steps, compared - outcome.identical);
    EXIT_FAILED
}

/// The run directory's scenario, checked to have agent processes and an agent `agent`; every
/// error names what and where.
fn setup(run_dir: &Path, agent: u32) -> Result<Setup, String> {
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
    Ok(s)
}

/// Read incarnation `n`'s recording and replay it into `out`; the outcome and whether the
/// recording was cut short.
fn incarnation_run(
    s: &Setup,
    run_dir: &Path,
    agent: u32,
    n: u32,
    out: &Path,
) -> Result<(replay::ReplayOutcome, bool), String> {
    let rec = reader::read(&recording::incarnation_path(run_dir, Proc::Agent(agent), n)).map_err(|e| e.to_string())?;
    if let Some(c) = &rec.cut_short {
        tracing::warn!("{c}");
    }
    if let Some(b) = rec.meta.get("build_id").filter(|b| b.as_str() != cohort_wire::build_id()) {
        tracing::warn!("recorded by build {b}, replayed with build {}", cohort_wire::build_id());
    }
    if n > 0 && rec.attachment(recording::RESTORED_FROM).is_none() {
        return Err(format!(
            "{}: a relaunched agent's recording without the checkpoint it resumed from (attachment {}): \
             written by an older build?",
            rec.path.display(),
            recording::RESTORED_FROM
        ));
    }
    let outcome = replay::replay_agent(s, &rec, agent, &RunDirs::new(out)).map_err(|e| e.to_string())?;
    tracing::info!("replayed agent's telemetry: {}", out.join("telemetry").display());
    Ok((outcome, rec.cut_short.is_some()))
}
