//! The `tsnr-net` plant table and its validation. The net model itself is `crate::net`; the
//! defaults are the project's choices where the paper is silent (see the crate README).

use std::sync::Arc;

use cohort_runtime::model::PlantModel;
use cohort_runtime::paper::{
    ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, agent_keys, section_as, table_of,
};
use cohort_scenario::{Checker, Problem, Scenario, fmt_f64};
use serde::{Deserialize, Serialize};

use crate::net::NetParams;

/// Readings per measurement: the MU's own [x, y, z, vx, vy, vz] in the target's LVLH frame
/// (m, m/s), then the net tension on it [Tx, Ty, Tz] (N).
pub const READINGS: usize = 9;

/// Number of agents the plant needs: one per corner of the net.
pub const N_MU: usize = crate::net::N_MU;

/// The net and its four MUs, relative to a target on a circular orbit (CW equations). Agent i is
/// MU i (MU1 (+y, +z), MU2 (−y, +z), MU3 (+y, −z), MU4 (−y, −z) at the paper's start); its
/// `r0_m`/`v0_mps` are the MU's initial state in the target's LVLH frame and the net starts
/// folded between the four MUs (the grid mapped onto their square).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TsnrNetPlant {
    /// Nodes along each side of the net (3..=64).
    #[serde(default = "default_nodes_per_side")]
    pub nodes_per_side: usize,
    /// Rest length of every mesh edge, m.
    #[serde(default = "default_edge_rest_m")]
    pub edge_rest_m: f64,
    /// Net mass, spread evenly over the non-corner nodes, kg.
    #[serde(default = "default_net_mass_kg")]
    pub net_mass_kg: f64,
    /// Mass of each MU (a corner node; the net puts no mass on the corners), kg.
    #[serde(default = "default_mu_mass_kg")]
    pub mu_mass_kg: f64,
    /// Axial stiffness EA of an edge, N.
    #[serde(default = "default_ea_n")]
    pub ea_n: f64,
    /// Damping coefficient c of an edge, N·s/m.
    #[serde(default = "default_damping")]
    pub damping_n_s_per_m: f64,
    /// Radius of the target's circular orbit, m.
    #[serde(default = "default_orbit_radius_m")]
    pub orbit_radius_m: f64,
    /// Longest RK4 sub-step, s (below the net's stability limit, ≈ 6 ms for the defaults).
    #[serde(default = "default_substep_s")]
    pub substep_s: f64,
    /// Thrust bound per axis per MU, N. Commands beyond it are applied as sent and counted in
    /// the `thrust_bound_violations` metric.
    #[serde(default = "default_thrust_bound_n")]
    pub thrust_bound_n: f64,
    /// Times at which every node's position is written to `snapshots/net_nodes.csv`, s: whole
    /// numbers of steps of scenario.dt_s, ascending, within [0, duration_s].
    #[serde(default = "default_snapshot_times_s")]
    pub snapshot_times_s: Vec<f64>,
}

fn default_nodes_per_side() -> usize {
    NetParams::default().nodes_per_side
}
fn default_edge_rest_m() -> f64 {
    NetParams::default().edge_rest_m
}
fn default_net_mass_kg() -> f64 {
    NetParams::default().net_mass_kg
}
fn default_mu_mass_kg() -> f64 {
    NetParams::default().mu_mass_kg
}
fn default_ea_n() -> f64 {
    NetParams::default().ea_n
}
fn default_damping() -> f64 {
    NetParams::default().damping_n_s_per_m
}
fn default_orbit_radius_m() -> f64 {
    NetParams::default().orbit_radius_m
}
fn default_substep_s() -> f64 {
    NetParams::default().substep_s
}
fn default_thrust_bound_n() -> f64 {
    5.0
}
fn default_snapshot_times_s() -> Vec<f64> {
    vec![0.0, 10.0, 20.0, 30.0]
}

impl TsnrNetPlant {
    pub fn net_params(&self) -> NetParams {
        NetParams {
            nodes_per_side: self.nodes_per_side,
            edge_rest_m: self.edge_rest_m,
            net_mass_kg: self.net_mass_kg,
            mu_mass_kg: self.mu_mass_kg,
            ea_n: self.ea_n,
            damping_n_s_per_m: self.damping_n_s_per_m,
            orbit_radius_m: self.orbit_radius_m,
            substep_s: self.substep_s,
        }
    }

    /// The step index of each snapshot time (validated to be whole steps of `dt_s`).
    pub fn snapshot_steps(&self, dt_s: f64) -> Vec<u64> {
        self.snapshot_times_s.iter().map(|t| (t / dt_s).round() as u64).collect()
    }
}

/// An MU's per-agent keys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MuAgent {
    /// MU initial position in the target's LVLH frame, m.
    pub r0_m: Option<[f64; 3]>,
    /// MU initial velocity in the target's LVLH frame, m/s.
    pub v0_mps: Option<[f64; 3]>,
}

pub struct TsnrNetKind;

/// A configured `tsnr-net` plant: the section and the MUs' initial states in id order.
pub struct TsnrNetSetup {
    pub config: TsnrNetPlant,
    pub r0_m: [[f64; 3]; N_MU],
    pub v0_mps: [[f64; 3]; N_MU],
}

impl PlantKind for TsnrNetKind {
    fn kind(&self) -> &'static str {
        "tsnr-net"
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let s = ctx.scenario;
        let p = section_as::<TsnrNetPlant>(&s.plant.body, "plant", c);
        let agents = agent_keys::<MuAgent>(s, c);
        if let Some(p) = &p {
            validate_plant(c, s, p);
        }
        let agents = agents?;
        let mut all = s.agents.len() == N_MU;
        for (k, a) in agents.iter().enumerate() {
            for (key, v, what) in [
                ("r0_m", &a.r0_m, "MU initial position in the target's LVLH frame, m"),
                ("v0_mps", &a.v0_mps, "MU initial velocity in the target's LVLH frame, m/s"),
            ] {
                match v {
                    None => {
                        all = false;
                        c.problems.push(Problem::new(
                            format!("agents[{k}].{key}"),
                            None,
                            format!("required by plant.kind = \"tsnr-net\" ({what})"),
                        ))
                    }
                    Some(v) => c.vec3(&format!("agents[{k}].{key}"), v),
                }
            }
        }
        let mut p = p?;
        if !ctx.ids_ok || !all {
            return None;
        }
        // Noted above: a --duration that ends the run earlier drops the later snapshots.
        let end = s.scenario.duration_s * (1.0 + 1e-12);
        p.snapshot_times_s.retain(|&t| t <= end);
        let order = by_id(s);
        Some(Arc::new(TsnrNetSetup {
            config: p,
            r0_m: std::array::from_fn(|i| agents[order[i]].r0_m.expect("checked above")),
            v0_mps: std::array::from_fn(|i| agents[order[i]].v0_mps.expect("checked above")),
        }))
    }
}

/// Agent index (file order) of every id 1..=N (ids validated).
fn by_id(s: &Scenario) -> Vec<usize> {
    (1..=s.n_agents()).map(|id| s.agents.iter().position(|a| a.id == id).expect("validated: ids are 1..=N")).collect()
}

impl PlantSetup for TsnrNetSetup {
    fn kind(&self) -> &'static str {
        TsnrNetKind.kind()
    }
    fn link_frame(&self) -> cohort_runtime::paper::LinkFrame {
        cohort_runtime::paper::LinkFrame::Relative
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        READINGS
    }
    fn command_len(&self) -> usize {
        3
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        let p = &self.config;
        let dt_s = setup.scenario.dt_s;
        let plant = crate::net_plant::TsnrNetPlant::new(
            p.net_params(),
            self.r0_m,
            self.v0_mps,
            p.thrust_bound_n,
            dt_s,
            p.snapshot_steps(dt_s),
        );
        Box::new(plant.expect("validated: the net parameters passed NetParams::validate"))
    }
}

fn validate_plant(c: &mut Checker, s: &Scenario, p: &TsnrNetPlant) {
    if let Err(e) = p.net_params().validate() {
        c.fail(format!("plant.{}", e.name), e.value, e.reason);
    }
    c.positive("plant.thrust_bound_n", p.thrust_bound_n);
    let (dt, end) = (s.scenario.dt_s, s.scenario.duration_s);
    let time_ok = dt.is_finite() && dt > 0.0 && end.is_finite() && end > 0.0;
    let mut last = f64::NEG_INFINITY;
    for (k, &t) in p.snapshot_times_s.iter().enumerate() {
        let path = format!("plant.snapshot_times_s[{k}]");
        if !c.finite(&path, t) {
            continue;
        }
        if t <= last {
            c.fail(&path, fmt_f64(t), "snapshot times must be strictly ascending");
        }
        last = t;
        if time_ok {
            let steps = t / dt;
            if t > end * (1.0 + 1e-12) && s.duration_from_command_line {
                c.note(&path, fmt_f64(t), "past the end of the run shortened by --duration: no snapshot then");
            } else if t < 0.0 || t > end * (1.0 + 1e-12) {
                c.fail(&path, fmt_f64(t), format!("outside the run [0, {}] s", fmt_f64(end)));
            } else if (steps - steps.round()).abs() > 1e-6 * steps.max(1.0) {
                c.fail(
                    &path,
                    fmt_f64(t),
                    format!("must be a whole number of steps of scenario.dt_s = {}", fmt_f64(dt)),
                );
            }
        }
    }
    if s.agents.len() != N_MU {
        c.fail(
            "agents",
            format!("{} entries", s.agents.len()),
            format!("plant.kind = \"tsnr-net\" needs exactly {N_MU} agents, the MUs at the net's corners"),
        );
    }
}
