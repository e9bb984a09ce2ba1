//! The `agent` process: one spacecraft's estimator, controller and learner. Launched by the
//! orchestrator; see `cohort_runtime::process` for exit codes. The algorithm comes from the paper
//! that registered the scenario's algorithm kind (`papers/registry`).

use std::process::ExitCode;

use clap::Parser;
use cohort_runtime::checkpoint::{AgentState, Checkpoint, CheckpointError, CheckpointProblem, path_for};
use cohort_runtime::process::{CommonArgs, child_main};
use cohort_runtime::record::{ErrorKind, ProcessError, ProcessReport};
use cohort_runtime::recording::walk::Attachment;
use cohort_runtime::recording::{CHECKPOINT_MEDIA_TYPE, RESTORED_FROM};
use cohort_wire::transport::Proc;

/// Cohort agent process (launched by `orchestrator launch`, not by hand).
#[derive(Parser)]
#[command(version = cohort_build_id::BUILD_ID)]
struct Args {
    /// This agent's id (1..=N, as in the scenario).
    #[arg(long)]
    id: u32,
    /// Relaunched by a `restart` fault: resume from the agent's latest checkpoint in the run
    /// directory (refused if it is damaged, of another version, run, agent or algorithm).
    /// Relaunched at this step: resume from the agent's latest checkpoint, which must be older.
    #[arg(long)]
    restore_at: Option<u64>,
    #[command(flatten)]
    common: CommonArgs,
}

fn main() -> ExitCode {
    // First: the handshakes, recordings and `--version` read the id through cohort_wire.
    cohort_wire::set_build_id(cohort_build_id::BUILD_ID);
    let a = Args::parse();
    let (id, restore_at) = (a.id, a.restore_at);
    // A relaunched agent reads its checkpoint once, here: the bytes it resumes from are the ones
    // its recording carries (`run.record`), so a replay of this incarnation starts from them too.
    let raw = restore_at.map(|_| {
        let path = path_for(&a.common.run_dir, id);
        std::fs::read(&path).map_err(|e| format!("cannot restore: checkpoint {}: cannot read: {e}", path.display()))
    });
    let mut spec = a.common.into_spec(Proc::Agent(id));
    if let Some(Ok(bytes)) = &raw {
        spec.record_attachments.push(Attachment {
            name: RESTORED_FROM.into(),
            media_type: CHECKPOINT_MEDIA_TYPE.into(),
            data: bytes.clone(),
        });
    }
    child_main(spec, cohort_registry::PAPERS, |setup, transport, params| {
        let mut algo = setup.algorithm.build(setup, id);
        let neighbours = setup.agent(id).neighbours.clone();
        let checkpoint = if let (Some(at), Some(raw)) = (restore_at, raw) {
            match raw.and_then(|bytes| {
                load(
                    &bytes,
                    &params.dirs.root,
                    (params.run_id, id),
                    &params.algorithm_kind,
                    algo.as_mut(),
                    (at, params.n_steps),
                )
            }) {
                Ok(c) => Some(c),
                Err(e) => return failed(id, e),
            }
        } else {
            None
        };
        cohort_runtime::drive::run_agent(transport, algo.as_mut(), id, &neighbours, params, checkpoint.as_ref())
    })
}

/// Check the latest checkpoint (`bytes`, the file as read), restore it, and leave evidence of both
/// for the tests and the curious: the file as read (`agent-<id>.loaded.ckpt`) and the state as
/// restored, encoded again from the live algorithm (`agent-<id>.restored.ckpt`).
fn load(
    bytes: &[u8],
    run_dir: &std::path::Path,
    (run_id, id): (u64, u32),
    kind: &str,
    algo: &mut dyn cohort_runtime::model::Algorithm,
    (relaunch_step, n_steps): (u64, u64),
) -> Result<Checkpoint, String> {
    let path = path_for(run_dir, id);
    let refused =
        |problem: CheckpointProblem| format!("cannot restore: {}", CheckpointError { path: path.clone(), problem });
    let c = Checkpoint::decode(bytes, run_id, id, kind).map_err(|e| refused(e.into()))?;
    c.check_resume(relaunch_step, n_steps).map_err(|e| refused(e.into()))?;
    algo.restore_state(&c.state.algorithm)
        .map_err(|e| format!("cannot restore: checkpoint {}: algorithm state: {e}", path.display()))?;
    let dir = path.parent().expect("checkpoints live in a directory");
    let loaded = dir.join(format!("agent-{id}.loaded.ckpt"));
    std::fs::write(&loaded, bytes).map_err(|e| format!("{}: {e}", loaded.display()))?;
    let again =
        Checkpoint { state: AgentState { algorithm: algo.save_state(), held: c.state.held.clone() }, ..c.clone() };
    // The error names the file.
    again.write(&dir.join(format!("agent-{id}.restored.ckpt"))).map_err(|e| e.to_string())?;
    tracing::info!("restored from checkpoint step {} ({})", c.step, path.display());
    Ok(c)
}

fn failed(id: u32, e: String) -> ProcessReport {
    ProcessReport::failed_at_start(Proc::Agent(id).name(), ProcessError::new(ErrorKind::Checkpoint, e))
}
