//! The `plant` process: integrates the truth, produces every agent's readings, applies their
//! commands. Launched by the orchestrator; see `cohort_runtime::process` for exit codes.

use std::process::ExitCode;

use clap::Parser;
use cohort_runtime::process::{CommonArgs, child_main};
use cohort_wire::transport::Proc;

/// Cohort plant process (launched by `orchestrator launch`, not by hand).
#[derive(Parser)]
#[command(version = cohort_wire::BUILD_ID)]
struct Args {
    #[command(flatten)]
    common: CommonArgs,
}

fn main() -> ExitCode {
    let spec = Args::parse().common.into_spec(Proc::Plant);
    child_main(spec, |scenario, transport, params| {
        let mut model = plant::build(scenario);
        let mut rng = cohort_runtime::rng::process_rng(scenario.scenario.seed, Proc::Plant);
        cohort_runtime::drive::run_plant(transport, model.as_mut(), &mut rng, scenario.n_agents(), params)
    })
}
