//! `orchestrator soak FILE --wall 10m [--realtime] [--faults KINDS]`: run a scenario
//! multi-process again and again for a wall-clock budget and watch what a long mission would
//! notice: per-link latency (HdrHistogram: p50/p99/p99.9/max, merged over the runs), deadline
//! misses, messages sent/received/rejected/held, the RSS of every process and the number of
//! iceoryx2 entries in /dev/shm, sampled every second. The soak fails (exit 1, saying why) when
//! a message is lost without being counted, when a process's RSS or the shm entries grow
//! steadily, or when a run fails.
//!
//! With `--faults kill,freeze,restart,delay,drop,corrupt` (any subset) every run also gets one
//! fault of each listed kind, on a random agent at a random time in the middle half of the run
//! (seeded from the run's seed): drop and corrupt at p = 0.1, delay of 2 steps, a 2-s freeze, a
//! restart after 2 s, each lasting a tenth of the run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use cohort_report::markdown::{Align, MdTable};
use cohort_runtime::paper::Setup;
use cohort_runtime::record::LatencyHist;
use cohort_runtime::run_status::RunStatus;
use cohort_scenario::Overrides;
use cohort_scenario::faults::{FAULT_KINDS, FaultSpec};
use serde::Serialize;

/// How often RSS and shm entries are sampled.
const SAMPLE_EVERY: Duration = Duration::from_secs(1);
/// RSS growth over a run's second half that counts as steady growth: this fraction of the
/// process's RSS at mid-run, and at least [`RSS_GROWTH_MIN_KB`].
const RSS_GROWTH_FRACTION: f64 = 0.10;
const RSS_GROWTH_MIN_KB: f64 = 4096.0;

pub struct Options {
    pub file: PathBuf,
    pub wall: Duration,
    pub realtime: bool,
    pub rate: f64,
    pub faults: Vec<String>,
    pub out: PathBuf,
    pub seed: Option<u64>,
}

/// Parse `10m`, `90s`, `1h`, `600` (seconds).
pub fn parse_wall(text: &str) -> Result<Duration, String> {
    let t = text.trim();
    let (num, unit) = match t.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => t.split_at(i),
        None => (t, "s"),
    };
    let x: f64 = num.parse().map_err(|_| format!("--wall {text:?}: expected a duration like 10m, 90s or 1h"))?;
    let secs = match unit {
        "s" => x,
        "m" | "min" => x * 60.0,
        "h" => x * 3600.0,
        _ => return Err(format!("--wall {text:?}: unknown unit {unit:?} (use s, m or h)")),
    };
    if !(secs.is_finite() && secs > 0.0 && secs <= 7.0 * 86400.0) {
        return Err(format!("--wall {text:?}: must be positive and at most a week"));
    }
    Ok(Duration::from_secs_f64(secs))
}

/// Check `--faults` (a comma list of fault kinds).
pub fn parse_fault_kinds(text: &str) -> Result<Vec<String>, String> {
    let kinds: Vec<String> = text.split(',').map(|k| k.trim().to_string()).filter(|k| !k.is_empty()).collect();
    for k in &kinds {
        if !FAULT_KINDS.contains(&k.as_str()) {
            return Err(format!("--faults: unknown fault kind {k:?} (expected some of: {})", FAULT_KINDS.join(", ")));
        }
    }
    Ok(kinds)
}

#[derive(Debug, Clone, Serialize)]
struct RssSample {
    wall_s: f64,
    run: usize,
    process: String,
    rss_kb: u64,
}

#[derive(Debug, Clone, Serialize)]
struct ShmSample {
    wall_s: f64,
    entries: usize,
}

#[derive(Debug, Serialize)]
struct LinkStats {
    samples: u64,
    p50_ns: u64,
    p99_ns: u64,
    p999_ns: u64,
    max_ns: u64,
}

impl LinkStats {
    /// The figures of `h`, or none when it holds no sample.
    fn of(h: &LatencyHist) -> Option<Self> {
        (!h.is_empty()).then(|| Self {
            samples: h.len(),
            p50_ns: h.quantile(0.5),
            p99_ns: h.quantile(0.99),
            p999_ns: h.quantile(0.999),
            max_ns: h.max(),
        })
    }
}

#[derive(Debug, Serialize)]
struct RunRecord {
    run: usize,
    seed: u64,
    status: RunStatus,
    error: Option<String>,
    steps: u64,
    wall_start_s: f64,
    wall_s: f64,
    deadline_misses: u64,
    messages_sent: u64,
    messages_received: u64,
    messages_rejected: u64,
    shares_held: u64,
    /// Steps missing at the readers (a full queue, or a sender that skipped), from step gaps.
    steps_missing: u64,
    unaccounted: Vec<String>,
    faults: Vec<String>,
    /// The run's latency over all its links, read from its `timing/` histograms before the
    /// soak deletes that directory (none: the run recorded no sample).
    latency: Option<LinkStats>,
}

#[derive(Debug, Serialize)]
struct SoakReport {
    scenario: String,
    wall_budget_s: f64,
    wall_s: f64,
    realtime_rate: Option<f64>,
    runs: Vec<RunRecord>,
    links: BTreeMap<String, LinkStats>,
    deadline_misses: u64,
    rss_first_last_kb: BTreeMap<String, (u64, u64)>,
    shm_entries_before: usize,
    shm_entries_after: usize,
    problems: Vec<String>,
}

/// iceoryx2 entries of any Cohort run: /dev/shm segments and files under /tmp/iceoryx2/.
fn shm_entries() -> usize {
    let count = |dir: &Path, recurse: bool| -> usize {
        let Ok(rd) = std::fs::read_dir(dir) else { return 0 };
        rd.flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with("cohort_"))
            .map(|e| if recurse && e.path().is_dir() { 1 + count_files(&e.path()) } else { 1 })
            .sum()
    };
    count(Path::new("/dev/shm"), false) + count(Path::new("/tmp/iceoryx2"), true)
}

fn count_files(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .map(|rd| rd.flatten().map(|e| if e.path().is_dir() { 1 + count_files(&e.path()) } else { 1 }).sum())
        .unwrap_or(0)
}

/// (process name, RSS kB) of every process whose command line mentions `run_dir`.
fn run_processes(run_dir: &str) -> Vec<(String, u64)> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir("/proc") else { return out };
    for e in rd.flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else { continue };
        let Ok(cmd) = std::fs::read(format!("/proc/{pid}/cmdline")) else { continue };
        let args: Vec<String> =
            cmd.split(|b| *b == 0).map(|a| String::from_utf8_lossy(a).to_string()).filter(|a| !a.is_empty()).collect();
        if !args.iter().any(|a| a == run_dir) {
            continue;
        }
        let exe = args.first().map(|a| Path::new(a).file_name().unwrap_or_default().to_string_lossy().to_string());
        let name = match exe.as_deref() {
            Some("plant") => "plant".to_string(),
            Some("agent") => {
                let id = args.iter().position(|a| a == "--id").and_then(|i| args.get(i + 1)).cloned();
                format!("agent-{}", id.unwrap_or_default())
            }
            _ => continue,
        };
        if let Some(kb) = rss_kb(&format!("/proc/{pid}/status")) {
            out.push((name, kb));
        }
    }
    out.sort();
    out
}

fn rss_kb(status: &str) -> Option<u64> {
    let text = std::fs::read_to_string(status).ok()?;
    text.lines().find(|l| l.starts_with("VmRSS:"))?.split_whitespace().nth(1)?.parse().ok()
}

/// The soak's scenario, validated once up front (with its first run's settings).
fn load_for_soak(file: &std::path::Path, o: &Options) -> Result<Setup, String> {
    let ov = Overrides { seed: o.seed, realtime_rate: o.realtime.then_some(o.rate), ..Default::default() };
    let s = crate::load(file, &ov).map_err(|e| e.to_string())?;
    if s.algorithm.coupled().is_some() {
        return Err(format!("{}: a coupled scenario runs in one process; a soak needs processes", file.display()));
    }
    Ok(s)
}

/// One random fault of each kind for run `seed`: a small deterministic generator, so a soak
/// can be repeated.
fn random_faults(kinds: &[String], s: &Setup, seed: u64) -> Vec<FaultSpec> {
    let mut state = seed ^ 0x5EED_50AC;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let d = s.scenario.duration_s;
    let dt = s.scenario.dt_s;
    let mut taken: Vec<u32> = Vec::new();
    let mut out = Vec::new();
    for kind in kinds {
        let n = s.n_agents();
        let mut agent = 1 + (next() * f64::from(n)) as u32 % n;
        // Process faults go to different agents, and at least one agent is never touched by one.
        let is_process = matches!(kind.as_str(), "kill" | "freeze" | "restart");
        if is_process {
            if taken.len() + 1 >= n as usize {
                continue;
            }
            while taken.contains(&agent) {
                agent = agent % n + 1;
            }
            taken.push(agent);
        }
        let t_s = ((0.25 + 0.5 * next()) * d / dt).round() * dt;
        let window = (0.1 * d / dt).round().max(1.0) * dt;
        let mut f = FaultSpec { kind: kind.clone(), agent, t_s, for_s: None, p: None, delay_steps: None };
        match kind.as_str() {
            "drop" | "corrupt" => (f.p, f.for_s) = (Some(0.1), Some(window)),
            "delay" => (f.delay_steps, f.for_s) = (Some(2), Some(window)),
            "freeze" | "restart" => f.for_s = Some((2.0 / dt).round().max(1.0) * dt),
            _ => {}
        }
        if f.t_s + f.for_s.unwrap_or(0.0) < d {
            out.push(f);
        }
    }
    out
}

/// A number as short as it reads (times are whole steps; no 9.450000000000001).
fn short(x: f64) -> String {
    let t = format!("{x:.6}");
    t.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// The fault in `--fault` form.
fn describe(f: &FaultSpec) -> String {
    let mut s = format!("{}:agent={}@t={}", f.kind, f.agent, short(f.t_s));
    if let Some(x) = f.for_s {
        s.push_str(&format!(",for={}", short(x)));
    }
    if let Some(p) = f.p {
        s.push_str(&format!(",p={p}"));
    }
    if let Some(n) = f.delay_steps {
        s.push_str(&format!(",steps={n}"));
    }
    s
}

/// Steady growth of one process's RSS within one run: its second half grew by more than the
/// threshold, and most of the samples of that half went up or stayed (not one late spike).
fn steady_growth(samples: &[u64]) -> Option<(u64, u64)> {
    if samples.len() < 8 {
        return None;
    }
    let half = &samples[samples.len() / 2..];
    let (first, last) = (half[0], *half.last().expect("non-empty"));
    let grew = last as f64 - first as f64;
    let rising = half.windows(2).filter(|w| w[1] >= w[0]).count();
    let threshold = (RSS_GROWTH_FRACTION * first as f64).max(RSS_GROWTH_MIN_KB);
    (grew > threshold && rising * 10 >= (half.len() - 1) * 8).then_some((first, last))
}

/// Run the soak: one run after another until the budget is spent, then the checks over all of
/// them, `soak.json`, `soak.md` and the plots. Returns the Markdown and whether it passed.
pub fn run(o: &Options) -> Result<(String, bool), String> {
    let mut soak = Soak::open(o)?;
    while soak.next_run(o)? {}
    soak.finish(o)
}

/// What the soak has gathered so far.
struct Soak {
    base: Setup,
    started: Instant,
    shm_before: usize,
    rss: Vec<RssSample>,
    shm: Vec<ShmSample>,
    runs: Vec<RunRecord>,
    links: BTreeMap<String, LatencyHist>,
    problems: Vec<String>,
    seed0: u64,
    /// The next run's number.
    index: usize,
}

impl Soak {
    /// Validate the scenario once and create the output directory.
    fn open(o: &Options) -> Result<Self, String> {
        let base = load_for_soak(&o.file, o)?;
        std::fs::create_dir_all(&o.out).map_err(|e| format!("{}: {e}", o.out.display()))?;
        let started = Instant::now();
        let shm_before = shm_entries();
        let seed0 = o.seed.unwrap_or(base.scenario.seed);
        Ok(Self {
            base,
            started,
            shm_before,
            rss: Vec::new(),
            shm: vec![ShmSample { wall_s: 0.0, entries: shm_before }],
            runs: Vec::new(),
            links: BTreeMap::new(),
            problems: Vec::new(),
            seed0,
            index: 0,
        })
    }

    /// The next run's scenario (its seed, its random faults, in real time cut to what is left of
    /// the budget); none when the budget is spent or the soak was interrupted.
    fn next_setup(&mut self, o: &Options) -> Result<Option<(Setup, u64)>, String> {
        if self.started.elapsed() >= o.wall {
            return Ok(None);
        }
        if cohort_supervisor::supervise::SIGNALLED.load(Ordering::SeqCst) != 0 {
            self.problems.push("interrupted".into());
            return Ok(None);
        }
        let base = &self.base;
        let remaining = o.wall.saturating_sub(self.started.elapsed()).as_secs_f64();
        let seed = self.seed0 + self.index as u64;
        let mut ov = Overrides { seed: Some(seed), realtime_rate: o.realtime.then_some(o.rate), ..Default::default() };
        // Real time: a run cannot outlast the budget (sim time = wall time × rate).
        if o.realtime {
            let fit = ((remaining * o.rate) / base.scenario.dt_s).floor() * base.scenario.dt_s;
            if fit < base.scenario.dt_s * 10.0 {
                return Ok(None);
            }
            if fit < base.scenario.duration_s {
                ov.duration_s = Some(fit);
            }
        }
        let mut s = crate::load(&o.file, &ov).map_err(|e| e.to_string())?;
        let extra = random_faults(&o.faults, &s, seed);
        s.parsed.faults.extend(extra);
        Ok(Some((s, seed)))
    }

    /// One run, its processes sampled while it runs. Returns whether the soak goes on.
    fn next_run(&mut self, o: &Options) -> Result<bool, String> {
        let Some((s, seed)) = self.next_setup(o)? else { return Ok(false) };
        let index = self.index;
        let dirs = crate::prepare(&s, Some(&o.out.join(format!("run-{index:03}"))))
            .map_err(|_| "cannot create the run directory".to_string())?;
        let stop = Arc::new(AtomicBool::new(false));
        let sampler = sampler(Arc::clone(&stop), dirs.root.display().to_string(), self.started, index);
        let wall_start_s = self.started.elapsed().as_secs_f64();
        tracing::info!(
            "soak run {index}: seed {seed}, {} steps{}",
            s.n_steps(),
            if s.faults.is_empty() {
                String::new()
            } else {
                format!(", faults {}", s.faults.iter().map(describe).collect::<Vec<_>>().join(" "))
            }
        );
        let (outcome, summary) = crate::run_once(&s, &dirs, false, false);
        stop.store(true, Ordering::SeqCst);
        let (r, m) = sampler.join().map_err(|_| "the sampler thread panicked".to_string())?;
        self.rss.extend(r);
        self.shm.extend(m);
        self.shm.push(ShmSample { wall_s: self.started.elapsed().as_secs_f64(), entries: shm_entries() });
        let record = self.record(&s, seed, wall_start_s, &outcome, &summary);
        if outcome.status.is_interrupted() {
            self.problems.push(format!("run {index} was interrupted"));
            self.runs.push(record);
            return Ok(false);
        }
        if outcome.error.is_some() {
            self.problems.push(format!(
                "run {index} (seed {seed}) {}: {}",
                outcome.status,
                record.error.clone().unwrap_or_default()
            ));
        }
        for u in &record.unaccounted {
            self.problems.push(format!("run {index}: message lost without being counted: {u}"));
        }
        // Telemetry of a soak is large and not its point; summaries stay.
        dirs.remove_bulk();
        let _ = std::fs::remove_dir_all(dirs.root.join("checkpoints"));
        self.runs.push(record);
        self.index += 1;
        Ok(true)
    }

    /// The run's record; its latency histograms added to the soak's per link.
    fn record(
        &mut self,
        s: &Setup,
        seed: u64,
        wall_start_s: f64,
        outcome: &cohort_supervisor::supervise::LaunchOutcome,
        summary: &crate::summary::Summary,
    ) -> RunRecord {
        let plant = summary.processes.iter().find(|p| p.process == "plant");
        // The histograms were read from `timing/` by the run's summary; the run's own figures
        // are taken here, before that directory is deleted.
        let mut run_latency = LatencyHist::default();
        for ((from, to), b) in &summary.histograms {
            let h = LatencyHist::from_buckets(b);
            run_latency.add(&h);
            self.links.entry(format!("{from} → {to}")).or_default().add(&h);
        }
        RunRecord {
            run: self.index,
            seed,
            status: outcome.status,
            error: outcome.error.clone(),
            steps: summary.steps_completed,
            wall_start_s,
            wall_s: outcome.wall_s,
            deadline_misses: plant.map_or(0, |p| p.faults.deadline_misses),
            messages_sent: summary.processes.iter().map(|p| p.messages_sent).sum(),
            messages_received: summary.messages_received,
            messages_rejected: summary.messages_rejected.values().sum(),
            shares_held: summary.processes.iter().flat_map(|p| p.faults.held.values()).sum(),
            steps_missing: summary.processes.iter().flat_map(|p| p.faults.overrun.values()).sum(),
            unaccounted: summary.messages_unaccounted.clone(),
            faults: s.faults.iter().map(describe).collect(),
            latency: LinkStats::of(&run_latency),
        }
    }

    /// The checks over every run (shm entries, RSS), the report and its files.
    fn finish(mut self, o: &Options) -> Result<(String, bool), String> {
        let shm_after = shm_entries();
        self.shm_problems(shm_after);
        let rss_first_last = self.rss_problems();
        let link_stats: BTreeMap<String, LinkStats> =
            self.links.iter().filter_map(|(k, h)| LinkStats::of(h).map(|st| (k.clone(), st))).collect();
        let report = SoakReport {
            scenario: self.base.scenario.name.clone(),
            wall_budget_s: o.wall.as_secs_f64(),
            wall_s: self.started.elapsed().as_secs_f64(),
            realtime_rate: o.realtime.then_some(o.rate),
            deadline_misses: self.runs.iter().map(|r| r.deadline_misses).sum(),
            runs: self.runs,
            links: link_stats,
            rss_first_last_kb: rss_first_last,
            shm_entries_before: self.shm_before,
            shm_entries_after: shm_after,
            problems: self.problems,
        };
        let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
        std::fs::write(o.out.join("soak.json"), json).map_err(|e| format!("{}: {e}", o.out.display()))?;
        let md = markdown(&report);
        std::fs::write(o.out.join("soak.md"), &md).map_err(|e| format!("{}: {e}", o.out.display()))?;
        plots(&o.out, &self.rss, &self.shm, &report)?;
        Ok((md, report.problems.is_empty()))
    }

    /// iceoryx2 entries left after the soak, or climbing from one run to the next.
    fn shm_problems(&mut self, shm_after: usize) {
        let shm_before = self.shm_before;
        if shm_after > shm_before {
            self.problems.push(format!("iceoryx2 entries grew over the soak: {shm_before} before, {shm_after} after"));
        }
        // From one run to the next: the entries left once a run has ended and cleaned up (the
        // last sample of each run, taken after it) must not climb. Not the largest sample during
        // a run: a run shorter than the sampling period is sampled once, at a moment of its
        // start-up when some of its segments exist and others do not yet, so that maximum was
        // the phase the sample happened to hit (a 1 s soak of four runs reported [1, 7, 10, 11]).
        let starts: Vec<f64> = self.runs.iter().map(|r| r.wall_start_s).collect();
        let left = left_after_runs(&starts, &self.shm);
        if left.len() >= 3 && left.windows(2).all(|w| w[1] > w[0]) {
            self.problems.push(format!("iceoryx2 entries left after each run grew run after run: {left:?}"));
        }
    }

    /// A process whose RSS grew steadily within a run. Returns each process's first and last
    /// RSS over the soak.
    fn rss_problems(&mut self) -> BTreeMap<String, (u64, u64)> {
        let mut rss_first_last: BTreeMap<String, (u64, u64)> = BTreeMap::new();
        let mut by_proc_run: BTreeMap<(String, usize), Vec<u64>> = BTreeMap::new();
        for x in &self.rss {
            by_proc_run.entry((x.process.clone(), x.run)).or_default().push(x.rss_kb);
            let e = rss_first_last.entry(x.process.clone()).or_insert((x.rss_kb, x.rss_kb));
            e.1 = x.rss_kb;
        }
        for ((process, run), samples) in &by_proc_run {
            if let Some((a, b)) = steady_growth(samples) {
                self.problems
                    .push(format!("RSS of {process} grew steadily in run {run}: {a} kB → {b} kB over its second half"));
            }
        }
        rss_first_last
    }
}

/// The entries of the last sample of each run (runs starting at `starts`, in order; 0 for a run
/// without a sample).
fn left_after_runs(starts: &[f64], shm: &[ShmSample]) -> Vec<usize> {
    let mut left = Vec::with_capacity(starts.len());
    for (i, &start) in starts.iter().enumerate() {
        let end = starts.get(i + 1).copied().unwrap_or(f64::INFINITY);
        let last =
            shm.iter().filter(|x| x.wall_s >= start && x.wall_s < end).max_by(|a, b| a.wall_s.total_cmp(&b.wall_s));
        left.push(last.map_or(0, |x| x.entries));
    }
    left
}

/// A thread sampling the RSS of run `index`'s processes (in `run_dir`) and the shm entries every
/// [`SAMPLE_EVERY`] until `stop`; joined, it returns its samples.
fn sampler(
    stop: Arc<AtomicBool>,
    run_dir: String,
    t0: Instant,
    index: usize,
) -> std::thread::JoinHandle<(Vec<RssSample>, Vec<ShmSample>)> {
    std::thread::spawn(move || {
        let (mut r, mut m) = (Vec::new(), Vec::new());
        while !stop.load(Ordering::SeqCst) {
            let wall_s = t0.elapsed().as_secs_f64();
            let procs = run_processes(&run_dir);
            // The orchestrator is watched while it supervises (its processes are alive):
            // afterwards it reads the whole run's telemetry for the summary, a one-off
            // that is not a leak (its RSS from run to run stays in the table).
            if !procs.is_empty()
                && let Some(kb) = rss_kb("/proc/self/status")
            {
                r.push(RssSample { wall_s, run: index, process: "orchestrator".into(), rss_kb: kb });
            }
            for (process, rss_kb) in procs {
                r.push(RssSample { wall_s, run: index, process, rss_kb });
            }
            m.push(ShmSample { wall_s, entries: shm_entries() });
            let until = Instant::now() + SAMPLE_EVERY;
            while Instant::now() < until && !stop.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        (r, m)
    })
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1e3)
}

/// One row per run: its outcome, traffic, latency and faults.
fn runs_table(runs: &[RunRecord]) -> MdTable {
    let header = [
        "run",
        "seed",
        "status",
        "steps",
        "wall s",
        "sent",
        "received",
        "rejected",
        "held",
        "steps missing (full queue or skipped)",
        "deadline misses",
        "latency p99 µs",
        "latency max µs",
        "faults",
    ];
    let mut t = MdTable::new(header);
    for c in (0..13).filter(|&c| c != 2) {
        t = t.align(c, Align::Right);
    }
    for x in runs {
        t.row([
            x.run.to_string(),
            x.seed.to_string(),
            x.status.to_string(),
            x.steps.to_string(),
            format!("{:.1}", x.wall_s),
            x.messages_sent.to_string(),
            x.messages_received.to_string(),
            x.messages_rejected.to_string(),
            x.shares_held.to_string(),
            x.steps_missing.to_string(),
            x.deadline_misses.to_string(),
            x.latency.as_ref().map_or("—".into(), |l| us(l.p99_ns)),
            x.latency.as_ref().map_or("—".into(), |l| us(l.max_ns)),
            x.faults.join(" "),
        ]);
    }
    t
}

fn markdown(r: &SoakReport) -> String {
    let mut s = format!(
        "# Soak of {} — {:.0} s wall ({} runs{})\n\n",
        r.scenario,
        r.wall_s,
        r.runs.len(),
        r.realtime_rate.map_or(String::from(", as fast as possible"), |x| format!(", real time at rate {x}"))
    );
    s.push_str(&format!(
        "Verdict: **{}**\n\n",
        if r.problems.is_empty() { "pass".to_string() } else { format!("FAIL — {}", r.problems.join("; ")) }
    ));
    s.push_str("## Per-link latency (send → receipt, µs, all runs)\n\n");
    let mut links = MdTable::new(["link", "samples", "p50", "p99", "p99.9", "max"]);
    for c in 1..6 {
        links = links.align(c, Align::Right);
    }
    for (k, l) in &r.links {
        links.row([k.clone(), l.samples.to_string(), us(l.p50_ns), us(l.p99_ns), us(l.p999_ns), us(l.max_ns)]);
    }
    s.push_str(&links.to_string());
    s.push_str(&format!("\nDeadline misses (plant, real time): {}\n\n## Runs\n\n", r.deadline_misses));
    s.push_str(&runs_table(&r.runs).to_string());
    s.push_str("\n## RSS, first and last sample (kB)\n\n");
    let mut rss = MdTable::new(["process", "first", "last"]).align(1, Align::Right).align(2, Align::Right);
    for (p, (a, b)) in &r.rss_first_last_kb {
        rss.row([p.clone(), a.to_string(), b.to_string()]);
    }
    s.push_str(&rss.to_string());
    s.push_str(&format!(
        "\niceoryx2 entries (/dev/shm and /tmp/iceoryx2, every Cohort run): {} before, {} after.\n",
        r.shm_entries_before, r.shm_entries_after
    ));
    s
}

fn plots(out: &Path, rss: &[RssSample], shm: &[ShmSample], r: &SoakReport) -> Result<(), String> {
    let mut by_proc: BTreeMap<&str, Vec<(f64, f64)>> = BTreeMap::new();
    for x in rss {
        by_proc.entry(&x.process).or_default().push((x.wall_s, x.rss_kb as f64 / 1024.0));
    }
    let series = by_proc.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
    cohort_report::chart::draw_lines(&out.join("rss.png"), "RSS of every process (soak)", "RSS [MiB]", series)?;
    let points = shm.iter().map(|x| (x.wall_s, x.entries as f64)).collect();
    cohort_report::chart::draw_lines(
        &out.join("shm.png"),
        "iceoryx2 entries (soak)",
        "entries",
        vec![("entries".into(), points)],
    )?;
    // Per run: every link's p99 and the worst max, at the run's start time.
    let mut lat: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let mut misses = Vec::new();
    // (From the figures each run kept: its `timing/` directory is gone by now.)
    for run in &r.runs {
        let Some(l) = &run.latency else { continue };
        let figures = [("p50", l.p50_ns), ("p99", l.p99_ns), ("p99.9", l.p999_ns), ("max", l.max_ns)];
        for (i, (name, v)) in figures.iter().enumerate() {
            if lat.len() <= i {
                lat.push((name.to_string(), Vec::new()));
            }
            lat[i].1.push((run.wall_start_s, *v as f64 / 1e3));
        }
        misses.push((run.wall_start_s, run.deadline_misses as f64));
    }
    cohort_report::chart::draw_lines(
        &out.join("latency.png"),
        "Message latency per run, all links (soak)",
        "latency [µs]",
        lat,
    )?;
    cohort_report::chart::draw_lines(
        &out.join("deadline_misses.png"),
        "Deadline misses per run (soak)",
        "misses",
        vec![("deadline misses".into(), misses)],
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What is left after each run counts, not what a run's start-up happened to show: four short
    /// runs sampled mid-creation at 1, 7, 10 and 11 entries, each leaving none, leave [0, 0, 0, 0];
    /// runs that each leave two more show it.
    #[test]
    fn the_entries_compared_are_those_left_after_each_run() {
        let smp = |wall_s: f64, entries: usize| ShmSample { wall_s, entries };
        let starts = [0.1, 0.4, 0.7, 1.0];
        let clean = [smp(0.0, 0), smp(0.11, 1), smp(0.35, 0), smp(0.41, 7), smp(0.65, 0), smp(0.71, 10)];
        let clean = [&clean[..], &[smp(0.95, 0), smp(1.01, 11), smp(1.3, 0)]].concat();
        assert_eq!(left_after_runs(&starts, &clean), vec![0, 0, 0, 0]);
        let leaking = [smp(0.11, 9), smp(0.35, 2), smp(0.41, 9), smp(0.65, 4), smp(0.71, 9), smp(0.95, 6), smp(1.3, 8)];
        assert_eq!(left_after_runs(&starts, &leaking), vec![2, 4, 6, 8]);
        assert_eq!(left_after_runs(&[0.0, 5.0], &[smp(1.0, 3)]), vec![3, 0], "a run without a sample counts 0");
    }

    #[test]
    fn wall_durations_parse_and_bad_ones_are_named() {
        assert_eq!(parse_wall("10m").unwrap(), Duration::from_secs(600));
        assert_eq!(parse_wall("90s").unwrap(), Duration::from_secs(90));
        assert_eq!(parse_wall("45").unwrap(), Duration::from_secs(45));
        assert_eq!(parse_wall("1h").unwrap(), Duration::from_secs(3600));
        for bad in ["", "ten", "5d", "-3m", "0"] {
            assert!(parse_wall(bad).unwrap_err().contains("--wall"), "{bad}");
        }
        assert!(parse_fault_kinds("kill,explode").unwrap_err().contains("explode"));
        assert_eq!(parse_fault_kinds("drop, corrupt").unwrap(), vec!["drop", "corrupt"]);
    }

    #[test]
    fn steady_growth_is_told_from_noise_and_a_late_spike() {
        let flat: Vec<u64> = (0..20).map(|i| 50_000 + (i % 3) * 100).collect();
        assert!(steady_growth(&flat).is_none());
        let leak: Vec<u64> = (0..20).map(|i| 50_000 + i * 2_000).collect();
        assert!(steady_growth(&leak).is_some());
        let mut spike = flat.clone();
        *spike.last_mut().unwrap() = 90_000;
        assert!(steady_growth(&spike).is_none());
    }
}
