//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! The science-phase trainers: `orchestrator train vtxo-science-data …` (the Pareto tables of
//! Sec. 3.1/3.2.2, [`crate::learn::science::data`]) and `orchestrator train vtxo-science …` (the science
//! DNN, [`crate::learn::science::train`], with the Table 3 analogue of [`crate::learn::science::stats`] in its
//! report).

use std::path::PathBuf;

use clap::{FromArgMatches, Parser};
use cohort_host::CommandError;

use crate::learn::science::data::{self, DataError, NAME, Options};
use crate::learn::science::sim::{DT_S, PHASE_S};

#[derive(Parser)]
#[command(
    name = "vtxo-science-data",
    about = "Seed 002 (VTXO) science-phase Pareto data (Sec. 3.1, 3.2.2): random science starts (84) with \
             their wheel and torque disturbances; a seeded NSGA-II over the PD (54) and SMC (58)-(60) gains \
             for chi = [E, e] (72); science-pd.csv and science-smc.csv, byte-identical per seed."
)]
pub struct DataArgs {
    /// Science starts (each gives one Pareto front per law).
    #[arg(long, default_value_t = 48)]
    pub draws: usize,
    /// Seeds every draw, its disturbances and its searches (draw i uses stream i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Designs per generation of the search.
    #[arg(long, default_value_t = 12)]
    pub population: usize,
    /// Generations of the search.
    #[arg(long, default_value_t = 8)]
    pub generations: usize,
    /// Length of the science phase, s.
    #[arg(long, default_value_t = PHASE_S)]
    pub phase: f64,
    /// Step (the command is held over it), s.
    #[arg(long, default_value_t = DT_S)]
    pub dt: f64,
    /// Worker threads (the tables do not depend on them).
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Directory of the two tables.
    #[arg(long, default_value = "papers/vtxo/data")]
    pub out: PathBuf,
}

/// The DNN trainer's name.
pub const DNN_NAME: &str = "vtxo-science";

#[derive(Parser)]
#[command(
    name = "vtxo-science",
    about = "Seed 002 (VTXO) science DNN (Sec. 3.2.2): per law (PD, SMC) (q0, w0, w) -> (E, e, k), 10-5-3 sigmoid              layers and a linear output layer, SGD on the MSE, <= 1000 epochs, candle on the CPU; writes the              weights (safetensors) and NAME-report.md with the held-out accuracy and the Table 3 analogue.              Byte-identical on re-run."
)]
pub struct DnnArgs {
    /// Directory of science-pd.csv and science-smc.csv (`orchestrator train vtxo-science-data`).
    #[arg(long, default_value = "papers/vtxo/data")]
    pub data: PathBuf,
    /// The transient table, whose end-of-transient rates are Table 3's ω_f.
    #[arg(long, default_value = "papers/vtxo/data/transient-sa.csv")]
    pub transient_data: PathBuf,
    /// Weights file to write.
    #[arg(long, default_value = crate::learn::science::dnn::COMMITTED)]
    pub out: PathBuf,
    /// Seeds the split, the initial weights and the batch order.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Most epochs (the paper: 1000).
    #[arg(long, default_value_t = 1000)]
    pub epochs: usize,
    /// SGD learning rate.
    #[arg(long, default_value_t = 0.3)]
    pub lr: f64,
}

/// The trainers' clap commands.
pub fn commands() -> Vec<clap::Command> {
    vec![<DataArgs as clap::CommandFactory>::command(), <DnnArgs as clap::CommandFactory>::command()]
}

/// Whether `name` is one of these trainers.
pub fn owns(name: &str) -> bool {
    name == NAME || name == DNN_NAME
}

fn run_dnn(matches: &clap::ArgMatches) -> Result<String, CommandError> {
    use crate::learn::science::sim::ScienceLaw;
    use crate::learn::science::train::{self, Options as TrainOptions};
    let a = DnnArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    if a.epochs == 0 || a.epochs > 100_000 || !(a.lr > 0.0 && a.lr <= 10.0) {
        return Err(CommandError::invalid(format!(
            "--epochs {} --lr {}: 1 to 100000 epochs, a learning rate in (0, 10]",
            a.epochs, a.lr
        )));
    }
    let mut tables = Vec::new();
    for law in ScienceLaw::ALL {
        let t = train::read_table(&a.data, law).map_err(|e| CommandError::invalid(format!("--data: {e}")))?;
        tables.push((law, t));
    }
    let transient = crate::learn::science::stats::transient_end_rates(&a.transient_data)
        .map_err(|e| CommandError::invalid(format!("--transient-data: {e}")))?;
    let mut o = TrainOptions::reference(a.data.clone(), a.out.clone(), a.seed);
    (o.epochs, o.lr) = (a.epochs, a.lr);
    let command = format!(
        "orchestrator train {DNN_NAME} --data {} --transient-data {} --out {} --seed {} --epochs {} --lr {}",
        a.data.display(),
        a.transient_data.display(),
        a.out.display(),
        a.seed,
        a.epochs,
        a.lr
    );
    let t0 = std::time::Instant::now();
    let reports = train::train(&o).map_err(CommandError::failed)?;
    let mut sources = vec![(format!("ours, end of transient ({})", a.transient_data.display()), transient)];
    for (law, t) in tables {
        sources.push((format!("ours, end of science phase, {} Pareto designs", law.name()), t.omega_end_rad_s));
    }
    let md = format!(
        "# Science DNN (Sec. 3.2.2) and Table 3 analogue\n\n`{command}`\n\n{}\n{}",
        train::accuracy_markdown(&reports, &o),
        crate::learn::science::stats::table3_markdown(&sources)
    );
    let path = train::report_path(&o.out);
    std::fs::write(&path, &md).map_err(|e| CommandError::failed(format!("{}: {e}", path.display())))?;
    Ok(format!(
        "{md}\nwall-clock {:.1} s\nwritten: {} and {}",
        t0.elapsed().as_secs_f64(),
        o.out.display(),
        path.display()
    ))
}

fn run_data(matches: &clap::ArgMatches) -> Result<String, CommandError> {
    let a = DataArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    let o = Options {
        draws: a.draws,
        seed: a.seed,
        population: a.population,
        generations: a.generations,
        phase_s: a.phase,
        dt_s: a.dt,
        threads: a.threads,
        out_dir: a.out,
    };
    let s = data::run(&o).map_err(|e| match e {
        DataError::Options(_) => CommandError::invalid(e.to_string()),
        DataError::Io { .. } => CommandError::failed(e.to_string()),
    })?;
    Ok(format!(
        "{NAME}: {} draws, {} PD and {} SMC Pareto rows, {} flights in {:.1} s\nwritten: {} and {}",
        o.draws,
        s.rows[0],
        s.rows[1],
        s.flights,
        s.seconds,
        data::table_path(&o.out_dir, crate::learn::science::sim::ScienceLaw::Pd).display(),
        data::table_path(&o.out_dir, crate::learn::science::sim::ScienceLaw::Smc).display()
    ))
}

/// Run trainer `name`.
pub fn run(name: &str, matches: &clap::ArgMatches) -> Result<String, CommandError> {
    if name == NAME {
        return run_data(matches);
    }
    if name == DNN_NAME {
        return run_dnn(matches);
    }
    Err(CommandError::invalid(format!("vtxo has no science trainer {name:?}")))
}
