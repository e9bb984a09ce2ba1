//! `orchestrator train nr-iso`: the SN-DNN guidance policy of "Neural-Rendezvous"
//! (arXiv:2208.04883) trained by imitation of the SCP global solution ([`crate::iso::train::imitation`]), written
//! as the weights file and its report (`<stem>-report.md` beside it). The same arguments give the
//! same bytes in both files: the report holds no wall-clock time (the command prints them).
//!
//! The orchestrator sets `RAYON_NUM_THREADS=1` before it starts the trainer (see
//! [`crate::Nr`]'s `trainer_env`): candle threads its CPU matrix products by it, and on these
//! small matrices one thread is the fastest; the bytes do not depend on it.

use std::path::{Path, PathBuf};

use clap::{FromArgMatches, Parser};
use cohort_host::CommandError;

use crate::iso::train::imitation::{TrainError, TrainOptions, train};

/// The trainer's name (`orchestrator train nr-iso`).
pub const NAME: &str = "nr-iso";

#[derive(Parser)]
#[command(
    name = "nr-iso",
    about = "Seed 003's SN-DNN guidance policy (Neural-Rendezvous): SCP data on the training ISOs, \
             imitation loss (10)-(12), candle on the CPU; writes the weights (safetensors) and \
             NAME-report.md beside them (Lemma 1's terms). Byte-identical on re-run."
)]
pub struct TrainArgs {
    /// Seeds the data, the initial weights and the batch order.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Weights file to write.
    #[arg(long, default_value = "papers/nr/weights/sn-dnn.safetensors")]
    pub out: PathBuf,
    /// Directory caching the generated SCP data (by a hash of its options); `none` for no cache.
    #[arg(long, default_value = "target/nr-cache")]
    pub cache: String,
    /// γ of C_x = γI, the state term's weight (reference 10).
    #[arg(long)]
    pub gamma: Option<f64>,
    /// Training epochs (reference 400).
    #[arg(long)]
    pub epochs: Option<usize>,
    /// Training ISOs A..B (reference 0..200; the test ISOs are 200..300).
    #[arg(long)]
    pub isos: Option<String>,
    /// Samples per training ISO (reference 30).
    #[arg(long)]
    pub samples: Option<u32>,
    /// Network inputs: 18 (ours) or the reference transform's 15.
    #[arg(long)]
    pub inputs: Option<usize>,
    /// C_sn of the spectral normalisation (reference 2).
    #[arg(long)]
    pub c_sn: Option<f64>,
}

impl TrainArgs {
    /// The training options the arguments ask for (bad values: exit 2).
    pub fn options(&self) -> Result<TrainOptions, CommandError> {
        let bad = |m: String| CommandError::invalid(m);
        let mut o = TrainOptions::reference(self.out.clone(), self.seed);
        o.cache_dir = (self.cache != "none").then(|| PathBuf::from(&self.cache));
        if let Some(g) = self.gamma {
            if !(g.is_finite() && g >= 0.0) {
                return Err(bad(format!("--gamma {g}: must be a number ≥ 0")));
            }
            o.gamma = g;
        }
        if let Some(e) = self.epochs {
            if e == 0 {
                return Err(bad("--epochs 0: at least 1".into()));
            }
            o.epochs = e;
        }
        if let Some(r) = &self.isos {
            o.data.isos = crate::iso::cli::isos("--isos", r).map_err(bad)?;
        }
        if let Some(s) = self.samples {
            if s == 0 {
                return Err(bad("--samples 0: at least 1 per ISO".into()));
            }
            o.data.samples_per_iso = s;
        }
        if let Some(n) = self.inputs {
            if n != crate::iso::guidance::features::N_FEATURES && n != crate::iso::guidance::features::REFERENCE_INPUTS
            {
                return Err(bad(format!("--inputs {n}: 18 (ours) or 15 (the reference transform)")));
            }
            o.inputs = n;
        }
        if let Some(c) = self.c_sn {
            if !(c.is_finite() && c > 0.0) {
                return Err(bad(format!("--c-sn {c}: must be a positive number")));
            }
            o.c_sn = c;
        }
        Ok(o)
    }

    /// The command line that reproduces this run.
    pub fn command(&self) -> String {
        let mut c = format!("orchestrator train {NAME} --seed {} --out {}", self.seed, self.out.display());
        let opts = [
            ("--gamma", self.gamma.map(|x| x.to_string())),
            ("--epochs", self.epochs.map(|x| x.to_string())),
            ("--isos", self.isos.clone()),
            ("--samples", self.samples.map(|x| x.to_string())),
            ("--inputs", self.inputs.map(|x| x.to_string())),
            ("--c-sn", self.c_sn.map(|x| x.to_string())),
        ];
        for (flag, v) in opts {
            if let Some(v) = v {
                c += &format!(" {flag} {v}");
            }
        }
        c
    }
}

/// `<stem>-report.md` beside the weights file.
pub fn report_path(weights: &Path) -> PathBuf {
    let stem = weights.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "sn-dnn".into());
    weights.with_file_name(format!("{stem}-report.md"))
}

/// The command (`matches` are the trainer's own): train, write both files, say what was written.
pub fn run(matches: &clap::ArgMatches) -> Result<String, CommandError> {
    let a = TrainArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    let o = a.options()?;
    let report = train(&o).map_err(|e| match e {
        TrainError::Options(_) => CommandError::invalid(e.to_string()),
        _ => CommandError::failed(e.to_string()),
    })?;
    let md = report.markdown(&a.command());
    let path = report_path(&o.out);
    std::fs::write(&path, &md).map_err(|e| CommandError::failed(format!("{}: {e}", path.display())))?;
    Ok(format!("{md}\nwall-clock: {}\nwritten: {} and {}", report.timings(), o.out.display(), path.display()))
}

/// The trainer's clap command.
pub fn command() -> clap::Command {
    <TrainArgs as clap::CommandFactory>::command()
}
