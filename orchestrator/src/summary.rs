//! `summary.json`: the run's headline metrics, message counters, and wall-clock figures, folded
//! from every process's `status/<proc>.json` and `timing/` files, and the paper's verdict.
//!
//! Kept small (a few kB): the per-link latency histograms stay where the processes wrote them,
//! in their latency logs `timing/<proc>.hlog` ([`cohort_runtime::record::LATENCY_LOG`]); the
//! summary keeps each link's and each receiving process's p50 / p99 / p99.9 / max.

use std::collections::BTreeMap;

use cohort_host::{RunStatus, VerdictLine};
use cohort_runtime::paper::Setup;
use cohort_runtime::record::{LatencyBuckets, LatencyHist, ProcessReport, RunDirs, timing_column};
use cohort_scenario::Scenario;
use serde::Serialize;

#[derive(Debug, Serialize)]
pub struct Percentiles {
    pub samples: usize,
    pub p50: u64,
    pub p99: u64,
    #[serde(rename = "p99.9")]
    pub p99_9: u64,
    pub max: u64,
    /// The samples' sum (what a run spent in all, e.g. every agent's compute over every step);
    /// absent for a histogram's percentiles, which keep no sum.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub total: Option<u64>,
}

impl Percentiles {
    pub fn of(mut xs: Vec<u64>) -> Option<Self> {
        if xs.is_empty() {
            return None;
        }
        xs.sort_unstable();
        let at = |q: f64| xs[((xs.len() - 1) as f64 * q).round() as usize];
        let total = xs.iter().fold(0u64, |a, x| a.saturating_add(*x));
        Some(Self {
            samples: xs.len(),
            p50: at(0.5),
            p99: at(0.99),
            p99_9: at(0.999),
            max: *xs.last().unwrap_or(&0),
            total: Some(total),
        })
    }
    /// A histogram's percentiles (each to the histogram's 2 significant figures: within 1 %).
    pub fn of_hist(h: &LatencyHist) -> Option<Self> {
        (!h.is_empty()).then(|| Self {
            samples: h.len() as usize,
            p50: h.quantile(0.5),
            p99: h.quantile(0.99),
            p99_9: h.quantile(0.999),
            max: h.max(),
            total: None,
        })
    }
}

#[derive(Debug, Serialize)]
pub struct Summary {
    pub scenario: String,
    pub seed: u64,
    pub mode: &'static str,
    pub run_id: String,
    /// How the run ended: "ok", "degraded", "diverged", "failed", "interrupted" or "salvaged"
    /// (see [`RunStatus`]).
    pub status: RunStatus,
    pub error: Option<String>,
    pub n_agents: u32,
    pub steps: u64,
    pub steps_completed: u64,
    pub sim_time_s: f64,
    /// Wall time of the whole launch (spawn to last exit, or thread start to join).
    pub wall_s: f64,
    /// Steps per second of the plant's step loop.
    pub steps_per_s: f64,
    /// Multi-process: from the first spawn to every process ready, s.
    pub startup_s: Option<f64>,
    pub metrics: BTreeMap<String, f64>,
    /// Non-numeric labels of the run (e.g. which learning law ran), from its algorithm.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub labels: BTreeMap<String, String>,
    pub messages_received: u64,
    pub messages_rejected: BTreeMap<String, u64>,
    pub timeouts: u64,
    /// Wall-clock latencies from `timing/`, in ns.
    pub latency_ns: BTreeMap<String, Percentiles>,
    /// Message latency (send → receipt) per link, `"<sender> → <receiver>"`, ns; the histograms
    /// are in the receivers' `timing/<receiver>.hlog`.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub link_latency_ns: BTreeMap<String, Percentiles>,
    /// The same per receiving process, over every link into it, ns.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub process_latency_ns: BTreeMap<String, Percentiles>,
    /// Each process's end report (`status/`, which has no latency histograms).
    pub processes: Vec<ProcessReport>,
    /// The memory the run's processes used together at its end: the sum of their proportional
    /// set sizes (each shared page counted once over all), kB. Multi-process runs only (the
    /// reference run's threads share one process).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pss_total_kb: Option<u64>,
    /// The histograms of the processes' latency logs, (sender, receiver) → buckets (kept in
    /// memory for a soak's merge, never written to `summary.json`).
    #[serde(skip)]
    pub histograms: BTreeMap<(String, String), LatencyBuckets>,
    /// Messages that went missing without being counted anywhere (sent, but neither received
    /// nor rejected by a reader that ran to the end): must be empty.
    pub messages_unaccounted: Vec<String>,
    /// Faults carried out, roster changes and their effect (empty without faults).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub timeline: Vec<cohort_runtime::record::TimelineEvent>,
    /// The run against its paper's published bounds and values (see `cohort_host::verdict`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub verdict: Vec<VerdictLine>,
    /// "pass" (no line fails, one passes), "fail" (a line fails) or "n/a"; absent without a
    /// verdict.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub verdict_overall: Option<&'static str>,
    /// What the analyses could not do (printed after the run's error when it failed).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<Warning>,
}

/// A problem the summary records without failing the run, by kind. `summary.json` lists their
/// messages (`"warnings"`), the text the log shows.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Warning {
    /// The processes' latency logs cannot be read (latency is diagnostic).
    #[error("latency histograms: {0}")]
    LatencyHistograms(String),
    /// The plant wrote no report: the steps completed are counted from the rest.
    #[error(
        "the plant left no report (status/plant.json): steps_completed = {steps} is a lower bound, from its \
         telemetry and the agents' reports"
    )]
    NoPlantReport { steps: u64 },
    /// A killed process's telemetry journal could not be sealed into its file.
    #[error("cannot turn a telemetry journal into its file: {0}")]
    UnsealedJournal(String),
    /// A paper's analysis of the run failed.
    #[error("{paper} analysis skipped: {reason}")]
    AnalysisSkipped { paper: String, reason: String },
    /// A paper's fault-effect analysis failed.
    #[error("{paper} fault effects skipped: {reason}")]
    FaultEffectsSkipped { paper: String, reason: String },
    /// `summary.json` itself could not be written.
    #[error("cannot write {}: {reason}", path.display())]
    SummaryNotWritten { path: std::path::PathBuf, reason: String },
}

impl Serialize for Warning {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

pub struct Outcome {
    pub startup_s: Option<f64>,
    pub mode: &'static str,
    pub run_id: String,
    pub status: RunStatus,
    pub error: Option<String>,
    pub wall_s: f64,
    pub timeline: Vec<cohort_runtime::record::TimelineEvent>,
}

pub fn build(s: &Setup, dirs: &RunDirs, outcome: Outcome) -> Summary {
    let mut processes: Vec<ProcessReport> = Vec::new();
    let names = std::iter::once("plant".to_string()).chain((1..=s.n_agents()).map(|i| format!("agent-{i}")));
    for name in names {
        let path = dirs.status().join(format!("{name}.json"));
        if let Some(r) = std::fs::read_to_string(&path).ok().and_then(|t| serde_json::from_str(&t).ok()) {
            processes.push(r);
        }
    }
    let mut warnings = Vec::new();
    // Latency is diagnostic: an unreadable log is a warning, never a lost summary.
    let histograms = cohort_runtime::record::read_latency_histograms(&dirs.root).unwrap_or_else(|e| {
        warnings.push(Warning::LatencyHistograms(e.to_string()));
        BTreeMap::new()
    });
    let (link_latency, process_latency) = percentiles(&histograms);
    let plant = processes.iter().find(|p| p.process == "plant");
    let steps_completed = match plant {
        Some(p) => p.steps_completed,
        None => {
            let n = steps_without_the_plants_report(dirs, &processes);
            // Only when the run got going: some process reported.
            if !processes.is_empty() {
                warnings.push(Warning::NoPlantReport { steps: n });
            }
            n
        }
    };
    let loop_wall = plant.map_or(0.0, |p| p.wall_s);
    let mut rejected: BTreeMap<String, u64> = BTreeMap::new();
    for p in &processes {
        for (k, v) in &p.messages_rejected {
            *rejected.entry(k.clone()).or_default() += v;
        }
    }
    let mut latency = BTreeMap::new();
    let t = dirs.timing();
    if let Some(p) = Percentiles::of(timing_column(&t, "plant", "round_ns")) {
        latency.insert("plant_round".to_string(), p);
    }
    if let Some(p) = Percentiles::of(timing_column(&t, "plant", "share_latency_max_ns")) {
        latency.insert("share_to_plant".to_string(), p);
    }
    let mut meas = Vec::new();
    let mut nbr = Vec::new();
    let mut compute = Vec::new();
    for i in 1..=s.n_agents() {
        let name = format!("agent-{i}");
        meas.extend(timing_column(&t, &name, "meas_latency_ns"));
        nbr.extend(timing_column(&t, &name, "neighbour_wait_ns"));
        compute.extend(timing_column(&t, &name, "compute_ns"));
    }
    for (name, xs) in [("measurement_to_agent", meas), ("agent_neighbour_wait", nbr), ("agent_compute", compute)] {
        if let Some(p) = Percentiles::of(xs) {
            latency.insert(name.to_string(), p);
        }
    }
    Summary {
        scenario: s.scenario.name.clone(),
        seed: s.scenario.seed,
        mode: outcome.mode,
        run_id: outcome.run_id,
        status: outcome.status,
        error: outcome.error,
        n_agents: s.n_agents(),
        steps: s.n_steps(),
        steps_completed,
        sim_time_s: steps_completed as f64 * s.scenario.dt_s,
        wall_s: outcome.wall_s,
        steps_per_s: if loop_wall > 0.0 { steps_completed as f64 / loop_wall } else { 0.0 },
        startup_s: outcome.startup_s,
        metrics: plant.map(|p| p.metrics.clone()).unwrap_or_default(),
        labels: s.algorithm.labels(),
        messages_received: processes.iter().map(|p| p.messages_received).sum(),
        messages_rejected: rejected,
        timeouts: processes.iter().map(|p| p.timeouts).sum(),
        latency_ns: latency,
        link_latency_ns: link_latency,
        process_latency_ns: process_latency,
        messages_unaccounted: unaccounted(s, &processes, &outcome.timeline),
        pss_total_kb: (outcome.mode == "multi-process").then(|| processes.iter().map(|p| p.pss_kb).sum()),
        processes,
        histograms,
        timeline: outcome.timeline,
        verdict: Vec::new(),
        verdict_overall: None,
        warnings,
    }
}

/// How many steps a plant that left no report (SIGKILLed, crashed) completed, at least: one past
/// the last row of its telemetry (its journal, sealed), or one less than the most steps an agent
/// completed (an agent computes step k only on the plant's measurement k, which the plant sends
/// once it has completed step k − 1), whichever is more.
fn steps_without_the_plants_report(dirs: &RunDirs, processes: &[ProcessReport]) -> u64 {
    let path = dirs.telemetry().join("plant.parquet");
    let from_telemetry = cohort_report::Table::read_columns(&path, &[] as &[&str])
        .ok()
        .and_then(|t| t.steps().last().map(|k| k + 1))
        .unwrap_or(0);
    let from_agents = processes.iter().map(|p| p.steps_completed).max().unwrap_or(0).saturating_sub(1);
    from_telemetry.max(from_agents)
}

type LinkHistograms = BTreeMap<(String, String), LatencyBuckets>;

/// The percentiles per link and per receiving process (all its links merged) of a run's
/// histograms.
fn percentiles(links: &LinkHistograms) -> (BTreeMap<String, Percentiles>, BTreeMap<String, Percentiles>) {
    let mut per_link = BTreeMap::new();
    let mut merged: BTreeMap<&str, LatencyHist> = BTreeMap::new();
    for ((from, to), b) in links {
        let h = LatencyHist::from_buckets(b);
        merged.entry(to.as_str()).or_default().add(&h);
        if let Some(q) = Percentiles::of_hist(&h) {
            per_link.insert(format!("{from} → {to}"), q);
        }
    }
    let per_process =
        merged.into_iter().filter_map(|(p, h)| Some((p.to_string(), Percentiles::of_hist(&h)?))).collect();
    (per_link, per_process)
}

pub fn write(dirs: &RunDirs, summary: &Summary) -> std::io::Result<()> {
    let text = serde_json::to_string_pretty(summary).map_err(std::io::Error::other)?;
    cohort_runtime::record::write_atomic(&dirs.root.join("summary.json"), (text + "\n").as_bytes())
}

/// Every message sent must reach every reader that ran to the end, where it is counted as
/// received (valid or rejected): a shortfall is a message lost without being counted (an
/// overflowing subscriber queue would be one). Links to or from an agent that a fault stopped,
/// or that died, are left out: a dead reader reads nothing, and a relaunched agent's report
/// covers only its second life.
pub fn unaccounted(
    s: &Scenario,
    processes: &[ProcessReport],
    timeline: &[cohort_runtime::record::TimelineEvent],
) -> Vec<String> {
    let complete = |name: &str| processes.iter().find(|p| p.process == name && p.error.is_none());
    let disturbed = |id: u32| timeline.iter().any(|e| e.agent == id && e.event != "alive");
    let mut out = Vec::new();
    let Some(plant) = complete("plant") else { return out };
    let n = s.n_agents();
    for j in 1..=n {
        let name = format!("agent-{j}");
        let Some(sender) = complete(&name) else { continue };
        if disturbed(j) {
            continue;
        }
        let readers = std::iter::once("plant".to_string())
            .chain(s.topology().readers_of(j).into_iter().filter(|&r| !disturbed(r)).map(|r| format!("agent-{r}")));
        for r in readers {
            let Some(reader) = complete(&r) else { continue };
            let got = reader.received_from.get(&name).copied().unwrap_or(0);
            // A gap in the sender's steps is either lost in a full queue or never sent: a sender
            // that fell behind in real time skips to the newest measurement (its `steps_missed`).
            let gap = reader.faults.overrun.get(&name).copied().unwrap_or(0);
            let skipped = sender.faults.steps_missed;
            if got + gap != sender.messages_sent + skipped {
                out.push(format!(
                    "{name} → {r}: {} sent (and {skipped} steps skipped), {got} received, {gap} steps missing",
                    sender.messages_sent
                ));
            }
        }
        let got = sender.received_from.get("plant").copied().unwrap_or(0);
        let overrun = sender.faults.overrun.get("plant").copied().unwrap_or(0);
        let sent = plant.messages_sent / u64::from(n);
        if got + overrun != sent {
            out.push(format!("plant → {name}: {sent} sent, {got} received, {overrun} counted as lost to a full queue"));
        }
    }
    out
}
