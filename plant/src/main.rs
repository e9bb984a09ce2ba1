//! The `plant` process: integrates the truth, produces every agent's readings, applies their
//! commands. Launched by the orchestrator; see `cohort_runtime::process` for exit codes. The model
//! comes from the paper that registered the scenario's plant kind (`papers/registry`).

use std::process::ExitCode;

use clap::Parser;
use cohort_runtime::process::{CommonArgs, child_main};
use cohort_wire::transport::Proc;

/// Cohort plant process (launched by `orchestrator launch`, not by hand).
#[derive(Parser)]
#[command(version = cohort_build_id::BUILD_ID)]
struct Args {
    #[command(flatten)]
    common: CommonArgs,
}

fn main() -> ExitCode {
    // First: the handshakes, recordings and `--version` read the id through cohort_wire.
    cohort_wire::set_build_id(cohort_build_id::BUILD_ID);
    let spec = Args::parse().common.into_spec(Proc::Plant);
    child_main(spec, cohort_registry::PAPERS, |setup, transport, params| {
        let mut model = setup.plant.build(setup);
        let mut rng = cohort_runtime::rng::process_rng(setup.scenario.seed, Proc::Plant);
        cohort_runtime::drive::run_plant(transport, model.as_mut(), &mut rng, setup.n_agents(), params)
    })
}
