//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! The paper's trainers, `orchestrator train vtxo-transient-data …` (the optimisation table of
//! Sec. 3.1/3.2.1, [`crate::learn::transient::data`]) and `orchestrator train vtxo-transient …` (the
//! transient DNN, [`crate::learn::transient::train`]), and the arguments of `orchestrator vtxo
//! transient-mc` ([`crate::learn::transient::mc`]).

use std::path::PathBuf;

use clap::{FromArgMatches, Parser};
use cohort_host::CommandError;

use crate::learn::transient::data::{self, DataError, NAME, Options};
use crate::learn::transient::sim::DT_S;

#[derive(Parser)]
#[command(
    name = "vtxo-transient-data",
    about = "Seed 002 (VTXO) transient optimisation data (Sec. 3.1, 3.2.1): random q0, w0, w; simulated \
             annealing of the Lyapunov gains (k1, k2) and the duration T minimising chi = E + w*e on the \
             attitude dynamics; CSV, resumable (a re-run continues the same file), byte-identical per seed."
)]
pub struct DataArgs {
    /// Points (rows) the table must hold.
    #[arg(long)]
    pub points: usize,
    /// Seeds every point's draw and annealer (point i uses stream i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Annealing candidates per point (the paper: 300).
    #[arg(long, default_value_t = 300)]
    pub iterations: u32,
    /// Integrator step, s (must divide 4 s and 7.2 s).
    #[arg(long, default_value_t = DT_S)]
    pub dt: f64,
    /// Worker threads (the result does not depend on them).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// The CSV to write or continue.
    #[arg(long)]
    pub out: PathBuf,
}

/// The DNN trainer's name.
pub const DNN_NAME: &str = "vtxo-transient";

#[derive(Parser)]
#[command(
    name = "vtxo-transient",
    about = "Seed 002 (VTXO) transient DNN (Sec. 3.2.1): R^8 (q0, w0, w) -> R^5 (E, e, T, k1, k2), a 3-layer ReLU \
             head per output, Adam on the MAPE, max-norm, 4-fold cross-validation, early stop on 20 %; \
             candle on the CPU; writes the weights (safetensors) and NAME-report.md. Byte-identical on re-run."
)]
pub struct DnnArgs {
    /// The data table (`orchestrator train vtxo-transient-data`).
    #[arg(long, default_value = "papers/vtxo/data/transient-sa.csv")]
    pub data: PathBuf,
    /// Weights file to write.
    #[arg(long, default_value = crate::learn::transient::dnn::COMMITTED)]
    pub out: PathBuf,
    /// Seeds the fold split, the initial weights and the batch order.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Most epochs per fit.
    #[arg(long, default_value_t = 300)]
    pub epochs: usize,
    /// Units per hidden layer.
    #[arg(long, default_value_t = 32)]
    pub hidden: usize,
    /// Fraction of the rows with the largest χ = E + w·e dropped before training (the paper's
    /// post-processing as we read it; 0 keeps every row).
    #[arg(long, default_value_t = crate::learn::transient::train::DROP_WORST)]
    pub drop_worst: f64,
}

/// `orchestrator vtxo transient-mc` arguments.
#[derive(clap::Args)]
pub struct McArgs {
    /// Draws (the paper's bounds are P99s: 200 or more).
    #[arg(long, default_value_t = 200)]
    pub draws: usize,
    /// Seed of the draws (the committed table uses seed 1: use another).
    #[arg(long, default_value_t = 2)]
    pub seed: u64,
    /// Annealing candidates per draw for the SA-optimal flight.
    #[arg(long, default_value_t = 300)]
    pub iterations: u32,
    /// The DNN's weights.
    #[arg(long, default_value = crate::learn::transient::dnn::COMMITTED)]
    pub weights: PathBuf,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
}

/// `orchestrator vtxo transient-mc`.
pub fn run_mc(a: &McArgs) -> Result<String, CommandError> {
    if a.draws == 0 || a.iterations == 0 || a.threads == 0 {
        return Err(CommandError::invalid("--draws, --iterations and --threads must be at least 1"));
    }
    let md = crate::learn::transient::mc::run(&a.weights, a.draws, a.seed, a.iterations, a.threads)
        .map_err(CommandError::invalid)?;
    Ok(format!(
        "{md}\n`orchestrator vtxo transient-mc --draws {} --seed {} --iterations {} --weights {}`",
        a.draws,
        a.seed,
        a.iterations,
        a.weights.display()
    ))
}

/// The trainers' clap commands.
pub fn commands() -> Vec<clap::Command> {
    vec![<DataArgs as clap::CommandFactory>::command(), <DnnArgs as clap::CommandFactory>::command()]
}

fn run_dnn(matches: &clap::ArgMatches) -> Result<String, CommandError> {
    let a = DnnArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    if a.epochs == 0 || a.hidden == 0 || a.hidden > crate::learn::transient::dnn::MAX_HIDDEN {
        return Err(CommandError::invalid(format!(
            "--epochs {} --hidden {}: at least 1 epoch, 1 to {} units",
            a.epochs,
            a.hidden,
            crate::learn::transient::dnn::MAX_HIDDEN
        )));
    }
    if !(0.0..1.0).contains(&a.drop_worst) {
        return Err(CommandError::invalid(format!("--drop-worst {}: a fraction in [0, 1)", a.drop_worst)));
    }
    if let Err(e) = crate::learn::transient::train::read_table(&a.data) {
        return Err(CommandError::invalid(format!("--data: {e}")));
    }
    let mut o = crate::learn::transient::train::Options::reference(a.data.clone(), a.out.clone(), a.seed);
    (o.epochs, o.hidden, o.drop_worst) = (a.epochs, a.hidden, a.drop_worst);
    let command = format!(
        "orchestrator train {DNN_NAME} --data {} --out {} --seed {} --epochs {} --hidden {} --drop-worst {}",
        a.data.display(),
        a.out.display(),
        a.seed,
        a.epochs,
        a.hidden,
        a.drop_worst
    );
    let t0 = std::time::Instant::now();
    let report = crate::learn::transient::train::train(&o).map_err(CommandError::failed)?;
    let md = report.markdown(&command, &o);
    let path = crate::learn::transient::train::report_path(&o.out);
    std::fs::write(&path, &md).map_err(|e| CommandError::failed(format!("{}: {e}", path.display())))?;
    Ok(format!(
        "{md}\nwall-clock {:.1} s\nwritten: {} and {}",
        t0.elapsed().as_secs_f64(),
        o.out.display(),
        path.display()
    ))
}

/// Run trainer `name`.
pub fn run(name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
    if name == DNN_NAME {
        return run_dnn(matches);
    }
    if name != NAME {
        return Err(CommandError::invalid(format!("vtxo has no trainer {name:?}")));
    }
    let a = DataArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    let o = Options {
        points: a.points,
        seed: a.seed,
        iterations: a.iterations,
        dt_s: a.dt,
        threads: a.threads,
        out: a.out,
    };
    let s = data::run(&o).map_err(|e| match e {
        DataError::Options(_) | DataError::Existing { .. } => CommandError::invalid(e.to_string()),
        DataError::Io { .. } => CommandError::failed(e.to_string()),
    })?;
    let rate = if s.seconds > 0.0 { s.written as f64 * 60.0 / s.seconds } else { 0.0 };
    let table2 = crate::learn::transient::stats::table2_markdown(&o.out).map_err(CommandError::failed)?;
    Ok(format!(
        "{table2}\n{}: {} points ({} were there, {} new) in {:.1} s: {:.1} points/min\nwritten: {}",
        NAME,
        s.resumed_from + s.written,
        s.resumed_from,
        s.written,
        s.seconds,
        rate,
        o.out.display()
    ))
}
