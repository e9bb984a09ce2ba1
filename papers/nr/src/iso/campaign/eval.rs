//! The in-process evaluation of Sec. 6.3 of "Neural-Rendezvous" (arXiv:2208.04883): every
//! method on every ISO of a range (the test ISOs 200–299 by default), one spacecraft per run,
//! our lockstep loop ([`crate::iso::campaign::sim`]): delivery error (median, p99, max, mean, std), Δv,
//! per-step compute time (p50, p99 over every step of every run) and, for Neural-Rendezvous,
//! the delivery error against the bound b_e(t_f). Run `seed` = `seed_base` + ISO index (the
//! navigation noise of each ISO is its own and the same for every method); with `realisations`
//! K > 1, realisation k of an ISO flies seed `seed_base` + ISO + k·10⁶ (k = 0 is the one-realisation
//! campaign's run), so the tails can be told from the luck of one noise draw ([`spread`]). Medians, p99s and
//! means are `cohort_report::stats`'s (the one quantile rule of every Cohort table).

use std::ops::Range;
use std::sync::Arc;

use cohort_host::campaign::{Campaign, CampaignError};
use cohort_report::markdown::MdTable;
use cohort_report::stats::{mean, median, quantile, sorted};
use serde::Serialize;

use crate::iso::campaign::sim;
use crate::iso::config::{IsoEncounterConfig, Method, NrAlgorithmConfig};
use crate::iso::control::agent::NrAgent;
use crate::iso::dynamics::constants::{DV_BUDGET_MPS, TEST_ISOS};
use crate::iso::dynamics::plant::IsoEncounterPlant;
use crate::nn::sn_dnn::SnDnn;

#[derive(Debug, Clone)]
pub struct CampaignOptions {
    pub methods: Vec<Method>,
    pub isos: Range<u32>,
    pub plant: IsoEncounterConfig,
    /// The algorithm section; `method` is replaced per run.
    pub algorithm: NrAlgorithmConfig,
    pub net: Option<Arc<SnDnn>>,
    pub dt_s: f64,
    pub seed_base: u64,
    /// Noise realisations per ISO (each its own seed, see the module docs).
    pub realisations: u32,
    pub threads: usize,
    /// Each run is flown this many times and each step keeps its smallest wall time (the runs
    /// are deterministic, so the work is identical and the minimum strips the interference of
    /// other processes); the outcomes are checked to be bit-identical.
    pub timing_repeats: usize,
}

impl CampaignOptions {
    pub fn new(methods: Vec<Method>, net: Option<Arc<SnDnn>>) -> Self {
        Self {
            methods,
            isos: TEST_ISOS,
            plant: IsoEncounterConfig::default(),
            algorithm: NrAlgorithmConfig::new(Method::Nmpc),
            net,
            dt_s: crate::iso::dynamics::constants::DT_S,
            seed_base: 0,
            realisations: 1,
            threads: 2,
            timing_repeats: 1,
        }
    }
}

/// One run.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    pub method: Method,
    pub iso: u32,
    /// Which noise realisation of the ISO (0 for a one-realisation campaign).
    pub realisation: u32,
    pub delivery_error_m: f64,
    pub dv_mps: f64,
    /// b_e(t_f) for the methods that keep a bound.
    pub bound_m: Option<f64>,
    pub clipped_steps: u64,
    /// Per-step compute times of the run, s.
    #[serde(skip)]
    pub compute_s: Vec<f64>,
}

/// One method over the campaign.
#[derive(Debug, Clone, Serialize)]
pub struct MethodSummary {
    pub method: Method,
    pub runs: usize,
    pub error_median_m: f64,
    pub error_p99_m: f64,
    pub error_max_m: f64,
    pub error_mean_m: f64,
    pub error_std_m: f64,
    pub share_within_200m: f64,
    pub dv_median_mps: f64,
    pub dv_max_mps: f64,
    pub dv_mean_mps: f64,
    pub runs_over_dv_budget: usize,
    pub compute_p50_s: f64,
    pub compute_p99_s: f64,
    pub compute_max_s: f64,
    /// Runs whose delivery error is ≤ b_e(t_f) (methods with a bound).
    pub within_bound: Option<usize>,
}

/// The seed gap between two realisations of one ISO.
pub const REALISATION_SEED_STRIDE: u64 = 1_000_000;

/// The run seed of realisation `k` of `iso`.
pub fn run_seed(o: &CampaignOptions, iso: u32, k: u32) -> u64 {
    o.seed_base + u64::from(iso) + u64::from(k) * REALISATION_SEED_STRIDE
}

/// Fly one ISO's realisation `k` with one method (`o.timing_repeats` times, see there).
pub fn run_one(o: &CampaignOptions, method: Method, iso: u32, k: u32) -> Result<RunResult, String> {
    let mut best = fly_once(o, method, iso, k)?;
    for _ in 1..o.timing_repeats {
        let again = fly_once(o, method, iso, k)?;
        if (again.delivery_error_m.to_bits(), again.dv_mps.to_bits())
            != (best.delivery_error_m.to_bits(), best.dv_mps.to_bits())
        {
            return Err(format!("{} on ISO {iso}: a repeated run differs", method.name()));
        }
        best.compute_s.iter_mut().zip(&again.compute_s).for_each(|(a, b)| *a = a.min(*b));
    }
    Ok(best)
}

fn fly_once(o: &CampaignOptions, method: Method, iso: u32, k: u32) -> Result<RunResult, String> {
    let plant_cfg = IsoEncounterConfig { iso_index: Some(iso), ..o.plant.clone() };
    let seed = run_seed(o, iso, k);
    let mut plant: IsoEncounterPlant =
        crate::iso::config::build_plant(&plant_cfg, 1, o.dt_s, seed).map_err(|p| format!("{p:?}"))?;
    let cfg = NrAlgorithmConfig { method, ..o.algorithm.clone() };
    let mut agents = [NrAgent::new(cfg, o.dt_s, o.net.clone()).map_err(|e| e.to_string())?];
    let steps = (plant_cfg.t_f_s / o.dt_s).round() as u64;
    let rec = sim::run(&mut plant, &mut agents, steps, o.dt_s, seed, false);
    Ok(RunResult {
        method,
        iso,
        realisation: k,
        delivery_error_m: plant.delivery_error_m(0).ok_or("t_f not reached")?,
        dv_mps: plant.dv_mps(0),
        bound_m: agents[0].bound_m(),
        clipped_steps: agents[0].clipped_steps(),
        compute_s: rec.compute_s.into_iter().next().unwrap_or_default(),
    })
}

/// Every (method, ISO, realisation) run, on `threads` threads; results in that order. `stop` is
/// asked by the calling thread between runs and every 50 ms while they go on (so it need not be
/// `Sync`, e.g. "has a signal come?"): once it says true, no further run starts, the runs under
/// way finish, and the result is an error. A failing run stops the hand-out too; the error is
/// the one of the first failing run in (method, ISO) order.
pub fn run_all(o: &CampaignOptions, stop: &dyn Fn() -> bool) -> Result<Vec<RunResult>, String> {
    let jobs: Vec<(Method, u32, u32)> = o
        .methods
        .iter()
        .flat_map(|m| o.isos.clone().flat_map(move |i| (0..o.realisations).map(move |k| (*m, i, k))))
        .collect();
    let runs =
        Campaign::new(jobs.len()).workers(o.threads).stop(stop).run(|j| run_one(o, jobs[j].0, jobs[j].1, jobs[j].2));
    runs.map_err(|e| match e {
        CampaignError::Case(f) => f.source,
        CampaignError::Stopped { .. } => "stopped before every run finished".into(),
    })
}

/// Summaries per method (in the options' order).
pub fn summarise(o: &CampaignOptions, runs: &[RunResult]) -> Vec<MethodSummary> {
    o.methods
        .iter()
        .map(|&m| {
            let rs: Vec<&RunResult> = runs.iter().filter(|r| r.method == m).collect();
            let e = sorted(rs.iter().map(|r| r.delivery_error_m));
            let dv = sorted(rs.iter().map(|r| r.dv_mps));
            let c = sorted(rs.iter().flat_map(|r| r.compute_s.iter().copied()));
            let n = e.len() as f64;
            let error_mean_m = mean(&e);
            // The population standard deviation (n in the denominator), as every published
            // "mean ± std" of this campaign (the γ sweep's among them) was computed.
            let std = (e.iter().map(|x| (x - error_mean_m).powi(2)).sum::<f64>() / n).sqrt();
            let with_bound: Vec<&&RunResult> = rs.iter().filter(|r| r.bound_m.is_some()).collect();
            MethodSummary {
                method: m,
                runs: rs.len(),
                error_median_m: median(&e),
                error_p99_m: quantile(&e, 0.99),
                error_max_m: e.last().copied().unwrap_or(f64::NAN),
                error_mean_m,
                error_std_m: std,
                share_within_200m: e.iter().filter(|x| **x <= 200.0).count() as f64 / n,
                dv_median_mps: median(&dv),
                dv_max_mps: dv.last().copied().unwrap_or(f64::NAN),
                dv_mean_mps: mean(&dv),
                runs_over_dv_budget: dv.iter().filter(|x| **x > DV_BUDGET_MPS).count(),
                compute_p50_s: median(&c),
                compute_p99_s: quantile(&c, 0.99),
                compute_max_s: c.last().copied().unwrap_or(f64::NAN),
                within_bound: (!with_bound.is_empty())
                    .then(|| with_bound.iter().filter(|r| r.delivery_error_m <= r.bound_m.expect("filtered")).count()),
            }
        })
        .collect()
}

/// Per-ISO comparisons of Neural-Rendezvous with every other method of the campaign: the share
/// of ISOs where NR's delivery error is smaller, and NR's Δv over the other's (median, max, and
/// how many ISOs exceed 1.25×), as Markdown (empty without NR runs).
pub fn comparisons(runs: &[RunResult]) -> String {
    let nr: Vec<&RunResult> = runs.iter().filter(|r| r.method == Method::NeuralRendezvous).collect();
    if nr.is_empty() {
        return String::new();
    }
    let mut t = MdTable::new(["NR vs", "runs", "NR error smaller", "NR Δv / other's: median", "max", "runs > 1.25×"]);
    for m in Method::ALL.into_iter().filter(|m| *m != Method::NeuralRendezvous) {
        let pairs: Vec<(&RunResult, &RunResult)> = nr
            .iter()
            .filter_map(|a| {
                runs.iter().find(|b| b.method == m && (b.iso, b.realisation) == (a.iso, a.realisation)).map(|b| (*a, b))
            })
            .collect();
        if pairs.is_empty() {
            continue;
        }
        let smaller = pairs.iter().filter(|(a, b)| a.delivery_error_m < b.delivery_error_m).count();
        let ratios = sorted(pairs.iter().map(|(a, b)| a.dv_mps / b.dv_mps));
        t.row([
            m.name().to_string(),
            pairs.len().to_string(),
            smaller.to_string(),
            format!("{:.3}", median(&ratios)),
            format!("{:.3}", ratios.last().copied().unwrap_or(f64::NAN)),
            ratios.iter().filter(|r| **r > 1.25).count().to_string(),
        ]);
    }
    t.to_string()
}

/// With several realisations per ISO: each method's statistics computed per realisation, as
/// their range over the realisations (least – largest), so a tail figure can be told from the
/// luck of one noise draw. Empty with one realisation.
pub fn spread(o: &CampaignOptions, runs: &[RunResult]) -> String {
    if o.realisations < 2 {
        return String::new();
    }
    let mut t = MdTable::new([
        "method",
        "realisations",
        "error median (m)",
        "p99 (m)",
        "max (m)",
        "mean (m)",
        "Δv median (m/s)",
        "≤ b_e(t_f)",
    ]);
    for &m in &o.methods {
        let per: Vec<MethodSummary> = (0..o.realisations)
            .map(|k| {
                let rs: Vec<RunResult> = runs.iter().filter(|r| r.method == m && r.realisation == k).cloned().collect();
                summarise(&CampaignOptions { methods: vec![m], ..o.clone() }, &rs).remove(0)
            })
            .collect();
        let range = |f: &dyn Fn(&MethodSummary) -> f64, digits: usize| {
            let (lo, hi) =
                per.iter().map(f).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
            format!("{lo:.digits$} – {hi:.digits$}")
        };
        let bound = per.iter().filter_map(|s| s.within_bound).collect::<Vec<_>>();
        t.row([
            m.name().to_string(),
            o.realisations.to_string(),
            range(&|s| s.error_median_m, 2),
            range(&|s| s.error_p99_m, 2),
            range(&|s| s.error_max_m, 2),
            range(&|s| s.error_mean_m, 2),
            range(&|s| s.dv_median_mps, 3),
            match (bound.iter().min(), bound.iter().max()) {
                (Some(lo), Some(hi)) => format!("{lo} – {hi} of {}", per[0].runs),
                _ => "–".into(),
            },
        ]);
    }
    t.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realisation_zero_is_the_one_realisation_seed_and_every_run_has_its_own() {
        let o = CampaignOptions { seed_base: 7, ..CampaignOptions::new(vec![Method::Nmpc], None) };
        assert_eq!(run_seed(&o, 203, 0), 210);
        let mut seeds: Vec<u64> =
            TEST_ISOS.flat_map(|i| (0..5).map(move |k| (i, k))).map(|(i, k)| run_seed(&o, i, k)).collect();
        let n = seeds.len();
        seeds.sort_unstable();
        seeds.dedup();
        assert_eq!(seeds.len(), n);
    }
}
