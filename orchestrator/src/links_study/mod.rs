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

use crate::campaign::fly::fly;
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
    /// Override scenario.seed (every rung flies the same seed).
    #[arg(long, value_parser = crate::seed_arg)]
    seed: Option<u64>,
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

/// One rung of one scenario, flown: its outcome and what its links did.
pub struct RungResult {
    pub rung: &'static str,
    /// None: the rung does not apply to this plant.
    pub flown: Option<(Outcome, table::LinkTotals)>,
}

pub fn command(cmd: &LinksCmd) -> ExitCode {
    let LinksCmd::Study(a) = cmd;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/links-study-{}", cohort_host::utc_stamp())));
    let overrides = Overrides { duration_s: a.duration, seed: a.seed, ..Overrides::default() };
    let workers = a.workers.map_or_else(|| std::thread::available_parallelism().map_or(1, usize::from), |w| w as usize);
    let mut md = String::from("# Links study\n\n");
    for file in &a.files {
        match study(file, &overrides, &out, workers) {
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

/// Fly every rung of `file`; the scenario's name and a result per rung.
fn study(file: &Path, o: &Overrides, out: &Path, workers: usize) -> Result<(String, Vec<RungResult>), CommandError> {
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
    let text = std::fs::read_to_string(file).map_err(|e| CommandError::failed(format!("{}: {e}", file.display())))?;
    let name = base.parsed.scenario.name.clone();
    let rungs = ladder(frame);
    let setups: Vec<Option<Setup>> = rungs
        .iter()
        .map(|r| r.links.as_ref().map(|l| with_links(&text, file, o, l)).transpose())
        .collect::<Result<_, _>>()?;
    let dir = out.join(&name);
    let fly_rung = |i: usize| -> Result<Option<(Outcome, table::LinkTotals)>, String> {
        let Some(setup) = &setups[i] else { return Ok(None) };
        let rung_dir = dir.join(format!("rung-{i}"));
        let outcome = fly(setup, &rung_dir, How::in_process(setup, true), false).map_err(|e| e.to_string())?;
        Ok(Some((outcome, table::LinkTotals::read(&rung_dir.join("summary.json")))))
    };
    tracing::info!("{}: {} rungs on {workers} worker(s)", file.display(), rungs.len());
    let flown =
        Campaign::new(rungs.len()).workers(workers).run(fly_rung).map_err(|e| CommandError::failed(e.source))?;
    Ok((name, rungs.iter().zip(flown).map(|(r, flown)| RungResult { rung: r.name, flown }).collect()))
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
