//! What the bench passes around: a case (a scenario and how to run it), a sample (what one run
//! of it measured) and an aggregate (a case's samples with their medians), plus the median the
//! tables use.

use std::time::Duration;

use cohort_runtime::paper::Setup;
use serde::Serialize;

/// One benchmark case: a scenario and how to run it.
#[derive(Clone)]
pub(super) struct Case {
    /// Stable key, e.g. `ring/N=20/poll`.
    pub(super) key: String,
    pub(super) group: &'static str,
    pub(super) n: u32,
    pub(super) variant: String,
    /// What the case's section calls it (a headline scenario's name).
    pub(super) label: String,
    pub(super) scenario: Setup,
    pub(super) reference: bool,
    /// Run with two busy-loop hogs on the machine (the "loaded" rows).
    pub(super) hogs: bool,
    /// Across the lab's namespaces, with this delay on what every namespace sends (zero: none).
    pub(super) lab: Option<Duration>,
    /// The `live` rows: served live (`--live`), with which client.
    pub(super) live: Option<super::live::LiveClient>,
}

/// What one run of a case measured.
#[derive(Debug, Clone, Serialize)]
pub(super) struct Sample {
    pub(super) wall_s: f64,
    pub(super) steps: u64,
    pub(super) steps_per_s: f64,
    pub(super) round_p50_us: f64,
    pub(super) round_p99_us: f64,
    pub(super) round_max_ms: f64,
    pub(super) startup_s: Option<f64>,
    /// Median over agent processes; and the plant's.
    pub(super) agent_cpu_s_per_1000_steps: f64,
    pub(super) plant_cpu_s_per_1000_steps: f64,
    pub(super) agent_cpu_share: f64,
    pub(super) agent_rss_mb: f64,
    pub(super) plant_rss_mb: f64,
    /// Proportional set sizes at the end (shared pages split among the processes mapping them):
    /// the median agent's, the plant's, and all processes' together, MB.
    pub(super) agent_pss_mb: f64,
    pub(super) plant_pss_mb: f64,
    pub(super) total_pss_mb: f64,
    /// Share of the plant's round spent in the agents' own computation (median over agents of
    /// compute / round), from timing/.
    pub(super) compute_share: Option<f64>,
    /// Agents that solve an optimisation problem every step (their end reports' solver
    /// statistics): the median over agents of their solve-time p50, the largest p99 and the
    /// largest single solve, µs. None when no agent reports a solver.
    pub(super) solver_p50_us: Option<f64>,
    pub(super) solver_p99_us: Option<f64>,
    pub(super) solver_max_us: Option<f64>,
    /// Every process's waits for messages, summed (how adaptive waiting spun or blocked).
    pub(super) wait: cohort_runtime::record::WaitStats,
    /// An agent's own computation per step (share and step, from timing/): the median over the
    /// first agents of each one's median, µs.
    pub(super) agent_compute_us: Option<f64>,
    /// The step's two one-way legs (from timing/, the start-up steps left out): a measurement's
    /// latency from the plant's send to an agent's receipt (the median over the first agents of
    /// each one's median), and the latency of the last share the plant waited for in a step (its
    /// median), µs. Both clocks are one machine's in the lab, whose namespaces share it.
    pub(super) meas_latency_us: Option<f64>,
    pub(super) share_latency_max_us: Option<f64>,
}

#[derive(Debug, Serialize)]
pub(super) struct Aggregate {
    pub(super) key: String,
    pub(super) group: String,
    pub(super) label: String,
    pub(super) n: u32,
    pub(super) variant: String,
    pub(super) samples: Vec<Sample>,
    pub(super) steps_per_s_median: f64,
    pub(super) steps_per_s_min: f64,
    pub(super) steps_per_s_max: f64,
    pub(super) wall_s_median: f64,
}

impl Aggregate {
    /// The median over the samples of what `f` gives (those that have it); none when none has.
    pub(super) fn median_of(&self, f: impl Fn(&Sample) -> Option<f64>) -> Option<f64> {
        let mut xs: Vec<f64> = self.samples.iter().filter_map(f).collect();
        (!xs.is_empty()).then(|| median(&mut xs))
    }
}

/// The median of `xs` (sorted in place) by `cohort_report::stats`'s rule; NaN when empty.
pub(super) fn median(xs: &mut [f64]) -> f64 {
    xs.sort_by(f64::total_cmp);
    cohort_report::stats::median(xs)
}
