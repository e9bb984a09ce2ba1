//! What a process records: sim-time telemetry (deterministic, in `telemetry/`), wall-clock timing
//! (not deterministic, kept apart in `timing/`: per-step rows in the run's telemetry format, and
//! the message-latency histograms as an HdrHistogram interval log), and an end-of-process report
//! (`status/`, without the histograms).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use cohort_scenario::TelemetryFormat;
use cohort_wire::validate::{RejectCounts, Rejection};
use serde::{Deserialize, Serialize};

/// Where each kind of output goes inside a run directory.
#[derive(Debug, Clone)]
pub struct RunDirs {
    pub root: PathBuf,
}

impl RunDirs {
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }
    pub fn telemetry(&self) -> PathBuf {
        self.root.join("telemetry")
    }
    pub fn timing(&self) -> PathBuf {
        self.root.join("timing")
    }
    pub fn status(&self) -> PathBuf {
        self.root.join("status")
    }
    pub fn logs(&self) -> PathBuf {
        self.root.join("logs")
    }
    /// Sim-time outputs that are not one row per step (a plant model's
    /// [`crate::model::PlantModel::extra_telemetry`]), created when there are some.
    pub fn snapshots(&self) -> PathBuf {
        self.root.join("snapshots")
    }
    /// Remove a finished run's per-step outputs (telemetry, timing, derived), keeping its
    /// scenario, summary, status and logs: what a sweep or campaign of many runs keeps of each.
    pub fn remove_bulk(&self) {
        for d in [self.telemetry(), self.timing(), self.root.join("derived")] {
            let _ = std::fs::remove_dir_all(d);
        }
    }
    /// The run's resolved scenario, which each of its processes reads.
    pub fn scenario(&self) -> PathBuf {
        self.root.join("scenario.toml")
    }
    /// Write the run's scenario text and its digest ([`cohort_scenario::digest`]), each
    /// atomically: the text for the user and the tools, the digest so that each process of the
    /// run need not parse the text again. Text that does not parse gets no digest (a process
    /// reading it reports the problem). The digest only saves work: one that cannot be written
    /// (a full disk) is a warning, and the processes parse the text.
    pub fn write_scenario(&self, text: &str) -> Result<(), WriteScenarioError> {
        let file = self.scenario();
        let digest = cohort_scenario::digest::path_for(&file);
        let _ = std::fs::remove_file(&digest);
        write_atomic(&file, text.as_bytes()).map_err(|source| WriteScenarioError { path: file.clone(), source })?;
        if let Ok(bytes) = cohort_scenario::digest::encode(text)
            && let Err(e) = write_atomic(&digest, &bytes)
        {
            tracing::warn!(
                "{}: cannot write: {e}; the run's processes parse {} instead",
                digest.display(),
                file.display()
            );
        }
        Ok(())
    }
    pub fn create_all(&self) -> std::io::Result<()> {
        for d in [self.telemetry(), self.timing(), self.status(), self.logs()] {
            std::fs::create_dir_all(d)?;
        }
        Ok(())
    }
}

/// A run's scenario or its digest could not be written ([`RunDirs::write_scenario`]).
#[derive(Debug, thiserror::Error)]
#[error("{}: cannot write: {source}", path.display())]
pub struct WriteScenarioError {
    pub path: PathBuf,
    pub source: std::io::Error,
}

/// One CSV of sim-time rows. Numbers are written in their shortest form that parses back to the
/// same bits (Ryū, as Rust's `{:?}` but several times faster, which matters: formatting was the
/// plant's largest cost after the dynamics), so telemetry round-trips exactly and two runs that
/// computed the same values write the same bytes.
pub struct CsvWriter {
    out: BufWriter<File>,
    path: PathBuf,
    width: usize,
    line: String,
}

impl CsvWriter {
    pub fn create(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        let mut out = BufWriter::with_capacity(1 << 16, File::create(path)?);
        writeln!(out, "{}", columns.join(","))?;
        Ok(Self { out, path: path.to_path_buf(), width: columns.len(), line: String::with_capacity(256) })
    }
    /// Reopen an existing CSV to add rows (a relaunched agent goes on with its predecessor's file).
    pub fn append(path: &Path, width: usize) -> std::io::Result<Self> {
        let file = std::fs::OpenOptions::new().append(true).open(path)?;
        Ok(Self { out: BufWriter::with_capacity(1 << 16, file), path: path.to_path_buf(), width, line: String::new() })
    }
    /// Write `k`, then the values (the header must have 1 + values.len() columns).
    pub fn row(&mut self, k: u64, values: &[f64]) -> std::io::Result<()> {
        use std::fmt::Write as _;
        debug_assert_eq!(values.len() + 1, self.width, "{}", self.path.display());
        self.line.clear();
        let _ = write!(self.line, "{k}");
        let mut buf = ryu::Buffer::new();
        for v in values {
            self.line.push(',');
            // Ryū prints non-finite values as NaN/inf/-inf, which parse back as well.
            self.line.push_str(buf.format(*v));
        }
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())
    }
    /// Write `k`, then whole-number values.
    pub fn row_u64(&mut self, k: u64, values: &[u64]) -> std::io::Result<()> {
        use std::fmt::Write as _;
        self.line.clear();
        let _ = write!(self.line, "{k}");
        for v in values {
            let _ = write!(self.line, ",{v}");
        }
        self.line.push('\n');
        self.out.write_all(self.line.as_bytes())
    }
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// A values type a row file holds: f64 (telemetry) or u64 (timing, ns). CSV writes each in its
/// shortest exact text; Parquet stores it as it is.
pub trait RowValue: crate::parquet_out::Value {
    fn csv_row(w: &mut CsvWriter, k: u64, values: &[Self]) -> std::io::Result<()>;
}
impl RowValue for f64 {
    fn csv_row(w: &mut CsvWriter, k: u64, values: &[f64]) -> std::io::Result<()> {
        w.row(k, values)
    }
}
impl RowValue for u64 {
    fn csv_row(w: &mut CsvWriter, k: u64, values: &[u64]) -> std::io::Result<()> {
        w.row_u64(k, values)
    }
}

/// A process's row file in the run's format (`run.telemetry`): rows of step `k` and values, the
/// same columns and numbers either way.
pub enum RowWriter<V: RowValue> {
    Csv(CsvWriter),
    Parquet(crate::parquet_out::ParquetWriter<V>),
}

/// Telemetry: f64 values.
pub type TelemetryWriter = RowWriter<f64>;
/// Wall-clock timing (`timing/<proc>.parquet`, or `.csv` with `run.telemetry = "csv"`): whole
/// numbers (nanoseconds), written by the telemetry's writers (so Parquet's units are in the
/// schema, as for telemetry).
pub type TimingWriter = RowWriter<u64>;

impl<V: RowValue> RowWriter<V> {
    /// A new file with these columns (`k` first).
    pub fn create(format: TelemetryFormat, path: &Path, columns: &[String]) -> std::io::Result<Self> {
        Ok(match format {
            TelemetryFormat::Csv => Self::Csv(CsvWriter::create(path, columns)?),
            TelemetryFormat::Parquet => Self::Parquet(crate::parquet_out::ParquetWriter::create(path, columns)?),
        })
    }
    /// Go on with an existing file (a relaunched agent continues its predecessor's rows).
    pub fn append(format: TelemetryFormat, path: &Path, columns: &[String]) -> std::io::Result<Self> {
        Ok(match format {
            TelemetryFormat::Csv => Self::Csv(CsvWriter::append(path, columns.len())?),
            TelemetryFormat::Parquet => Self::Parquet(crate::parquet_out::ParquetWriter::append(path, columns)?),
        })
    }
    /// Step `k`, then the values (one per column after `k`).
    pub fn row(&mut self, k: u64, values: &[V]) -> std::io::Result<()> {
        match self {
            Self::Csv(w) => V::csv_row(w, k, values),
            Self::Parquet(w) => w.row(k, values),
        }
    }
    /// Every row written so far on disk, readable (before a process fault that may end the
    /// process); the file stays open for more rows.
    pub fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Self::Csv(w) => w.flush(),
            Self::Parquet(w) => w.flush(),
        }
    }
    /// The end of the process's rows: every row on disk in the complete file (also after an
    /// error).
    pub fn finish(&mut self) -> std::io::Result<()> {
        match self {
            Self::Csv(w) => w.flush(),
            Self::Parquet(w) => w.finish(),
        }
    }
}

/// The timing file of process `name` in `timing`, in whichever format the run wrote it.
pub fn timing_file(timing: &Path, name: &str) -> PathBuf {
    let parquet = timing.join(format!("{name}.parquet"));
    if parquet.is_file() { parquet } else { timing.join(format!("{name}.csv")) }
}

/// One column of process `name`'s timing file (Parquet or CSV), or nothing when the file or the
/// column is missing or damaged: timing is diagnostic, never a reason to lose a summary.
pub fn timing_column(timing: &Path, name: &str, column: &str) -> Vec<u64> {
    let path = timing_file(timing, name);
    if path.extension().is_some_and(|e| e == "parquet") {
        return crate::parquet_out::read_u64_column(&path, column).unwrap_or_default();
    }
    let Ok(text) = std::fs::read_to_string(&path) else { return Vec::new() };
    let mut lines = text.lines();
    let Some(idx) = lines.next().and_then(|h| h.split(',').position(|c| c == column)) else { return Vec::new() };
    lines.filter_map(|l| l.split(',').nth(idx)?.parse().ok()).collect()
}

/// Rejected-message counters as a name → count map for JSON.
pub fn reject_map(c: &RejectCounts) -> std::collections::BTreeMap<String, u64> {
    Rejection::ALL.iter().map(|r| (r.name().to_string(), c.get(*r))).collect()
}

/// One entry of the run's fault timeline (`timeline.json`, folded into `summary.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TimelineEvent {
    /// Wall time since the launch, s.
    pub wall_s: f64,
    /// The step it applies to (the plant's step when it was seen).
    pub step: u64,
    pub t_s: f64,
    pub agent: u32,
    /// kill, freeze, thaw, relaunch (process faults carried out); dead, alive (roster changes by
    /// the plant); died (a process ended outside the plan); restore-failed.
    pub event: String,
    pub detail: String,
}

/// Why a process ended before its last step, by kind: the exit code and the orchestrator's
/// diagnosis go by the kind, never by the wording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ErrorKind {
    /// Stopped on request (a stop message, SIGTERM, or another process's failure).
    Stopped,
    /// A peer stayed silent past the step timeout.
    Timeout,
    /// The messaging failed.
    Transport,
    /// Writing telemetry, timing or a checkpoint failed.
    Io,
    /// The model produced a non-finite number.
    Diverged,
    /// A relaunched agent could not restore its checkpoint.
    Checkpoint,
    /// The model's own code failed (a Python exception or a wrong return value).
    Model,
}

/// A process's error: its kind and the message, which names who, what and the step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProcessError {
    pub kind: ErrorKind,
    pub message: String,
    /// Simulated time of the failure, s, when it belongs to a step (a divergence).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_s: Option<f64>,
}

impl ProcessError {
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self { kind, message: message.into(), t_s: None }
    }
    /// The same error, at simulated time `t_s`.
    pub fn at(self, t_s: f64) -> Self {
        Self { t_s: Some(t_s), ..self }
    }
    pub fn is_stop(&self) -> bool {
        self.kind == ErrorKind::Stopped
    }
}

impl std::fmt::Display for ProcessError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// Written by every process at exit (success or failure) to `status/<proc>.json`; the
/// orchestrator folds them into `summary.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ProcessReport {
    pub process: String,
    pub pid: u32,
    pub steps_completed: u64,
    pub wall_s: f64,
    pub messages_received: u64,
    pub messages_rejected: std::collections::BTreeMap<String, u64>,
    pub timeouts: u64,
    /// Wall time from process start to its first step (start-up cost).
    pub startup_s: f64,
    /// CPU time (user + system) of this process (of this thread, in the reference run), s.
    #[serde(default)]
    pub cpu_s: f64,
    /// Peak resident set size of the process, kB (the whole process in the reference run).
    #[serde(default)]
    pub max_rss_kb: u64,
    /// Proportional set size at the end of the process's run, kB: its private pages plus its
    /// share of every page it maps with others (iceoryx2's segments, the binary's text), so the
    /// run's processes' values add up to the memory they use together (0 where
    /// `/proc/self/smaps_rollup` cannot be read; the whole process in the reference run).
    #[serde(default)]
    pub pss_kb: u64,
    /// Headline metrics (plant only). JSON has no NaN: a non-finite metric is written as `null`
    /// and read back as NaN, so a diverged run's report still loads.
    #[serde(deserialize_with = "metrics_with_nulls")]
    pub metrics: std::collections::BTreeMap<String, f64>,
    /// Why the process ended early, if it did.
    pub error: Option<ProcessError>,
    /// Faults injected by and seen by this process.
    #[serde(default)]
    pub faults: FaultReport,
    /// Messages this process published (shares, or measurements).
    #[serde(default)]
    pub messages_sent: u64,
    /// Per sender (`plant`, `agent-j`): every message received from it, valid or not.
    #[serde(default)]
    pub received_from: std::collections::BTreeMap<String, u64>,
    /// Per sender: wall latency (send → receipt) of its valid messages, ns, as histogram buckets.
    /// Not in `status/<proc>.json`: [`ProcessReport::write`] writes them once, to the process's
    /// latency log `timing/<proc>.hlog` ([`LATENCY_LOG`]).
    #[serde(skip)]
    pub latency_from_ns: std::collections::BTreeMap<String, LatencyBuckets>,
    /// Agents whose algorithm solves an optimisation problem every step: solver counts and solve
    /// times (see [`crate::model::Algorithm::solver_stats`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<crate::solver_stats::SolverStats>,
    /// How this process's waits for messages went (spinning against blocking): what adaptive
    /// waiting decided and what it cost.
    #[serde(default)]
    pub wait: WaitStats,
    /// The plant's, under `[links]` model `geometric`: what every directed link did.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub links: Vec<crate::links::LinkRow>,
}

/// A process's waits for its messages (measurements or shares), counted by the step loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct WaitStats {
    /// Waits that found their messages incomplete at first and so waited.
    pub waits: u64,
    /// Of those, waits that spun (drained and yielded the CPU) before blocking.
    pub spun: u64,
    /// Spinning waits cut short because a yield came back only after another program had held
    /// the core for a scheduler slice (the machine is contended).
    pub spin_stalls: u64,
    /// Spinning waits whose spin budget ran out before the messages came (they then blocked).
    pub spin_expired: u64,
    /// Wall time spent spinning, s.
    pub spin_s: f64,
    /// Adaptive waiting: the trials (every 8 192 steps) that chose spinning, and blocking.
    pub chose_spin: u64,
    pub chose_block: u64,
    /// Adaptive waiting: waits that went as the plant's trial chose rather than as this
    /// process's own (every process's but the plant's, between trials, once the plant's choice
    /// reached it: on its host through the doorbell file, on another through the gateways).
    pub advised: u64,
    /// Adaptive waiting's last trial: the median step of its blocking half and of its spinning
    /// half (none where spinning was given up before its median could win), µs: what the choice
    /// was made on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trial_block_step_us: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trial_spin_step_us: Option<f64>,
}

impl WaitStats {
    /// One wait that did not find its messages at once: whether it `spun`, whether one of its
    /// yields `stalled`, whether it blocked after spinning (`blocked_after_spin`), and how long it
    /// spun.
    pub fn count(&mut self, spun: bool, stalled: bool, blocked_after_spin: bool, spin: std::time::Duration) {
        self.waits += 1;
        if spun {
            self.spun += 1;
            self.spin_stalls += u64::from(stalled);
            self.spin_expired += u64::from(blocked_after_spin && !stalled);
            self.spin_s += spin.as_secs_f64();
        }
    }
}

impl ProcessReport {
    /// The report of this process (its pid) before it has done anything: every count zero, no
    /// error. Drivers and coupled runs fill in what they did.
    pub fn new(process: String) -> Self {
        Self {
            process,
            pid: std::process::id(),
            steps_completed: 0,
            wall_s: 0.0,
            messages_received: 0,
            messages_rejected: Default::default(),
            timeouts: 0,
            startup_s: 0.0,
            cpu_s: 0.0,
            max_rss_kb: 0,
            pss_kb: 0,
            metrics: Default::default(),
            error: None,
            faults: Default::default(),
            messages_sent: 0,
            received_from: Default::default(),
            latency_from_ns: Default::default(),
            solver: None,
            wait: WaitStats::default(),
            links: Vec::new(),
        }
    }

    /// The report of a process that failed before its first step.
    pub fn failed_at_start(process: String, error: ProcessError) -> Self {
        Self { error: Some(error), ..Self::new(process) }
    }
}

fn metrics_with_nulls<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<std::collections::BTreeMap<String, f64>, D::Error> {
    let m: std::collections::BTreeMap<String, Option<f64>> = serde::Deserialize::deserialize(d)?;
    Ok(m.into_iter().map(|(k, v)| (k, v.unwrap_or(f64::NAN))).collect())
}

/// A latency histogram (HdrHistogram, 2 significant figures: every value within 1 %, 100 ns to
/// 60 s) kept by a receiver per sender. Counts are u32 (saturating at 4.29 · 10⁹ messages a
/// bucket). Its 3 072 buckets take 12 kB a link: a plant keeps one per agent, each agent one per
/// neighbour and the plant's. With 3 significant figures they took 86 kB a link (21 504 buckets,
/// ≈ 56 kB of them touched by a link's spread of latencies), and each record was a cache miss
/// into them: a tenth of a 1 000-agent plant's time (`perf`), 56 MB of its memory. The log's
/// encoding (V2, variable-length counts) does not change.
pub struct LatencyHist(hdrhistogram::Histogram<u32>);

/// Significant figures of a [`LatencyHist`].
const LATENCY_SIGFIG: u8 = 2;

impl Default for LatencyHist {
    fn default() -> Self {
        Self(hdrhistogram::Histogram::new_with_bounds(100, 60_000_000_000, LATENCY_SIGFIG).expect("valid bounds"))
    }
}

impl LatencyHist {
    pub fn record(&mut self, ns: u64) {
        self.0.saturating_record(ns.max(100));
    }
    /// The histogram itself (to encode it).
    pub fn histogram(&self) -> &hdrhistogram::Histogram<u32> {
        &self.0
    }
    pub fn buckets(&self) -> LatencyBuckets {
        LatencyBuckets(self.0.iter_recorded().map(|v| (v.value_iterated_to(), u64::from(v.count_at_value()))).collect())
    }
    /// Rebuild from buckets (to merge the runs of a soak).
    pub fn from_buckets(b: &LatencyBuckets) -> Self {
        let mut h = Self::default();
        for &(v, n) in &b.0 {
            h.0.saturating_record_n(v, u32::try_from(n).unwrap_or(u32::MAX));
        }
        h
    }
    pub fn add(&mut self, other: &LatencyHist) {
        let _ = self.0.add(&other.0);
    }
    pub fn len(&self) -> u64 {
        self.0.len()
    }
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
    pub fn quantile(&self, q: f64) -> u64 {
        self.0.value_at_quantile(q)
    }
    pub fn max(&self) -> u64 {
        self.0.max()
    }
}

/// A histogram's recorded buckets: (value, count), ascending.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct LatencyBuckets(pub Vec<(u64, u64)>);

/// A process's message-latency histograms, `timing/<proc>.hlog` (relative to the run directory,
/// `<proc>` the receiving process): an HdrHistogram interval log (the format of HdrHistogram's
/// `HistogramLogWriter`, read by its `HistogramLogReader` in Java, Python (`hdrh`), Go, Rust …),
/// one interval per sender, tagged with the sender's name (`Tag=agent-2,…`), each histogram in
/// the compressed V2 encoding (2 significant figures, 100 ns to 60 s, as recorded). Compact: a
/// whole (360 s) fig1 run's 24 links took 79 kB at 3 significant figures, against 2.2 MB as one
/// CSV row per bucket, the form the histograms had before. Read a run's back with [`read_latency_histograms`].
pub const LATENCY_LOG: &str = "timing/<proc>.hlog";

/// The latency log of process `name` in `timing` (see [`LATENCY_LOG`]).
pub fn latency_log_path(timing: &Path, name: &str) -> PathBuf {
    timing.join(format!("{name}.hlog"))
}

/// Write `from` (sender → buckets) as the latency log at `path`; the intervals span the
/// process's steps (`wall_s`).
pub fn write_latency_log(
    path: &Path,
    receiver: &str,
    from: &std::collections::BTreeMap<String, LatencyBuckets>,
    wall_s: f64,
) -> std::io::Result<()> {
    use hdrhistogram::serialization::V2DeflateSerializer;
    use hdrhistogram::serialization::interval_log::{IntervalLogWriterBuilder, Tag};
    let mut bytes = Vec::new();
    let mut serializer = V2DeflateSerializer::new();
    let mut log = IntervalLogWriterBuilder::new()
        .add_comment(&format!(
            "Cohort: message latency (send → receipt) in ns of the valid messages {receiver} received, one histogram per sender (its tag)"
        ))
        .begin_log_with(&mut bytes, &mut serializer)?;
    let span = std::time::Duration::from_secs_f64(wall_s.max(0.0));
    for (sender, b) in from {
        let tag = Tag::new(sender)
            .ok_or_else(|| std::io::Error::other(format!("{sender:?} cannot be an interval log tag")))?;
        let h = LatencyHist::from_buckets(b);
        log.write_histogram(h.histogram(), std::time::Duration::ZERO, span, Some(tag))
            .map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
    }
    drop(log);
    write_atomic(path, &bytes)
}

/// Read one latency log: sender → buckets. Err names the file and what is wrong with it.
pub fn read_latency_log(path: &Path) -> Result<std::collections::BTreeMap<String, LatencyBuckets>, String> {
    use base64::Engine as _;
    use hdrhistogram::serialization::Deserializer;
    use hdrhistogram::serialization::interval_log::{IntervalLogIterator, LogEntry};
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = std::collections::BTreeMap::new();
    for entry in IntervalLogIterator::new(&bytes) {
        let bad = |why: String| format!("{}: not a latency log: {why}", path.display());
        let LogEntry::Interval(h) = entry.map_err(|e| bad(format!("{e:?}")))? else { continue };
        let sender = h.tag().map(|t| t.as_str().to_string()).ok_or_else(|| bad("an interval without a tag".into()))?;
        let encoded = base64::engine::general_purpose::STANDARD
            .decode(h.encoded_histogram())
            .map_err(|e| bad(format!("{sender}: {e}")))?;
        let hist: hdrhistogram::Histogram<u64> = Deserializer::new()
            .deserialize(&mut std::io::Cursor::new(encoded))
            .map_err(|e| bad(format!("{sender}: {e}")))?;
        let b = LatencyBuckets(hist.iter_recorded().map(|v| (v.value_iterated_to(), v.count_at_value())).collect());
        out.insert(sender, b);
    }
    Ok(out)
}

/// Every link's latency histogram of the run in `root`, from the latency logs of its processes
/// (`plant`, `agent-<i>`, any other `timing/*.hlog`): (sender, receiver) → buckets. Rebuild a
/// link's histogram with [`LatencyHist::from_buckets`].
pub fn read_latency_histograms(
    root: &Path,
) -> Result<std::collections::BTreeMap<(String, String), LatencyBuckets>, String> {
    let timing = root.join("timing");
    let mut logs: Vec<PathBuf> = std::fs::read_dir(&timing)
        .map_err(|e| format!("{}: {e}", timing.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "hlog"))
        .collect();
    logs.sort();
    let mut out = std::collections::BTreeMap::new();
    for log in logs {
        let receiver = log.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        for (sender, b) in read_latency_log(&log)? {
            out.insert((sender, receiver.clone()), b);
        }
    }
    Ok(out)
}

/// What a process injected (as a sender) and saw (as a receiver) of the fault plan, and the
/// roster changes the plant made. Every lost share is counted here or in `messages_rejected`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct FaultReport {
    /// Sender: shares withheld by a `drop` fault.
    pub shares_dropped: u64,
    /// Sender: shares published garbled by a `corrupt` fault, per garbling.
    pub shares_corrupted: std::collections::BTreeMap<String, u64>,
    /// Sender: shares published late by a `delay` fault.
    pub shares_delayed: u64,
    /// Receiver: per peer (`agent-j`), steps at which its last valid share stood in for one that
    /// did not arrive (dropped, corrupted, delayed, or a missed real-time deadline).
    pub held: std::collections::BTreeMap<String, u64>,
    /// Receiver: the oldest share used, in steps behind the step it was used at.
    pub max_age_steps: u64,
    /// Receiver, `[links]` model `geometric`: shares that arrived but that their link did not
    /// deliver (out of range, blocked, lost in transit, or not sent while the link was busy).
    #[serde(default)]
    pub link_undelivered: u64,
    /// Receiver: valid shares that came after their step had closed (real-time mode).
    pub late: u64,
    /// Receiver, per sender: steps missing from its messages — lost in this reader's full queue
    /// (iceoryx2 keeps the newest when a slow reader falls behind, e.g. in real time), or never
    /// sent because the sender itself fell behind and skipped them (its `steps_missed`).
    pub overrun: std::collections::BTreeMap<String, u64>,
    /// Plant, real-time mode: commands that missed their step's deadline.
    pub deadline_misses: u64,
    /// Agent: steps it was not on the roster for (frozen, or between kill and relaunch); it
    /// propagated its state through them on its return.
    pub steps_missed: u64,
    /// Agent: checkpoints written.
    pub checkpoints_written: u64,
    /// Agent: the checkpoint step this process resumed from (a relaunched agent).
    pub restored_from_step: Option<u64>,
    /// Plant: every roster change.
    pub roster: Vec<RosterChange>,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RosterChange {
    /// The first step the change applies to.
    pub step: u64,
    pub agent: u32,
    pub live: bool,
    /// "silent" (step timeout), "died" (the orchestrator saw the process end), "fault" (the plan).
    pub reason: String,
    /// Wall time of the decision, s since the plant's start barrier.
    pub wall_s: f64,
}

impl ProcessReport {
    /// `status/<proc>.json`, and the latency histograms (if any) once, in `timing/<proc>.hlog`.
    pub fn write(&self, dirs: &RunDirs) -> std::io::Result<()> {
        let path = dirs.status().join(format!("{}.json", self.process));
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        // The report first: the orchestrator needs it more than the histograms.
        let status = write_atomic(&path, text.as_bytes());
        let latency = if self.latency_from_ns.is_empty() {
            Ok(())
        } else {
            let path = latency_log_path(&dirs.timing(), &self.process);
            write_latency_log(&path, &self.process, &self.latency_from_ns, self.wall_s)
        };
        status.and(latency)
    }
}

/// Write a file whole or not at all: into a temporary name beside it, then renamed over it; on
/// any error (a full disk) the temporary file is removed, so no empty or half-written file is
/// left where a reader expects a complete one. The temporary name is the writer's own (pid and a
/// counter), created exclusively: two writers of one path never write into each other's file.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = path.with_file_name(format!(".{name}.{}-{n}.tmp", std::process::id()));
    let written = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_data()?;
        std::fs::rename(&tmp, path)
    })();
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// (CPU seconds of the calling thread (`RUSAGE_THREAD`), peak RSS of its process in kB).
///
/// The peak comes from `VmHWM` in /proc/self/status, not from `ru_maxrss`: Linux carries
/// `ru_maxrss` across fork and exec, so every child would report at least its parent's peak (the
/// orchestrator's, after it has read a large run's telemetry).
pub fn cpu_and_rss() -> (f64, u64) {
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage fills the struct we own.
    unsafe { libc::getrusage(libc::RUSAGE_THREAD, &mut ru) };
    let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let hwm_kb = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse::<u64>().ok()))
        })
        .unwrap_or(0);
    (secs(ru.ru_utime) + secs(ru.ru_stime), hwm_kb)
}

/// The calling process's proportional set size now, kB (`Pss:` of `/proc/self/smaps_rollup`; 0
/// where it cannot be read).
pub fn pss_kb() -> u64 {
    std::fs::read_to_string("/proc/self/smaps_rollup")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Pss:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse::<u64>().ok()))
        })
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pss_is_read_and_at_most_the_peak_rss() {
        let pss = pss_kb();
        let (_, hwm) = cpu_and_rss();
        assert!(pss > 0, "no Pss in /proc/self/smaps_rollup");
        assert!(pss <= hwm, "PSS {pss} kB above the peak RSS {hwm} kB");
    }

    #[test]
    fn a_runs_scenario_is_written_with_its_digest_unless_its_text_does_not_parse_or_it_cannot_be() {
        let dirs = RunDirs::new(std::env::temp_dir().join(format!("cohort-digest-w-{}", std::process::id())));
        std::fs::create_dir_all(&dirs.root).unwrap();
        let digest = cohort_scenario::digest::path_for(&dirs.scenario());
        let text = "[scenario]\nname = \"x\"\n";
        dirs.write_scenario(text).unwrap();
        assert_eq!(std::fs::read_to_string(dirs.scenario()).unwrap(), text);
        let table = cohort_scenario::digest::read(&digest, &dirs.scenario(), text).unwrap();
        assert_eq!(table, text.parse::<toml::Table>().unwrap());
        // The digest of the text before must not outlive it.
        dirs.write_scenario("[scenario\n").unwrap();
        assert!(!digest.exists(), "a digest of a text that does not parse, or of the one before");
        // A digest that cannot be written (here a directory in its place) leaves the text alone.
        std::fs::create_dir(&digest).unwrap();
        dirs.write_scenario(text).unwrap();
        assert_eq!(std::fs::read_to_string(dirs.scenario()).unwrap(), text);
        assert!(digest.is_dir());
        std::fs::remove_dir_all(&dirs.root).unwrap();
    }

    #[test]
    fn latency_histograms_round_trip_through_their_log() {
        let dir = std::env::temp_dir().join(format!("cohort-hgrm-{}", std::process::id()));
        let dirs = RunDirs::new(&dir);
        dirs.create_all().unwrap();
        let mut h = LatencyHist::default();
        for ns in [150, 2_000, 2_001, 45_000, 45_000, 9_000_000, 59_000_000_000] {
            h.record(ns);
        }
        let mut report = ProcessReport::failed_at_start("agent-1".into(), ProcessError::new(ErrorKind::Stopped, "x"));
        report.latency_from_ns.insert("agent-2".to_string(), h.buckets());
        report.latency_from_ns.insert("plant".to_string(), LatencyHist::default().buckets());
        report.write(&dirs).unwrap();
        // status/ has no histogram; the log has both senders' (the empty one too).
        let status = std::fs::read_to_string(dirs.status().join("agent-1.json")).unwrap();
        assert!(!status.contains("latency_from_ns"), "{status}");
        let back = read_latency_histograms(&dir).unwrap();
        let keys: Vec<_> = back.keys().cloned().collect();
        let link = |s: &str| (s.to_string(), "agent-1".to_string());
        assert_eq!(keys, vec![link("agent-2"), link("plant")]);
        assert_eq!(back[&link("agent-2")], h.buckets());
        assert!(back[&link("plant")].0.is_empty());
        let again = LatencyHist::from_buckets(&back[&link("agent-2")]);
        assert_eq!((again.len(), again.quantile(0.5), again.max()), (h.len(), h.quantile(0.5), h.max()));
        std::fs::write(latency_log_path(&dirs.timing(), "plant"), "Tag=agent-1,0.000,1.000,1.0,@@@\n").unwrap();
        let e = read_latency_histograms(&dir).unwrap_err();
        assert!(e.contains("plant.hlog") && e.contains("agent-1"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn csv_numbers_round_trip_bit_for_bit() {
        let dir = std::env::temp_dir().join(format!("cohort-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        let tricky = [
            0.1 + 0.2,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324, // smallest subnormal
            f64::MAX,
            -1.0 / 3.0,
            6.500_396_690_704_936e-9,
            42164e3,
            1e-7,
            123_456_789.123_456_78,
        ];
        let cols: Vec<String> =
            std::iter::once("k".to_string()).chain((0..tricky.len()).map(|i| format!("c{i}"))).collect();
        let mut w = CsvWriter::create(&path, &cols).unwrap();
        w.row(7, &tricky).unwrap();
        w.flush().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let row = text.lines().nth(1).unwrap();
        let back: Vec<f64> = row.split(',').skip(1).map(|v| v.parse().unwrap()).collect();
        for (a, b) in tricky.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits(), "{a:?} came back as {b:?}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
