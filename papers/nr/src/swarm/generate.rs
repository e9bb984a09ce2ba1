//! `orchestrator generate swarm --agents N [--seed S] [--weights FILE] [--out FILE]`: the swarm
//! of `topologies/swarm-20.toml` (the paper's configuration: NR over the committed deep set, the
//! safety filter and the estimator) for any N, with
//!
//! - the cuboid scaled so that the density is swarm-20's (20 vehicles in [−2, 2] × [−2, 2] ×
//!   [0.5, 2] m, 1.2 m³ each): every side × (N/20)^⅓, x and y about 0, z up from the 0.5 m floor
//!   ([`cuboid_for`]; N = 20 gives swarm-20's cuboid exactly);
//! - sparse neighbour lists: each vehicle hears those the rule of
//!   [`crate::swarm::dynamics::neighbours`] pairs it with on the problem the plant will draw (the
//!   seed's, in that cuboid), instead of all.

use std::path::{Path, PathBuf};

use clap::{CommandFactory, FromArgMatches, Parser};
use cohort_host::CommandError;

use crate::swarm::dynamics::neighbours::neighbour_lists;
use crate::swarm::dynamics::setup::{CUBOID_M, Cuboid, R_COMM_M, draw_in};

/// The shape's name: `orchestrator generate swarm`.
pub const NAME: &str = "swarm";
/// The vehicles of swarm-20, whose density every generated swarm keeps.
const DENSITY_AGENTS: f64 = 20.0;
/// Most vehicles (each its own process).
pub const MAX_AGENTS: u32 = 1000;

/// The committed weights of `orchestrator train nr-swarm --seed 1` (the shipped scenarios').
fn committed_weights() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("weights").join("swarm.safetensors")
}

/// `generate swarm`'s own arguments (the orchestrator adds `--out`).
#[derive(Parser)]
#[command(
    name = "swarm",
    about = "Seed 003's swarm (Sec. 7.2) of N vehicles at swarm-20's density, each hearing only the vehicles \
             it could meet within R_comm (papers/nr/README.md, \"Neighbours\")"
)]
struct GenerateArgs {
    /// Vehicles (2 to 1000), one process each.
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..=i64::from(MAX_AGENTS)))]
    agents: u32,
    /// The scenario's seed (0 to 2^63 − 1): it draws the starts and goals the neighbour lists are
    /// made for, the reading noise and the disturbance.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u64).range(0..=i64::MAX as u64))]
    seed: u64,
    /// The deep-set policy's weights file (default: the committed papers/nr/weights/swarm.safetensors).
    #[arg(long, value_name = "FILE")]
    weights: Option<PathBuf>,
}

pub fn command() -> clap::Command {
    GenerateArgs::command()
}

/// The scenario text for `matches`.
pub fn run(matches: &clap::ArgMatches) -> Result<String, CommandError> {
    let a = GenerateArgs::from_arg_matches(matches).map_err(|e| CommandError::invalid(e.to_string()))?;
    let weights = match a.weights {
        Some(w) => {
            std::path::absolute(&w).map_err(|e| CommandError::invalid(format!("--weights {}: {e}", w.display())))?
        }
        None => committed_weights(),
    };
    if !weights.is_file() {
        return Err(CommandError::invalid(format!("--weights {}: no such file", weights.display())));
    }
    scenario_text(a.agents, a.seed, &weights).map_err(CommandError::invalid)
}

/// The cuboid of `n` vehicles at swarm-20's density (module docs), m.
pub fn cuboid_for(n: u32) -> Cuboid {
    let scale = (f64::from(n) / DENSITY_AGENTS).cbrt();
    let [[x0, x1], [y0, y1], [z0, z1]] = CUBOID_M;
    [[x0 * scale, x1 * scale], [y0 * scale, y1 * scale], [z0, z0 + (z1 - z0) * scale]]
}

/// The scenario of `n` vehicles and `seed`, flying the policy of `weights` (an absolute path).
pub fn scenario_text(n: u32, seed: u64, weights: &Path) -> Result<String, String> {
    let cuboid_m = cuboid_for(n);
    let (starts, goals) =
        draw_in(n as usize, seed, &cuboid_m).map_err(|e| format!("--agents {n} --seed {seed}: {e}"))?;
    let lists = neighbour_lists(&starts, &goals, R_COMM_M);
    let links: usize = lists.iter().map(Vec::len).sum();
    let mut t = header(n, seed, links);
    t.push_str(&sections(&cuboid_m, weights));
    for (i, l) in lists.iter().enumerate() {
        let ids: Vec<String> = l.iter().map(u32::to_string).collect();
        t.push_str(&format!("\n[[agents]]\nid = {}\nneighbours = [{}]\n", i + 1, ids.join(", ")));
    }
    Ok(t)
}

fn header(n: u32, seed: u64, links: usize) -> String {
    let all = u64::from(n) * u64::from(n - 1);
    format!(
        "# Written by `orchestrator generate swarm --agents {n} --seed {seed}`: seed 003's swarm (Sec. 7.2 of\n\
         # arXiv:2208.04883) as topologies/swarm-20.toml flies it, {n} vehicles at its density (the cuboid\n\
         # scaled by (N/20)^(1/3)). Each vehicle hears only those whose start->goal segments come within\n\
         # R_comm + 2 x 1 m + 0.05 m of its own (papers/nr/README.md, \"Neighbours\"): {links} of the {all}\n\
         # all-to-all subscriptions. The lists are made for the problem of this seed: another seed\n\
         # (--seed) is refused unless they also hold for its problem.\n\n\
         [scenario]\n\
         name = \"swarm-gen-{n}\"\n\
         description = \"Seed 003 Sec. 7.2: {n}-vehicle swarm reconfiguration at swarm-20's density, NR over the learned deep set, sparse neighbours\"\n\
         seed = {seed}\n\
         dt_s = 0.1\n\
         duration_s = 10.0\n"
    )
}

/// The plant and algorithm sections: swarm-20's, with the cuboid and the weights.
fn sections(cuboid_m: &Cuboid, weights: &Path) -> String {
    let cuboid: Vec<String> = cuboid_m.iter().map(|[lo, hi]| format!("[{lo:?}, {hi:?}]")).collect();
    let weights = toml::Value::String(weights.display().to_string());
    format!(
        "\n[plant]\n\
         kind = \"swarm\"\n\
         a_max_mps2 = 2.0\n\
         disturbance_mps2 = 0.0\n\
         pos_noise_m = 0.001\n\
         vel_noise_mps = 0.01\n\
         substeps = 10\n\
         t_reconfig_s = 8.0\n\
         cuboid_m = [{}]\n\
         \n[algorithm]\n\
         kind = \"nr-swarm\"\n\
         method = \"nr\"\n\
         policy = \"deep-set\"\n\
         weights = {weights}\n\
         r_comm_m = {R_COMM_M:?}\n\
         lambda_per_s = 2.0\n\
         alpha_per_s = 2.0\n\
         horizon_s = 2.0\n\
         rebuild_every_s = 0.5\n\
         \n[algorithm.safety]\n\
         margin = 1.15\n\
         braking_share = 0.5\n\
         gamma_per_s = 2.0\n\
         disturbance_mps2 = 0.0\n\
         \n[algorithm.estimator]\n\
         pos_sigma_m = 0.001\n\
         vel_sigma_mps = 0.01\n\
         accel_sigma_mps2 = 0.02\n",
        cuboid.join(", ")
    )
}
