//! `orchestrator links study FILE...`: each scenario flown under ideal links and a ladder of
//! link conditions from the geometry (`ladder`), its paper's verdict and headline numbers
//! tabulated per rung, with the first rung where the verdict fails (docs/links.md).
//!
//! Every rung is the scenario with its `[links]` replaced, flown in-process (bit-identical to a
//! process run) on the campaign kit's workers; each keeps its run directory's summary.

mod ladder;
mod table;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Subcommand};
use cohort_host::CommandError;
use cohort_host::campaign::Campaign;
use cohort_runtime::paper::{LinkFrame, Setup};
use cohort_scenario::Overrides;
use cohort_scenario::links::Links;

use crate::campaign::fly::fly_with_summary;
use crate::campaign::row::Outcome;
use crate::launcher::How;
pub use ladder::ladder;

#[derive(Subcommand)]
pub enum LinksCmd {
    /// Fly each scenario under ideal links and a ladder of geometric link conditions (range-only
    /// delay; + blockage by the central body; + loss 1 %, 10 %, 30 %; + a 64 kbit/s rate cap)
    /// and tabulate its paper's verdict and headline numbers per rung, with the first rung where
    /// the verdict fails; writes links-study.md and each rung's summary under --out.
    Study(StudyArgs),
}

#[derive(Args)]
pub struct StudyArgs {
    /// Scenario files (TOML) whose plant gives positions.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Override scenario.duration_s, in seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Override scenario.seed (every rung flies the same seeds).
    #[arg(long, value_parser = crate::seed_arg)]
    seed: Option<u64>,
    /// Seeds per rung (the scenario's seed, or --seed, and the next ones): the table gives each
    /// verdict line's mean and range and how many seeds fail.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=1000))]
    seeds: u64,
    /// Rungs flown at once (default: the machine's cores). The tables do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1024))]
    workers: Option<u64>,
    /// Output directory; default runs/links-study-<UTC time>/.
    #[arg(long)]
    out: Option<PathBuf>,
    /// A summary metric to tabulate beside the verdict (repeatable), e.g. `collisions`.
    #[arg(long = "metric", value_name = "NAME")]
    metrics: Vec<String>,
}

/// One rung of one scenario, flown: per seed, its outcome and what its links did.
pub struct RungResult {
    pub rung: &'static str,
    /// Empty: the rung does not apply to this plant.
    pub flown: Vec<(Outcome, table::LinkTotals)>,
}

pub fn command(cmd: &LinksCmd) -> ExitCode {
    let LinksCmd::Study(a) = cmd;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/links-study-{}", cohort_host::utc_stamp())));
    let overrides = Overrides { duration_s: a.duration, seed: a.seed, ..Overrides::default() };
    let workers = a.workers.map_or_else(|| std::thread::available_parallelism().map_or(1, usize::from), |w| w as usize);
    let mut md = String::from("# Links study\n\n");
    for file in &a.files {
        match study(file, &overrides, a.seeds, &out, workers) {
            Ok((name, results)) => md.push_str(&table::markdown(&name, file, &results, &a.metrics)),
            Err(e) => return crate::fail(e),
        }
    }
    let path = out.join("links-study.md");
    if let Err(e) = std::fs::write(&path, &md) {
        return crate::fail(CommandError::failed(format!("{}: {e}", path.display())));
    }
    outln!("{md}");
    tracing::info!("the tables: {}", path.display());
    ExitCode::SUCCESS
}

/// Fly every rung of `file` at `seeds` seeds; the scenario's name and a result per rung.
fn study(
    file: &Path,
    o: &Overrides,
    seeds: u64,
    out: &Path,
    workers: usize,
) -> Result<(String, Vec<RungResult>), CommandError> {
    let base = cohort_registry::load(file, o).map_err(|e| CommandError::invalid(e.to_string()))?;
    let frame = base.plant.link_frame();
    if frame == LinkFrame::None {
        let why = format!(
            "{}: plant kind {:?} gives no positions: links study needs them",
            file.display(),
            base.plant.kind()
        );
        return Err(CommandError::invalid(why));
    }
    let first = base.parsed.scenario.seed;
    if first.checked_add(seeds - 1).is_none_or(|s| s > cohort_scenario::validate::MAX_SEED) {
        return Err(CommandError::invalid(format!("--seeds {seeds} from seed {first}: the last passes 2^63 − 1")));
    }
    let text = std::fs::read_to_string(file).map_err(|e| CommandError::failed(format!("{}: {e}", file.display())))?;
    let name = base.parsed.scenario.name.clone();
    let rungs = ladder(frame);
    let n = seeds as usize;
    // Case i: rung i / n at seed first + i % n.
    let setups: Vec<Option<Setup>> = (0..rungs.len() * n)
        .map(|i| {
            let o = Overrides { seed: Some(first + (i % n) as u64), ..o.clone() };
            rungs[i / n].links.as_ref().map(|l| with_links(&text, file, &o, l)).transpose()
        })
        .collect::<Result<_, _>>()?;
    let dir = out.join(&name);
    let fly_case = |i: usize| -> Result<Option<(Outcome, table::LinkTotals)>, String> {
        let Some(setup) = &setups[i] else { return Ok(None) };
        let case_dir = match n {
            1 => dir.join(format!("rung-{i}")),
            _ => dir.join(format!("rung-{}", i / n)).join(format!("seed-{}", first + (i % n) as u64)),
        };
        let (outcome, summary) =
            fly_with_summary(setup, &case_dir, How::in_process(setup, true), false).map_err(|e| e.to_string())?;
        Ok(Some((outcome, table::LinkTotals::of(&summary))))
    };
    tracing::info!("{}: {} rungs × {n} seed(s) on {workers} worker(s)", file.display(), rungs.len());
    let flown =
        Campaign::new(setups.len()).workers(workers).run(fly_case).map_err(|e| CommandError::failed(e.source))?;
    let mut flown = flown.into_iter();
    let results =
        rungs.iter().map(|r| RungResult { rung: r.name, flown: flown.by_ref().take(n).flatten().collect() }).collect();
    Ok((name, results))
}

/// The scenario of `text` with its `[links]` replaced by `links`, configured.
fn with_links(text: &str, file: &Path, o: &Overrides, links: &Links) -> Result<Setup, CommandError> {
    let bad = |e: String| CommandError::invalid(format!("{}: {e}", file.display()));
    let mut t: toml::Table = text.parse().map_err(|e: toml::de::Error| bad(e.to_string()))?;
    t.remove("links");
    if *links != Links::default() {
        t.insert("links".into(), toml::Table::try_from(links).map_err(|e| bad(e.to_string()))?.into());
    }
    let text = toml::to_string(&t).map_err(|e| bad(e.to_string()))?;
    cohort_registry::load_text(&text, file, o).map_err(|e| CommandError::invalid(e.to_string()))
}
