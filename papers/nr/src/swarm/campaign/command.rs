//! `orchestrator nr swarm-campaign`: the swarm evaluation of Sec. 7.2 of "Neural-Rendezvous"
//! (arXiv:2208.04883). Three groups of cases, each from a shipped scenario re-seeded per case
//! (`--cases-8` cases of `topologies/swarm-8.toml`, N = 8, d̄ = 0; `--cases-20` of `swarm-20.toml`;
//! `--cases-20-disturbed` of `swarm-20-disturbed.toml`, d̄ = 0.2 m/s²), each case's seed drawn
//! from `--seed` (a stream per group), flown by NR over the deep set with the scenario's safety
//! filter, NR without it, the deep set alone (no filter) and the global SCP
//! ([`crate::swarm::campaign::case`]; how the SCP is flown is said there).
//!
//! Writes into `--out`: `cases.csv` (one row per case × method, units in the column names),
//! `summary.md` (per group and method, and verdict lines against the goals: 0 collisions
//! for NR in every case, every vehicle within 0.1 m of its goal at T + 2 s, ∫‖u‖dt ≤ 1.3× the
//! SCP's, per-step compute ≥ 100× faster than one SCP solve) and `runs/` (the reference run of
//! each case flown by the runtime; the first
//! `--figures` cases of each group with `plots/swarm_trajectories.png` and
//! `plots/swarm_min_distance.png`).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use cohort_host::{CommandError, Launcher};
use cohort_runtime::paper::Setup;
use cohort_runtime::rng::setup_rng;
use cohort_scenario::Overrides;
use rand::Rng;

use crate::swarm::campaign::case::{CampaignMethod, fly_case};
use crate::swarm::config::SwarmPolicyKind;
use crate::swarm::host::kinds::SwarmSetup;

#[derive(Args, Debug, Clone)]
pub struct SwarmCampaignArgs {
    /// Seed of the cases' seeds (one stream per group).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Cases at N = 8 (d̄ = 0), from --scenario-8.
    #[arg(long, default_value_t = 20)]
    pub cases_8: usize,
    /// Cases at N = 20 (d̄ = 0), from --scenario-20.
    #[arg(long, default_value_t = 5)]
    pub cases_20: usize,
    /// Cases at N = 20 with the disturbance, from --scenario-20-disturbed.
    #[arg(long, default_value_t = 5)]
    pub cases_20_disturbed: usize,
    #[arg(long, default_value = "topologies/swarm-8.toml")]
    pub scenario_8: PathBuf,
    #[arg(long, default_value = "topologies/swarm-20.toml")]
    pub scenario_20: PathBuf,
    #[arg(long, default_value = "topologies/swarm-20-disturbed.toml")]
    pub scenario_20_disturbed: PathBuf,
    /// Comma list of nr, nr-no-filter, deep-set, scp (default all four).
    #[arg(long, default_value = "nr,nr-no-filter,deep-set,scp")]
    pub methods: String,
    /// Cases of each group whose runs draw their figures.
    #[arg(long, default_value_t = 1)]
    pub figures: usize,
    /// Output directory (absent or empty); default runs/nr-swarm-campaign-<UTC time>/.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Most cases of one group (a guard against a typo of hours).
const MAX_CASES: usize = 1000;

struct Group {
    name: &'static str,
    setup: Setup,
    seeds: Vec<u64>,
}

fn methods(s: &str) -> Result<Vec<CampaignMethod>, String> {
    let mut out = Vec::new();
    for name in s.split(',').map(str::trim) {
        let all = CampaignMethod::ALL.map(CampaignMethod::name).join(", ");
        let m = CampaignMethod::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| format!("--methods {s:?}: unknown method {name:?} (expected {all})"))?;
        if out.contains(&m) {
            return Err(format!("--methods {s:?}: {name:?} given twice"));
        }
        out.push(m);
    }
    Ok(out)
}

/// Case seeds of a group: the first `count` of its stream, distinct.
fn seeds(seed: u64, group: &str, count: usize) -> Vec<u64> {
    let mut rng = setup_rng(seed, &format!("nr-swarm-campaign[{group}]"));
    let mut out: Vec<u64> = Vec::with_capacity(count);
    while out.len() < count {
        let s = rng.random_range(0..1_000_000_000u64);
        if !out.contains(&s) {
            out.push(s);
        }
    }
    out
}

fn group(
    launcher: &dyn Launcher,
    a: &SwarmCampaignArgs,
    name: &'static str,
    (flag, file, n): (&str, &PathBuf, u32),
    (count_flag, count): (&str, usize),
) -> Result<Option<Group>, String> {
    if count > MAX_CASES {
        return Err(format!("{count_flag} {count}: at most {MAX_CASES}"));
    }
    if count == 0 {
        return Ok(None);
    }
    let setup = launcher.load(file, &Overrides::default()).map_err(|e| format!("{flag} {}: {e}", file.display()))?;
    let Some(alg) = setup.algorithm_as::<SwarmSetup>() else {
        return Err(format!("{flag} {}: not a swarm scenario flown by nr-swarm", file.display()));
    };
    if alg.config.policy != SwarmPolicyKind::DeepSet {
        return Err(format!(
            "{flag} {}: algorithm.policy is {:?}; the campaign flies the deep set (policy = \"deep-set\")",
            file.display(),
            alg.config.policy.name()
        ));
    }
    if setup.n_agents() != n {
        return Err(format!("{flag} {}: {} agents, this group needs {n}", file.display(), setup.n_agents()));
    }
    Ok(Some(Group { name, setup, seeds: seeds(a.seed, name, count) }))
}

fn plan(a: &SwarmCampaignArgs, launcher: &dyn Launcher) -> Result<(Vec<Group>, Vec<CampaignMethod>, PathBuf), String> {
    let methods = methods(&a.methods)?;
    let out =
        a.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/nr-swarm-campaign-{}", cohort_host::utc_stamp())));
    if std::fs::read_dir(&out).is_ok_and(|mut d| d.next().is_some()) {
        return Err(format!("--out {}: not empty", out.display()));
    }
    if out.exists() && !out.is_dir() {
        return Err(format!("--out {}: not a directory", out.display()));
    }
    let groups = [
        group(launcher, a, "n8", ("--scenario-8", &a.scenario_8, 8), ("--cases-8", a.cases_8))?,
        group(launcher, a, "n20", ("--scenario-20", &a.scenario_20, 20), ("--cases-20", a.cases_20))?,
        group(
            launcher,
            a,
            "n20-disturbed",
            ("--scenario-20-disturbed", &a.scenario_20_disturbed, 20),
            ("--cases-20-disturbed", a.cases_20_disturbed),
        )?,
    ];
    let groups: Vec<Group> = groups.into_iter().flatten().collect();
    if groups.is_empty() {
        return Err("--cases-8, --cases-20, --cases-20-disturbed: all 0, nothing to fly".into());
    }
    Ok((groups, methods, out))
}

/// The command.
pub fn run(a: &SwarmCampaignArgs, launcher: &dyn Launcher) -> Result<String, CommandError> {
    let started = Instant::now();
    let (groups, methods, out) = plan(a, launcher).map_err(CommandError::invalid)?;
    std::fs::create_dir_all(&out).map_err(|e| CommandError::invalid(format!("--out {}: {e}", out.display())))?;
    let mut rows = Vec::new();
    for g in &groups {
        for (case, &seed) in g.seeds.iter().enumerate() {
            if let Some(sig) = launcher.interrupted() {
                return Err(CommandError {
                    message: format!("interrupted by signal {sig}; nothing written but the runs so far"),
                    exit_code: 128u8.saturating_add(sig as u8),
                });
            }
            let plots = case < a.figures;
            rows.extend(
                fly_case(launcher, &g.setup, g.name, case, seed, &methods, &out.join("runs"), plots)
                    .map_err(CommandError::failed)?,
            );
        }
    }
    let csv = crate::swarm::campaign::report::csv(&rows);
    let md = crate::swarm::campaign::report::summary(&rows, &command_line(a), started.elapsed().as_secs_f64(), &out);
    for (file, text) in [("cases.csv", &csv), ("summary.md", &md)] {
        let path = out.join(file);
        std::fs::write(&path, text).map_err(|e| CommandError::failed(format!("{}: {e}", path.display())))?;
    }
    let mut msg = md;
    let _ = write!(msg, "\nwritten: {}", out.display());
    Ok(msg)
}

fn command_line(a: &SwarmCampaignArgs) -> String {
    format!(
        "orchestrator nr swarm-campaign --seed {} --cases-8 {} --cases-20 {} --cases-20-disturbed {} --methods {} \
         --figures {}",
        a.seed, a.cases_8, a.cases_20, a.cases_20_disturbed, a.methods, a.figures
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_and_seeds_parse_and_repeat() {
        assert_eq!(methods("nr,scp").unwrap(), vec![CampaignMethod::Nr, CampaignMethod::Scp]);
        let e = methods("nr,magic").unwrap_err();
        assert!(e.contains("--methods") && e.contains("magic"), "{e}");
        assert!(methods("nr,nr").unwrap_err().contains("twice"));
        let s = seeds(1, "n8", 20);
        assert_eq!(s, seeds(1, "n8", 20));
        assert_eq!(&s[..5], &seeds(1, "n8", 5)[..]);
        assert_ne!(s[..5], seeds(1, "n20", 5)[..]);
        let mut d = s.clone();
        d.sort_unstable();
        d.dedup();
        assert_eq!(d.len(), 20);
    }
}
