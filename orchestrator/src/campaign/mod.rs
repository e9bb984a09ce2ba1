//! `orchestrator campaign FILE --cases N`: a Monte Carlo campaign over the scenario's
//! `[[dispersions]]` (or `--dispersions FILE`'s), see docs/monte-carlo.md.
//!
//! Every case is drawn and validated first (a bad draw is exit 2 before anything runs), then the
//! cases run on `--workers` threads of the campaign kit (`cohort_host::campaign`) — in-process
//! reference runs by default (bit-identical to process runs, and the fast path), or process runs
//! with `--multi-process`. Each finished case leaves `cases/case-NNNNNN/row.json`; the same
//! command with the same `--out` continues an interrupted campaign from those rows (and a larger
//! `--cases` extends a finished one). At the end: `campaign.parquet` (a row per case),
//! `campaign.md` and `plots/`.

pub(crate) mod fly;
mod plan;
mod remote;
mod report;
pub(crate) mod row;
pub mod serve;
mod table;
mod until;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::Args;
use cohort_host::CommandError;
use cohort_host::campaign::{Campaign, CampaignError};
use cohort_supervisor::supervise::SIGNALLED;
use tracing::{error, info, warn};

use plan::{Plan, PlanArgs};
use row::CaseRow;
pub use until::Until;

#[derive(Args)]
pub struct CampaignArgs {
    /// Cases to run (1 to 1 000 000); with --until, the most to run.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    cases: u64,
    /// Cases run at once (default: the machine's cores). The table does not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1024))]
    workers: Option<u64>,
    /// Run every case as processes (plant and agents over iceoryx2) instead of in-process; the
    /// rows are the same.
    #[arg(long)]
    multi_process: bool,
    /// Stop once the 95 % interval of METRIC's mean is within ±X (judged on the cases in index
    /// order, from --min-cases on), e.g. `servicer_1.e_norm_last10s_mean_m:±0.05`.
    #[arg(long, value_name = "METRIC:±X")]
    until: Option<Until>,
    /// The fewest cases --until may stop at.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(2..))]
    min_cases: u64,
    /// The metric the progress, the plots and the report's estimate follow (default: --until's,
    /// else the first verdict line's `ours`).
    #[arg(long)]
    metric: Option<String>,
    /// A file of [[dispersions]] that replaces the scenario's own.
    #[arg(long, value_name = "FILE")]
    dispersions: Option<PathBuf>,
    /// The campaign seed: the draws' streams, and case i's scenario seed (seed + i). Default:
    /// the scenario's seed.
    #[arg(long, value_parser = crate::seed_arg)]
    seed: Option<u64>,
    /// Every case keeps the campaign seed (only the dispersions vary).
    #[arg(long)]
    fixed_seed: bool,
    /// Override scenario.duration_s, in seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// The campaign's directory; default runs/<scenario>-campaign-<UTC time>/. An existing one of
    /// the same campaign is continued.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Keep each case's telemetry (by default only its summary and row stay).
    #[arg(long)]
    keep_telemetry: bool,
    /// Send the cases to the host daemons of this file (`[[hosts]]` with name and endpoint;
    /// `orchestrator host` on each machine, whose --workers says how many cases it runs at once).
    /// The rows are the one-machine campaign's; a host lost mid-campaign leaves its cases to the
    /// others.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["multi_process", "workers", "keep_telemetry"])]
    hosts: Option<PathBuf>,
    /// No plots.
    #[arg(long)]
    no_plots: bool,
    /// The links to the hosts' daemons: as `launch --hosts` (docs/multihost.md, "Security").
    #[command(flatten)]
    security: crate::security_args::SecurityArgs,
}

/// Why a case did not give a row.
#[derive(Debug, thiserror::Error)]
pub(crate) enum CaseError {
    #[error("interrupted")]
    Interrupted,
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    Io(String),
}

pub fn command(file: &Path, a: &CampaignArgs) -> ExitCode {
    let plan = match Plan::new(&PlanArgs {
        file,
        dispersions_file: a.dispersions.as_deref(),
        seed: a.seed,
        fixed_seed: a.fixed_seed,
        duration_s: a.duration,
    }) {
        Ok(p) => p,
        Err(e) => return crate::fail(e),
    };
    if !a.fixed_seed && plan.seed.checked_add(a.cases - 1).is_none_or(|s| s > cohort_scenario::validate::MAX_SEED) {
        return crate::fail(CommandError::invalid(format!(
            "--seed {} --cases {}: the last case's seed passes 2^63 − 1 (or use --fixed-seed)",
            plan.seed, a.cases
        )));
    }
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let workers = a.workers.map_or(cores, |w| w as usize);
    // Every case drawn and validated before one runs (an in-process case with a process fault
    // included: a dispersion may draw one).
    let check = |i: usize| {
        let (_, s) = plan.case(i as u64)?;
        let remedy = if a.hosts.is_some() { "cases on hosts run in-process" } else { "add --multi-process" };
        if let Some(why) = crate::reference_refusal(&s, remedy).filter(|_| !a.multi_process) {
            return Err(format!("{}: case {i}: {why}", file.display()));
        }
        // Paced by the wall clock, a case's deadlines (and so its rows) would depend on the load.
        if let Some(rate) = s.run.realtime_rate {
            return Err(format!(
                "{}: case {i}: run.realtime_rate = {rate}: a campaign's cases run as fast as they can \
                 (paced, their deadline misses would depend on the machine's load); remove it",
                file.display()
            ));
        }
        Ok(())
    };
    if let Err(e) = Campaign::new(a.cases as usize).workers(workers).run(check) {
        return crate::fail(CommandError::invalid(e.source));
    }
    match plan.dispersions.items.len() {
        0 => info!("{} cases, differing by their seeds only (no [[dispersions]]), every one valid", a.cases),
        n => info!("{} cases drawn from {n} dispersion(s), every one valid", a.cases),
    }
    let hosts = match a.hosts.as_deref().map(|f| remote::Hosts::open(f, &plan, &a.security)).transpose() {
        Ok(h) => h,
        Err(e) => return crate::fail(e),
    };
    let workers = hosts.as_ref().map_or(workers, |h| h.farm.slots());
    let root = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("runs/{}-campaign-{}", plan.name, cohort_host::utc_stamp())));
    if let Err(e) = manifest(&root, &plan, a) {
        return crate::fail(e);
    }
    let mut done = Vec::with_capacity(a.cases as usize);
    for i in 0..a.cases {
        match row::load(&root, i, plan.dispersions.columns().len()) {
            Ok(r) => done.push(r),
            Err(e) => return crate::fail(CommandError::invalid(e)),
        }
    }
    let resumed = done.iter().flatten().count();
    let mode = match &hosts {
        Some(h) => format!("reference, on the hosts {}", h.farm.describe()),
        None if a.multi_process => "multi-process".into(),
        None => "reference".into(),
    };
    info!(
        "campaign of {} → {} ({} cases, {mode}, {workers} worker(s){})",
        file.display(),
        root.display(),
        a.cases,
        if resumed > 0 { format!(", {resumed} done before") } else { String::new() }
    );
    run(&Job { plan: &plan, a, root: &root, hosts: hosts.as_ref() }, workers, done, &mode)
}

/// `campaign.json`: what the campaign is; a directory holding another campaign is refused.
fn manifest(root: &Path, plan: &Plan, a: &CampaignArgs) -> Result<(), CommandError> {
    let m = serde_json::json!({
        "scenario_text": plan.text,
        "dispersions": plan.spec_text,
        "seed": plan.seed,
        "fixed_seed": plan.fixed_seed,
        "duration_s": a.duration,
    });
    let path = root.join("campaign.json");
    let bad = |why: String| CommandError::invalid(format!("{}: {why}", root.display()));
    match std::fs::read(&path) {
        Ok(bytes) => {
            let old: serde_json::Value =
                serde_json::from_slice(&bytes).map_err(|e| bad(format!("campaign.json: {e}")))?;
            let differs: Vec<&str> = ["scenario_text", "dispersions", "seed", "fixed_seed", "duration_s"]
                .into_iter()
                .filter(|k| old.get(*k) != m.get(*k))
                .collect();
            if !differs.is_empty() {
                let what = differs.join(", ").replace("scenario_text", "the scenario file");
                return Err(bad(format!("holds another campaign ({what} differ); choose another --out")));
            }
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if std::fs::read_dir(root).is_ok_and(|mut d| d.next().is_some()) {
                return Err(bad("exists and is not a campaign's directory; choose another --out".into()));
            }
            std::fs::create_dir_all(root).map_err(|e| bad(e.to_string()))?;
            let text = serde_json::to_vec_pretty(&m).map_err(|e| bad(e.to_string()))?;
            cohort_runtime::record::write_atomic(&path, &text).map_err(|e| bad(e.to_string()))
        }
        Err(e) => Err(bad(format!("campaign.json: {e}"))),
    }
}

/// How a case flies: as processes with `--multi-process`; else in-process with every driver on
/// the worker's own thread, so W workers use W cores (Python kinds excepted, see `How`).
fn how(s: &cohort_runtime::paper::Setup, a: &CampaignArgs) -> crate::launcher::How {
    if a.multi_process { crate::launcher::How::Processes } else { crate::launcher::How::in_process(s, true) }
}

/// Case `i` run to its row (kept on disk before it is returned): here, or on a host of `farm`.
fn run_case(job: &Job, i: u64) -> Result<CaseRow, CaseError> {
    let (plan, a, root) = (job.plan, job.a, job.root);
    let (values, outcome, host) = match job.hosts {
        None => {
            let (values, setup) = plan.case(i).map_err(CaseError::Invalid)?;
            (values, fly::fly(&setup, &row::case_dir(root, i), how(&setup, a), a.keep_telemetry)?, None)
        }
        Some(hosts) => {
            let (values, outcome, host) = remote::run_case(hosts, plan, i, &row::case_dir(root, i))?;
            (values, outcome, Some(host))
        }
    };
    let r = CaseRow::new(i, plan.case_seed(i), &values, outcome, host);
    row::save(root, &r).map_err(|e| CaseError::Io(format!("{}: {e}", row::case_dir(root, i).display())))?;
    if r.outcome.status != "ok" {
        warn!(
            "case {i}: {}{}",
            r.outcome.status,
            r.outcome.error.as_deref().map(|e| format!(": {e}")).unwrap_or_default()
        );
    }
    Ok(r)
}

/// The metric a campaign follows: `--metric`, `--until`'s, else the first verdict line's `ours`
/// (known once a case has finished).
fn chosen_metric(a: &CampaignArgs, first: Option<&CaseRow>) -> Option<String> {
    a.metric.clone().or_else(|| a.until.as_ref().map(|u| u.metric.clone())).or_else(|| {
        first.and_then(|r| r.outcome.verdict.iter().find(|v| v.ours.is_some())).map(|v| format!("ours: {}", v.name))
    })
}

/// The names a metric may be, for an error naming a wrong one.
fn metric_choices(r: &CaseRow) -> String {
    let mut names: Vec<String> = r.outcome.metrics.keys().cloned().collect();
    names.extend(r.outcome.verdict.iter().filter(|v| v.ours.is_some()).map(|v| format!("ours: {}", v.name)));
    names.join(", ")
}

/// A chosen metric none of the first this many cases (by index, those that ran ok) produced is refused.
const METRIC_CHECK_CASES: usize = 5;

/// Run the cases not done yet, then write the table and the report.
/// What a campaign's cases are run from.
struct Job<'a> {
    plan: &'a Plan,
    a: &'a CampaignArgs,
    root: &'a Path,
    /// `--hosts`: the cases go there.
    hosts: Option<&'a remote::Hosts>,
}

fn run(job: &Job, workers: usize, done: Vec<Option<CaseRow>>, mode: &str) -> ExitCode {
    let (plan, a, root) = (job.plan, job.a, job.root);
    let n = done.len();
    let rows = Mutex::new(done);
    let bad_metric = AtomicBool::new(false);
    let until_met = || -> Option<usize> {
        let u = a.until.as_ref()?;
        let rows = rows.lock().expect("no case panics holding the rows");
        let values: Vec<Option<Option<f64>>> = rows.iter().map(|r| r.as_ref().map(|r| r.value(&u.metric))).collect();
        until::met_at(&values, a.min_cases as usize, u.half_width)
    };
    let progress = |finished: usize, total: usize| {
        let rows = rows.lock().expect("no case panics holding the rows");
        let first = rows.iter().flatten().next();
        let Some(metric) = chosen_metric(a, first) else {
            info!("[{finished}/{total}]");
            return;
        };
        // A metric some cases lack (a method without a QP) is fine; one that none of the first
        // cases by index that ran ok has is a wrong name. Judged once those cases have all
        // finished, whatever order they finished in, so the verdict does not depend on the workers.
        let head = &rows[..total.min(METRIC_CHECK_CASES)];
        let ok: Vec<&CaseRow> = head.iter().flatten().filter(|r| r.outcome.status == "ok").collect();
        let judged = head.iter().all(Option::is_some) && !ok.is_empty();
        if judged && ok.iter().all(|r| r.value(&metric).is_none()) && !bad_metric.swap(true, Ordering::SeqCst) {
            error!(
                "no metric {metric:?} in the runs' summaries; they have: {}",
                first.map(metric_choices).unwrap_or_default()
            );
        }
        let mut est = until::Running::default();
        rows.iter().flatten().filter_map(|r| r.value(&metric)).for_each(|x| est.push(x));
        info!("[{finished}/{total}] {metric}: {}", est.describe());
    };
    let stop = || SIGNALLED.load(Ordering::SeqCst) != 0 || bad_metric.load(Ordering::SeqCst) || until_met().is_some();
    let result = Campaign::new(n).workers(workers).progress(&progress).stop(&stop).run(|i| {
        if let Some(r) = rows.lock().expect("no case panics holding the rows")[i].clone() {
            return Ok(r);
        }
        let r = run_case(job, i as u64)?;
        rows.lock().expect("no case panics holding the rows")[i] = Some(r.clone());
        Ok::<_, CaseError>(r)
    });
    if bad_metric.load(Ordering::SeqCst) {
        return ExitCode::from(crate::EXIT_INVALID);
    }
    let signal = SIGNALLED.load(Ordering::SeqCst);
    let interrupted = |kept: usize| {
        warn!("interrupted with {kept} of {n} cases done; the same command with --out {} continues", root.display());
        ExitCode::from(128 + signal.clamp(1, 127) as u8)
    };
    let finished: Vec<Option<CaseRow>> = match result {
        Ok(all) => all.into_iter().map(Some).collect(),
        Err(CampaignError::Case(f)) if matches!(f.source, CaseError::Interrupted) => {
            return interrupted(rows.lock().map(|r| r.iter().flatten().count()).unwrap_or(0));
        }
        Err(CampaignError::Case(f)) => {
            return crate::fail(CommandError::failed(format!("case {}: {}", f.index, f.source)));
        }
        Err(CampaignError::Stopped { done, .. }) if signal != 0 => return interrupted(done),
        Err(CampaignError::Stopped { .. }) => rows.into_inner().unwrap_or_default(),
    };
    finish(plan, a, root, mode, finished)
}

/// The table's cases (all, or the first `n` at which `--until` was met) and why it stopped.
fn cut(a: &CampaignArgs, finished: Vec<Option<CaseRow>>) -> (Vec<CaseRow>, Option<String>) {
    let total = finished.len();
    let Some(u) = &a.until else { return (finished.into_iter().flatten().collect(), None) };
    let values: Vec<Option<Option<f64>>> = finished.iter().map(|r| r.as_ref().map(|r| r.value(&u.metric))).collect();
    let (take, why) = match until::met_at(&values, a.min_cases as usize, u.half_width) {
        Some(k) => (
            k,
            format!(
                "Stopped by `--until {}:±{}` at {k} cases: the 95 % interval of its mean is within ±{}.",
                u.metric, u.half_width, u.half_width
            ),
        ),
        None => (total, format!("`--until {}:±{}` was not met within {total} cases.", u.metric, u.half_width)),
    };
    (finished.into_iter().take(take).flatten().collect(), Some(why))
}

/// Write `campaign.parquet`, `plots/` and `campaign.md`.
fn finish(plan: &Plan, a: &CampaignArgs, root: &Path, mode: &str, finished: Vec<Option<CaseRow>>) -> ExitCode {
    let (rows, stopped) = cut(a, finished);
    let columns = plan.dispersions.columns();
    let metric = chosen_metric(a, rows.first());
    let plots = match (&metric, a.no_plots) {
        (Some(m), false) => report::plots(root, m, &columns, &rows),
        (None, false) => {
            let example = rows.first().and_then(|r| r.outcome.metrics.keys().next().cloned()).unwrap_or_default();
            info!("no metric to plot: choose one with --metric (e.g. {example})");
            Vec::new()
        }
        (_, true) => Vec::new(),
    };
    let meta = [
        ("cohort.campaign.scenario", plan.file.display().to_string()),
        ("cohort.campaign.seed", plan.seed.to_string()),
        ("cohort.campaign.dispersions", plan.spec_text.clone()),
        ("cohort.campaign.drawn", serde_json::to_string(&columns).unwrap_or_default()),
    ];
    if let Err(e) = table::write(root, &rows, &columns, &meta) {
        return crate::fail(CommandError::failed(e));
    }
    let header = report::Header {
        file: &plan.file,
        seed: plan.seed,
        mode,
        columns: &columns,
        spec_text: &plan.spec_text,
        metric: metric.as_deref(),
        stopped,
    };
    let md = report::markdown(&header, &rows, &plots);
    let md_path = root.join("campaign.md");
    if let Err(e) = std::fs::write(&md_path, &md) {
        return crate::fail(CommandError::failed(format!("{}: {e}", md_path.display())));
    }
    let not_ok = rows.iter().filter(|r| r.outcome.status != "ok").count();
    if not_ok > 0 {
        warn!("{not_ok} of {} cases did not end ok (their status is in the table)", rows.len());
    }
    outln!("campaign results: {} and {}", root.join(table::FILE).display(), md_path.display());
    ExitCode::SUCCESS
}
