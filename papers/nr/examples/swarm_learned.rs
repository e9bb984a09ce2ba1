//! `cargo run --release -p cohort-paper-nr --example swarm_learned -- [--weights FILE] [--seed S]
//! [--n N] [--cases C]`: the learned swarm policy alone, in-process, on C seeded cases of N
//! vehicles (labels `eval0…`, never trained on), against the centralised SCP global solution of
//! each case: collisions, distance to the targets at T + 2 s, ∫‖u‖dt and compute time (see
//! `cohort_paper_nr::swarm::train::eval`). Prints a markdown table; exit 2 on a bad argument or file.
use std::path::PathBuf;

use clap::Parser;
use cohort_paper_nr::swarm::control::policy::DeepSetPolicy;
use cohort_paper_nr::swarm::train::eval::{evaluate, markdown};

#[derive(Parser)]
struct Args {
    #[arg(long, default_value = "papers/nr/weights/swarm.safetensors")]
    weights: PathBuf,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long, default_value_t = 8)]
    n: usize,
    #[arg(long, default_value_t = 10)]
    cases: usize,
}

fn main() {
    let a = Args::parse();
    let policy = match DeepSetPolicy::load(&a.weights) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    match evaluate(&policy, a.seed, a.n, a.cases) {
        Ok(rows) => print!("{}", markdown(&rows)),
        Err(e) => {
            eprintln!("--n {} --seed {}: {e}", a.n, a.seed);
            std::process::exit(2);
        }
    }
}
