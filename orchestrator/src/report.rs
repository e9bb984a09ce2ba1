//! Post-run plots: read a run directory's telemetry CSVs and draw PNG figures into
//! `run_dir/plots/`.
//!
//! The reader knows only the shape every telemetry file shares: a header row whose first two
//! columns are `k` (step, integer) and `t_s` (simulated time in seconds), then one `f64` column
//! per quantity. Everything else is inferred from the column names, so new scenarios get plots
//! without changes here:
//!
//! * A column name is `[a<i>_]<name>[_<axis>][_<unit>]`. The `a<i>_` prefix (plant-side files
//!   only) says which agent the column belongs to; `<axis>` is `x`, `y` or `z`; `<unit>` is one
//!   of the suffixes [`unit_label`] knows (`m`, `mps`, `mps2`, ...).
//! * Columns sharing agent, name and unit, and having two or more axes, form a vector, plotted
//!   as its Euclidean norm. Any other column is a scalar, plotted as is.
//! * One figure per family (name and unit): `plant.csv` gives `plant_<name>.png` with one line
//!   per agent; the `agent-<id>.csv` files together give `agents_<name>.png`, overlaying all
//!   agents. Any other `<stem>.csv` gives `<stem>_<name>.png`.
//! * A file with agent positions (`a<i>_r_x_<unit>`, `a<i>_r_y_<unit>`) also gets an x–y path
//!   plot, `trajectories_xy.png` for `plant.csv`.
//!
//! Every series is reduced to at most [`MAX_POINTS`] points (min/max per bucket, so spikes
//! survive), and a figure whose values are all positive and span more than
//! [`LOG_SCALE_RATIO`] gets a logarithmic y axis (formation error converging to zero, say).
//! Non-finite values are accepted and leave gaps in the lines.
//!
//! All files are read and checked before any figure is drawn, so a malformed file leaves no
//! half-written set of plots behind.
//!
//! A run directory holding `derived/fig1.csv` (the seed-000 servicing scenario, written by the
//! orchestrator after the run) also gets the paper's figures, drawn by [`fig1`]; its per-body
//! plant columns (`b<b>_...`) are then left out of the generic figures. A seed-001 run (tethered
//! net: `snapshots/net_nodes.csv` or the plant's `mu<i>_tension_*_n` columns) also gets the
//! tension and 3-D net figures of [`crate::report_tsnr`].

use std::collections::{HashMap, HashSet};
use std::error::Error;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::register_font;

#[path = "report_fig1.rs"]
pub(crate) mod fig1;

/// Most points drawn per series; longer series are reduced to this many.
pub const MAX_POINTS: usize = 4000;
/// A figure whose values are all positive and whose max/min exceeds this gets a log y axis.
pub const LOG_SCALE_RATIO: f64 = 1e3;

const TIME_FIGURE_SIZE: (u32, u32) = (1200, 700);
const XY_FIGURE_SIZE: (u32, u32) = (1000, 1000);
pub(crate) const MARGIN: u32 = 20;
pub(crate) const X_LABEL_AREA: u32 = 60;
pub(crate) const Y_LABEL_AREA: u32 = 110;
pub(crate) const CAPTION_SIZE: u32 = 26;
pub(crate) const FONT_FAMILY: &str = "sans-serif";
/// Embedded because the `ab_glyph` font backend has no system font lookup. The path is relative
/// to this file: `<workspace>/assets/DejaVuSans.ttf`.
static FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// Why [`report`] could not draw the plots. Every message names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("no telemetry directory at {} (did the run write any telemetry?)", .path.display())]
    MissingTelemetryDir { path: PathBuf },
    #[error("telemetry directory {} holds no .csv files", .path.display())]
    NoTelemetry { path: PathBuf },
    #[error("cannot read {}: {error}", .path.display())]
    Io { path: PathBuf, error: std::io::Error },
    #[error("{}: bad header: {reason}", .path.display())]
    BadHeader { path: PathBuf, reason: String },
    #[error(
        "{}:{line}: expected {expected} columns (as in the header), found {found}",
        .path.display()
    )]
    ColumnCount { path: PathBuf, line: usize, expected: usize, found: usize },
    #[error("{}:{line}: column `{column}`: cannot parse {value:?} as a number", .path.display())]
    BadNumber { path: PathBuf, line: usize, column: String, value: String },
    #[error("cannot create plot directory {}: {error}", .path.display())]
    CreatePlotDir { path: PathBuf, error: std::io::Error },
    #[error("cannot register the embedded plot font (assets/DejaVuSans.ttf)")]
    Font,
    #[error("cannot draw {}: {message}", .path.display())]
    Plot { path: PathBuf, message: String },
    #[error("{}: {reason}", .path.display())]
    Fig1Input { path: PathBuf, reason: String },
    /// A seed-001 (tethered net) input that cannot be drawn; `line` is 1-based, when known.
    #[error("{}{}: {reason}", .path.display(), .line.map(|l| format!(":{l}")).unwrap_or_default())]
    TsnrInput { path: PathBuf, line: Option<usize>, reason: String },
}

/// Reads `run_dir/telemetry/*.csv` and writes PNG plots into `run_dir/plots/` (created if
/// needed; existing files of the same names are overwritten). Returns the paths written, in
/// drawing order: the paper's figures of a tsnr run or a `derived/fig1.csv` run first (see
/// [`crate::report_tsnr`], [`fig1`]), then the figures of `plant.csv` and any other non-agent
/// file, then those of the agent files.
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

pub fn report(run_dir: &Path) -> Result<Vec<PathBuf>, ReportError> {
    let telemetry_dir = run_dir.join("telemetry");
    let files = list_telemetry(&telemetry_dir)?;
    let fig1_path = run_dir.join(fig1::DERIVED_FILE);
    let is_fig1 = fig1_path.is_file();

    // Read everything first: a malformed file fails the report before any figure is drawn.
    let mut figures = Vec::new();
    let mut used_stems = HashSet::new();
    let mut agent_tables = Vec::new();
    let mut fig1_bodies = None;
    // Kept for the seed-001 figures, which join the plant's truth with the agents' telemetry.
    let mut plant_table = None;
    for file in &files {
        let is_fig1_plant = is_fig1 && file.kind == FileKind::Other && file.stem == "plant";
        let table = if is_fig1_plant {
            // Only the LVLH positions of the per-body columns are used (by the fig1 figures);
            // the ECI states are neither parsed nor plotted.
            let mut table =
                read_table_with(&file.path, &|name| fig1::body_column(name).is_none() || fig1::is_lvlh_column(name))?;
            let (bodies, rest): (Vec<Column>, Vec<Column>) =
                table.columns.into_iter().partition(|c| fig1::body_column(&c.name).is_some());
            table.columns = rest;
            fig1_bodies = Some((file.path.clone(), Table { t: table.t.clone(), columns: bodies }));
            table
        } else {
            read_table(&file.path)?
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
    if is_fig1 {
        let derived = read_table(&fig1_path)?;
        let plant_path = telemetry_dir.join("plant.csv");
        let (plant_path, bodies) = match &fig1_bodies {
            Some((path, bodies)) => (path.as_path(), Some(bodies)),
            None => (plant_path.as_path(), None),
        };
        let fig1_figures = fig1::figures(&fig1_path, &derived, plant_path, bodies)?;
        for figure in &fig1_figures {
            used_stems.insert(figure.stem().to_string());
        }
        figures.splice(0..0, fig1_figures);
    }
    let tsnr_figures = crate::report_tsnr::figures(run_dir, plant_table.as_ref(), &agent_tables)?;
    let tsnr_figures: Vec<Figure> = tsnr_figures
        .into_iter()
        .map(|(stem, fig)| {
            used_stems.insert(stem.clone());
            Figure::Tsnr(stem, fig)
        })
        .collect();
    figures.splice(0..0, tsnr_figures);

    ensure_font()?;
    let plots_dir = run_dir.join("plots");
    std::fs::create_dir_all(&plots_dir)
        .map_err(|error| ReportError::CreatePlotDir { path: plots_dir.clone(), error })?;

    let mut written = Vec::with_capacity(figures.len());
    for figure in &figures {
        let path = plots_dir.join(format!("{}.png", figure.stem()));
        // Plotters should not panic on the finite, non-degenerate ranges we hand it, but a plot
        // is not worth taking the orchestrator down for: turn any panic into an error.
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match figure {
            Figure::Time(_, fig) => draw_time_figure(&path, fig),
            Figure::Xy(_, fig) => draw_xy_figure(&path, fig),
            Figure::Fig1(_, fig) => fig.draw(&path),
            Figure::Tsnr(_, fig) => fig.draw(&path),
        }));
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

// ---------------------------------------------------------------------------------------------
// Finding and reading the CSV files

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FileKind {
    /// `agent-<id>.csv`.
    Agent(u32),
    /// `plant.csv` or any other CSV file.
    Other,
}

#[derive(Debug)]
struct TelemetryFile {
    path: PathBuf,
    stem: String,
    kind: FileKind,
}

/// The `.csv` files in `dir`: `plant.csv` first, then other non-agent files by name, then
/// `agent-<id>.csv` by id.
fn list_telemetry(dir: &Path) -> Result<Vec<TelemetryFile>, ReportError> {
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
        let is_csv = path.extension().is_some_and(|ext| ext.eq_ignore_ascii_case("csv"));
        if !is_csv || !path.is_file() {
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

/// One telemetry file, column-major.
#[derive(Debug)]
pub(crate) struct Table {
    /// The `t_s` column.
    pub(crate) t: Vec<f64>,
    /// The columns after `k` and `t_s`, in header order.
    pub(crate) columns: Vec<Column>,
}

#[derive(Debug)]
pub(crate) struct Column {
    pub(crate) name: String,
    pub(crate) values: Vec<f64>,
}

pub(crate) fn read_table(path: &Path) -> Result<Table, ReportError> {
    read_table_with(path, &|_| true)
}

/// Like [`read_table`], but keeps (and parses) only the columns after `k` and `t_s` whose name
/// passes `keep`; the other fields are counted but not checked.
fn read_table_with(path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<Table, ReportError> {
    let io_err = |error| ReportError::Io { path: path.to_path_buf(), error };
    let bad_header = |reason: String| ReportError::BadHeader { path: path.to_path_buf(), reason };
    let mut lines = BufReader::new(File::open(path).map_err(io_err)?).lines();
    let header = match lines.next() {
        None => return Err(bad_header("the file is empty".to_string())),
        Some(line) => line.map_err(io_err)?,
    };
    let names: Vec<&str> = header.trim_end_matches('\r').split(',').map(str::trim).collect();
    if names.len() < 2 || names[0] != "k" || names[1] != "t_s" {
        return Err(bad_header(format!(
            "the first two columns must be `k,t_s`, found `{}`",
            names.iter().take(2).copied().collect::<Vec<_>>().join(",")
        )));
    }
    let mut seen = HashSet::new();
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            return Err(bad_header(format!("column {} has an empty name", i + 1)));
        }
        if !seen.insert(*name) {
            return Err(bad_header(format!("duplicate column `{name}`")));
        }
    }

    let mut t = Vec::new();
    // For each field after `k,t_s`, the index of its column in `columns`, if kept.
    let mut slots: Vec<Option<usize>> = Vec::with_capacity(names.len() - 2);
    let mut columns: Vec<Column> = Vec::new();
    for name in &names[2..] {
        if keep(name) {
            slots.push(Some(columns.len()));
            columns.push(Column { name: (*name).to_string(), values: Vec::new() });
        } else {
            slots.push(None);
        }
    }
    for (index, line) in lines.enumerate() {
        let line_no = index + 2; // 1-based, after the header
        let line = line.map_err(io_err)?;
        let line = line.trim_end_matches('\r');
        if line.trim().is_empty() {
            continue;
        }
        let found = line.split(',').count();
        if found != names.len() {
            return Err(ReportError::ColumnCount {
                path: path.to_path_buf(),
                line: line_no,
                expected: names.len(),
                found,
            });
        }
        let bad_number = |column: &str, value: &str| ReportError::BadNumber {
            path: path.to_path_buf(),
            line: line_no,
            column: column.to_string(),
            value: value.to_string(),
        };
        let mut fields = line.split(',').map(str::trim);
        let (Some(k), Some(t_s)) = (fields.next(), fields.next()) else {
            unreachable!("the row has as many fields as the header, which has at least two");
        };
        k.parse::<u64>().map_err(|_| bad_number("k", k))?;
        t.push(t_s.parse::<f64>().map_err(|_| bad_number("t_s", t_s))?);
        for (slot, field) in slots.iter().zip(fields) {
            if let Some(index) = *slot {
                let column = &mut columns[index];
                let value = field.parse::<f64>().map_err(|_| bad_number(&column.name, field))?;
                column.values.push(value);
            }
        }
    }
    Ok(Table { t, columns })
}

// ---------------------------------------------------------------------------------------------
// Column names to quantities and figures

/// Display form of a unit suffix, or `None` if `suffix` is not a unit we know (it is then taken
/// as part of the quantity's name).
fn unit_label(suffix: &str) -> Option<&'static str> {
    Some(match suffix {
        "m" => "m",
        "km" => "km",
        "mps" => "m/s",
        "kmps" => "km/s",
        "mps2" => "m/s²",
        "kmps2" => "km/s²",
        "s" => "s",
        "ms" => "ms",
        "us" => "µs",
        "ns" => "ns",
        "rad" => "rad",
        "radps" => "rad/s",
        "radps2" => "rad/s²",
        "deg" => "deg",
        "degps" => "deg/s",
        "N" => "N",
        "Nm" => "N·m",
        "kg" => "kg",
        "J" => "J",
        "W" => "W",
        "Hz" => "Hz",
        "pct" => "%",
        _ => return None,
    })
}

/// A column name split into its parts; see the module documentation.
#[derive(Debug, Clone, PartialEq, Eq)]
struct ColumnName {
    owner: Option<u32>,
    name: String,
    axis: Option<char>,
    unit: Option<String>,
}

fn parse_column_name(column: &str, allow_owner: bool) -> ColumnName {
    let owner_prefix = column.split_once('_').filter(|_| allow_owner).and_then(|(prefix, tail)| {
        let digits = prefix.strip_prefix('a')?;
        let is_id = !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit());
        if !is_id || tail.is_empty() {
            return None;
        }
        Some((digits.parse::<u32>().ok()?, tail))
    });
    let (owner, rest) = match owner_prefix {
        Some((id, tail)) => (Some(id), tail),
        None => (None, column),
    };
    let mut tokens: Vec<&str> = rest.split('_').collect();
    let mut unit = None;
    if tokens.len() >= 2 && tokens.last().is_some_and(|s| unit_label(s).is_some()) {
        unit = tokens.pop().map(str::to_string);
    }
    let mut axis = None;
    if let [_, .., a @ ("x" | "y" | "z")] = tokens[..] {
        axis = a.chars().next();
        tokens.pop();
    }
    ColumnName { owner, name: tokens.join("_"), axis, unit }
}

/// A plotted quantity of one table: a scalar column, or a vector of axis columns.
#[derive(Debug, Clone, PartialEq)]
struct Quantity {
    owner: Option<u32>,
    name: String,
    unit: Option<String>,
    /// `(axis, column index)`; exactly one entry with axis `None` for a scalar.
    components: Vec<(Option<char>, usize)>,
}

impl Quantity {
    fn is_vector(&self) -> bool {
        self.components.len() >= 2
    }

    /// Per-row values: the column itself for a scalar, the Euclidean norm for a vector.
    fn values(&self, table: &Table) -> Vec<f64> {
        if let [(_, col)] = self.components[..] {
            return table.columns[col].values.clone();
        }
        let rows = self.components.iter().map(|&(_, col)| table.columns[col].values.len()).min().unwrap_or(0);
        (0..rows)
            .map(|row| {
                self.components.iter().map(|&(_, col)| table.columns[col].values[row].powi(2)).sum::<f64>().sqrt()
            })
            .collect()
    }

    fn column<'t>(&self, table: &'t Table, axis: char) -> Option<&'t [f64]> {
        self.components.iter().find(|(a, _)| *a == Some(axis)).map(|&(_, col)| table.columns[col].values.as_slice())
    }
}

/// Groups a table's columns into quantities, in order of first appearance. `file_owner` is the
/// agent id of an agent file (whose columns carry no `a<i>_` prefix).
fn classify_columns(table: &Table, file_owner: Option<u32>) -> Vec<Quantity> {
    let mut quantities: Vec<Quantity> = Vec::new();
    let mut vector_index: HashMap<(Option<u32>, String, Option<String>), usize> = HashMap::new();
    for (col, column) in table.columns.iter().enumerate() {
        let parsed = parse_column_name(&column.name, file_owner.is_none());
        let owner = file_owner.or(parsed.owner);
        match parsed.axis {
            Some(axis) => {
                let key = (owner, parsed.name.clone(), parsed.unit.clone());
                if let Some(&q) = vector_index.get(&key) {
                    quantities[q].components.push((Some(axis), col));
                } else {
                    vector_index.insert(key, quantities.len());
                    quantities.push(Quantity {
                        owner,
                        name: parsed.name,
                        unit: parsed.unit,
                        components: vec![(Some(axis), col)],
                    });
                }
            }
            None => {
                quantities.push(Quantity { owner, name: parsed.name, unit: parsed.unit, components: vec![(None, col)] })
            }
        }
    }
    // A lone axis column (say `r_x_m` without `r_y_m`) is a scalar named `r_x`.
    for q in &mut quantities {
        if let [(Some(axis), _)] = q.components[..] {
            q.name = format!("{}_{axis}", q.name);
            q.components[0].0 = None;
        }
    }
    quantities
}

/// Where a set of figures comes from: `label` prefixes file names, `file_desc` starts titles.
struct Source {
    label: String,
    file_desc: String,
}

/// One line of a figure; non-finite points split the line.
#[derive(Debug)]
pub(crate) struct Series {
    pub(crate) label: String,
    pub(crate) color: RGBColor,
    pub(crate) points: Vec<(f64, f64)>,
}

#[derive(Debug)]
struct TimeFigure {
    title: String,
    y_desc: String,
    series: Vec<Series>,
}

#[derive(Debug)]
struct XyFigure {
    title: String,
    x_desc: String,
    y_desc: String,
    paths: Vec<Series>,
}

#[derive(Debug)]
enum Figure {
    Time(String, TimeFigure),
    Xy(String, XyFigure),
    Fig1(String, fig1::Fig1Figure),
    Tsnr(String, crate::report_tsnr::TsnrFigure),
}

impl Figure {
    fn stem(&self) -> &str {
        match self {
            Figure::Time(stem, _) | Figure::Xy(stem, _) | Figure::Fig1(stem, _) | Figure::Tsnr(stem, _) => stem,
        }
    }
}

/// One time-history figure per family (name, unit, scalar/vector) across `tables`, one line
/// per quantity.
fn time_figures(source: &Source, tables: &[(&Table, Vec<Quantity>)], used_stems: &mut HashSet<String>) -> Vec<Figure> {
    type FamilyKey = (String, Option<String>, bool);
    let mut order: Vec<FamilyKey> = Vec::new();
    let mut members: HashMap<FamilyKey, Vec<(&Table, &Quantity)>> = HashMap::new();
    for (table, quantities) in tables {
        for q in quantities {
            let key = (q.name.clone(), q.unit.clone(), q.is_vector());
            let entry = members.entry(key.clone()).or_default();
            if entry.is_empty() {
                order.push(key);
            }
            entry.push((table, q));
        }
    }

    let mut figures = Vec::new();
    for key in order {
        let Some(family) = members.get(&key) else {
            continue;
        };
        let (name, unit, vector) = &key;
        let per_agent = family.iter().any(|(_, q)| q.owner.is_some());
        let quantity = if *vector { format!("‖{name}‖") } else { name.clone() };
        let mut title = format!("{} — {quantity}", source.file_desc);
        if per_agent {
            title.push_str(" per agent");
        }
        if let (true, Some((_, q))) = (*vector, family.first()) {
            let axes: Vec<String> =
                q.components.iter().filter_map(|(axis, _)| axis.map(|a| format!("{name}_{a}"))).collect();
            title.push_str(&format!(" (norm of {})", axes.join(", ")));
        }
        let y_desc = match unit.as_deref().and_then(unit_label) {
            Some(unit) => format!("{quantity} [{unit}]"),
            None => quantity.clone(),
        };
        let series = family
            .iter()
            .enumerate()
            .map(|(i, (table, q))| Series {
                label: match q.owner {
                    Some(id) => format!("agent {id}"),
                    None => quantity.clone(),
                },
                color: series_color(q.owner, i),
                points: downsample_min_max(&table.t, &q.values(table), MAX_POINTS),
            })
            .collect();
        let stem = unique_stem(&format!("{}_{}", source.label, sanitize(name)), used_stems);
        figures.push(Figure::Time(stem, TimeFigure { title, y_desc, series }));
    }
    figures
}

/// The x–y paths of the table's position vectors (`r` with x and y axes), if it has any.
fn trajectory_figure(source: &Source, table: &Table, quantities: &[Quantity]) -> Option<XyFigure> {
    let mut unit = None;
    let paths: Vec<Series> = quantities
        .iter()
        .filter(|q| q.name == "r")
        .filter_map(|q| Some((q, q.column(table, 'x')?, q.column(table, 'y')?)))
        .enumerate()
        .map(|(i, (q, x, y))| {
            unit = unit.or(q.unit.as_deref().and_then(unit_label));
            Series {
                label: match q.owner {
                    Some(id) => format!("agent {id}"),
                    None => "r".to_string(),
                },
                color: series_color(q.owner, i),
                points: downsample_stride(x, y, MAX_POINTS),
            }
        })
        .collect();
    if paths.is_empty() {
        return None;
    }
    let desc = |axis: &str| match unit {
        Some(unit) => format!("{axis} [{unit}]"),
        None => axis.to_string(),
    };
    Some(XyFigure {
        title: format!("{} — x–y trajectories (● start, × end)", source.file_desc),
        x_desc: desc("x"),
        y_desc: desc("y"),
        paths,
    })
}

fn sanitize(name: &str) -> String {
    let s: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
    if s.is_empty() { "unnamed".to_string() } else { s }
}

/// `stem`, or `stem_2`, `stem_3`, ... if already taken.
fn unique_stem(stem: &str, used: &mut HashSet<String>) -> String {
    let mut candidate = stem.to_string();
    let mut n = 2;
    while !used.insert(candidate.clone()) {
        candidate = format!("{stem}_{n}");
        n += 1;
    }
    candidate
}

/// Agent `id` always gets the same colour, so agents match across figures.
pub(crate) fn series_color(owner: Option<u32>, index: usize) -> RGBColor {
    const TABLEAU: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    let i = match owner {
        Some(id) => (id as usize).saturating_sub(1),
        None => index,
    };
    match TABLEAU.get(i) {
        Some(c) => *c,
        None => {
            let (r, g, b) = Palette99::pick(i).to_rgba().rgb();
            RGBColor(r, g, b)
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Downsampling

/// A point that splits a line.
const GAP: (f64, f64) = (f64::NAN, f64::NAN);

fn is_finite_point(p: &(f64, f64)) -> bool {
    p.0.is_finite() && p.1.is_finite()
}

/// At most `max_points` finite points of `(x[i], y[i])`: all of them if few enough, else the
/// minimum and maximum of `y` in each of `max_points / 2` equal buckets of rows, in row order,
/// so peaks survive. Non-finite points become gaps (`GAP`, at most one per bucket).
pub(crate) fn downsample_min_max(x: &[f64], y: &[f64], max_points: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    let point = |i: usize| (x[i], y[i]);
    let buckets = (max_points / 2).max(1);
    if n <= max_points || n <= buckets {
        return (0..n)
            .map(|i| {
                let p = point(i);
                if is_finite_point(&p) { p } else { GAP }
            })
            .collect();
    }
    let mut out = Vec::with_capacity(max_points + buckets);
    for b in 0..buckets {
        let start = b * n / buckets;
        let end = (b + 1) * n / buckets;
        let mut min: Option<usize> = None;
        let mut max: Option<usize> = None;
        let mut gap = false;
        for i in start..end {
            if !is_finite_point(&point(i)) {
                gap = true;
                continue;
            }
            if min.is_none_or(|m| y[i] < y[m]) {
                min = Some(i);
            }
            if max.is_none_or(|m| y[i] > y[m]) {
                max = Some(i);
            }
        }
        match (min, max) {
            (Some(a), Some(b)) if a == b => out.push(point(a)),
            (Some(a), Some(b)) => {
                out.push(point(a.min(b)));
                out.push(point(a.max(b)));
            }
            _ => {}
        }
        if gap {
            out.push(GAP);
        }
    }
    out
}

/// Every k-th point of the path `(x[i], y[i])` (and the last one), at most about `max_points`.
/// Non-finite points become gaps.
fn downsample_stride(x: &[f64], y: &[f64], max_points: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    if n == 0 {
        return Vec::new();
    }
    let stride = n.div_ceil(max_points.max(1)).max(1);
    let mut indices: Vec<usize> = (0..n).step_by(stride).collect();
    if indices.last() != Some(&(n - 1)) {
        indices.push(n - 1);
    }
    indices
        .into_iter()
        .map(|i| {
            let p = (x[i], y[i]);
            if is_finite_point(&p) { p } else { GAP }
        })
        .collect()
}

/// The runs of finite points between gaps.
fn finite_runs(points: &[(f64, f64)]) -> impl Iterator<Item = &[(f64, f64)]> {
    points.split(|p| !is_finite_point(p)).filter(|run| !run.is_empty())
}

// ---------------------------------------------------------------------------------------------
// Drawing

pub(crate) type DrawResult = Result<(), Box<dyn Error + Send + Sync>>;

/// Register the embedded font once per process (every figure of the orchestrator uses it).
pub(crate) fn ensure_font() -> Result<(), ReportError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok());
    if ok { Ok(()) } else { Err(ReportError::Font) }
}

/// Smallest and largest finite value, if any.
pub(crate) fn finite_bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// A finite, non-empty axis range around `bounds` with 5 % margins.
pub(crate) fn linear_range(bounds: Option<(f64, f64)>) -> (f64, f64) {
    let Some((lo, hi)) = bounds else {
        return (0.0, 1.0);
    };
    // Keep the span finite so the coordinate maths cannot overflow.
    let (lo, hi) = (lo.max(-f64::MAX / 4.0), hi.min(f64::MAX / 4.0));
    let span = hi - lo;
    if span > 0.0 {
        let pad = span * 0.05;
        (lo - pad, hi + pad)
    } else {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        (lo - pad, hi + pad)
    }
}

pub(crate) fn format_tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.2e}");
        match s.split_once('e') {
            Some((mantissa, exponent)) => format!("{}e{exponent}", trim_zeros(mantissa)),
            None => s,
        }
    } else {
        trim_zeros(&format!("{v:.4}")).to_string()
    }
}

/// `"2.500"` → `"2.5"`, `"40.000"` → `"40"`.
fn trim_zeros(s: &str) -> &str {
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { s }
}

fn draw_time_figure(path: &Path, fig: &TimeFigure) -> DrawResult {
    let x_range = linear_range(finite_bounds(fig.series.iter().flat_map(|s| s.points.iter().map(|p| p.0))));
    let y_bounds = finite_bounds(fig.series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));

    let root = BitMapBackend::new(path, TIME_FIGURE_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&fig.title, (FONT_FAMILY, CAPTION_SIZE))
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA);
    match y_bounds {
        Some((lo, hi)) if lo > 0.0 && hi / lo > LOG_SCALE_RATIO => {
            let y_range = (lo / 1.5)..(hi * 1.5);
            let mut chart = builder.build_cartesian_2d(x_range.0..x_range.1, y_range.log_scale())?;
            let y_desc = format!("{} (log scale)", fig.y_desc);
            fill_time_chart(&mut chart, &y_desc, &fig.series)?;
        }
        _ => {
            let y_range = linear_range(y_bounds);
            let mut chart = builder.build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)?;
            fill_time_chart(&mut chart, &fig.y_desc, &fig.series)?;
        }
    }
    root.present()?;
    Ok(())
}

/// A line chart of named series against time, for reports other than a run's (the soak's).
pub(crate) fn draw_lines(
    path: &Path,
    title: &str,
    y_desc: &str,
    series: Vec<(String, Vec<(f64, f64)>)>,
) -> Result<(), String> {
    ensure_font().map_err(|e| e.to_string())?;
    let series = series
        .into_iter()
        .enumerate()
        .map(|(i, (label, points))| Series { label, color: series_color(None, i), points })
        .collect();
    let fig = TimeFigure { title: title.into(), y_desc: y_desc.into(), series };
    draw_time_figure(path, &fig).map_err(|e| format!("{}: {e}", path.display()))
}

fn fill_time_chart<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    y_desc: &str,
    series: &[Series],
) -> DrawResult
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    draw_time_series(chart, y_desc, series, 2)?;
    if series.len() > 1 {
        draw_legend(chart)?;
    }
    Ok(())
}

/// Axes, mesh and every series of a time chart (each with a legend entry; `stroke` in pixels).
fn draw_time_series<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    y_desc: &str,
    series: &[Series],
    stroke: u32,
) -> DrawResult
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc(y_desc)
        .x_label_formatter(&format_tick)
        .y_label_formatter(&format_tick)
        .label_style((FONT_FAMILY, 16))
        .axis_desc_style((FONT_FAMILY, 18))
        .draw()?;
    for s in series {
        let color = s.color;
        let style = color.stroke_width(stroke);
        // An empty series carries the legend entry; the runs are drawn unlabelled.
        chart
            .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), style))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
        for run in finite_runs(&s.points) {
            if let [p] = run {
                chart.draw_series(std::iter::once(Circle::new(*p, 2, color.filled())))?;
            } else {
                draw_polyline(chart, run, style)?;
            }
        }
    }
    Ok(())
}

/// The legend box, upper right (any chart: time series, trajectories, 3-D).
pub(crate) fn draw_legend<'a, 'b: 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, CT>,
) -> DrawResult {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT_FAMILY, 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// Draws `run` as separate two-point segments. Plotters turns a path wider than one pixel into
/// a single polygon, whose joins spike far outside the chart where the path zig-zags at pixel
/// scale (noisy data, min/max downsampling); lone segments have no joins.
fn draw_polyline<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    run: &[(f64, f64)],
    style: ShapeStyle,
) -> DrawResult
where
    Y: Ranged<ValueType = f64>,
{
    chart.draw_series(run.windows(2).map(|w| PathElement::new(vec![w[0], w[1]], style)))?;
    Ok(())
}

fn draw_xy_figure(path: &Path, fig: &XyFigure) -> DrawResult {
    let points = || fig.paths.iter().flat_map(|s| s.points.iter());
    let x = linear_range(finite_bounds(points().map(|p| p.0)));
    let y = linear_range(finite_bounds(points().map(|p| p.1)));
    // Equal scales on both axes: widen the narrower range to the plotting area's aspect ratio.
    let (w, h) = XY_FIGURE_SIZE;
    let plot_w = f64::from(w.saturating_sub(2 * MARGIN + Y_LABEL_AREA).max(1));
    let plot_h = f64::from(h.saturating_sub(2 * MARGIN + X_LABEL_AREA + 2 * CAPTION_SIZE).max(1));
    let scale = ((x.1 - x.0) / plot_w).max((y.1 - y.0) / plot_h);
    let widen = |(lo, hi): (f64, f64), px: f64| {
        let mid = lo / 2.0 + hi / 2.0;
        let half = scale * px / 2.0;
        if (mid - half).is_finite() && (mid + half).is_finite() { (mid - half, mid + half) } else { (lo, hi) }
    };
    let (x, y) = (widen(x, plot_w), widen(y, plot_h));

    let root = BitMapBackend::new(path, XY_FIGURE_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&fig.title, (FONT_FAMILY, CAPTION_SIZE))
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    chart
        .configure_mesh()
        .x_desc(&fig.x_desc)
        .y_desc(&fig.y_desc)
        .x_label_formatter(&format_tick)
        .y_label_formatter(&format_tick)
        .label_style((FONT_FAMILY, 16))
        .axis_desc_style((FONT_FAMILY, 18))
        .draw()?;
    for s in &fig.paths {
        let color = s.color;
        let style = color.stroke_width(2);
        chart
            .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), style))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
        for run in finite_runs(&s.points) {
            draw_polyline(&mut chart, run, style)?;
        }
        let finite = || s.points.iter().copied().filter(is_finite_point);
        if let Some(start) = finite().next() {
            chart.draw_series(std::iter::once(Circle::new(start, 6, color.filled())))?;
        }
        if let Some(end) = finite().next_back() {
            chart.draw_series(std::iter::once(Cross::new(end, 7, color.stroke_width(3))))?;
        }
    }
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fmt::Write as _;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// A scratch run directory, removed on drop.
    struct TempRun(PathBuf);

    impl TempRun {
        fn new(tag: &str) -> Self {
            static COUNTER: AtomicU32 = AtomicU32::new(0);
            let dir = std::env::temp_dir().join(format!(
                "cohort-report-{tag}-{}-{}",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(dir.join("telemetry")).unwrap();
            TempRun(dir)
        }

        fn write(&self, name: &str, contents: &str) -> PathBuf {
            let path = self.0.join("telemetry").join(name);
            std::fs::write(&path, contents).unwrap();
            path
        }
    }

    impl Drop for TempRun {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    const AXES: [&str; 3] = ["x", "y", "z"];

    /// A double-integrator run of `agents` agents converging onto a ring, `rows` rows.
    fn write_synthetic_run(run: &TempRun, agents: u32, rows: usize) {
        let dt = 0.1;
        let mut plant = String::from("k,t_s,formation_error_m");
        for i in 1..=agents {
            for q in ["r", "v"] {
                let unit = if q == "r" { "m" } else { "mps" };
                for a in AXES {
                    write!(plant, ",a{i}_{q}_{a}_{unit}").unwrap();
                }
            }
            for a in AXES {
                write!(plant, ",a{i}_u_{a}_mps2").unwrap();
            }
        }
        plant.push('\n');
        let mut agent_files: Vec<String> = (1..=agents)
            .map(|_| {
                "k,t_s,r_hat_x_m,r_hat_y_m,r_hat_z_m,v_hat_x_mps,v_hat_y_mps,v_hat_z_mps,\
                 u_x_mps2,u_y_mps2,u_z_mps2\n"
                    .to_string()
            })
            .collect();
        for k in 0..rows {
            let t = k as f64 * dt;
            let decay = (-0.05 * t).exp();
            // Falls over five decades, so its figure gets a log axis.
            write!(plant, "{k},{t:?},{:?}", 10.0 * (-0.25 * t).exp() + 1e-7).unwrap();
            for i in 1..=agents {
                let phase = f64::from(i) * std::f64::consts::TAU / f64::from(agents);
                let radius = 20.0 + 15.0 * decay * f64::from(i);
                let r =
                    [radius * (phase + 0.02 * t).cos(), radius * (phase + 0.02 * t).sin(), 0.5 * decay * f64::from(i)];
                let v = [
                    -0.02 * radius * (phase + 0.02 * t).sin(),
                    0.02 * radius * (phase + 0.02 * t).cos(),
                    -0.025 * decay * f64::from(i),
                ];
                let u = [-1e-3 * r[0], -1e-3 * r[1], 1e-4 * decay];
                for value in r.iter().chain(&v).chain(&u) {
                    write!(plant, ",{value:?}").unwrap();
                }
                let noise = 0.1 * (t * f64::from(i)).sin();
                let file = &mut agent_files[i as usize - 1];
                write!(file, "{k},{t:?}").unwrap();
                for value in r.iter().map(|x| x + noise).chain(v).chain(u) {
                    write!(file, ",{value:?}").unwrap();
                }
                file.push('\n');
            }
            plant.push('\n');
        }
        run.write("plant.csv", &plant);
        for (i, contents) in agent_files.iter().enumerate() {
            run.write(&format!("agent-{}.csv", i + 1), contents);
        }
    }

    fn file_names(paths: &[PathBuf]) -> Vec<String> {
        paths.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect()
    }

    /// With `COHORT_REPORT_KEEP=<dir>` set, copies the figures to `<dir>/<tag>/` to be looked at.
    fn keep_for_inspection(tag: &str, written: &[PathBuf]) {
        let Some(dir) = std::env::var_os("COHORT_REPORT_KEEP") else {
            return;
        };
        let dir = PathBuf::from(dir).join(tag);
        std::fs::create_dir_all(&dir).unwrap();
        for path in written {
            std::fs::copy(path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }

    fn assert_png(path: &Path) {
        let bytes = std::fs::read(path).unwrap();
        assert!(bytes.len() > 1024, "{} is only {} bytes", path.display(), bytes.len());
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", path.display());
    }

    #[test]
    fn plots_a_double_integrator_run() {
        let run = TempRun::new("ok");
        write_synthetic_run(&run, 3, 600);
        let written = report(&run.0).unwrap();
        assert_eq!(
            file_names(&written),
            [
                "plant_formation_error.png",
                "plant_r.png",
                "plant_v.png",
                "plant_u.png",
                "trajectories_xy.png",
                "agents_r_hat.png",
                "agents_v_hat.png",
                "agents_u.png",
            ]
        );
        for path in &written {
            assert_eq!(path.parent().unwrap(), run.0.join("plots"));
            assert_png(path);
        }
        keep_for_inspection("double_integrator", &written);
    }

    #[test]
    fn long_runs_are_downsampled_and_still_plotted() {
        let run = TempRun::new("long");
        write_synthetic_run(&run, 2, 12_000);
        let written = report(&run.0).unwrap();
        assert_eq!(written.len(), 8);
        written.iter().for_each(|p| assert_png(p));
        keep_for_inspection("long", &written);
    }

    #[test]
    fn odd_values_and_empty_files_do_not_panic() {
        let run = TempRun::new("odd");
        run.write(
            "plant.csv",
            "k,t_s,formation_error_m,a1_r_x_m,a1_r_y_m,mystery\n\
             0,0.0,NaN,1e308,-1e308,5\n\
             1,0.1,inf,-inf,NaN,5\n\
             2,0.2,1.0,0.0,0.0,5\n\
             \n\
             3,0.3,-2.5,1.0,1.0,5\r\n",
        );
        run.write("agent-1.csv", "k,t_s,u_x_mps2,u_y_mps2\n");
        run.write("agent-2.csv", "k,t_s,u_x_mps2,u_y_mps2\n0,0.0,NaN,NaN\n");
        let written = report(&run.0).unwrap();
        assert_eq!(
            file_names(&written),
            ["plant_formation_error.png", "plant_r.png", "plant_mystery.png", "trajectories_xy.png", "agents_u.png",]
        );
        written.iter().for_each(|p| assert_png(p));
        keep_for_inspection("odd", &written);
    }

    #[test]
    fn bad_number_names_file_line_and_column() {
        let run = TempRun::new("badnum");
        let path = run.write("plant.csv", "k,t_s,formation_error_m,a1_r_x_m\n0,0.0,1.0,2.0\n1,0.1,1.0e,2.0\n");
        let err = report(&run.0).unwrap_err();
        match &err {
            ReportError::BadNumber { path: p, line, column, value } => {
                assert_eq!(p, &path);
                assert_eq!(*line, 3);
                assert_eq!(column, "formation_error_m");
                assert_eq!(value, "1.0e");
            }
            other => panic!("expected BadNumber, got {other:?}"),
        }
        let msg = err.to_string();
        assert!(msg.contains("plant.csv:3"), "{msg}");
        assert!(msg.contains("formation_error_m"), "{msg}");
        assert!(msg.contains("\"1.0e\""), "{msg}");
        assert!(!run.0.join("plots").exists(), "no plots after a read error");
    }

    #[test]
    fn bad_step_number_is_reported_against_k() {
        let run = TempRun::new("badk");
        run.write("agent-4.csv", "k,t_s,u_x_mps2\n0.5,0.0,1.0\n");
        let err = report(&run.0).unwrap_err();
        assert!(matches!(&err, ReportError::BadNumber { line: 2, column, .. } if column == "k"), "{err:?}");
        assert!(err.to_string().contains("agent-4.csv:2"), "{err}");
    }

    #[test]
    fn wrong_column_count_names_file_and_line() {
        let run = TempRun::new("cols");
        write_synthetic_run(&run, 2, 5);
        let path = run.write("agent-2.csv", "k,t_s,u_x_mps2,u_y_mps2\n0,0.0,1.0,2.0\n1,0.1,1.0\n");
        let err = report(&run.0).unwrap_err();
        match &err {
            ReportError::ColumnCount { path: p, line, expected, found } => {
                assert_eq!(p, &path);
                assert_eq!((*line, *expected, *found), (3, 4, 3));
            }
            other => panic!("expected ColumnCount, got {other:?}"),
        }
        let msg = err.to_string();
        assert!(msg.contains("agent-2.csv:3"), "{msg}");
        assert!(msg.contains("expected 4 columns"), "{msg}");
    }

    #[test]
    fn missing_telemetry_dir_is_reported() {
        let run = TempRun::new("missing");
        std::fs::remove_dir_all(run.0.join("telemetry")).unwrap();
        let err = report(&run.0).unwrap_err();
        assert!(matches!(err, ReportError::MissingTelemetryDir { .. }), "{err:?}");
        let msg = err.to_string();
        assert!(msg.contains(&run.0.join("telemetry").display().to_string()), "{msg}");
    }

    #[test]
    fn empty_telemetry_dir_is_reported() {
        let run = TempRun::new("empty");
        let err = report(&run.0).unwrap_err();
        assert!(matches!(err, ReportError::NoTelemetry { .. }), "{err:?}");
    }

    #[test]
    fn bad_headers_are_reported() {
        for (contents, needle) in [
            ("", "empty"),
            ("t_s,k,x_m\n", "`k,t_s`"),
            ("k\n", "`k,t_s`"),
            ("k,t_s,x_m,x_m\n", "duplicate column `x_m`"),
            ("k,t_s,,x_m\n", "column 3 has an empty name"),
        ] {
            let run = TempRun::new("header");
            run.write("plant.csv", contents);
            let err = report(&run.0).unwrap_err();
            assert!(matches!(err, ReportError::BadHeader { .. }), "{err:?}");
            let msg = err.to_string();
            assert!(msg.contains("plant.csv: bad header"), "{msg}");
            assert!(msg.contains(needle), "{msg} lacks {needle}");
        }
    }

    #[test]
    fn column_names_are_split_into_owner_name_axis_unit() {
        let parse = |s, owner| parse_column_name(s, owner);
        let cn = |owner, name: &str, axis, unit: Option<&str>| ColumnName {
            owner,
            name: name.to_string(),
            axis,
            unit: unit.map(str::to_string),
        };
        assert_eq!(parse("a12_r_x_m", true), cn(Some(12), "r", Some('x'), Some("m")));
        assert_eq!(parse("a12_r_x_m", false), cn(None, "a12_r", Some('x'), Some("m")));
        assert_eq!(parse("r_hat_z_m", false), cn(None, "r_hat", Some('z'), Some("m")));
        assert_eq!(parse("u_y_mps2", false), cn(None, "u", Some('y'), Some("mps2")));
        assert_eq!(parse("formation_error_m", true), cn(None, "formation_error", None, Some("m")));
        assert_eq!(parse("u_x", true), cn(None, "u", Some('x'), None));
        assert_eq!(parse("x_m", true), cn(None, "x", None, Some("m")));
        assert_eq!(parse("mystery", true), cn(None, "mystery", None, None));
        assert_eq!(parse("a_b", true), cn(None, "a_b", None, None));
        assert_eq!(parse("a1_", true), cn(None, "a1_", None, None));
    }

    #[test]
    fn lone_axis_columns_are_scalars() {
        let table = Table {
            t: vec![0.0],
            columns: ["r_x_m", "v_x_mps", "v_y_mps"]
                .iter()
                .map(|n| Column { name: n.to_string(), values: vec![3.0] })
                .collect(),
        };
        let qs = classify_columns(&table, Some(2));
        assert_eq!(qs.len(), 2);
        assert_eq!((qs[0].name.as_str(), qs[0].is_vector()), ("r_x", false));
        assert_eq!((qs[1].name.as_str(), qs[1].is_vector()), ("v", true));
        assert_eq!(qs[1].owner, Some(2));
        assert_eq!(qs[1].values(&table), vec![(18.0f64).sqrt()]);
    }

    #[test]
    fn min_max_downsampling_bounds_points_and_keeps_extremes() {
        let n = 36_000;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.01).sin()).collect();
        y[12_345] = 50.0;
        y[20_000] = -50.0;
        let out = downsample_min_max(&x, &y, MAX_POINTS);
        assert!(out.len() <= MAX_POINTS, "{}", out.len());
        assert!(out.contains(&(12_345.0, 50.0)));
        assert!(out.contains(&(20_000.0, -50.0)));
        assert!(out.windows(2).all(|w| w[0].0 < w[1].0), "x stays in order");

        y[30_000] = f64::NAN;
        let out = downsample_min_max(&x, &y, MAX_POINTS);
        assert_eq!(out.iter().filter(|p| !is_finite_point(p)).count(), 1);
        assert_eq!(finite_runs(&out).count(), 2);

        let short = downsample_min_max(&x[..10], &y[..10], MAX_POINTS);
        assert_eq!(short.len(), 10);
    }

    #[test]
    fn stride_downsampling_keeps_first_and_last() {
        let n = 36_001;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let out = downsample_stride(&x, &x, MAX_POINTS);
        assert!(out.len() <= MAX_POINTS + 1, "{}", out.len());
        assert_eq!(out.first(), Some(&(0.0, 0.0)));
        assert_eq!(out.last(), Some(&(36_000.0, 36_000.0)));
        assert!(downsample_stride(&[], &[], MAX_POINTS).is_empty());
    }

    /// A run shaped like the seed-000 servicing scenario: `servicers` servicers closing on a
    /// defunct spacecraft, `rows` rows `dt` seconds apart. `plant.csv` has per-body ECI and LVLH
    /// columns and per-agent `e_norm`, `zeta`, `u`; `agent-<i>.csv` has `zeta_hat` and
    /// `theta_norm`; with `derived`, `derived/fig1.csv` is computed from them the way the
    /// orchestrator does. Returns the path of `derived/fig1.csv`.
    fn write_fig1_run(run: &TempRun, servicers: u32, rows: usize, dt: f64, derived: bool) -> PathBuf {
        let mut plant = String::from("k,t_s");
        for b in 0..=servicers {
            for q in ["r_eci", "v_eci", "q_lvlh"] {
                let unit = if q == "v_eci" { "mps" } else { "m" };
                for a in AXES {
                    write!(plant, ",b{b}_{q}_{a}_{unit}").unwrap();
                }
            }
        }
        for i in 1..=servicers {
            write!(plant, ",a{i}_e_norm_m").unwrap();
            for q in ["zeta", "u"] {
                let unit = if q == "zeta" { "mps" } else { "mps2" };
                for a in AXES {
                    write!(plant, ",a{i}_{q}_{a}_{unit}").unwrap();
                }
            }
        }
        plant.push('\n');
        let mut agents: Vec<String> = (1..=servicers)
            .map(|_| {
                "k,t_s,u_x_mps2,u_y_mps2,u_z_mps2,theta_norm,zeta_hat_x_mps,zeta_hat_y_mps,zeta_hat_z_mps\n".into()
            })
            .collect();
        let mut fig1 = String::from("k,t_s");
        for i in 1..=servicers {
            write!(fig1, ",a{i}_e_norm_m,a{i}_zeta_err_norm_mps,a{i}_u_norm_mps2,a{i}_theta_norm").unwrap();
        }
        fig1.push('\n');
        let norm = |v: [f64; 3]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
        for k in 0..rows {
            let t = k as f64 * dt;
            write!(plant, "{k},{t:?}").unwrap();
            write!(fig1, "{k},{t:?}").unwrap();
            let q0 = [-0.004 * t * t, 0.01 * t, 0.0];
            let q: Vec<[f64; 3]> = (0..=servicers)
                .map(|b| {
                    if b == 0 {
                        return q0;
                    }
                    let phase = f64::from(b) * 2.0;
                    let size = 3000.0 * (-t / 40.0).exp() + 2.0 + (0.3 * t + phase).sin();
                    [q0[0] + size * phase.cos(), q0[1] + size * phase.sin(), q0[2] + 0.4 * size]
                })
                .collect();
            for qb in &q {
                let r = [6.678e6 + qb[0], qb[1], qb[2]];
                let v = [0.0, 7.7e3, 0.1 * qb[2]];
                for value in r.iter().chain(&v).chain(qb) {
                    write!(plant, ",{value:?}").unwrap();
                }
            }
            for i in 1..=servicers {
                let e = norm([0, 1, 2].map(|a| q[i as usize][a] - q0[a]));
                let zeta = [10.0 * (0.1 * t).cos(), 3.0, -1.0];
                let err = 1e4 * (-t / 5.0).exp() + 0.5 * (t * f64::from(i)).sin().abs();
                let zeta_hat = [zeta[0] - err, zeta[1], zeta[2]];
                // One exact zero for the log axis to floor.
                let u = if k == 3 { [0.0; 3] } else { [-0.01 * e, 1e-3, 2e-3 * (t / 7.0).sin()] };
                let theta = 6.0 + 0.01 * t;
                write!(plant, ",{e:?}").unwrap();
                for value in zeta.iter().chain(&u) {
                    write!(plant, ",{value:?}").unwrap();
                }
                let file = &mut agents[i as usize - 1];
                write!(file, "{k},{t:?}").unwrap();
                for value in u.iter().chain([&theta]).chain(&zeta_hat) {
                    write!(file, ",{value:?}").unwrap();
                }
                file.push('\n');
                let zeta_err = norm([0, 1, 2].map(|a| zeta[a] - zeta_hat[a]));
                // One NaN, a gap in the line.
                let e_out = if k == 5 && i == 1 { f64::NAN } else { e };
                write!(fig1, ",{e_out:?},{zeta_err:?},{:?},{theta:?}", norm(u)).unwrap();
            }
            plant.push('\n');
            fig1.push('\n');
        }
        run.write("plant.csv", &plant);
        for (i, contents) in agents.iter().enumerate() {
            run.write(&format!("agent-{}.csv", i + 1), contents);
        }
        let derived_path = run.0.join("derived").join("fig1.csv");
        if derived {
            std::fs::create_dir_all(derived_path.parent().unwrap()).unwrap();
            std::fs::write(&derived_path, fig1).unwrap();
        }
        derived_path
    }

    const FIG1_FIGURES: [&str; 5] = [
        "fig2_trajectories_3d.png",
        "fig3_zeta_error.png",
        "fig4_tracking_error.png",
        "fig4_tracking_error_late.png",
        "u_norm.png",
    ];

    #[test]
    fn fig1_run_gets_the_paper_figures() {
        let run = TempRun::new("fig1");
        write_fig1_run(&run, 2, 73, 5.0, true);
        let written = report(&run.0).unwrap();
        let names = file_names(&written);
        assert_eq!(names[..5], FIG1_FIGURES, "{names:?}");
        // The generic figures stay, but not the per-body ECI/LVLH ones.
        assert_eq!(
            names[5..],
            [
                "plant_e_norm.png",
                "plant_zeta.png",
                "plant_u.png",
                "agents_u.png",
                "agents_theta_norm.png",
                "agents_zeta_hat.png"
            ]
        );
        written.iter().for_each(|p| assert_png(p));
        keep_for_inspection("fig1", &written);
    }

    #[test]
    fn short_fig1_run_still_gets_every_figure() {
        // 20 s: shorter than Fig. 2's window and than the late view's 150 s start.
        let run = TempRun::new("fig1short");
        write_fig1_run(&run, 2, 5, 5.0, true);
        let written = report(&run.0).unwrap();
        assert_eq!(file_names(&written)[..5], FIG1_FIGURES);
        written.iter().for_each(|p| assert_png(p));
    }

    #[test]
    fn without_derived_fig1_csv_only_generic_plots() {
        let run = TempRun::new("nofig1");
        write_fig1_run(&run, 2, 20, 5.0, false);
        let names = file_names(&report(&run.0).unwrap());
        for fig in FIG1_FIGURES {
            assert!(!names.iter().any(|n| n == fig), "{fig} in {names:?}");
        }
        // Unchanged behaviour: every plant column family gets its generic figure.
        assert!(names.iter().any(|n| n == "plant_b0_r_eci.png"), "{names:?}");
        assert!(names.iter().any(|n| n == "plant_b2_q_lvlh.png"), "{names:?}");
        assert!(names.iter().any(|n| n == "plant_e_norm.png"), "{names:?}");
    }

    #[test]
    fn malformed_derived_fig1_csv_names_file_and_line() {
        let run = TempRun::new("fig1bad");
        let derived = write_fig1_run(&run, 2, 10, 5.0, true);
        let good = std::fs::read_to_string(&derived).unwrap();
        let mut lines: Vec<String> = good.lines().map(str::to_string).collect();

        // A bad number on line 4 (the header is line 1).
        let mut bad = lines.clone();
        bad[3] = bad[3].replacen(",", ",x", 2).replacen(",x", ",", 1);
        std::fs::write(&derived, bad.join("\n")).unwrap();
        let err = report(&run.0).unwrap_err();
        assert!(matches!(&err, ReportError::BadNumber { path, line: 4, .. } if *path == derived), "{err:?}");
        let msg = err.to_string();
        assert!(msg.contains("derived/fig1.csv:4"), "{msg}");
        assert!(!run.0.join("plots").exists(), "no plots after a read error");

        // A short row.
        let mut short = lines.clone();
        short[6] = short[6].rsplit_once(',').unwrap().0.to_string();
        std::fs::write(&derived, short.join("\n")).unwrap();
        let msg = report(&run.0).unwrap_err().to_string();
        assert!(msg.contains("derived/fig1.csv:7: expected 10 columns"), "{msg}");

        // A missing column.
        for line in &mut lines {
            *line = line.rsplitn(3, ',').nth(2).unwrap().to_string();
        }
        assert!(lines[0].ends_with("a2_zeta_err_norm_mps"), "{}", lines[0]);
        std::fs::write(&derived, lines.join("\n")).unwrap();
        let err = report(&run.0).unwrap_err();
        assert!(matches!(&err, ReportError::Fig1Input { path, .. } if *path == derived), "{err:?}");
        let msg = err.to_string();
        assert!(msg.contains("derived/fig1.csv: missing column `a2_u_norm_mps2`"), "{msg}");

        // No agents at all; an empty file.
        std::fs::write(&derived, "k,t_s,theta\n0,0.0,1.0\n").unwrap();
        let msg = report(&run.0).unwrap_err().to_string();
        assert!(msg.contains("derived/fig1.csv: no `a<i>_e_norm_m` columns"), "{msg}");
        std::fs::write(&derived, "").unwrap();
        let msg = report(&run.0).unwrap_err().to_string();
        assert!(msg.contains("derived/fig1.csv: bad header"), "{msg}");
        assert!(!run.0.join("plots").exists(), "no plots after a read error");
    }

    #[test]
    fn fig1_run_needs_the_lvlh_columns() {
        let run = TempRun::new("fig1nolvlh");
        write_fig1_run(&run, 2, 10, 5.0, true);
        let plant = run.0.join("telemetry").join("plant.csv");
        std::fs::write(&plant, "k,t_s,a1_e_norm_m\n0,0.0,1.0\n").unwrap();
        let err = report(&run.0).unwrap_err();
        assert!(matches!(&err, ReportError::Fig1Input { path, .. } if *path == plant), "{err:?}");
        assert!(err.to_string().contains("q_lvlh"), "{err}");
        std::fs::remove_file(&plant).unwrap();
        let msg = report(&run.0).unwrap_err().to_string();
        assert!(msg.contains("plant.csv: missing"), "{msg}");
    }

    #[test]
    fn column_filter_skips_unparsed_columns() {
        let run = TempRun::new("filter");
        let path = run.write("plant.csv", "k,t_s,b0_r_eci_x_m,b0_q_lvlh_x_m,a1_e_norm_m\n0,0.0,junk,1.0,2.0\n");
        let table = read_table_with(&path, &|name| !name.contains("eci")).unwrap();
        let names: Vec<&str> = table.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["b0_q_lvlh_x_m", "a1_e_norm_m"]);
        assert_eq!(table.columns[1].values, [2.0]);
        assert!(read_table(&path).is_err(), "the full read still checks every field");
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(format_tick(&0.0), "0");
        assert_eq!(format_tick(&2.5), "2.5");
        assert_eq!(format_tick(&-40.0), "-40");
        assert_eq!(format_tick(&0.0012), "0.0012");
        assert_eq!(format_tick(&1e-7), "1e-7");
        assert_eq!(format_tick(&-2.5e-4), "-2.5e-4");
        assert_eq!(format_tick(&250_000.0), "2.5e5");
        assert_eq!(format_tick(&123_456_789.0), "1.23e8");
    }
}
