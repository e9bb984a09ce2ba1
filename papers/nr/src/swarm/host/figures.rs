//! The figures of a swarm run (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883; its Figs. 18–19
//! show the trajectories), for runs of the `nr-swarm` algorithm, one colour per vehicle:
//!
//! * `swarm_trajectories.png` — every vehicle's true path in 3-D (z up) from the plant's rows,
//!   ending at its position after the last interval (`snapshots/swarm.csv`); a dot at the start,
//!   a cross and the vehicle's number at its goal;
//! * `swarm_min_distance.png` — the least pairwise distance in the collision metric
//!   ‖diag(0.12, 0.12, 0.30)⁻¹Δp‖ over each control interval (the plant's 10 checks per
//!   interval) against time, with the collision level 1 and the sampling separation 1.25 marked;
//!   and each vehicle's distance to its goal (log scale) with 0.1 m and T marked.

use std::path::Path;

use cohort_report::chart::{DrawResult, FONT_FAMILY, draw_legend, ensure_font, series_color};
use cohort_report::chart3d::cube_chart;
use cohort_report::{ColumnUse, FigureSource, PaperFigure, ReportError, Table, Telemetry};
use cohort_runtime::paper::Setup;
use plotters::prelude::*;

use crate::plots::{self, Line, Panel, Style};
use crate::swarm::config::SwarmConfig;
use crate::swarm::dynamics::plant::SWARM_FILE;
use crate::swarm::dynamics::setup::{CUBOID_M, MIN_SAMPLE_SEPARATION};
use crate::swarm::host::analysis::{ARRIVED_M, VehicleEnd, read_end};
use crate::swarm::host::kinds::SwarmSetup;

pub const TRAJECTORIES_STEM: &str = "swarm_trajectories";
pub const MIN_DISTANCE_STEM: &str = "swarm_min_distance";
const AXES: [&str; 3] = ["x", "y", "z"];

/// What the figures need of the scenario.
pub struct SwarmFigures {
    label: String,
    n: u32,
    t_reconfig_s: f64,
}

impl SwarmFigures {
    /// None for a run of other kinds.
    pub fn of(setup: &Setup) -> Option<Self> {
        let (p, a) = (setup.plant_as::<SwarmConfig>()?, setup.algorithm_as::<SwarmSetup>()?);
        Some(Self {
            label: format!(
                "{}, {} over {}, d̄ = {} m/s²",
                setup.scenario.name,
                a.config.method.name(),
                a.config.policy.name(),
                p.disturbance_mps2
            ),
            n: setup.n_agents(),
            t_reconfig_s: p.t_reconfig_s,
        })
    }
}

fn column<'t>(t: &'t Table, name: &str, file: &Path) -> Result<&'t [f64], ReportError> {
    t.get(name).ok_or_else(|| ReportError::MissingColumn { path: file.to_path_buf(), column: name.to_string() })
}

/// The 3-D paths (world frame) with start, goal and number.
struct Trajectories {
    title: String,
    paths: Vec<Vec<[f64; 3]>>,
    goals: Vec<[f64; 3]>,
}

impl PaperFigure for Trajectories {
    fn stem(&self) -> &str {
        TRAJECTORIES_STEM
    }

    /// Chart axes (world y, z, x): z vertical, a cyclic permutation so the view is not mirrored.
    fn draw(&self, path: &Path) -> DrawResult {
        ensure_font()?;
        let all = self.paths.iter().flatten().chain(&self.goals);
        let mut r = CUBOID_M.map(|[lo, hi]| (lo, hi));
        for p in all.filter(|p| p.iter().all(|x| x.is_finite())) {
            for a in 0..3 {
                r[a] = (r[a].0.min(p[a]), r[a].1.max(p[a]));
            }
        }
        let to_chart = |p: &[f64; 3]| (p[1], p[2], p[0]);
        let root = BitMapBackend::new(path, (1300, 1100)).into_drawing_area();
        let mut chart = cube_chart(&root, &self.title, [r[1], r[2], r[0]], (0.6, 0.35, 0.8))?;
        let font = (FONT_FAMILY, 16).into_font().color(&BLACK);
        for (j, (p, g)) in self.paths.iter().zip(&self.goals).enumerate() {
            let color = series_color(Some(j as u32 + 1), j);
            let pts: Vec<_> = p.iter().filter(|q| q.iter().all(|x| x.is_finite())).map(to_chart).collect();
            chart.draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))?;
            if let Some(s) = pts.first() {
                chart.draw_series(std::iter::once(Circle::new(*s, 5, color.filled())))?;
            }
            chart.draw_series(std::iter::once(Cross::new(to_chart(g), 7, color.stroke_width(3))))?;
            chart.draw_series(std::iter::once(
                EmptyElement::at(to_chart(g)) + Text::new(format!("{}", j + 1), (8, -16), font.clone()),
            ))?;
        }
        let grey = RGBColor(80, 80, 80);
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64, f64), i32>>())?
            .label("start")
            .legend(move |(x, y)| Circle::new((x + 12, y), 5, grey.filled()));
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64, f64), i32>>())?
            .label("goal (vehicle number); axes x, y, z in m, z up")
            .legend(move |(x, y)| Cross::new((x + 12, y), 7, grey.stroke_width(3)));
        draw_legend(&mut chart)?;
        root.present()?;
        Ok(())
    }
}

/// A figure of line panels.
struct Panels {
    title: String,
    panels: Vec<Panel>,
}

impl PaperFigure for Panels {
    fn stem(&self) -> &str {
        MIN_DISTANCE_STEM
    }
    fn draw(&self, path: &Path) -> DrawResult {
        plots::draw(path, &self.title, &self.panels, 2, (1700, 750))
    }
}

impl SwarmFigures {
    fn trajectories(&self, plant: &Table, file: &Path, end: &[VehicleEnd]) -> Result<Trajectories, ReportError> {
        let mut paths = Vec::new();
        for j in 1..=self.n {
            let c: Vec<&[f64]> =
                AXES.iter().map(|a| column(plant, &format!("a{j}_p_{a}_m"), file)).collect::<Result<_, _>>()?;
            let mut p: Vec<[f64; 3]> = (0..plant.rows()).map(|k| [c[0][k], c[1][k], c[2][k]]).collect();
            p.extend(end.get(j as usize - 1).map(|e| e.p_m));
            paths.push(p);
        }
        Ok(Trajectories {
            title: format!("Swarm trajectories ({})", self.label),
            paths,
            goals: end.iter().map(|e| e.goal_m).collect(),
        })
    }

    /// The separation from the swarm's columns (`plant`), the arrival from the vehicles' (`aside`).
    fn distances(&self, plant: &Table, aside: &Table, file: &Path) -> Result<Panels, ReportError> {
        let least = column(plant, "min_pair_ellipsoid_interval", file)?;
        let mut sep = Panel {
            caption: "least pairwise ‖diag(0.12, 0.12, 0.30)⁻¹Δp‖ over each interval".into(),
            x_desc: "t (s)".into(),
            y_desc: "ellipsoid distance".into(),
            marks_y: vec![(1.0, "collision".into()), (MIN_SAMPLE_SEPARATION, "sampled ≥ 1.25".into())],
            marks_x: vec![(self.t_reconfig_s, "T".into())],
            ..Panel::default()
        };
        let pts = plant.t.iter().zip(least).map(|(t, d)| (*t, *d)).collect();
        sep.lines.push(Line::new("least pair", RGBColor(30, 30, 30), pts, Style::Solid));
        let mut goal = Panel {
            caption: "distance to the goal (truth)".into(),
            x_desc: "t (s)".into(),
            y_desc: "m (log scale)".into(),
            log_y: true,
            marks_y: vec![(ARRIVED_M, "0.1 m".into())],
            marks_x: vec![(self.t_reconfig_s, "T".into())],
            ..Panel::default()
        };
        for j in 1..=self.n {
            let d = column(aside, &format!("a{j}_goal_dist_m"), file)?;
            let pts = aside.t.iter().zip(d).map(|(t, d)| (*t, *d)).collect();
            let label = if self.n <= 10 { format!("vehicle {j}") } else { String::new() };
            goal.lines.push(Line::new(label, series_color(Some(j), j as usize - 1), pts, Style::Solid));
        }
        Ok(Panels { title: format!("Separation and arrival ({})", self.label), panels: vec![sep, goal] })
    }
}

impl FigureSource for SwarmFigures {
    /// The per-vehicle columns are drawn here; the generic figures keep the swarm's three.
    fn plant_column(&self, name: &str) -> ColumnUse {
        if name.starts_with('a') && name.contains('_') { ColumnUse::PaperOnly } else { ColumnUse::Generic }
    }

    fn figures(&self, t: &Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError> {
        let (Some(plant), Some(aside)) = (t.plant, t.plant_aside) else { return Ok(Vec::new()) };
        let file = t.run_dir.join("telemetry/plant.csv");
        let end_file = t.run_dir.join("snapshots").join(SWARM_FILE);
        // A run that ended in an error before the plant wrote it has none: draw the rows alone.
        let end = if end_file.is_file() {
            read_end(t.run_dir, self.n)
                .map_err(|reason| ReportError::PaperInput { path: end_file, line: None, reason })?
                .0
        } else {
            Vec::new()
        };
        Ok(vec![Box::new(self.trajectories(aside, &file, &end)?), Box::new(self.distances(plant, aside, &file)?)])
    }
}
