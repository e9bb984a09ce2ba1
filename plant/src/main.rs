//! The `plant` process: integrates the truth, produces every agent's readings, applies their
//! commands. Launched by the orchestrator; see `cohort_runtime::process` for exit codes.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use cohort_runtime::process::{ChildSpec, child_main};
use cohort_wire::transport::Proc;

/// Cohort plant process (launched by `orchestrator launch`, not by hand).
#[derive(Parser)]
#[command(version = cohort_wire::BUILD_ID)]
struct Args {
    /// Run directory (holds the resolved scenario.toml; telemetry goes there).
    #[arg(long)]
    run_dir: PathBuf,
    /// Run id, hexadecimal (names the run's iceoryx2 resources).
    #[arg(long)]
    run_id: String,
    /// Build id of the orchestrator; must equal this binary's.
    #[arg(long)]
    build_id: String,
    /// Override of run.step_timeout_s.
    #[arg(long)]
    step_timeout_s: Option<f64>,
}

fn main() -> ExitCode {
    let a = Args::parse();
    let spec = ChildSpec {
        me: Proc::Plant,
        run_dir: a.run_dir,
        run_id: a.run_id,
        build_id: a.build_id,
        step_timeout_s: a.step_timeout_s,
    };
    child_main(spec, |scenario, transport, params| {
        let mut model = plant::build(scenario);
        let mut rng = cohort_runtime::rng::process_rng(scenario.scenario.seed, Proc::Plant);
        cohort_runtime::drive::run_plant(transport, model.as_mut(), &mut rng, scenario.n_agents(), params)
    })
}
