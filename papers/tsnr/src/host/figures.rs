//! The figures of seed 001, the tethered space net robot (Ma et al., Sec. 4), for runs of the
//! `tsnr-net` plant:
//!
//! * `tsnr_tension.png` — Figs. 8/9: one panel per MU (2 × 2), the tension the MU's controller
//!   assumed for t_k (`tension_used_{x,y,z}_n` of `agent-<i>.csv`: for AEMC with the DNN forecast,
//!   the prediction made from data up to t_{k−1}; `tension_meas_*` for a controller that keeps no
//!   such column, SMC) dashed, over the plant's true tension on that MU (`mu<i>_tension_{x,y,z}_n`
//!   of `plant.csv`) solid, per LVLH axis; the panel title gives the RMS of ‖used − true‖;
//! * `tsnr_net_3d.png` — the net at each time of `snapshots/net_nodes.csv` (0, 10, 20, 30 s): its
//!   mesh edges (grid neighbours) in one colour per time, the MU corners marked and numbered, the
//!   MUs' paths from `plant.csv` and the target at [`TARGET_LVLH_M`], equal scales on all axes;
//! * [`draw_comparison`] (for `orchestrator tsnr compare`): Figs. 10/11, MU 1's position tracking
//!   error per axis for several methods' runs, `tsnr_err_mu1.png`.
//!
//! [`TsnrFigures`] gives the first two to the report whenever their inputs exist.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use cohort_report::chart::{
    CAPTION_SIZE, DrawResult, FONT_FAMILY, MARGIN, MAX_POINTS, Series, X_LABEL_AREA, Y_LABEL_AREA, downsample_min_max,
    draw_legend, ensure_font, finite_bounds, format_tick, linear_range, series_color,
};
use cohort_report::{FigureSource, PaperFigure, ReportError, Table, Telemetry};
use cohort_runtime::paper::Setup;

use crate::config::formation::{Method, TsnrFormation};

/// The plant's node snapshots, relative to the run directory.
pub(crate) const SNAPSHOT_FILE: &str = "snapshots/net_nodes.csv";
pub(crate) const TENSION_STEM: &str = "tsnr_tension";
pub(crate) const NET_STEM: &str = "tsnr_net_3d";
/// File stem (in `<dir>/plots/`) of the figure [`draw_comparison`] writes.
pub const COMPARISON_STEM: &str = "tsnr_err_mu1";
/// papers/tsnr/README.md: the target sits at [5, 0, 0] m in the LVLH frame.
const TARGET_LVLH_M: [f64; 3] = [5.0, 0.0, 0.0];
/// The paper (Sec. 4): the net is fully deployed at 10 s, the sudden change in tension where
/// DMPC and SMC peak and AEMC does not.
const DEPLOYED_AT_S: f64 = 10.0;
const AXES: [char; 3] = ['x', 'y', 'z'];
const AXIS_NAMES: [&str; 3] = ["x (radial)", "y (along-track)", "z (cross-track)"];
/// Header of `snapshots/net_nodes.csv`, as the `tsnr-net` plant writes it.
const SNAPSHOT_COLUMNS: [&str; 7] = ["t_s", "node", "grid_row", "grid_col", "r_lvlh_x_m", "r_lvlh_y_m", "r_lvlh_z_m"];
/// Agent and plant rows of one step carry the same k·Δt; closer than this they are one step, s.
const SAME_STEP_S: f64 = 1e-9;

const TENSION_FIGURE_SIZE: (u32, u32) = (1500, 1050);
const COMPARISON_FIGURE_SIZE: (u32, u32) = (1300, 1250);
const NET_FIGURE_SIZE: (u32, u32) = (1200, 1100);
/// Height of the key drawn under a multi-panel figure's title, px.
const KEY_HEIGHT: u32 = 36;
const KEY_FONT_SIZE: u32 = 17;
const PANEL_CAPTION_SIZE: u32 = 19;
/// 3-D view (radians): turned about the vertical axis, then tipped towards the viewer (see
/// [`draw_net`]).
const VIEW_YAW: f64 = 0.95;
const VIEW_PITCH: f64 = 0.3;
const VIEW_SCALE: f64 = 0.75;

/// A figure of a tsnr run, drawn by [`TsnrFigure::draw`].
#[derive(Debug)]
pub(crate) enum TsnrFigure {
    Tension(TensionFigure),
    Net(NetFigure),
}

impl TsnrFigure {
    pub(crate) fn draw(&self, path: &Path) -> DrawResult {
        match self {
            TsnrFigure::Tension(fig) => draw_tension(path, fig),
            TsnrFigure::Net(fig) => draw_net(path, fig),
        }
    }
}

#[derive(Debug)]
pub(crate) struct TensionFigure {
    title: String,
    panels: Vec<TensionPanel>,
    /// What the dashed lines are, for the key.
    controller_desc: String,
}

/// One MU: `truth` and `controller` hold one series per axis (`controller` empty when the
/// agent's telemetry has no tension columns).
#[derive(Debug)]
struct TensionPanel {
    caption: String,
    truth: Vec<Series>,
    controller: Vec<Series>,
}

#[derive(Debug)]
pub(crate) struct NetFigure {
    title: String,
    snapshots: Vec<DrawnSnapshot>,
    /// (MU id, LVLH positions in m) from `plant.csv`; non-finite points split a path.
    mu_paths: Vec<(u32, Vec<[f64; 3]>)>,
}

/// One snapshot ready to draw: LVLH positions, m.
#[derive(Debug)]
struct DrawnSnapshot {
    t_s: f64,
    color: RGBColor,
    edges: Vec<[[f64; 3]; 2]>,
    corners: Vec<(u32, [f64; 3])>,
}

/// One line of `snapshots/net_nodes.csv`: a node's grid place and LVLH position, m.
#[derive(Debug, Clone, PartialEq)]
struct NetNode {
    row: usize,
    col: usize,
    r_m: [f64; 3],
}

/// Every node of the net at one time.
#[derive(Debug, Clone, PartialEq)]
struct NetSnapshot {
    t_s: f64,
    nodes: Vec<NetNode>,
}

/// The run's figures for the report: see the module docs. `label` ("scenario, method[,
/// forecast]") goes into the titles.
pub struct TsnrFigures {
    pub label: Option<String>,
}

impl TsnrFigures {
    pub fn of(setup: &Setup) -> Self {
        Self { label: Some(run_label(setup)) }
    }
}

impl FigureSource for TsnrFigures {
    fn figures(&self, t: &Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError> {
        let figures = figures(t.run_dir, t.plant, t.agents, self.label.as_deref())?;
        Ok(figures.into_iter().map(|(stem, fig)| Box::new(Named(stem, fig)) as Box<dyn PaperFigure>).collect())
    }
}

struct Named(String, TsnrFigure);

impl PaperFigure for Named {
    fn stem(&self) -> &str {
        &self.0
    }
    fn draw(&self, path: &Path) -> DrawResult {
        self.1.draw(path)
    }
}

/// The tsnr figures of the run in `run_dir` (named by stem): the tension figure when `plant`
/// (`plant.csv`) has `mu<i>_tension_{x,y,z}_n` columns, the 3-D net when `snapshots/net_nodes.csv`
/// exists. None for another kind of run. Fails, naming the file and line, on a malformed
/// snapshot file.
pub(crate) fn figures(
    run_dir: &Path,
    plant: Option<&Table>,
    agents: &[(u32, Table)],
    label: Option<&str>,
) -> Result<Vec<(String, TsnrFigure)>, ReportError> {
    let tension_plant = plant.filter(|p| !mu_ids(p, "tension", "n").is_empty());
    let snapshot_path = run_dir.join(SNAPSHOT_FILE);
    let has_snapshots = snapshot_path.is_file();
    if tension_plant.is_none() && !has_snapshots {
        return Ok(Vec::new());
    }
    let mut out = Vec::new();
    if let Some(plant) = tension_plant {
        out.push((TENSION_STEM.to_string(), TsnrFigure::Tension(tension_figure(plant, agents, label))));
    }
    if has_snapshots {
        let text = std::fs::read_to_string(&snapshot_path)
            .map_err(|error| ReportError::Io { path: snapshot_path.clone(), error })?;
        let snapshots = parse_snapshots(&text, &snapshot_path)?;
        let mu_paths = plant.map(mu_paths).unwrap_or_default();
        out.push((NET_STEM.to_string(), TsnrFigure::Net(net_figure(&snapshots, mu_paths, label))));
    }
    Ok(out)
}

/// "scenario, method[, forecast]", for titles.
fn run_label(s: &Setup) -> String {
    let mut label = s.scenario.name.clone();
    if let Some(a) = s.algorithm_as::<TsnrFormation>() {
        label.push_str(&format!(", {}", a.method.name()));
        // The forecast setting is AEMC's alone (the schema's `tension_forecast`).
        if a.method == Method::Aemc
            && let Some(m) = &a.mpc
        {
            label.push_str(&format!(", {} tension forecast", m.tension_forecast.name()));
        }
    }
    label
}

fn column<'t>(table: &'t Table, name: &str) -> Option<&'t [f64]> {
    table.columns.iter().find(|c| c.name == name).map(|c| c.values.as_slice())
}

/// The three axis columns `<prefix>_{x,y,z}_<unit>`, if all exist.
fn axis_columns<'t>(table: &'t Table, prefix: &str, unit: &str) -> Option<[&'t [f64]; 3]> {
    let [x, y, z] = AXES.map(|a| column(table, &format!("{prefix}_{a}_{unit}")));
    Some([x?, y?, z?])
}

/// One series per axis, `"<who> T_<axis>"`, of a tension's three columns.
fn xyz_series(who: &str, t: &[f64], cols: &[&[f64]; 3]) -> Vec<Series> {
    (0..3)
        .map(|a| Series {
            label: format!("{who} T_{}", AXES[a]),
            color: axis_color(a),
            points: downsample_min_max(t, cols[a], MAX_POINTS),
        })
        .collect()
}

/// The MU ids `i` of a plant table with all three `mu<i>_<quantity>_{x,y,z}_<unit>`, ascending.
fn mu_ids(table: &Table, quantity: &str, unit: &str) -> Vec<u32> {
    let mut ids: Vec<u32> = table
        .columns
        .iter()
        .filter_map(|c| {
            let (prefix, _) = c.name.split_once('_')?;
            let digits = prefix.strip_prefix("mu")?;
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                return None;
            }
            digits.parse().ok()
        })
        .filter(|&i| axis_columns(table, &format!("mu{i}_{quantity}"), unit).is_some())
        .collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// Colour of LVLH axis `axis` (0, 1, 2) in the per-axis figures.
fn axis_color(axis: usize) -> RGBColor {
    series_color(None, axis)
}

fn tension_figure(plant: &Table, agents: &[(u32, Table)], label: Option<&str>) -> TensionFigure {
    let mut uses_forecast = false;
    let mut uses_measured = false;
    let panels = mu_ids(plant, "tension", "n")
        .into_iter()
        .map(|i| {
            let truth_cols = axis_columns(plant, &format!("mu{i}_tension"), "n").unwrap_or([&[]; 3]);
            let truth = xyz_series("true", &plant.t, &truth_cols);
            let agent = agents.iter().find(|(id, _)| *id == i).map(|(_, t)| t);
            // Controllers without a forecast (SMC) compensate the measured tension: that is what
            // they used.
            let used = agent.and_then(|t| {
                let forecast = axis_columns(t, "tension_used", "n").map(|c| (t, c, true));
                forecast.or_else(|| axis_columns(t, "tension_meas", "n").map(|c| (t, c, false)))
            });
            let (controller, caption) = match used {
                Some((table, cols, forecast)) => {
                    uses_forecast |= forecast;
                    uses_measured |= !forecast;
                    let controller = xyz_series("controller", &table.t, &cols);
                    let what = if forecast { "used" } else { "measured" };
                    let caption = match rms_vector_difference(&table.t, &cols, &plant.t, &truth_cols) {
                        Some(rms_n) => format!("MU {i} — RMS ‖{what} − true‖ = {} N", format_tick(&rms_n)),
                        None => format!("MU {i} — no step in common with plant.csv"),
                    };
                    (controller, caption)
                }
                None => (Vec::new(), format!("MU {i} — no tension columns in agent-{i}.csv: true tension only")),
            };
            TensionPanel { caption, truth, controller }
        })
        .collect();
    let controller_desc = match (uses_forecast, uses_measured) {
        (true, false) => "dashed: tension the controller used for t_k",
        (false, true) => "dashed: measured tension (the controller's)",
        _ => "dashed: tension the controller used (else measured)",
    };
    let mut title = "Figs. 8/9 analogue — net tension on each MU, controller's vs true".to_string();
    if let Some(label) = label {
        title.push_str(&format!(" ({label})"));
    }
    TensionFigure { title, panels, controller_desc: controller_desc.to_string() }
}

/// √(mean over common steps of ‖a − b‖²) for two 3-axis series `a` (at times `t_a`) and `b` (at
/// `t_b`), both in time order; rows are paired where their times agree within [`SAME_STEP_S`]
/// and every component is finite. `None` if no row pairs.
fn rms_vector_difference(t_a: &[f64], a: &[&[f64]; 3], t_b: &[f64], b: &[&[f64]; 3]) -> Option<f64> {
    let rows_a = a.iter().map(|c| c.len()).fold(t_a.len(), usize::min);
    let rows_b = b.iter().map(|c| c.len()).fold(t_b.len(), usize::min);
    let (mut j, mut sum, mut n) = (0, 0.0, 0usize);
    for i in 0..rows_a {
        if !t_a[i].is_finite() {
            continue;
        }
        // Past b's earlier steps and any NaN time.
        while j < rows_b && (t_b[j].is_nan() || t_b[j] < t_a[i] - SAME_STEP_S) {
            j += 1;
        }
        if j == rows_b {
            break;
        }
        if (t_b[j] - t_a[i]).abs() > SAME_STEP_S {
            continue;
        }
        let d2: f64 = (0..3).map(|ax| (a[ax][i] - b[ax][j]).powi(2)).sum();
        if d2.is_finite() {
            sum += d2;
            n += 1;
        }
    }
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// Parses `snapshots/net_nodes.csv` (`text`, read from `path`): its header must name
/// [`SNAPSHOT_COLUMNS`] (any order); grid places and node numbers are non-negative integers, times
/// finite, positions numbers (a non-finite one drops the node's edges); a grid place appears at
/// most once per time. Snapshots come out in time order.
fn parse_snapshots(text: &str, path: &Path) -> Result<Vec<NetSnapshot>, ReportError> {
    let fail = |line: Option<usize>, reason: String| ReportError::PaperInput { path: path.to_path_buf(), line, reason };
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end_matches('\r')));
    let Some((_, header)) = lines.next() else {
        return Err(fail(None, "the file is empty".to_string()));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut at = [0usize; SNAPSHOT_COLUMNS.len()];
    for (slot, wanted) in at.iter_mut().zip(SNAPSHOT_COLUMNS) {
        let mut found = names.iter().enumerate().filter(|(_, n)| **n == wanted).map(|(i, _)| i);
        match (found.next(), found.next()) {
            (Some(i), None) => *slot = i,
            (None, _) => return Err(fail(Some(1), format!("bad header: no column `{wanted}`"))),
            (Some(_), Some(_)) => return Err(fail(Some(1), format!("bad header: duplicate column `{wanted}`"))),
        }
    }
    let mut snapshots: Vec<NetSnapshot> = Vec::new();
    let mut seen: HashMap<(u64, usize, usize), usize> = HashMap::new();
    for (line_no, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(fail(
                Some(line_no),
                format!("expected {} columns (as in the header), found {}", names.len(), fields.len()),
            ));
        }
        let field = |c: usize| (SNAPSHOT_COLUMNS[c], fields[at[c]]);
        let number = |c: usize| {
            let (name, value) = field(c);
            value.parse::<f64>().map_err(|_| fail(Some(line_no), format!("column `{name}`: {value:?} is not a number")))
        };
        let index = |c: usize| {
            let (name, value) = field(c);
            value
                .parse::<usize>()
                .map_err(|_| fail(Some(line_no), format!("column `{name}`: {value:?} is not a non-negative integer")))
        };
        let t_s = number(0)?;
        if !t_s.is_finite() {
            return Err(fail(Some(line_no), format!("column `t_s`: {t_s} is not a finite time")));
        }
        index(1)?;
        let (row, col) = (index(2)?, index(3)?);
        let r_m = [number(4)?, number(5)?, number(6)?];
        if let Some(first) = seen.insert((t_s.to_bits(), row, col), line_no) {
            return Err(fail(
                Some(line_no),
                format!("grid place ({row}, {col}) at t = {t_s} s already given on line {first}"),
            ));
        }
        let node = NetNode { row, col, r_m };
        match snapshots.iter_mut().find(|s| s.t_s == t_s) {
            Some(s) => s.nodes.push(node),
            None => snapshots.push(NetSnapshot { t_s, nodes: vec![node] }),
        }
    }
    if snapshots.is_empty() {
        return Err(fail(None, "no node rows after the header".to_string()));
    }
    snapshots.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    Ok(snapshots)
}

/// The net's mesh edges as index pairs into `nodes`: each node joined to its grid neighbours
/// (same row, next column; same column, next row) when those are present.
fn mesh_edges(nodes: &[NetNode]) -> Vec<[usize; 2]> {
    let place: HashMap<(usize, usize), usize> = nodes.iter().enumerate().map(|(i, n)| ((n.row, n.col), i)).collect();
    let mut edges = Vec::with_capacity(2 * nodes.len());
    for (i, n) in nodes.iter().enumerate() {
        for next in [(n.row, n.col + 1), (n.row + 1, n.col)] {
            if let Some(&j) = place.get(&next) {
                edges.push([i, j]);
            }
        }
    }
    edges
}

/// `(MU id, index into nodes)` of the grid's corners present in `nodes`. The plant's MU i is
/// corner i of (0, 0), (0, last), (last, 0), (last, last) (`crate::net::Net::corner_nodes`;
/// a test holds the two together). Empty for a grid without two rows and two columns.
fn mu_corners(nodes: &[NetNode]) -> Vec<(u32, usize)> {
    let last_row = nodes.iter().map(|n| n.row).max().unwrap_or(0);
    let last_col = nodes.iter().map(|n| n.col).max().unwrap_or(0);
    if last_row == 0 || last_col == 0 {
        return Vec::new();
    }
    [(0, 0), (0, last_col), (last_row, 0), (last_row, last_col)]
        .into_iter()
        .zip(1u32..)
        .filter_map(|(place, mu)| nodes.iter().position(|n| (n.row, n.col) == place).map(|i| (mu, i)))
        .collect()
}

fn is_finite3(p: &[f64; 3]) -> bool {
    p.iter().all(|v| v.is_finite())
}

/// Each MU's LVLH path (`mu<i>_r_lvlh_{x,y,z}_m`), at most [`MAX_POINTS`] points, last row kept.
fn mu_paths(plant: &Table) -> Vec<(u32, Vec<[f64; 3]>)> {
    mu_ids(plant, "r_lvlh", "m")
        .into_iter()
        .filter_map(|i| {
            let [x, y, z] = axis_columns(plant, &format!("mu{i}_r_lvlh"), "m")?;
            let n = x.len().min(y.len()).min(z.len());
            let stride = n.div_ceil(MAX_POINTS).max(1);
            let last = n.checked_sub(1).filter(|last| !last.is_multiple_of(stride));
            Some((i, (0..n).step_by(stride).chain(last).map(|k| [x[k], y[k], z[k]]).collect()))
        })
        .collect()
}

fn net_figure(snapshots: &[NetSnapshot], mu_paths: Vec<(u32, Vec<[f64; 3]>)>, label: Option<&str>) -> NetFigure {
    let snapshots = snapshots
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let edges = mesh_edges(&s.nodes)
                .into_iter()
                .map(|[a, b]| [s.nodes[a].r_m, s.nodes[b].r_m])
                .filter(|[a, b]| is_finite3(a) && is_finite3(b))
                .collect();
            let corners = mu_corners(&s.nodes)
                .into_iter()
                .map(|(mu, n)| (mu, s.nodes[n].r_m))
                .filter(|(_, r)| is_finite3(r))
                .collect();
            DrawnSnapshot { t_s: s.t_s, color: snapshot_color(i), edges, corners }
        })
        .collect();
    let mut title = "Net at the snapshot times, LVLH".to_string();
    if let Some(label) = label {
        title.push_str(&format!(" ({label})"));
    }
    NetFigure { title, snapshots, mu_paths }
}

/// Snapshot colours in time order: dark to light along one hue sequence, so the order reads
/// without the legend; past four, the generic palette.
fn snapshot_color(i: usize) -> RGBColor {
    const SEQUENCE: [RGBColor; 4] =
        [RGBColor(68, 1, 84), RGBColor(49, 104, 142), RGBColor(31, 158, 137), RGBColor(230, 145, 0)];
    SEQUENCE.get(i).copied().unwrap_or_else(|| series_color(None, i))
}

// ---------------------------------------------------------------------------------------------
// Cross-method comparison (Figs. 10/11)

/// MU 1's tracking error of one run.
struct ErrorRun {
    method: String,
    t_s: Vec<f64>,
    err_m: [Vec<f64>; 3],
}

/// Draws the Figs. 10/11 analogue into `dir/plots/` (created if needed): MU 1's position tracking
/// error (`err_{x,y,z}_m` of `telemetry/agent-1.csv`) against time for each `(method name, run
/// directory)` of `runs`, one panel per LVLH axis, with a marker at 10 s where the paper sees
/// DMPC and SMC peak. Returns the files written. Fails, naming the file, when a run's
/// `agent-1.csv` is missing, malformed or lacks an error column, or when `runs` is empty.
/// `scenario` (the runs' scenario name) goes into the title.
pub fn draw_comparison(dir: &Path, runs: &[(String, PathBuf)], scenario: Option<&str>) -> Result<Vec<PathBuf>, String> {
    if runs.is_empty() {
        return Err("no runs to compare".to_string());
    }
    let mut data = Vec::with_capacity(runs.len());
    for (method, run_dir) in runs {
        let path = run_dir.join("telemetry").join("agent-1.csv");
        let table = Table::read(&path).map_err(|e| e.to_string())?;
        let err_m = AXES.map(|a| column(&table, &format!("err_{a}_m")).map(<[f64]>::to_vec));
        let [Some(x), Some(y), Some(z)] = err_m else {
            return Err(format!("{}: no `err_{{x,y,z}}_m` columns (MU 1's tracking error)", path.display()));
        };
        data.push(ErrorRun { method: method.clone(), t_s: table.t, err_m: [x, y, z] });
    }

    ensure_font().map_err(|e| e.to_string())?;
    let plots = dir.join("plots");
    std::fs::create_dir_all(&plots).map_err(|e| format!("cannot create {}: {e}", plots.display()))?;
    let path = plots.join(format!("{COMPARISON_STEM}.png"));
    // As in `report::report`: a plot is not worth a panic of the orchestrator.
    let outcome =
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| draw_error_comparison(&path, &data, scenario)));
    match outcome {
        Ok(Ok(())) => Ok(vec![path]),
        Ok(Err(e)) => Err(format!("cannot draw {}: {e}", path.display())),
        Err(_) => Err(format!("cannot draw {}: the plotting library panicked", path.display())),
    }
}

// ---------------------------------------------------------------------------------------------
// Drawing

/// A key entry's glyph.
enum Glyph {
    Line(RGBColor),
    Dashed(RGBColor),
}

/// A one-line key, centred in `area` (the strip under a multi-panel figure's title).
fn draw_key(area: &DrawingArea<BitMapBackend<'_>, Shift>, items: &[(Glyph, String)]) -> DrawResult {
    const GLYPH_W: i32 = 34;
    const GAP: i32 = 8;
    const SPACING: i32 = 30;
    let font: TextStyle = (FONT_FAMILY, KEY_FONT_SIZE).into();
    let mut widths = Vec::with_capacity(items.len());
    for (_, label) in items {
        widths.push(area.estimate_text_size(label, &font)?.0 as i32);
    }
    let total: i32 = widths.iter().map(|w| GLYPH_W + GAP + w).sum::<i32>() + SPACING * (items.len() as i32 - 1);
    let (w, h) = area.dim_in_pixel();
    let y = h as i32 / 2;
    let mut x = ((w as i32 - total) / 2).max(4);
    let text_style = font.color(&BLACK).pos(Pos::new(HPos::Left, VPos::Center));
    for ((glyph, label), text_w) in items.iter().zip(widths) {
        match glyph {
            Glyph::Line(c) => area.draw(&PathElement::new(vec![(x, y), (x + GLYPH_W, y)], c.stroke_width(3)))?,
            Glyph::Dashed(c) => {
                for dash in [(0, 8), (13, 21), (26, GLYPH_W)] {
                    area.draw(&PathElement::new(vec![(x + dash.0, y), (x + dash.1, y)], c.stroke_width(3)))?;
                }
            }
        }
        area.draw_text(label, &text_style, (x + GLYPH_W + GAP, y))?;
        x += GLYPH_W + GAP + text_w + SPACING;
    }
    Ok(())
}

/// `points` as dashed lines, split at non-finite points.
fn draw_dashed<'a, 'b: 'a>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    points: &[(f64, f64)],
    style: ShapeStyle,
) -> DrawResult {
    for run in points.split(|p| !(p.0.is_finite() && p.1.is_finite())).filter(|r| r.len() >= 2) {
        chart.draw_series(DashedLineSeries::new(run.iter().copied(), 7, 5, style))?;
    }
    Ok(())
}

/// Axes and mesh of a time panel (t in s; `y_desc`), then each series as solid lines of `stroke`
/// px (a lone finite point as a dot). Plotters accumulates its tick values, so a tick at zero can
/// come out as 6.9e-18: ticks within a billionth of the axis span of zero print as 0.
fn draw_panel<'a, 'b: 'a>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    y_desc: &str,
    series: &[Series],
    stroke: u32,
) -> DrawResult {
    let snap = |span: f64| move |v: &f64| if v.abs() < span * 1e-9 { "0".to_string() } else { format_tick(v) };
    let (x_range, y_range) = (chart.x_range(), chart.y_range());
    let (x_tick, y_tick) = (snap(x_range.end - x_range.start), snap(y_range.end - y_range.start));
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc(y_desc)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .label_style((FONT_FAMILY, 16))
        .axis_desc_style((FONT_FAMILY, 18))
        .draw()?;
    for s in series {
        let style = s.color.stroke_width(stroke);
        for run in s.points.split(|p| !(p.0.is_finite() && p.1.is_finite())).filter(|r| !r.is_empty()) {
            if let [p] = run {
                chart.draw_series(std::iter::once(Circle::new(*p, 2, s.color.filled())))?;
            } else {
                // Two-point segments: plotters joins a wide polyline into one polygon whose
                // corners spike where the line zig-zags at pixel scale (see `report`).
                chart.draw_series(run.windows(2).map(|w| PathElement::new(vec![w[0], w[1]], style)))?;
            }
        }
    }
    Ok(())
}

fn series_bounds<'s>(series: impl Iterator<Item = &'s Series> + Clone) -> ((f64, f64), (f64, f64)) {
    let t = linear_range(finite_bounds(series.clone().flat_map(|s| s.points.iter().map(|p| p.0))));
    let y = linear_range(finite_bounds(series.flat_map(|s| s.points.iter().map(|p| p.1))));
    (t, y)
}

fn draw_tension(path: &Path, fig: &TensionFigure) -> DrawResult {
    let root = BitMapBackend::new(path, TENSION_FIGURE_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let body = root.titled(&fig.title, (FONT_FAMILY, CAPTION_SIZE))?;
    let (key, body) = body.split_vertically(KEY_HEIGHT);
    let mut items: Vec<(Glyph, String)> =
        (0..3).map(|a| (Glyph::Line(axis_color(a)), format!("T_{}, {}", AXES[a], AXIS_NAMES[a]))).collect();
    items.push((Glyph::Line(RGBColor(90, 90, 90)), "solid: true tension (plant)".to_string()));
    items.push((Glyph::Dashed(RGBColor(90, 90, 90)), fig.controller_desc.clone()));
    draw_key(&key, &items)?;
    // One range for all four MUs, so their panels compare at a glance.
    let all = fig.panels.iter().flat_map(|p| p.truth.iter().chain(&p.controller));
    let ((t0, t1), (y0, y1)) = series_bounds(all);
    let cols = if fig.panels.len() > 1 { 2 } else { 1 };
    let rows = fig.panels.len().div_ceil(cols).max(1);
    for (area, panel) in body.split_evenly((rows, cols)).iter().zip(&fig.panels) {
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.caption, (FONT_FAMILY, PANEL_CAPTION_SIZE))
            .margin(MARGIN / 2)
            .x_label_area_size(X_LABEL_AREA - 10)
            .y_label_area_size(Y_LABEL_AREA - 30)
            .build_cartesian_2d(t0..t1, y0..y1)?;
        draw_panel(&mut chart, "tension on the MU [N]", &panel.truth, 2)?;
        for s in &panel.controller {
            draw_dashed(&mut chart, &s.points, s.color.stroke_width(2))?;
        }
    }
    root.present()?;
    Ok(())
}

fn draw_error_comparison(path: &Path, runs: &[ErrorRun], scenario: Option<&str>) -> DrawResult {
    let root = BitMapBackend::new(path, COMPARISON_FIGURE_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut title = "Figs. 10/11 analogue — MU 1 position tracking error r − r_des".to_string();
    if let Some(s) = scenario {
        title.push_str(&format!(" ({s})"));
    }
    let body = root.titled(&title, (FONT_FAMILY, CAPTION_SIZE))?;
    let (key, body) = body.split_vertically(KEY_HEIGHT);
    let marker_color = RGBColor(90, 90, 90);
    let mut items: Vec<(Glyph, String)> =
        runs.iter().enumerate().map(|(i, r)| (Glyph::Line(series_color(None, i)), r.method.clone())).collect();
    items.push((
        Glyph::Dashed(marker_color),
        format!("t = {} s: net fully deployed (DMPC, SMC peak in the paper)", format_tick(&DEPLOYED_AT_S)),
    ));
    draw_key(&key, &items)?;
    for (axis, area) in body.split_evenly((3, 1)).iter().enumerate() {
        let series: Vec<Series> = runs
            .iter()
            .enumerate()
            .map(|(i, r)| Series {
                label: r.method.clone(),
                color: series_color(None, i),
                points: downsample_min_max(&r.t_s, &r.err_m[axis], MAX_POINTS),
            })
            .collect();
        let peaks: Vec<String> = runs
            .iter()
            .map(|r| {
                let peak_m =
                    r.err_m[axis].iter().copied().filter(|v| v.is_finite()).fold(0.0, |m: f64, v| m.max(v.abs()));
                format!("{} {} m", r.method, format_tick(&peak_m))
            })
            .collect();
        let caption = format!(
            "({}) {} — peak |err_{}|: {}",
            ['a', 'b', 'c'][axis],
            AXIS_NAMES[axis],
            AXES[axis],
            peaks.join(", ")
        );
        let ((t0, t1), (y0, y1)) = series_bounds(series.iter());
        let mut chart = ChartBuilder::on(area)
            .caption(&caption, (FONT_FAMILY, PANEL_CAPTION_SIZE))
            .margin(MARGIN / 2)
            .x_label_area_size(X_LABEL_AREA - 10)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(t0..t1, y0..y1)?;
        draw_panel(&mut chart, &format!("err_{} [m]", AXES[axis]), &series, 2)?;
        if (t0..=t1).contains(&DEPLOYED_AT_S) {
            chart.draw_series(DashedLineSeries::new(
                [(DEPLOYED_AT_S, y0), (DEPLOYED_AT_S, y1)],
                6,
                5,
                marker_color.stroke_width(2),
            ))?;
        }
    }
    root.present()?;
    Ok(())
}

/// A cube of equal extent on the three axes around every finite point: `(lo, hi)` per LVLH axis.
fn cube_ranges(points: impl Iterator<Item = [f64; 3]> + Clone) -> [(f64, f64); 3] {
    let finite = points.filter(is_finite3);
    let bounds = [0, 1, 2].map(|a| finite_bounds(finite.clone().map(|p| p[a])));
    let half = bounds.iter().map(|b| b.map_or(0.0, |(lo, hi)| (hi - lo) / 2.0)).fold(0.0f64, f64::max);
    let half = if half > 0.0 { half.min(f64::MAX / 8.0) * 1.05 } else { 1.0 };
    bounds.map(|b| {
        let mid = b.map_or(0.0, |(lo, hi)| lo / 2.0 + hi / 2.0);
        (mid - half, mid + half)
    })
}

/// The 3-D net. Chart axes are (LVLH y, z, x): cross-track z is vertical, and the order is a
/// cyclic permutation of LVLH's, so the view is not mirrored. [`VIEW_YAW`] turns radial x (the
/// direction of travel) far enough across the picture that the snapshots, 15 m apart in all,
/// stand side by side with their y–z faces half towards the viewer.
fn draw_net(path: &Path, fig: &NetFigure) -> DrawResult {
    let points = fig
        .snapshots
        .iter()
        .flat_map(|s| s.edges.iter().flatten().copied().chain(s.corners.iter().map(|c| c.1)))
        .chain(fig.mu_paths.iter().flat_map(|(_, p)| p.iter().copied()))
        .chain(std::iter::once(TARGET_LVLH_M));
    let [xr, yr, zr] = cube_ranges(points);
    let to_chart = |p: [f64; 3]| (p[1], p[2], p[0]);

    let root = BitMapBackend::new(path, NET_FIGURE_SIZE).into_drawing_area();
    let mut chart =
        cohort_report::chart3d::cube_chart(&root, &fig.title, [yr, zr, xr], (VIEW_YAW, VIEW_PITCH, VIEW_SCALE))?;
    // Axis names beside the middle of the edges that carry the tick labels (with this view: y
    // front left, x front right, z at the back right), offset in pixels past the labels.
    let axis_font = (FONT_FAMILY, 18).into_font().color(&BLACK);
    let mid = |(lo, hi): (f64, f64)| lo / 2.0 + hi / 2.0;
    let anchored = |h, v| axis_font.clone().pos(Pos::new(h, v));
    for (text, at, offset, style) in [
        ("y (along-track) [m]", (mid(yr), zr.0, xr.1), (-40, 42), anchored(HPos::Right, VPos::Top)),
        ("x (radial) [m]", (yr.1, zr.0, mid(xr)), (40, 42), anchored(HPos::Left, VPos::Top)),
        (
            "z (cross-track) [m]",
            (yr.1, mid(zr), xr.0),
            (52, 0),
            anchored(HPos::Center, VPos::Center).transform(FontTransform::Rotate90),
        ),
    ] {
        chart.draw_series(std::iter::once(EmptyElement::at(at) + Text::new(text, offset, style)))?;
    }

    let path_color = RGBColor(120, 120, 120);
    for (n, (_, p)) in fig.mu_paths.iter().enumerate() {
        let style = path_color.stroke_width(1);
        let points: Vec<_> = p.iter().map(|&q| (q, to_chart(q))).collect();
        for run in points.split(|(q, _)| !is_finite3(q)).filter(|r| r.len() >= 2) {
            let series = chart.draw_series(run.windows(2).map(|w| PathElement::new(vec![w[0].1, w[1].1], style)))?;
            if n == 0 {
                series
                    .label("MU paths (plant)")
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], path_color.stroke_width(2)));
            }
        }
    }
    let number_font = (FONT_FAMILY, 16).into_font().color(&BLACK);
    for s in &fig.snapshots {
        let color = s.color;
        let style = color.stroke_width(1);
        chart
            .draw_series(s.edges.iter().map(|[a, b]| PathElement::new(vec![to_chart(*a), to_chart(*b)], style)))?
            .label(format!("net at t = {} s", format_tick(&s.t_s)))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
        for &(mu, r) in &s.corners {
            let at = to_chart(r);
            chart.draw_series(std::iter::once(Circle::new(at, 6, BLACK.filled())))?;
            chart.draw_series(std::iter::once(Circle::new(at, 4, color.filled())))?;
            chart.draw_series(std::iter::once(
                EmptyElement::at(at) + Text::new(mu.to_string(), (7, -18), number_font.clone()),
            ))?;
        }
    }
    let grey = RGBColor(80, 80, 80);
    chart.draw_series(std::iter::empty::<Circle<(f64, f64, f64), i32>>())?.label("MU corner (number: MU id)").legend(
        move |(x, y)| {
            EmptyElement::at((x + 12, y))
                + Circle::new((0, 0), 6, BLACK.filled())
                + Circle::new((0, 0), 4, grey.filled())
        },
    );
    let target = to_chart(TARGET_LVLH_M);
    chart
        .draw_series(std::iter::once(Cross::new(target, 9, RGBColor(200, 0, 0).stroke_width(3))))?
        .label(format!(
            "target [{}, {}, {}] m",
            format_tick(&TARGET_LVLH_M[0]),
            format_tick(&TARGET_LVLH_M[1]),
            format_tick(&TARGET_LVLH_M[2])
        ))
        .legend(move |(x, y)| Cross::new((x + 12, y), 7, RGBColor(200, 0, 0).stroke_width(3)));
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fmt::Write as _;
    use std::sync::atomic::{AtomicU32, Ordering};

    use crate::net::{Net, NetParams};

    /// A scratch directory, removed on drop.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(tag: &str) -> Self {
            static COUNTER: AtomicU32 = AtomicU32::new(0);
            let dir = std::env::temp_dir().join(format!(
                "cohort-report-tsnr-{tag}-{}-{}",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            TempDir(dir)
        }

        fn write(&self, rel: &str, contents: &str) -> PathBuf {
            write_file(&self.0, rel, contents)
        }
    }

    fn write_file(dir: &Path, rel: &str, contents: &str) -> PathBuf {
        let path = dir.join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, contents).unwrap();
        path
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn nodes(n: usize) -> Vec<NetNode> {
        (0..n * n).map(|i| NetNode { row: i / n, col: i % n, r_m: [0.0, i as f64, 0.0] }).collect()
    }

    fn sorted(mut pairs: Vec<[usize; 2]>) -> Vec<[usize; 2]> {
        for p in &mut pairs {
            p.sort_unstable();
        }
        pairs.sort_unstable();
        pairs
    }

    /// The edges and corners read back from the snapshot rows are the plant's own: the same grid
    /// neighbours as `Net::edges`, and MU i on `Net::corner_nodes()[i − 1]`.
    #[test]
    fn mesh_and_corners_match_the_plants_net() {
        for n in [3, 11] {
            let net = Net::new(NetParams { nodes_per_side: n, ..NetParams::default() }).unwrap();
            // Node k of the snapshot file is row k / n, column k % n (the plant's numbering).
            let grid = nodes(n);
            assert_eq!(sorted(mesh_edges(&grid)), sorted(net.edges().to_vec()), "{n} × {n}");
            assert_eq!(mesh_edges(&grid).len(), 2 * n * (n - 1));
            let corners: Vec<usize> = mu_corners(&grid).into_iter().map(|(_, i)| i).collect();
            assert_eq!(corners, net.corner_nodes().to_vec(), "{n} × {n}");
            assert_eq!(mu_corners(&grid).iter().map(|c| c.0).collect::<Vec<_>>(), [1, 2, 3, 4]);
        }
    }

    #[test]
    fn missing_nodes_drop_their_edges_and_order_does_not_matter() {
        // 3 × 3 without the centre: the 12 edges less the centre's 4.
        let mut grid: Vec<NetNode> = nodes(3).into_iter().filter(|n| (n.row, n.col) != (1, 1)).collect();
        assert_eq!(mesh_edges(&grid).len(), 8);
        grid.reverse();
        let pairs: Vec<[(usize, usize); 2]> =
            mesh_edges(&grid).iter().map(|&[a, b]| [(grid[a].row, grid[a].col), (grid[b].row, grid[b].col)]).collect();
        for [a, b] in &pairs {
            let step = (b.0 - a.0) + (b.1 - a.1);
            assert_eq!(step, 1, "{a:?}–{b:?} are not grid neighbours");
        }
        assert!(pairs.contains(&[(0, 0), (0, 1)]) && pairs.contains(&[(1, 2), (2, 2)]), "{pairs:?}");
        // A single row has no corners to mark.
        let row: Vec<NetNode> = (0..4).map(|c| NetNode { row: 0, col: c, r_m: [0.0; 3] }).collect();
        assert!(mu_corners(&row).is_empty());
        assert_eq!(mesh_edges(&row).len(), 3);
    }

    fn snapshot_text(n: usize, times: &[f64]) -> String {
        let mut text = SNAPSHOT_COLUMNS.join(",") + "\n";
        for &t in times {
            for k in 0..n * n {
                let (row, col) = (k / n, k % n);
                writeln!(text, "{t:?},{k},{row},{col},{:?},{:?},{:?}", -10.0 + t, 0.5 * col as f64, 0.5 * row as f64)
                    .unwrap();
            }
        }
        text
    }

    #[test]
    fn snapshots_are_grouped_by_time_and_nan_positions_drop_edges() {
        let path = Path::new("run/snapshots/net_nodes.csv");
        let mut text = snapshot_text(3, &[10.0, 0.0]);
        text = text.replacen("10.0,4,1,1,0.0,0.5,0.5", "10.0,4,1,1,NaN,0.5,0.5", 1);
        let snaps = parse_snapshots(&text, path).unwrap();
        assert_eq!(snaps.iter().map(|s| s.t_s).collect::<Vec<_>>(), [0.0, 10.0], "time order");
        assert!(snaps.iter().all(|s| s.nodes.len() == 9));
        assert_eq!(snaps[0].nodes[5], NetNode { row: 1, col: 2, r_m: [-10.0, 1.0, 0.5] });
        let fig = net_figure(&snaps, Vec::new(), None);
        assert_eq!(fig.snapshots[0].edges.len(), 12);
        assert_eq!(fig.snapshots[1].edges.len(), 8, "the NaN centre node's 4 edges are dropped");
        assert_eq!(fig.snapshots[1].corners.iter().map(|c| c.0).collect::<Vec<_>>(), [1, 2, 3, 4]);
        assert_eq!(fig.snapshots[0].corners[3], (4, [-10.0, 1.0, 1.0]));
        // Columns in another order are found by name.
        let swapped = "grid_col,grid_row,node,t_s,r_lvlh_z_m,r_lvlh_y_m,r_lvlh_x_m\n2,1,5,0.0,3.0,2.0,1.0\n";
        let snaps = parse_snapshots(swapped, path).unwrap();
        assert_eq!(snaps[0].nodes, [NetNode { row: 1, col: 2, r_m: [1.0, 2.0, 3.0] }]);
    }

    #[test]
    fn malformed_snapshots_name_file_line_and_problem() {
        let path = Path::new("run/snapshots/net_nodes.csv");
        let good = snapshot_text(3, &[0.0]);
        let err = |text: &str| parse_snapshots(text, path).unwrap_err().to_string();
        assert_eq!(err(""), "run/snapshots/net_nodes.csv: the file is empty");
        assert_eq!(
            err("t_s,node,grid_row,grid_col,r_lvlh_x_m,r_lvlh_y_m\n"),
            "run/snapshots/net_nodes.csv:1: bad header: no column `r_lvlh_z_m`"
        );
        assert!(
            err("t_s,t_s,node,grid_row,grid_col,r_lvlh_x_m,r_lvlh_y_m,r_lvlh_z_m\n").contains("duplicate column `t_s`")
        );
        assert_eq!(
            err(&(SNAPSHOT_COLUMNS.join(",") + "\n")),
            "run/snapshots/net_nodes.csv: no node rows after the header"
        );
        let bad_number = good.replacen("0.0,3,1,0,-10.0", "0.0,3,1,0,-1O.0", 1);
        assert_eq!(err(&bad_number), "run/snapshots/net_nodes.csv:5: column `r_lvlh_x_m`: \"-1O.0\" is not a number");
        let bad_place = good.replacen("0.0,3,1,0,", "0.0,3,-1,0,", 1);
        assert!(err(&bad_place).starts_with("run/snapshots/net_nodes.csv:5: column `grid_row`"), "{}", err(&bad_place));
        let short = good.replacen("0.0,3,1,0,-10.0,", "0.0,3,1,0,", 1);
        assert_eq!(err(&short), "run/snapshots/net_nodes.csv:5: expected 7 columns (as in the header), found 6");
        let twice = good.replacen("0.0,3,1,0,", "0.0,3,1,1,", 1);
        assert!(err(&twice).contains(":6: grid place (1, 1) at t = 0 s already given on line 5"), "{}", err(&twice));
        let nan_time = good.replacen("0.0,3,1,0,", "NaN,3,1,0,", 1);
        assert!(err(&nan_time).contains(":5: column `t_s`: NaN is not a finite time"), "{}", err(&nan_time));
    }

    #[test]
    fn rms_pairs_rows_by_time() {
        let zeros = [0.0; 4];
        let ones = [1.0; 4];
        // b has an extra first step and a NaN: a's steps 0.1, 0.2, 0.3 pair with b's; 0.2 is NaN.
        let t_a = [0.1, 0.2, 0.3, 0.4];
        let t_b = [0.0, 0.1, 0.2, 0.3];
        let a: [&[f64]; 3] = [&[3.0, 9.0, 3.0, 9.0], &[4.0, 9.0, 4.0, 9.0], &zeros];
        let b: [&[f64]; 3] = [&zeros, &[0.0, 0.0, f64::NAN, 0.0], &zeros];
        assert_eq!(rms_vector_difference(&t_a, &a, &t_b, &b), Some(5.0));
        let c: [&[f64]; 3] = [&ones, &ones, &ones];
        assert_eq!(rms_vector_difference(&[5.0], &c, &t_b, &b), None, "no common step");
    }

    /// A tsnr-like run: plant.csv with four MUs' positions and tensions, agent files with the
    /// controller's tension (`tension_used` when `forecast`, else only `tension_meas`) and
    /// tracking errors, and the net snapshots.
    fn write_tsnr_run(dir: &Path, forecast: bool, err_scale_m: f64) {
        let rows = 300;
        let mut plant = String::from("k,t_s");
        for i in 1..=4 {
            for q in ["r_lvlh", "tension"] {
                let unit = if q == "r_lvlh" { "m" } else { "n" };
                for a in AXES {
                    write!(plant, ",mu{i}_{q}_{a}_{unit}").unwrap();
                }
            }
        }
        plant.push('\n');
        let mut agents: Vec<String> = (1..=4)
            .map(|_| {
                let mut h =
                    String::from("k,t_s,err_x_m,err_y_m,err_z_m,tension_meas_x_n,tension_meas_y_n,tension_meas_z_n");
                if forecast {
                    h.push_str(",tension_used_x_n,tension_used_y_n,tension_used_z_n");
                }
                h + "\n"
            })
            .collect();
        for k in 0..rows {
            let t = k as f64 * 0.1;
            write!(plant, "{k},{t:?}").unwrap();
            for i in 1..=4u32 {
                let (sy, sz) = ([1.0, -1.0, 1.0, -1.0][i as usize - 1], [1.0, 1.0, -1.0, -1.0][i as usize - 1]);
                let tension = if (8.0..21.0).contains(&t) { -5.0 * (0.5 * t).sin().abs() } else { 0.0 };
                let r = [-10.0 + 0.5 * t, sy * 2.5, sz * 2.5];
                let tv = [0.3 * tension, sy * tension, sz * tension];
                for v in r.iter().chain(&tv) {
                    write!(plant, ",{v:?}").unwrap();
                }
                let file = &mut agents[i as usize - 1];
                let e = err_scale_m * (t - 10.0).sin() / (1.0 + (t - 10.0).abs());
                write!(file, "{k},{t:?},{e:?},{:?},{:?}", 0.5 * e, -0.5 * e).unwrap();
                for v in &tv {
                    write!(file, ",{v:?}").unwrap();
                }
                if forecast {
                    for v in &tv {
                        write!(file, ",{:?}", v + 0.2 * (3.0 * t).sin()).unwrap();
                    }
                }
                file.push('\n');
            }
            plant.push('\n');
        }
        write_file(dir, "telemetry/plant.csv", &plant);
        for (i, text) in agents.iter().enumerate() {
            write_file(dir, &format!("telemetry/agent-{}.csv", i + 1), text);
        }
        write_file(dir, SNAPSHOT_FILE, &snapshot_text(11, &[0.0, 10.0, 20.0, 30.0]));
    }

    fn assert_png(path: &Path) {
        let bytes = std::fs::read(path).unwrap();
        assert!(bytes.len() > 1024, "{} is only {} bytes", path.display(), bytes.len());
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", path.display());
    }

    #[test]
    fn report_draws_the_tsnr_figures_and_fails_on_a_bad_snapshot() {
        let run = TempDir::new("report");
        write_tsnr_run(&run.0, true, 0.05);
        let written = cohort_report::report(&run.0, &[&TsnrFigures { label: None }]).unwrap();
        let names: Vec<String> =
            written.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names[..2], ["tsnr_tension.png", "tsnr_net_3d.png"], "{names:?}");
        for p in &written[..2] {
            assert_png(p);
        }
        // Without `tension_used` the measured tension stands in (SMC) and it still draws.
        let smc = TempDir::new("report-smc");
        write_tsnr_run(&smc.0, false, 0.05);
        let fig = tension_figure(
            &Table::read(&smc.0.join("telemetry/plant.csv")).unwrap(),
            &(1..=4)
                .map(|i| (i, Table::read(&smc.0.join(format!("telemetry/agent-{i}.csv"))).unwrap()))
                .collect::<Vec<_>>(),
            None,
        );
        assert!(fig.controller_desc.contains("measured"), "{}", fig.controller_desc);
        assert_eq!(fig.panels.len(), 4);
        assert!(fig.panels[0].caption.starts_with("MU 1 — RMS ‖measured − true‖ = 0 N"), "{}", fig.panels[0].caption);
        assert!(cohort_report::report(&smc.0, &[&TsnrFigures { label: None }]).is_ok());

        let snap = run.write(SNAPSHOT_FILE, "t_s,node,grid_row,grid_col,r_lvlh_x_m,r_lvlh_y_m,r_lvlh_z_m\n0.0,0,0\n");
        let msg = cohort_report::report(&run.0, &[&TsnrFigures { label: None }]).unwrap_err().to_string();
        assert_eq!(msg, format!("{}:2: expected 7 columns (as in the header), found 3", snap.display()));
    }

    #[test]
    fn a_run_without_tsnr_data_gets_no_tsnr_figures() {
        let run = TempDir::new("plain");
        run.write("telemetry/plant.csv", "k,t_s,a1_r_x_m,a1_r_y_m\n0,0.0,1.0,2.0\n1,0.1,1.5,2.5\n");
        let plant = Table::read(&run.0.join("telemetry/plant.csv")).unwrap();
        assert!(figures(&run.0, Some(&plant), &[], None).unwrap().is_empty());
        let written = cohort_report::report(&run.0, &[&TsnrFigures { label: None }]).unwrap();
        assert!(written.iter().all(|p| !p.file_name().unwrap().to_string_lossy().starts_with("tsnr_")));
    }

    #[test]
    fn comparison_draws_one_figure_and_names_bad_files() {
        let out = TempDir::new("compare");
        let runs: Vec<(String, PathBuf)> = [("aemc", 0.02), ("dmpc", 0.05), ("smc", 0.08)]
            .iter()
            .map(|&(method, scale)| {
                let run = out.0.join(method);
                write_tsnr_run(&run, true, scale);
                (method.to_string(), run)
            })
            .collect();
        let written = draw_comparison(&out.0, &runs, None).unwrap();
        assert_eq!(written, [out.0.join("plots/tsnr_err_mu1.png")]);
        assert_png(&written[0]);

        let missing = out.0.join("nowhere");
        let msg = draw_comparison(&out.0, &[("aemc".to_string(), missing.clone())], None).unwrap_err();
        assert!(msg.contains(&missing.join("telemetry/agent-1.parquet").display().to_string()), "{msg}");
        assert!(msg.contains("or .csv: neither exists"), "{msg}");
        let bad = out.0.join("bad");
        std::fs::create_dir_all(bad.join("telemetry")).unwrap();
        let agent = bad.join("telemetry/agent-1.csv");
        std::fs::write(&agent, "k,t_s,err_x_m,err_y_m,err_z_m\n0,0.0,1.0,x,0.0\n").unwrap();
        let msg = draw_comparison(&out.0, &[("smc".to_string(), bad.clone())], None).unwrap_err();
        assert_eq!(msg, format!("{}:2: column `err_y_m`: cannot parse \"x\" as a number", agent.display()));
        std::fs::write(&agent, "k,t_s,err_x_m,err_y_m\n0,0.0,1.0,0.0\n").unwrap();
        let msg = draw_comparison(&out.0, &[("smc".to_string(), bad)], None).unwrap_err();
        assert!(msg.contains("agent-1.csv: no `err_{x,y,z}_m` columns"), "{msg}");
        assert_eq!(draw_comparison(&out.0, &[], None).unwrap_err(), "no runs to compare");
    }
}
