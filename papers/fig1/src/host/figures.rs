//! The figures of the seed-000 servicing scenario (Nino et al., Sec. 6), drawn for a run
//! directory holding `derived/fig1.csv`:
//!
//! * `fig2_trajectories_3d.png` — Fig. 2: the bodies' LVLH positions (`b<b>_q_lvlh_*` of
//!   `plant.csv`, body 0 the defunct spacecraft) over the first [`TRAJECTORY_WINDOW_S`] seconds,
//!   in 3-D with equal scales on the three axes;
//! * `fig3_zeta_error.png` — Fig. 3: ‖ζ̃ᵢ‖ against time, log axis, with the paper's level;
//! * `fig4_tracking_error.png` — Fig. 4: ‖eᵢ‖ against time, log axis, with the paper's level;
//! * `fig4_tracking_error_late.png` — Fig. 4 from [`LATE_FROM_S`] on, linear axis, where the
//!   steady-state oscillation shows;
//! * `u_norm.png` — ‖uᵢ‖ against time, log axis.
//!
//! A fig1 run leaves the per-body columns of `plant.csv` out of the generic figures: their ECI
//! states (~6.7e6 m) say nothing at plot scale (they are not even read), and the LVLH positions
//! are in Fig. 2 (and, as range to the defunct spacecraft, in ‖eᵢ‖).
//!
//! `derived/fig1.csv` has the usual `k,t_s` columns, then per agent `i`: `a<i>_e_norm_m`,
//! `a<i>_zeta_err_norm_mps` and `a<i>_u_norm_mps2` (all three required; older runs also have
//! `a<i>_theta_norm`, a copy of the agents' `theta_norm`, not read). On log axes, zeros and values more than [`LOG_MAX_DECADES`] decades below
//! the largest are drawn at the axis floor; non-finite values leave gaps.

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use cohort_report::chart::{
    CAPTION_SIZE, DrawResult, FONT_FAMILY, MARGIN, MAX_POINTS, Series, X_LABEL_AREA, Y_LABEL_AREA, downsample_min_max,
    draw_legend, draw_time_series, finite_bounds, format_tick, series_color,
};
use cohort_report::chart3d::cube_chart;
use cohort_report::{ColumnUse, FigureSource, PaperFigure, ReportError, Table, Telemetry};

/// Where the derived per-agent series live, relative to the run directory (read as
/// `derived/fig1.parquet` when the run wrote Parquet: see [`cohort_report::table::resolve`]).
pub(crate) const DERIVED_FILE: &str = "derived/fig1.csv";
/// Fig. 2 shows the trajectories over this first stretch of the run.
const TRAJECTORY_WINDOW_S: f64 = 60.0;
/// The late, linear-axis view of Fig. 4 starts here (or halfway through a shorter run).
const LATE_FROM_S: f64 = 150.0;
/// The levels the paper reports (Sec. 6): ‖ζ̃ᵢ‖ ≈ 5 m/s after 150 s, ‖eᵢ‖ ≈ 5 m after 200 s.
const PAPER_ZETA: Reference = Reference { value: 5.0, t_s: 150.0, label: "paper: ≈ 5 m/s after 150 s" };
const PAPER_E: Reference = Reference { value: 5.0, t_s: 200.0, label: "paper: ≈ 5 m after 200 s" };
/// A log axis spans at most this many decades below the largest value drawn.
const LOG_MAX_DECADES: i32 = 9;

const FIGURE_SIZE: (u32, u32) = (1200, 700);
const FIGURE_3D_SIZE: (u32, u32) = (1100, 1000);
/// View of the 3-D figure (radians): turned about the vertical (radial) axis, then tipped
/// towards the viewer.
const VIEW_YAW: f64 = 0.65;
const VIEW_PITCH: f64 = 0.45;
const VIEW_SCALE: f64 = 0.72;

/// `(b, rest)` for a per-body plant column `b<b>_<rest>`.
pub(crate) fn body_column(name: &str) -> Option<(u32, &str)> {
    let (prefix, rest) = name.split_once('_')?;
    let digits = prefix.strip_prefix('b')?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) || rest.is_empty() {
        return None;
    }
    Some((digits.parse().ok()?, rest))
}

/// Is `name` one of the LVLH position columns `b<b>_q_lvlh_{x,y,z}_m`?
pub(crate) fn is_lvlh_column(name: &str) -> bool {
    body_column(name).is_some_and(|(_, rest)| matches!(rest, "q_lvlh_x_m" | "q_lvlh_y_m" | "q_lvlh_z_m"))
}

/// The servicing run's figures, for the generic report (see the module docs).
pub struct Fig1Figures;

impl FigureSource for Fig1Figures {
    fn plant_column(&self, name: &str) -> ColumnUse {
        match body_column(name) {
            None => ColumnUse::Generic,
            Some(_) if is_lvlh_column(name) => ColumnUse::PaperOnly,
            Some(_) => ColumnUse::Skip,
        }
    }
    /// ‖uᵢ‖ is `u_norm.png` (from the joined series); the agents' own u columns would repeat it.
    fn agent_column(&self, name: &str) -> ColumnUse {
        if matches!(name, "u_x_mps2" | "u_y_mps2" | "u_z_mps2") { ColumnUse::Skip } else { ColumnUse::Generic }
    }
    fn figures(&self, t: &Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError> {
        let derived_path = cohort_report::table::resolve(&t.run_dir.join(DERIVED_FILE));
        if !derived_path.is_file() {
            return Ok(Vec::new());
        }
        let derived = Table::read(&derived_path)?;
        let plant_path = t.run_dir.join("telemetry").join("plant.csv");
        // A plant file without LVLH columns still counts as read: the figures say which are missing.
        let empty = Table::default();
        let bodies = t.plant_aside.or(t.plant.map(|_| &empty));
        let figures = figures(&derived_path, &derived, &plant_path, bodies)?;
        Ok(figures.into_iter().map(|(stem, fig)| Box::new(Named(stem, fig)) as Box<dyn PaperFigure>).collect())
    }
}

struct Named(String, Fig1Figure);

impl PaperFigure for Named {
    fn stem(&self) -> &str {
        &self.0
    }
    fn draw(&self, path: &Path) -> DrawResult {
        self.1.draw(path)
    }
}

/// A level reported in the paper: a dashed line at `value` and a vertical line at `t_s`.
#[derive(Debug, Clone, Copy)]
struct Reference {
    value: f64,
    t_s: f64,
    label: &'static str,
}

#[derive(Debug)]
pub(crate) enum Fig1Figure {
    Time(PaperTimeFigure),
    Trajectories(TrajectoryFigure),
}

impl Fig1Figure {
    pub(crate) fn draw(&self, path: &Path) -> DrawResult {
        match self {
            Fig1Figure::Time(fig) => draw_time(path, fig),
            Fig1Figure::Trajectories(fig) => draw_trajectories(path, fig),
        }
    }
}

#[derive(Debug)]
pub(crate) struct PaperTimeFigure {
    title: String,
    y_desc: String,
    t_range: (f64, f64),
    y_range: (f64, f64),
    log: bool,
    /// Line width in pixels: 1 for the noisy series, where wider lines merge into a band.
    stroke: u32,
    series: Vec<Series>,
    reference: Option<Reference>,
}

#[derive(Debug)]
pub(crate) struct TrajectoryFigure {
    title: String,
    paths: Vec<Path3d>,
}

/// One body's path, LVLH `(x, y, z)` in metres; non-finite points split it.
#[derive(Debug)]
struct Path3d {
    label: String,
    color: RGBColor,
    defunct: bool,
    points: Vec<(f64, f64, f64)>,
}

/// The figures of a fig1 run: `derived` is `derived/fig1.csv` (read from `derived_path`),
/// `bodies` the LVLH columns of `plant.csv` (at `plant_path`; `None` if the run has no
/// `plant.csv`). Fails, naming the file, if a needed column is missing.
pub(crate) fn figures(
    derived_path: &Path,
    derived: &Table,
    plant_path: &Path,
    bodies: Option<&Table>,
) -> Result<Vec<(String, Fig1Figure)>, ReportError> {
    let agents = agent_ids(derived);
    if agents.is_empty() {
        return Err(ReportError::PaperInput {
            line: None,
            path: derived_path.to_path_buf(),
            reason: "no `a<i>_e_norm_m` columns, so no agents to plot".to_string(),
        });
    }
    let per_agent = |suffix: &str| -> Result<Vec<(u32, &[f64])>, ReportError> {
        agents
            .iter()
            .map(|&i| {
                let name = format!("a{i}_{suffix}");
                match column(derived, &name) {
                    Some(values) => Ok((i, values)),
                    None => Err(ReportError::PaperInput {
                        line: None,
                        path: derived_path.to_path_buf(),
                        reason: format!("missing column `{name}`"),
                    }),
                }
            })
            .collect()
    };
    let e = per_agent("e_norm_m")?;
    let zeta = per_agent("zeta_err_norm_mps")?;
    let u = per_agent("u_norm_mps2")?;

    let bodies_err = |reason: &str| ReportError::PaperInput {
        line: None,
        path: plant_path.to_path_buf(),
        reason: format!("{reason}; {DERIVED_FILE} is present, and Fig. 2 needs the bodies' `b<b>_q_lvlh_{{x,y,z}}_m`"),
    };
    let Some(bodies) = bodies else {
        return Err(bodies_err("missing"));
    };
    let lvlh = lvlh_columns(bodies);
    if lvlh.is_empty() {
        return Err(bodies_err("no LVLH position columns"));
    }

    let t = &derived.t;
    let log_figure = |title: &str, y_desc: &str, columns: &[(u32, &[f64])], reference: Option<Reference>, stroke| {
        let (series, y_range) = log_series(t, columns, reference.map(|r| r.value));
        Fig1Figure::Time(PaperTimeFigure {
            title: title.to_string(),
            y_desc: y_desc.to_string(),
            t_range: time_range(t.iter().copied()),
            y_range,
            log: true,
            stroke,
            series,
            reference,
        })
    };
    // No ζ̃ on the y axis: the tilde is put back on captions only (see `split_tildes`).
    let fig3_title = "Fig. 3 — ‖ζ\u{303}ᵢ‖, neighbourhood velocity estimation error";
    let figures = vec![
        ("fig2_trajectories_3d".to_string(), trajectory_figure(bodies, &lvlh)),
        (
            "fig3_zeta_error".to_string(),
            log_figure(fig3_title, "velocity estimation error [m/s]", &zeta, Some(PAPER_ZETA), 1),
        ),
        (
            "fig4_tracking_error".to_string(),
            log_figure("Fig. 4 — ‖eᵢ‖, tracking error", "‖eᵢ‖ [m]", &e, Some(PAPER_E), 2),
        ),
        ("fig4_tracking_error_late".to_string(), late_figure(t, &e)),
        ("u_norm".to_string(), log_figure("‖uᵢ‖, commanded control acceleration", "‖uᵢ‖ [m/s²]", &u, None, 1)),
    ];
    Ok(figures)
}

/// The agent ids `i` with an `a<i>_e_norm_m` column, ascending.
fn agent_ids(table: &Table) -> Vec<u32> {
    let mut ids: Vec<u32> = table
        .columns
        .iter()
        .filter_map(|c| {
            let (prefix, rest) = c.name.split_once('_')?;
            let digits = prefix.strip_prefix('a')?;
            let is_id = !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit());
            if is_id && rest == "e_norm_m" { digits.parse().ok() } else { None }
        })
        .collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

fn column<'t>(table: &'t Table, name: &str) -> Option<&'t [f64]> {
    table.columns.iter().find(|c| c.name == name).map(|c| c.values.as_slice())
}

/// `(b, [x, y, z])` for each body with all three LVLH position columns, by body number.
fn lvlh_columns(table: &Table) -> Vec<(u32, [&[f64]; 3])> {
    let mut ids: Vec<u32> = table.columns.iter().filter_map(|c| body_column(&c.name).map(|(b, _)| b)).collect();
    ids.sort_unstable();
    ids.dedup();
    ids.into_iter()
        .filter_map(|b| {
            let axis = |a: char| column(table, &format!("b{b}_q_lvlh_{a}_m"));
            Some((b, [axis('x')?, axis('y')?, axis('z')?]))
        })
        .collect()
}

/// The first and last finite time, as an axis range.
fn time_range(t: impl DoubleEndedIterator<Item = f64> + Clone) -> (f64, f64) {
    let first = t.clone().find(|v| v.is_finite());
    let last = t.rev().find(|v| v.is_finite());
    match (first, last) {
        (Some(a), Some(b)) if b > a => (a, b),
        (Some(a), _) => (a, a + 1.0),
        _ => (0.0, 1.0),
    }
}

/// The floor of a log axis over `values` (and `extra`, a reference level drawn with them): the
/// smallest positive finite value (a decade below it if some values are zero or negative, so
/// they show as dips to the floor), but no more than [`LOG_MAX_DECADES`] below the largest.
/// Returns `(floor, top)`.
fn log_bounds(values: impl Iterator<Item = f64>, extra: Option<f64>) -> (f64, f64) {
    let mut top = f64::NEG_INFINITY;
    let mut smallest = f64::INFINITY;
    let mut non_positive = false;
    for v in values.chain(extra).filter(|v| v.is_finite()) {
        if v > 0.0 {
            top = top.max(v);
            smallest = smallest.min(v);
        } else {
            non_positive = true;
        }
    }
    if !top.is_finite() {
        return (1e-3, 1.0);
    }
    let lowest = if non_positive { smallest / 10.0 } else { smallest };
    let floor = lowest.max(top * 10f64.powi(-LOG_MAX_DECADES));
    if floor >= top { (top / 10.0, top * 10.0) } else { (floor, top) }
}

/// One series per agent for a log axis, values clamped up to the axis floor (non-finite values
/// stay gaps), and the y range.
fn log_series(t: &[f64], columns: &[(u32, &[f64])], extra: Option<f64>) -> (Vec<Series>, (f64, f64)) {
    let (floor, top) = log_bounds(columns.iter().flat_map(|(_, v)| v.iter().copied()), extra);
    let series = columns
        .iter()
        .map(|&(i, values)| {
            let clamped: Vec<f64> =
                values.iter().map(|&v| if v.is_finite() { v.max(floor) } else { f64::NAN }).collect();
            Series {
                label: format!("servicer {i}"),
                color: series_color(Some(i), 0),
                points: downsample_min_max(t, &clamped, MAX_POINTS),
            }
        })
        .collect();
    (series, (floor / 1.5, top * 2.0))
}

/// Fig. 4 from [`LATE_FROM_S`] (or halfway through a shorter run) on, on a linear axis from 0.
fn late_figure(t: &[f64], e: &[(u32, &[f64])]) -> Fig1Figure {
    let (t0, t1) = time_range(t.iter().copied());
    let from = if t1 > LATE_FROM_S { LATE_FROM_S } else { t0 + (t1 - t0) / 2.0 };
    let start = t.iter().position(|&v| v >= from).unwrap_or(t.len());
    let t_late = &t[start..];
    let series: Vec<Series> = e
        .iter()
        .map(|&(i, values)| Series {
            label: format!("servicer {i}"),
            color: series_color(Some(i), 0),
            points: downsample_min_max(t_late, values.get(start..).unwrap_or(&[]), MAX_POINTS),
        })
        .collect();
    let top = finite_bounds(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)))
        .map_or(PAPER_E.value, |(_, hi)| hi.max(PAPER_E.value));
    let bottom = finite_bounds(series.iter().flat_map(|s| s.points.iter().map(|p| p.1))).map_or(0.0, |(lo, _)| lo);
    Fig1Figure::Time(PaperTimeFigure {
        title: format!("Fig. 4, t ≥ {} s — ‖eᵢ‖, tracking error (linear scale)", format_tick(&from)),
        y_desc: "‖eᵢ‖ [m]".to_string(),
        t_range: (from, t1.max(from + 1.0)),
        y_range: (bottom.min(0.0), top * 1.08),
        log: false,
        stroke: 2,
        series,
        reference: Some(PAPER_E),
    })
}

/// Fig. 2: every body's LVLH path over the first [`TRAJECTORY_WINDOW_S`] seconds.
fn trajectory_figure(bodies: &Table, lvlh: &[(u32, [&[f64]; 3])]) -> Fig1Figure {
    let t0 = bodies.t.iter().copied().find(|v| v.is_finite()).unwrap_or(0.0);
    // Rows up to the end of the window (a NaN time does not end it).
    let rows = bodies.t.iter().take_while(|&&t| t <= t0 + TRAJECTORY_WINDOW_S || t.is_nan()).count();
    let paths = lvlh
        .iter()
        .map(|&(b, [x, y, z])| {
            let n = rows.min(x.len()).min(y.len()).min(z.len());
            // Every stride-th row, and the last one.
            let stride = n.div_ceil(MAX_POINTS / 2).max(1);
            let last = n.checked_sub(1).filter(|last| !last.is_multiple_of(stride));
            let points = (0..n)
                .step_by(stride)
                .chain(last)
                .map(|k| {
                    let p = (x[k], y[k], z[k]);
                    if p.0.is_finite() && p.1.is_finite() && p.2.is_finite() { p } else { (f64::NAN, 0.0, 0.0) }
                })
                .collect();
            Path3d {
                label: if b == 0 { "defunct (dotted)".to_string() } else { format!("servicer {b}") },
                color: if b == 0 { BLACK } else { series_color(Some(b), 0) },
                defunct: b == 0,
                points,
            }
        })
        .collect();
    Fig1Figure::Trajectories(TrajectoryFigure {
        title: format!(
            "Fig. 2 — trajectories, first {} s (LVLH of the reference orbit)",
            format_tick(&TRAJECTORY_WINDOW_S)
        ),
        paths,
    })
}

// ---------------------------------------------------------------------------------------------
// Drawing

/// `text` without its combining tildes (U+0303), and the byte offsets in it of the letters that
/// carried one. Plotters' text layout ignores glyph bearings, so it draws a combining mark after
/// its letter instead of over it; [`draw_tildes`] puts them back.
fn split_tildes(text: &str) -> (String, Vec<usize>) {
    let mut plain = String::with_capacity(text.len());
    let mut marked = Vec::new();
    let mut last_start = None;
    for c in text.chars() {
        if c == '\u{303}' {
            marked.extend(last_start);
        } else {
            last_start = Some(plain.len());
            plain.push(c);
        }
    }
    (plain, marked)
}

/// Draws a tilde over each `marked` letter of the caption `plain`, which `ChartBuilder::caption`
/// draws centred at the top of `root`, inside [`MARGIN`].
fn draw_tildes(root: &DrawingArea<BitMapBackend<'_>, Shift>, plain: &str, marked: &[usize]) -> DrawResult {
    if marked.is_empty() {
        return Ok(());
    }
    let font: TextStyle = (FONT_FAMILY, CAPTION_SIZE).into();
    let width = |s: &str| root.estimate_text_size(s, &font).map(|(w, _)| w as i32);
    let (area_w, _) = root.dim_in_pixel();
    let (text_w, text_h) = root.estimate_text_size(plain, &font)?;
    let margin = MARGIN as i32;
    let left = margin + (area_w as i32 - 2 * margin) / 2 - text_w as i32 / 2;
    // `DrawingArea::titled` leaves min(h / 2, 5) pixels above the caption; the lift raises a
    // lower-case tilde above an ascender (ζ, l, ...).
    let top = margin + (text_h as i32 / 2).min(5) - (f64::from(CAPTION_SIZE) * 0.34) as i32;
    let tilde = "\u{2dc}";
    let tilde_w = width(tilde)?;
    let style = font.color(&BLACK).pos(Pos::new(HPos::Left, VPos::Top));
    for &at in marked {
        let Some(letter) = plain[at..].chars().next() else {
            continue;
        };
        let x = left + width(&plain[..at])? + width(letter.encode_utf8(&mut [0; 4]))? / 2 - tilde_w / 2;
        root.draw_text(tilde, &style, (x, top))?;
    }
    Ok(())
}

fn draw_time(path: &Path, fig: &PaperTimeFigure) -> DrawResult {
    let root = BitMapBackend::new(path, FIGURE_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (title, marked) = split_tildes(&fig.title);
    draw_tildes(&root, &title, &marked)?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&title, (FONT_FAMILY, CAPTION_SIZE))
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA);
    let (t0, t1) = fig.t_range;
    let (y0, y1) = fig.y_range;
    if fig.log {
        let mut chart = builder.build_cartesian_2d(t0..t1, (y0..y1).log_scale())?;
        fill_time(&mut chart, fig, &format!("{} (log scale)", fig.y_desc))?;
    } else {
        let mut chart = builder.build_cartesian_2d(t0..t1, y0..y1)?;
        fill_time(&mut chart, fig, &fig.y_desc)?;
    }
    root.present()?;
    Ok(())
}

fn fill_time<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    fig: &PaperTimeFigure,
    y_desc: &str,
) -> DrawResult
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    draw_time_series(chart, y_desc, &fig.series, fig.stroke)?;
    if let Some(r) = fig.reference {
        let (t0, t1) = fig.t_range;
        let (y0, y1) = fig.y_range;
        let level = BLACK.stroke_width(2);
        chart.draw_series(DashedLineSeries::new([(t0, r.value), (t1, r.value)], 12, 8, level))?.label(r.label).legend(
            move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (9, 0)], level)
                    + PathElement::new(vec![(15, 0), (24, 0)], level)
            },
        );
        if (t0..=t1).contains(&r.t_s) {
            let marker = RGBColor(90, 90, 90).stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new([(r.t_s, y0), (r.t_s, y1)], 4, 5, marker))?
                .label(format!("t = {} s", format_tick(&r.t_s)))
                .legend(move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (4, 0)], marker)
                        + PathElement::new(vec![(10, 0), (14, 0)], marker)
                        + PathElement::new(vec![(20, 0), (24, 0)], marker)
                });
        }
    }
    draw_legend(chart)
}

/// A cube of equal extent on the three axes around every finite point: `(lo, hi)` per LVLH axis.
fn cube_ranges(paths: &[Path3d]) -> [(f64, f64); 3] {
    let points = || paths.iter().flat_map(|p| p.points.iter()).filter(|p| p.0.is_finite());
    let bounds = [
        finite_bounds(points().map(|p| p.0)),
        finite_bounds(points().map(|p| p.1)),
        finite_bounds(points().map(|p| p.2)),
    ];
    let half =
        bounds.iter().map(|b| b.map_or(0.0, |(lo, hi)| (hi - lo) / 2.0)).fold(0.0f64, f64::max).min(f64::MAX / 8.0);
    let half = if half > 0.0 { half * 1.08 } else { 1.0 };
    bounds.map(|b| {
        let mid = b.map_or(0.0, |(lo, hi)| lo / 2.0 + hi / 2.0);
        (mid - half, mid + half)
    })
}

/// Fig. 2. The chart's axes are (cross-track z, radial x, in-track y): radial is vertical, and
/// the order is a cyclic permutation of LVLH's, so the view is not mirrored.
fn draw_trajectories(path: &Path, fig: &TrajectoryFigure) -> DrawResult {
    let [xr, yr, zr] = cube_ranges(&fig.paths);
    let to_chart = |(x, y, z): (f64, f64, f64)| (z, x, y);

    let root = BitMapBackend::new(path, FIGURE_3D_SIZE).into_drawing_area();
    let mut chart = cube_chart(&root, &fig.title, [zr, xr, yr], (VIEW_YAW, VIEW_PITCH, VIEW_SCALE))?;

    // Axis names, just beyond the middle of the edges the tick labels are drawn on.
    let axis_font = (FONT_FAMILY, 18).into_font().color(&BLACK);
    let mid = |(lo, hi): (f64, f64)| lo / 2.0 + hi / 2.0;
    let beyond = |(lo, hi): (f64, f64), f: f64| lo + (hi - lo) * f;
    for (text, at) in [
        ("x (radial) [m]", (beyond(zr, -0.05), beyond(xr, 1.12), beyond(yr, 1.0))),
        ("y (in-track) [m]", (beyond(zr, 1.25), beyond(xr, 0.0), mid(yr))),
        ("z (cross-track) [m]", (mid(zr), beyond(xr, 0.0), beyond(yr, 1.3))),
    ] {
        chart.draw_series(std::iter::once(Text::new(text, at, axis_font.clone())))?;
    }

    let finite = |q: &(f64, f64, f64)| q.0.is_finite() && q.1.is_finite() && q.2.is_finite();
    let chart_points = |p: &Path3d| -> Vec<(f64, f64, f64)> { p.points.iter().map(|&q| to_chart(q)).collect() };
    // Legend entries in body order, but the defunct is drawn last, on top of the servicers'
    // paths that converge on it.
    for p in &fig.paths {
        let color = p.color;
        let style = color.stroke_width(2);
        if p.defunct {
            chart.draw_series(std::iter::empty::<Circle<(f64, f64, f64), i32>>())?.label(&p.label).legend(
                move |(x, y)| {
                    EmptyElement::at((x, y))
                        + PathElement::new(vec![(0, 0), (3, 0)], style)
                        + PathElement::new(vec![(8, 0), (11, 0)], style)
                        + TriangleMarker::new((19, 0), 6, color.filled())
                },
            );
            continue;
        }
        chart
            .draw_series(LineSeries::new(std::iter::empty::<(f64, f64, f64)>(), style))?
            .label(&p.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
        let points = chart_points(p);
        for run in points.split(|q| !finite(q)) {
            chart.draw_series(run.windows(2).map(|w| PathElement::new(vec![w[0], w[1]], style)))?;
        }
        if let Some(start) = points.iter().copied().find(finite) {
            chart.draw_series(std::iter::once(Circle::new(start, 5, color.filled())))?;
        }
        if let Some(end) = points.iter().copied().rfind(finite) {
            chart.draw_series(std::iter::once(Cross::new(end, 6, color.stroke_width(3))))?;
        }
    }
    for p in fig.paths.iter().filter(|p| p.defunct) {
        let style = p.color.stroke_width(2);
        let points = chart_points(p);
        for run in points.split(|q| !finite(q)).filter(|run| run.len() >= 2) {
            chart.draw_series(DashedLineSeries::new(run.iter().copied(), 2, 5, style))?;
        }
        if let Some(start) = points.iter().copied().find(finite) {
            chart.draw_series(std::iter::once(TriangleMarker::new(start, 11, WHITE.filled())))?;
            chart.draw_series(std::iter::once(TriangleMarker::new(start, 8, p.color.filled())))?;
        }
    }
    // Marker key: the start and end markers are drawn in each servicer's colour.
    let grey = RGBColor(80, 80, 80);
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64, f64), i32>>())?
        .label("start (t = 0)")
        .legend(move |(x, y)| Circle::new((x + 12, y), 5, grey.filled()));
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64, f64), i32>>())?
        .label(format!("end (t = {} s)", format_tick(&TRAJECTORY_WINDOW_S)))
        .legend(move |(x, y)| Cross::new((x + 12, y), 6, grey.stroke_width(3)));
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cohort_report::chart::is_finite_point;

    #[test]
    fn body_columns_are_recognised() {
        assert_eq!(body_column("b0_q_lvlh_x_m"), Some((0, "q_lvlh_x_m")));
        assert_eq!(body_column("b12_r_eci_z_m"), Some((12, "r_eci_z_m")));
        assert_eq!(body_column("a1_e_norm_m"), None);
        assert_eq!(body_column("b_x"), None);
        assert_eq!(body_column("bx1_x"), None);
        assert_eq!(body_column("b1_"), None);
        assert!(is_lvlh_column("b3_q_lvlh_z_m"));
        assert!(!is_lvlh_column("b3_r_eci_z_m"));
        assert!(!is_lvlh_column("a3_q_lvlh_z_m"));
    }

    #[test]
    fn log_axis_floors_zeros_and_skips_non_finite() {
        let t = [0.0, 1.0, 2.0, 3.0, 4.0];
        let values = [1e4, 0.0, f64::NAN, 1e-30, 0.5];
        let (series, (lo, hi)) = log_series(&t, &[(1, &values)], Some(5.0));
        let floor = 1e4 * 1e-9;
        assert!((lo - floor / 1.5).abs() < 1e-12 && hi == 2e4, "{lo} {hi}");
        let points = &series[0].points;
        assert_eq!(points[0], (0.0, 1e4));
        assert_eq!(points[1], (1.0, floor), "zero drawn at the floor");
        assert!(!is_finite_point(&points[2]), "NaN is a gap");
        assert_eq!(points[3], (3.0, floor), "below the floor: at the floor");
        assert_eq!(points[4], (4.0, 0.5));
        assert_eq!(series[0].label, "servicer 1");

        // All zeros or no data at all still give a valid positive range.
        let (floor, top) = log_bounds([2.0, 0.5, 1.0].into_iter(), None);
        assert_eq!((floor, top), (0.5, 2.0), "no zeros: the floor is the smallest value");
        let (floor, _) = log_bounds([2.0, 0.5, 0.0].into_iter(), None);
        assert_eq!(floor, 0.05, "zeros: a decade lower, so they show");
        let (lo, hi) = log_bounds([0.0, 0.0].into_iter(), None);
        assert!(lo > 0.0 && hi > lo);
        let (lo, hi) = log_bounds(std::iter::empty(), Some(5.0));
        assert!(lo > 0.0 && lo < 5.0 && hi > 5.0, "{lo} {hi}");
    }

    #[test]
    fn time_range_skips_non_finite_ends() {
        assert_eq!(time_range([f64::NAN, 1.0, 5.0, f64::NAN].into_iter()), (1.0, 5.0));
        assert_eq!(time_range([2.0].into_iter()), (2.0, 3.0));
        assert_eq!(time_range(std::iter::empty()), (0.0, 1.0));
    }
}
