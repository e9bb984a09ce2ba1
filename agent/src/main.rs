//! The `agent` process: one spacecraft's estimator, controller and learner. Launched by the
//! orchestrator; see `cohort_runtime::process` for exit codes.

use std::process::ExitCode;

use clap::Parser;
use cohort_runtime::process::{CommonArgs, child_main};
use cohort_wire::transport::Proc;

/// Cohort agent process (launched by `orchestrator launch`, not by hand).
#[derive(Parser)]
#[command(version = cohort_wire::BUILD_ID)]
struct Args {
    /// This agent's id (1..=N, as in the scenario).
    #[arg(long)]
    id: u32,
    #[command(flatten)]
    common: CommonArgs,
}

fn main() -> ExitCode {
    let a = Args::parse();
    let id = a.id;
    child_main(a.common.into_spec(Proc::Agent(id)), |scenario, transport, params| {
        let mut algo = agent::build(scenario, id);
        let neighbours = scenario.agent(id).neighbours.clone();
        cohort_runtime::drive::run_agent(transport, algo.as_mut(), id, &neighbours, params)
    })
}
