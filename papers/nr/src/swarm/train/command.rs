//! `orchestrator train nr-swarm`: the swarm's deep-set policy of "Neural-Rendezvous"
//! (arXiv:2208.04883, Sec. 7.2) trained by imitation of the centralised SCP global solution
//! ([`crate::swarm::train::imitation`]), written as the weights file and its report (`<stem>-report.md`
//! beside it). The same arguments give the same bytes in both files (the report holds no
//! wall-clock time; the command prints them). The orchestrator sets RAYON_NUM_THREADS=1 for
//! every trainer of the crate ([`crate::Nr`]'s `trainer_env`).

use std::path::PathBuf;

use clap::{FromArgMatches, Parser};
use cohort_host::CommandError;

use crate::iso::train::imitation::TrainError;
use crate::swarm::train::imitation::{SwarmTrainOptions, train};

/// The trainer's name (`orchestrator train nr-swarm`).
pub const NAME: &str = "nr-swarm";

#[derive(Parser)]
#[command(
    name = "nr-swarm",
    about = "Seed 003's swarm policy (Neural-Rendezvous Sec. 7.2): centralised SCP global solutions \
             of random N = 6-8 reconfigurations, perturbed states, deep-set SN-DNN on local \
             observations, candle on the CPU; writes the weights (safetensors) and NAME-report.md \
             beside them. Byte-identical on re-run."
)]
pub struct SwarmTrainArgs {
    /// Seeds the cases, the perturbations, the initial weights and the batch order.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Weights file to write.
    #[arg(long, default_value = "papers/nr/weights/swarm.safetensors")]
    pub out: PathBuf,
    /// Global solutions (reference 150; the last 10 % are held out for validation).
    #[arg(long)]
    pub cases: Option<usize>,
    /// Training epochs (reference 40).
    #[arg(long)]
    pub epochs: Option<usize>,
    /// DAgger rounds after the epochs (reference 0; `swarm_dagger`).
    #[arg(long)]
    pub dagger_rounds: Option<usize>,
    /// Epochs of each DAgger round (reference 8).
    #[arg(long)]
    pub dagger_epochs: Option<usize>,
    /// Extra copies of each near-conflict sample (reference 0; `swarm::train::avoidance`).
    #[arg(long)]
    pub near_copies: Option<usize>,
    /// Weight λ of the collision-aware loss term (reference 0: off).
    #[arg(long)]
    pub collision_weight: Option<f64>,
}

impl SwarmTrainArgs {
    /// The training options the arguments ask for (bad values: exit 2).
    pub fn options(&self) -> Result<SwarmTrainOptions, CommandError> {
        let mut o = SwarmTrainOptions::reference(self.out.clone(), self.seed);
        if let Some(c) = self.cases {
            if c < 2 {
                return Err(CommandError::invalid(format!("--cases {c}: at least 2 (one is held out)")));
            }
            o.data.cases = c;
            o.validation_cases = (c / 10).max(1);
        }
        if let Some(e) = self.epochs {
            if e == 0 {
                return Err(CommandError::invalid("--epochs 0: at least 1".to_string()));
            }
            o.epochs = e;
        }
        if let Some(r) = self.dagger_rounds {
            if r > 10 {
                return Err(CommandError::invalid(format!("--dagger-rounds {r}: at most 10")));
            }
            o.dagger_rounds = r;
        }
        if let Some(e) = self.dagger_epochs {
            if e == 0 {
                return Err(CommandError::invalid("--dagger-epochs 0: at least 1".to_string()));
            }
            o.dagger_epochs = e;
        }
        if let Some(k) = self.near_copies {
            if k > 20 {
                return Err(CommandError::invalid(format!("--near-copies {k}: at most 20")));
            }
            o.near_copies = k;
        }
        if let Some(w) = self.collision_weight {
            if !(w.is_finite() && w >= 0.0) {
                return Err(CommandError::invalid(format!("--collision-weight {w}: a finite weight ≥ 0")));
            }
            o.collision.weight = w;
        }
        Ok(o)
    }

    /// The command line that reproduces this run.
    pub fn command(&self) -> String {
        let mut c = format!("orchestrator train {NAME} --seed {} --out {}", self.seed, self.out.display());
        if let Some(n) = self.cases {
            c += &format!(" --cases {n}");
        }
        if let Some(e) = self.epochs {
            c += &format!(" --epochs {e}");
        }
        if let Some(r) = self.dagger_rounds {
            c += &format!(" --dagger-rounds {r}");
        }
        if let Some(e) = self.dagger_epochs {
            c += &format!(" --dagger-epochs {e}");
        }
        if let Some(k) = self.near_copies {
            c += &format!(" --near-copies {k}");
        }
        if let Some(w) = self.collision_weight {
            c += &format!(" --collision-weight {w}");
        }
        c
    }
}

/// The command (`matches` are the trainer's own): train, write both files, say what was written.
pub fn run(matches: &clap::ArgMatches) -> Result<String, CommandError> {
    let a = SwarmTrainArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    let o = a.options()?;
    let report = train(&o).map_err(|e| match e {
        TrainError::Options(_) => CommandError::invalid(e.to_string()),
        _ => CommandError::failed(e.to_string()),
    })?;
    let md = report.markdown(&a.command());
    let path = crate::iso::train::command::report_path(&o.out);
    std::fs::write(&path, &md).map_err(|e| CommandError::failed(format!("{}: {e}", path.display())))?;
    Ok(format!("{md}\nwall-clock: {}\nwritten: {} and {}", report.timings(), o.out.display(), path.display()))
}

/// The trainer's clap command.
pub fn command() -> clap::Command {
    <SwarmTrainArgs as clap::CommandFactory>::command()
}
