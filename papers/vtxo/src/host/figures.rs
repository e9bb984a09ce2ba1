//! The figures of a seed-002 run (the paper's Sec. 7 and the science phase), drawn for a run
//! directory with the plant's telemetry and `derived/vtxo.csv` ([`crate::host::analysis`]):
//!
//! * `vtxo_formation.png` — the Figs. 6–8 analogue: (a) r_rel components (ECI, m) against t,
//!   (b) |r_rel − r_f| and the transverse error √(e_x² + e_y²) on a log axis with the 1 m
//!   formation tolerance and the 1 mm transverse requirement (Sec. 2.3), (c) e_x, e_y in mm over
//!   the metrics window at the end of the run (Figs. 7–8 show the last 15 s);
//! * `vtxo_attitude.png` — per spacecraft (columns): the attitude error e = 2 acos|δq₄| from q_f
//!   (deg), and the MEKF's true error δθᵢ per body axis with its ±3σᵢ envelope (µrad);
//! * `vtxo_wheel_torque.png` — the applied wheel torque per spacecraft (mN·m, body axes);
//! * `vtxo_thrust.png` — |F| per spacecraft on a log axis (N), and the follower's thrust
//!   components over the metrics window (the sign law's chattering shows there).
//!
//! With `run.telemetry_every_steps` > 1 the figures show the rows there are. Log axes span at most
//! [`LOG_MAX_DECADES`] decades; zeros and smaller values are drawn at the floor.

use std::path::Path;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use cohort_report::chart::{
    CAPTION_SIZE, DrawResult, FONT_FAMILY, MARGIN, MAX_POINTS, Series, X_LABEL_AREA, Y_LABEL_AREA, downsample_min_max,
    draw_legend, draw_time_series, finite_bounds, format_tick, linear_range, series_color,
};
use cohort_report::{FigureSource, PaperFigure, ReportError, Table, Telemetry};

use crate::host::analysis::{DERIVED_FILE, ROLES};
use crate::model::config::VtxoPlantConfig;

const LOG_MAX_DECADES: i32 = 9;
const PANEL_CAPTION_SIZE: u32 = 19;
const XYZ: [&str; 3] = ["x", "y", "z"];
/// The transverse requirement of Sec. 2.3: < 1 mm.
const TRANSVERSE_REQUIREMENT_M: f64 = 1e-3;

/// A horizontal reference line.
#[derive(Debug, Clone)]
struct Level {
    value: f64,
    label: String,
}

#[derive(Debug)]
struct Panel {
    caption: String,
    y_desc: String,
    log: bool,
    series: Vec<Series>,
    /// Drawn thin and grey over the series (the ±3σ envelope): the label goes in the legend once.
    envelope: Option<(String, Vec<Series>)>,
    levels: Vec<Level>,
}

#[derive(Debug)]
pub struct VtxoFigure {
    stem: String,
    title: String,
    size: (u32, u32),
    grid: (usize, usize),
    panels: Vec<Panel>,
}

impl PaperFigure for VtxoFigure {
    fn stem(&self) -> &str {
        &self.stem
    }
    fn draw(&self, path: &Path) -> DrawResult {
        draw(path, self)
    }
}

/// The figures of a run of the `vtxo` plant (see the module docs).
pub struct VtxoFigures {
    /// The end-of-run window of the metrics (plant.metrics.transverse_window_s), s.
    pub window_s: f64,
    /// The formation tolerance (plant.metrics.formation_tolerance_m), m.
    pub tolerance_m: f64,
}

impl VtxoFigures {
    pub fn of(p: &VtxoPlantConfig) -> Self {
        Self { window_s: p.metrics.transverse_window_s, tolerance_m: p.metrics.formation_tolerance_m }
    }
}

impl FigureSource for VtxoFigures {
    fn figures(&self, t: &Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError> {
        let Some(plant) = t.plant else { return Ok(Vec::new()) };
        let plant_path = t.run_dir.join("telemetry/plant.csv");
        let need = |table: &Table, path: &Path, name: &str| -> Result<Vec<f64>, ReportError> {
            table
                .get(name)
                .map(<[f64]>::to_vec)
                .ok_or_else(|| ReportError::MissingColumn { path: path.to_path_buf(), column: name.to_string() })
        };
        let p = |name: &str| need(plant, &plant_path, name);
        let mut out: Vec<Box<dyn PaperFigure>> = vec![
            Box::new(self.formation(&plant.t, &p)?),
            Box::new(wheel_torque(&plant.t, &p)?),
            Box::new(self.thrust(&plant.t, &p)?),
        ];
        let derived_path = t.run_dir.join(DERIVED_FILE);
        if derived_path.is_file() {
            let derived = Table::read(&derived_path)?;
            let d = |name: &str| need(&derived, &derived_path, name);
            out.push(Box::new(attitude(&plant.t, &p, &derived.t, &d)?));
        }
        Ok(out)
    }
}

type Column<'a> = dyn Fn(&str) -> Result<Vec<f64>, ReportError> + 'a;

fn series(label: impl Into<String>, color: RGBColor, t: &[f64], y: &[f64]) -> Series {
    Series { label: label.into(), color, points: downsample_min_max(t, y, MAX_POINTS) }
}

/// The rows from `t_end − window_s` on.
fn window_start(t: &[f64], window_s: f64) -> usize {
    let end = t.last().copied().unwrap_or(0.0);
    t.iter().position(|&x| x >= end - window_s - 1e-9).unwrap_or(0)
}

fn panel(caption: impl Into<String>, y_desc: impl Into<String>, log: bool, series: Vec<Series>) -> Panel {
    Panel { caption: caption.into(), y_desc: y_desc.into(), log, series, envelope: None, levels: Vec::new() }
}

impl VtxoFigures {
    fn formation(&self, t: &[f64], p: &Column<'_>) -> Result<VtxoFigure, ReportError> {
        let comps: Vec<Series> = XYZ
            .iter()
            .enumerate()
            .map(|(i, ax)| {
                Ok(series(format!("r_rel,{ax}"), series_color(None, i), t, &p(&format!("r_rel_eci_{ax}_m"))?))
            })
            .collect::<Result<_, ReportError>>()?;
        let mut errors = panel(
            "(b) formation error |r_rel − r_f| and transverse error √(e_x² + e_y²)",
            "error [m]",
            true,
            vec![
                series("|r_rel − r_f|", series_color(None, 0), t, &p("formation_error_m")?),
                series("transverse √(e_x² + e_y²)", series_color(None, 3), t, &p("transverse_error_m")?),
            ],
        );
        errors.levels = vec![
            Level {
                value: self.tolerance_m,
                label: format!("{} m: formation reached", format_tick(&self.tolerance_m)),
            },
            Level { value: TRANSVERSE_REQUIREMENT_M, label: "1 mm: transverse requirement".into() },
        ];
        let from = window_start(t, self.window_s);
        let tail: Vec<Series> = ["x", "y"]
            .iter()
            .enumerate()
            .map(|(i, ax)| {
                let mm: Vec<f64> = p(&format!("transverse_error_{ax}_m"))?[from..].iter().map(|v| v * 1e3).collect();
                Ok(series(format!("e_{ax}"), series_color(None, i), &t[from..], &mm))
            })
            .collect::<Result<_, ReportError>>()?;
        Ok(VtxoFigure {
            stem: "vtxo_formation".into(),
            title: "Figs. 6–8 analogue — relative position (ECI) and transverse error".into(),
            size: (1300, 1500),
            grid: (3, 1),
            panels: vec![
                panel("(a) r_rel = r_F − r_L, ECI components", "r_rel [m]", false, comps),
                errors,
                panel(
                    format!("(c) transverse error over the last {} s", format_tick(&self.window_s)),
                    "e [mm]",
                    false,
                    tail,
                ),
            ],
        })
    }

    fn thrust(&self, t: &[f64], p: &Column<'_>) -> Result<VtxoFigure, ReportError> {
        let norms: Vec<Series> = ROLES
            .iter()
            .enumerate()
            .map(|(i, role)| {
                let c: Vec<Vec<f64>> =
                    XYZ.iter().map(|ax| p(&format!("{role}_thrust_eci_{ax}_n"))).collect::<Result<_, _>>()?;
                let norm: Vec<f64> = (0..t.len()).map(|r| c.iter().map(|v| v[r] * v[r]).sum::<f64>().sqrt()).collect();
                Ok(series(format!("{role} |F|"), series_color(Some(i as u32 + 1), 0), t, &norm))
            })
            .collect::<Result<_, ReportError>>()?;
        let from = window_start(t, self.window_s);
        let comps: Vec<Series> = XYZ
            .iter()
            .enumerate()
            .map(|(i, ax)| {
                let v = p(&format!("follower_thrust_eci_{ax}_n"))?;
                Ok(series(format!("F_{ax}"), series_color(None, i), &t[from..], &v[from..]))
            })
            .collect::<Result<_, ReportError>>()?;
        Ok(VtxoFigure {
            stem: "vtxo_thrust".into(),
            title: "Applied thrust (ECI)".into(),
            size: (1300, 1100),
            grid: (2, 1),
            panels: vec![
                panel("(a) |F| per spacecraft", "|F| [N]", true, norms),
                panel(
                    format!("(b) follower thrust components over the last {} s", format_tick(&self.window_s)),
                    "F [N]",
                    false,
                    comps,
                ),
            ],
        })
    }
}

fn wheel_torque(t: &[f64], p: &Column<'_>) -> Result<VtxoFigure, ReportError> {
    let panels = ROLES
        .iter()
        .map(|role| {
            let s: Vec<Series> = XYZ
                .iter()
                .enumerate()
                .map(|(i, ax)| {
                    let mnm: Vec<f64> = p(&format!("{role}_tau_in_body_{ax}_n_m"))?.iter().map(|v| v * 1e3).collect();
                    Ok(series(format!("τ_{ax}"), series_color(None, i), t, &mnm))
                })
                .collect::<Result<_, ReportError>>()?;
            Ok(panel(role.to_string(), "τ [mN·m]", false, s))
        })
        .collect::<Result<_, ReportError>>()?;
    Ok(VtxoFigure {
        stem: "vtxo_wheel_torque".into(),
        title: "Applied reaction-wheel torque (body axes)".into(),
        size: (1300, 1000),
        grid: (2, 1),
        panels,
    })
}

fn attitude(t: &[f64], p: &Column<'_>, td: &[f64], d: &Column<'_>) -> Result<VtxoFigure, ReportError> {
    // Row-major grid: row 0 the attitude errors, rows 1–3 the axes; column per spacecraft.
    let mut panels = Vec::new();
    for (i, role) in ROLES.iter().enumerate() {
        let e = p(&format!("{role}_attitude_error_deg"))?;
        let color = series_color(Some(i as u32 + 1), 0);
        panels.push(panel(
            format!("{role}: attitude error from q_f"),
            "e [deg]",
            false,
            vec![series("e", color, t, &e)],
        ));
    }
    for (a, ax) in XYZ.iter().enumerate() {
        for role in ROLES {
            let err: Vec<f64> = d(&format!("{role}_dtheta_{ax}_rad"))?.iter().map(|v| v * 1e6).collect();
            let s3: Vec<f64> = d(&format!("{role}_sigma_theta_{ax}_rad"))?.iter().map(|v| 3e6 * v).collect();
            let neg: Vec<f64> = s3.iter().map(|v| -v).collect();
            let grey = RGBColor(70, 70, 70);
            let mut pn = panel(
                format!("{role}: MEKF error δθ_{ax}"),
                "δθ [µrad]",
                false,
                vec![series(format!("δθ_{ax}"), series_color(None, a), td, &err)],
            );
            pn.envelope = Some(("±3σ".into(), vec![series("+3σ", grey, td, &s3), series("−3σ", grey, td, &neg)]));
            panels.push(pn);
        }
    }
    Ok(VtxoFigure {
        stem: "vtxo_attitude".into(),
        title: "Attitude error and the MEKF's true error with its ±3σ envelope".into(),
        size: (1500, 1600),
        grid: (4, 2),
        panels,
    })
}

/// `(floor, top)` of a log axis over the panel's values: at most [`LOG_MAX_DECADES`] decades.
fn log_range(p: &Panel) -> (f64, f64) {
    let positive = p.series.iter().flat_map(|s| s.points.iter().map(|q| q.1)).chain(p.levels.iter().map(|l| l.value));
    let bounds = finite_bounds(positive.filter(|v| *v > 0.0));
    let Some((lo, hi)) = bounds else { return (1e-3, 1.0) };
    let floor = lo.max(hi * 10f64.powi(-LOG_MAX_DECADES));
    if floor >= hi { (hi / 10.0, hi * 10.0) } else { (floor / 1.5, hi * 2.0) }
}

fn draw(path: &Path, fig: &VtxoFigure) -> DrawResult {
    let root = BitMapBackend::new(path, fig.size).into_drawing_area();
    root.fill(&WHITE)?;
    let body = root.titled(&fig.title, (FONT_FAMILY, CAPTION_SIZE))?;
    for (area, p) in body.split_evenly(fig.grid).iter().zip(&fig.panels) {
        let all = || p.series.iter().chain(p.envelope.iter().flat_map(|(_, e)| e.iter())).flat_map(|s| s.points.iter());
        let (t0, t1) = linear_range(finite_bounds(all().map(|q| q.0)));
        let mut builder = ChartBuilder::on(area);
        builder
            .caption(&p.caption, (FONT_FAMILY, PANEL_CAPTION_SIZE))
            .margin(MARGIN / 2)
            .x_label_area_size(X_LABEL_AREA - 10)
            .y_label_area_size(Y_LABEL_AREA - 20);
        if p.log {
            let (lo, hi) = log_range(p);
            let clamp = |s: &Series| Series {
                label: s.label.clone(),
                color: s.color,
                points: s.points.iter().map(|&(x, y)| (x, if y.is_finite() { y.max(lo) } else { y })).collect(),
            };
            let clamped = Panel {
                caption: String::new(),
                y_desc: format!("{} (log scale)", p.y_desc),
                log: true,
                series: p.series.iter().map(clamp).collect(),
                envelope: None,
                levels: p.levels.clone(),
            };
            let mut chart = builder.build_cartesian_2d(t0..t1, (lo..hi).log_scale())?;
            fill(&mut chart, &clamped, (t0, t1))?;
        } else {
            let extra = p.levels.iter().map(|l| l.value);
            let (y0, y1) = linear_range(finite_bounds(all().map(|q| q.1).chain(extra)));
            let mut chart = builder.build_cartesian_2d(t0..t1, y0..y1)?;
            fill(&mut chart, p, (t0, t1))?;
        }
    }
    root.present()?;
    Ok(())
}

fn fill<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    p: &Panel,
    (t0, t1): (f64, f64),
) -> DrawResult
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    draw_time_series(chart, &p.y_desc, &p.series, 1)?;
    if let Some((label, env)) = &p.envelope {
        for (i, s) in env.iter().enumerate() {
            let style = s.color.stroke_width(1);
            let drawn =
                chart.draw_series(LineSeries::new(s.points.iter().copied().filter(|q| q.1.is_finite()), style))?;
            if i == 0 {
                drawn.label(label).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
            }
        }
    }
    for (i, l) in p.levels.iter().enumerate() {
        let style = RGBColor(90, 90, 90).stroke_width(2);
        let dash = if i == 0 { (12, 8) } else { (4, 5) };
        chart
            .draw_series(DashedLineSeries::new([(t0, l.value), (t1, l.value)], dash.0, dash.1, style))?
            .label(&l.label)
            .legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (dash.0 - 2, 0)], style)
                    + PathElement::new(vec![(dash.0 + 4, 0), (24, 0)], style)
            });
    }
    draw_legend(chart)
}
