//! The figures of a run: the paper's ([`FigureSource`]) first, then the generic ones, drawn into
//! `run_dir/plots/` with the chart kit (the crate docs say how columns become figures).

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::ReportError;
use crate::chart::{DrawResult, ensure_font};
use crate::columns::classify_columns;
use crate::generic::{Figure, Source, time_figures, trajectory_figure, unique_stem};
use crate::table::{Column, Table, read_table_with};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FileKind {
    /// `agent-<id>.csv`.
    Agent(u32),
    /// `plant.csv` or any other CSV file.
    Other,
}

#[derive(Debug)]
pub(crate) struct TelemetryFile {
    pub(crate) path: PathBuf,
    pub(crate) stem: String,
    pub(crate) kind: FileKind,
}

/// The `.csv` files in `dir`: `plant.csv` first, then other non-agent files by name, then
/// `agent-<id>.csv` by id.
pub(crate) fn list_telemetry(dir: &Path) -> Result<Vec<TelemetryFile>, ReportError> {
    let io_err = |error| ReportError::Io { path: dir.to_path_buf(), error };
    match std::fs::metadata(dir) {
        Ok(meta) if meta.is_dir() => {}
        Ok(_) => {
            return Err(ReportError::MissingTelemetryDir { path: dir.to_path_buf() });
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(ReportError::MissingTelemetryDir { path: dir.to_path_buf() });
        }
        Err(e) => return Err(io_err(e)),
    }
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io_err)? {
        let path = entry.map_err(io_err)?.path();
        let is_table = path.extension().is_some_and(|ext| ext == "csv" || ext == "parquet");
        if !is_table || !path.is_file() {
            continue;
        }
        let Some(stem) = path.file_stem().map(|s| s.to_string_lossy().into_owned()) else {
            continue;
        };
        let kind = match stem.strip_prefix("agent-").map(str::parse::<u32>) {
            Some(Ok(id)) => FileKind::Agent(id),
            _ => FileKind::Other,
        };
        files.push(TelemetryFile { path, stem, kind });
    }
    // A stem in both formats: the Parquet file is the run's (`.parquet` sorts after `.csv`).
    files.sort_by(|a, b| a.stem.cmp(&b.stem).then_with(|| b.path.cmp(&a.path)));
    files.dedup_by(|later, first| later.stem == first.stem);
    if files.is_empty() {
        return Err(ReportError::NoTelemetry { path: dir.to_path_buf() });
    }
    files.sort_by(|a, b| {
        let rank = |f: &TelemetryFile| match f.kind {
            FileKind::Other if f.stem == "plant" => (0, 0),
            FileKind::Other => (1, 0),
            FileKind::Agent(id) => (2, id),
        };
        rank(a).cmp(&rank(b)).then_with(|| a.stem.cmp(&b.stem))
    });
    Ok(files)
}

/// How a paper's figures use a plant column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum ColumnUse {
    /// Drawn by the generic figures (the default).
    Generic,
    /// Read for the paper's figures only ([`Telemetry::plant_aside`]), left out of the generic ones.
    PaperOnly,
    /// Neither read nor drawn (e.g. a state in a frame no figure shows).
    Skip,
}

/// A run's telemetry as read for the figures.
pub struct Telemetry<'a> {
    pub run_dir: &'a Path,
    /// `plant.csv` without the columns set aside, if the run has one.
    pub plant: Option<&'a Table>,
    /// The plant columns the papers set aside ([`ColumnUse::PaperOnly`]), if any.
    pub plant_aside: Option<&'a Table>,
    /// `agent-<id>.csv` by id.
    pub agents: &'a [(u32, Table)],
}

/// One figure of a paper: its file stem in `plots/` and how to draw it.
pub trait PaperFigure {
    fn stem(&self) -> &str;
    fn draw(&self, path: &Path) -> DrawResult;
}

/// A paper's figures of one run (from `RunHooks::figures` on the host side).
pub trait FigureSource {
    /// How the paper's figures use plant column `name` (default: not at all).
    fn plant_column(&self, _name: &str) -> ColumnUse {
        ColumnUse::Generic
    }
    /// Whether an agent column (`agent-<id>.csv`) is left out of the generic figures because a
    /// paper figure shows it already (default: no).
    fn agent_column(&self, _name: &str) -> ColumnUse {
        ColumnUse::Generic
    }
    /// The paper's figures of the run, read and checked (not yet drawn).
    fn figures(&self, telemetry: &Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError>;
}

enum Drawable<'a> {
    Paper(&'a dyn PaperFigure),
    Generic(&'a Figure),
}

/// Reads `run_dir/telemetry/*.parquet` (or `*.csv`) and writes PNG plots into `run_dir/plots/` (created if
/// needed; existing files of the same names are overwritten). Returns the paths written, in
/// drawing order: the papers' figures first, then the figures of `plant.csv` and any other
/// non-agent file, then those of the agent files, then `timeline.md` when the run has faults.
pub fn report(run_dir: &Path, papers: &[&dyn FigureSource]) -> Result<Vec<PathBuf>, ReportError> {
    let telemetry_dir = run_dir.join("telemetry");
    let files = list_telemetry(&telemetry_dir)?;
    // The strongest claim on a plant column wins (a paper that sets it aside over one that
    // leaves it generic; skipping over both).
    let plant_use = |name: &str| papers.iter().map(|p| p.plant_column(name)).max().unwrap_or(ColumnUse::Generic);

    // Read everything first: a malformed file fails the report before any figure is drawn.
    let mut figures = Vec::new();
    let mut used_stems = HashSet::new();
    let mut agent_tables = Vec::new();
    // Plant columns set aside for the papers' figures.
    let mut plant_aside = None;
    // Kept for the papers' figures, which join the plant's truth with the agents' telemetry.
    let mut plant_table = None;
    for file in &files {
        let is_plant = file.kind == FileKind::Other && file.stem == "plant";
        let table = if is_plant {
            let mut table = read_table_with(&file.path, &|name| plant_use(name) != ColumnUse::Skip)?;
            let (aside, rest): (Vec<Column>, Vec<Column>) =
                table.columns.into_iter().partition(|c| plant_use(&c.name) == ColumnUse::PaperOnly);
            table.columns = rest;
            if !aside.is_empty() {
                plant_aside = Some(Table { k: table.k.clone(), t: table.t.clone(), columns: aside });
            }
            table
        } else if matches!(file.kind, FileKind::Agent(_)) {
            let agent_use =
                |name: &str| papers.iter().map(|p| p.agent_column(name)).max().unwrap_or(ColumnUse::Generic);
            let mut table = Table::read(&file.path)?;
            table.columns.retain(|c| agent_use(&c.name) == ColumnUse::Generic);
            table
        } else {
            Table::read(&file.path)?
        };
        match file.kind {
            FileKind::Agent(id) => agent_tables.push((id, table)),
            FileKind::Other => {
                let quantities = classify_columns(&table, None);
                let source = Source { label: file.stem.clone(), file_desc: format!("{}.csv", file.stem) };
                let tables = [(&table, quantities)];
                figures.extend(time_figures(&source, &tables, &mut used_stems));
                let xy_stem = if file.stem == "plant" {
                    "trajectories_xy".to_string()
                } else {
                    format!("{}_trajectories_xy", file.stem)
                };
                if let Some(fig) = trajectory_figure(&source, &table, &tables[0].1) {
                    figures.push(Figure::Xy(unique_stem(&xy_stem, &mut used_stems), fig));
                }
                if file.stem == "plant" {
                    plant_table = Some(table);
                }
            }
        }
    }
    if !agent_tables.is_empty() {
        let source = Source { label: "agents".to_string(), file_desc: "agent-*.csv".to_string() };
        let tables: Vec<_> =
            agent_tables.iter().map(|(id, table)| (table, classify_columns(table, Some(*id)))).collect();
        figures.extend(time_figures(&source, &tables, &mut used_stems));
    }
    let telemetry =
        Telemetry { run_dir, plant: plant_table.as_ref(), plant_aside: plant_aside.as_ref(), agents: &agent_tables };
    let mut paper_figures = Vec::new();
    for p in papers {
        paper_figures.extend(p.figures(&telemetry)?);
    }
    // A paper's figure keeps its stem; a generic figure of the same stem is renamed.
    let mut taken: HashSet<String> = paper_figures.iter().map(|f| f.stem().to_string()).collect();
    taken.extend(used_stems);
    for f in &mut figures {
        if paper_figures.iter().any(|p| p.stem() == f.stem()) {
            let stem = unique_stem(f.stem(), &mut taken);
            f.rename(stem);
        }
    }

    ensure_font()?;
    let plots_dir = run_dir.join("plots");
    std::fs::create_dir_all(&plots_dir)
        .map_err(|error| ReportError::CreatePlotDir { path: plots_dir.clone(), error })?;

    let mut written = Vec::with_capacity(figures.len() + paper_figures.len());
    // Paper figures first, then the generic ones.
    let drawables = paper_figures
        .iter()
        .map(|f| (f.stem(), Drawable::Paper(f.as_ref())))
        .chain(figures.iter().map(|f| (f.stem(), Drawable::Generic(f))));
    for (stem, figure) in drawables {
        let path = plots_dir.join(format!("{stem}.png"));
        let draw = |p: &Path| match figure {
            Drawable::Paper(f) => f.draw(p),
            Drawable::Generic(f) => f.draw(p),
        };
        // Plotters should not panic on the finite, non-degenerate ranges we hand it, but a plot
        // is not worth taking the orchestrator down for: turn any panic into an error.
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| draw(&path)));
        match outcome {
            Ok(Ok(())) => written.push(path),
            Ok(Err(e)) => {
                return Err(ReportError::Plot { path, message: e.to_string() });
            }
            Err(_) => {
                return Err(ReportError::Plot { path, message: "the plotting library panicked".to_string() });
            }
        }
    }
    if let Some(md) = timeline_table(run_dir) {
        let path = plots_dir.join("timeline.md");
        std::fs::write(&path, md).map_err(|error| ReportError::Io { path: path.clone(), error })?;
        written.push(path);
    }
    Ok(written)
}

/// The run's fault timeline as a Markdown table (`plots/timeline.md`), when it has one.
fn timeline_table(run_dir: &Path) -> Option<String> {
    let text = std::fs::read_to_string(run_dir.join("summary.json")).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let events = v["timeline"].as_array().filter(|t| !t.is_empty())?;
    let mut md = String::from(
        "# Fault timeline\n\n| wall s | step | t s | agent | event | detail |\n|---:|---:|---:|---:|---|---|\n",
    );
    for e in events {
        md.push_str(&format!(
            "| {:.3} | {} | {:.2} | {} | {} | {} |\n",
            e["wall_s"].as_f64().unwrap_or(f64::NAN),
            e["step"],
            e["t_s"].as_f64().unwrap_or(f64::NAN),
            e["agent"],
            e["event"].as_str().unwrap_or(""),
            e["detail"].as_str().unwrap_or("").replace('|', "/")
        ));
    }
    let effects: Vec<String> = v["metrics"]
        .as_object()
        .into_iter()
        .flatten()
        .filter(|(k, _)| k.starts_with("fault."))
        .map(|(k, x)| format!("| {k} | {x} |"))
        .collect();
    if !effects.is_empty() {
        md.push_str("\n## Effect on the headline metric\n\n| metric | value |\n|---|---:|\n");
        md.push_str(&effects.join("\n"));
        md.push('\n');
    }
    Some(md)
}
