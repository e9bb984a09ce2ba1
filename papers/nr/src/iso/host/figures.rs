//! The figures of a seed 003 run ("Neural-Rendezvous", arXiv:2208.04883), for runs of the
//! `neural-rendezvous` algorithm, one line (colour) per spacecraft:
//!
//! * `nr_relative_trajectory.png` — the true position relative to the ISO in its LVLH frame
//!   (radial x, along-track y, cross-track z; km): y–x and y–z views of each approach from the
//!   plant's rows, ending at the true p(t_f) of `snapshots/encounter.csv`, with ρ_f marked;
//! * `nr_error_bound.png` — Fig. 10's quantities over time (log scale): the true distance to the
//!   desired terminal position ‖p − ρ_f‖ over the approach; from t_s the true tracking error
//!   ‖p − p_d‖ (solid) against the bound b_e(t) (dashed), and at t_f (where p_d = ρ_f) the
//!   delivery error (dot) against b_e(t_f) ([`crate::iso::host::analysis::bound_after_last_row`]);
//! * `nr_control.png` — the command in the estimated LVLH frame per axis (N) with ±u_max, and
//!   ‖u* − u_ℓ‖, what the min-norm control (27) changes of the nominal command; t_s marked.

use std::path::Path;

use cohort_report::chart::{DrawResult, series_color};
use cohort_report::{FigureSource, PaperFigure, ReportError, Table, Telemetry};
use cohort_runtime::paper::Setup;
use plotters::style::RGBColor;

use crate::iso::config::IsoEncounterConfig;
use crate::iso::host::analysis::{Encounter, bound_after_last_row, read_encounter, tracking_errors};
use crate::iso::host::kinds::NrSetup;
use crate::plots::{self, Line, Panel, Style};

pub const TRAJECTORY_STEM: &str = "nr_relative_trajectory";
pub const BOUND_STEM: &str = "nr_error_bound";
pub const CONTROL_STEM: &str = "nr_control";
const AXES: [&str; 3] = ["x", "y", "z"];
const H: f64 = 3600.0;

/// What the figures need of the scenario.
pub struct NrFigures {
    label: String,
    n_agents: u32,
    dt_s: f64,
    t_f_s: f64,
    t_s_s: f64,
    u_max_n: f64,
    alpha_per_s: f64,
    lambda_per_s: f64,
}

impl NrFigures {
    /// None for a run of other kinds.
    pub fn of(setup: &Setup) -> Option<Self> {
        let (p, a) = (setup.plant_as::<IsoEncounterConfig>()?, setup.algorithm_as::<NrSetup>()?);
        Some(Self {
            label: format!("{}, {}, ISO {}", setup.scenario.name, a.config.method.name(), p.index(setup.scenario.seed)),
            n_agents: setup.n_agents(),
            dt_s: setup.scenario.dt_s,
            t_f_s: p.t_f_s,
            t_s_s: a.config.t_s_fraction * p.t_f_s,
            u_max_n: p.u_max_n,
            alpha_per_s: a.config.alpha_per_s,
            lambda_per_s: a.config.lambda_per_s,
        })
    }
}

/// A figure ready to draw.
struct Figure {
    stem: &'static str,
    title: String,
    panels: Vec<Panel>,
    cols: usize,
    size: (u32, u32),
}

impl PaperFigure for Figure {
    fn stem(&self) -> &str {
        self.stem
    }
    fn draw(&self, path: &Path) -> DrawResult {
        plots::draw(path, &self.title, &self.panels, self.cols, self.size)
    }
}

fn column<'t>(t: &'t Table, name: &str, file: &Path) -> Result<&'t [f64], ReportError> {
    t.get(name).ok_or_else(|| ReportError::MissingColumn { path: file.to_path_buf(), column: name.to_string() })
}

impl NrFigures {
    fn trajectory(&self, plant: &Table, plant_file: &Path, enc: &[Encounter]) -> Result<Figure, ReportError> {
        let km = 1e-3;
        let mut views =
            [("radial x", "radial x (km)"), ("cross-track z", "cross-track z (km)")].map(|(what, y_desc)| Panel {
                caption: format!("{what} against along-track y"),
                x_desc: "along-track y (km)".into(),
                y_desc: y_desc.into(),
                ..Panel::default()
            });
        for j in 1..=self.n_agents {
            let p: Vec<&[f64]> =
                AXES.iter().map(|a| column(plant, &format!("a{j}_p_{a}_m"), plant_file)).collect::<Result<_, _>>()?;
            let color = series_color(Some(j), j as usize - 1);
            for (view, (h, v)) in views.iter_mut().zip([(1, 0), (1, 2)]) {
                let mut pts: Vec<(f64, f64)> = (0..plant.rows()).map(|k| (p[h][k] * km, p[v][k] * km)).collect();
                if let Some(e) = enc.get(j as usize - 1) {
                    pts.push((e.p_m[h] * km, e.p_m[v] * km));
                    let rho = vec![(e.rho_f_m[h] * km, e.rho_f_m[v] * km)];
                    view.lines.push(Line::new(format!("ρ_f, spacecraft {j}"), color, rho, Style::Markers));
                }
                view.lines.push(Line::new(format!("spacecraft {j}"), color, pts, Style::Solid));
            }
        }
        Ok(Figure {
            stem: TRAJECTORY_STEM,
            title: format!("Relative trajectory in the ISO's LVLH frame ({})", self.label),
            panels: views.into(),
            cols: 2,
            size: (1600, 800),
        })
    }

    fn bound(
        &self,
        plant: &Table,
        pf: &Path,
        agents: &[(u32, Table)],
        enc: &[Encounter],
    ) -> Result<Figure, ReportError> {
        let mut approach = Panel {
            caption: "distance to ρ_f (truth)".into(),
            x_desc: "t (h)".into(),
            y_desc: "m (log scale)".into(),
            log_y: true,
            marks_x: vec![(self.t_s_s / H, "t_s".into())],
            ..Panel::default()
        };
        let mut tracking = Panel {
            caption: "from t_s: ‖p − p_d‖ (truth) and the bound b_e".into(),
            x_desc: "t (h)".into(),
            y_desc: "m (log scale)".into(),
            log_y: true,
            ..Panel::default()
        };
        for (j, agent) in agents {
            let color = series_color(Some(*j), *j as usize - 1);
            let miss = column(plant, &format!("a{j}_miss_m"), pf)?;
            let mut pts: Vec<(f64, f64)> = plant.t.iter().zip(miss).map(|(t, m)| (t / H, *m)).collect();
            let e = enc.get(*j as usize - 1).filter(|e| e.reached_t_f);
            if let Some(e) = e {
                pts.push((self.t_f_s / H, e.miss_m));
            }
            approach.lines.push(Line::new(format!("spacecraft {j}"), color, pts, Style::Solid));
            if agent.get("p_d_x_m").is_none() || agent.get("b_e_m").is_none() {
                continue;
            }
            let e_track = tracking_errors(plant, agent, *j).map_err(|reason| ReportError::PaperInput {
                path: pf.to_path_buf(),
                line: None,
                reason,
            })?;
            let mut err: Vec<(f64, f64)> = agent.t.iter().zip(&e_track).map(|(t, e)| (t / H, *e)).collect();
            let mut bound: Vec<(f64, f64)> = agent
                .t
                .iter()
                .zip(agent.col("b_e_m"))
                .map(|(t, b)| (t / H, if *b >= 0.0 { *b } else { f64::NAN }))
                .collect();
            let b_tf = bound_after_last_row(agent, self.dt_s, self.alpha_per_s, self.lambda_per_s);
            if let (Some(e), Some(b)) = (e, b_tf) {
                // At t_f, p_d = ρ_f: the tracking error is the delivery error.
                err.push((self.t_f_s / H, e.miss_m));
                bound.push((self.t_f_s / H, b));
                tracking.lines.push(Line::new("", color, vec![(self.t_f_s / H, e.miss_m)], Style::Markers));
            }
            if err.iter().any(|q| q.1.is_finite()) {
                tracking.lines.push(Line::new(format!("spacecraft {j}"), color, err, Style::Solid));
            }
            if bound.iter().any(|q| q.1.is_finite()) {
                tracking.lines.push(Line::new("", color, bound, Style::Dashed));
            }
        }
        if !tracking.lines.is_empty() {
            // What the line styles are (legend entries without points).
            let grey = RGBColor(90, 90, 90);
            tracking.lines.push(Line::new("solid: ‖p − p_d‖", grey, Vec::new(), Style::Solid));
            tracking.lines.push(Line::new("dashed: b_e", grey, Vec::new(), Style::Dashed));
            tracking.lines.push(Line::new("dot: delivery error at t_f", grey, Vec::new(), Style::Markers));
        }
        let mut panels = vec![approach];
        if !tracking.lines.is_empty() {
            panels.push(tracking);
        }
        Ok(Figure {
            stem: BOUND_STEM,
            title: format!("Delivery error and its bound ({})", self.label),
            panels,
            cols: 2,
            size: (1700, 750),
        })
    }

    fn control(&self, agents: &[(u32, Table)], run_dir: &Path) -> Result<Figure, ReportError> {
        let mut panels: Vec<Panel> = AXES
            .iter()
            .map(|a| Panel {
                caption: format!("u_{a} (LVLH)"),
                x_desc: "t (h)".into(),
                y_desc: "N".into(),
                marks_x: vec![(self.t_s_s / H, "t_s".into())],
                marks_y: vec![(self.u_max_n, "±u_max".into()), (-self.u_max_n, String::new())],
                ..Panel::default()
            })
            .collect();
        panels.push(Panel {
            caption: "‖u* − u_ℓ‖ (min-norm correction)".into(),
            x_desc: "t (h)".into(),
            y_desc: "N".into(),
            marks_x: vec![(self.t_s_s / H, "t_s".into())],
            ..Panel::default()
        });
        for (j, agent) in agents {
            let file = run_dir.join(format!("telemetry/agent-{j}.csv"));
            let color = series_color(Some(*j), *j as usize - 1);
            let names = AXES.map(|a| format!("u_{a}_n")).into_iter().chain(["du_n".to_string()]);
            for (panel, name) in panels.iter_mut().zip(names) {
                let v = column(agent, &name, &file)?;
                let pts = agent.t.iter().zip(v).map(|(t, u)| (t / H, *u)).collect();
                panel.lines.push(Line::new(format!("spacecraft {j}"), color, pts, Style::Solid));
            }
        }
        Ok(Figure {
            stem: CONTROL_STEM,
            title: format!("Command and min-norm correction ({})", self.label),
            panels,
            cols: 2,
            size: (1600, 1000),
        })
    }
}

impl FigureSource for NrFigures {
    fn figures(&self, t: &Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError> {
        let Some(plant) = t.plant else { return Ok(Vec::new()) };
        let plant_file = t.run_dir.join("telemetry/plant.csv");
        let enc_file = t.run_dir.join("snapshots").join(crate::iso::dynamics::plant::ENCOUNTER_FILE);
        // A run that ended in an error before the plant wrote it has none: draw without t_f.
        let enc = if enc_file.is_file() {
            read_encounter(t.run_dir, self.n_agents).map_err(|reason| ReportError::PaperInput {
                path: enc_file,
                line: None,
                reason,
            })?
        } else {
            Vec::new()
        };
        let mut out: Vec<Box<dyn PaperFigure>> = vec![Box::new(self.trajectory(plant, &plant_file, &enc)?)];
        if !t.agents.is_empty() {
            out.push(Box::new(self.bound(plant, &plant_file, t.agents, &enc)?));
            out.push(Box::new(self.control(t.agents, t.run_dir)?));
        }
        Ok(out)
    }
}
