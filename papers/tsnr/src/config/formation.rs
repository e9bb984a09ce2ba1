//! Seed 001 (tethered space net robot): the `tsnr-formation` algorithm table — the desired
//! trajectories and the three formation controllers compared in Sec. 4 (AEMC, DMPC, SMC) — and
//! its validation.
//!
//! One table serves all three methods so that a scenario compares them by changing `method`
//! alone: the trajectory is shared; `[algorithm.mpc]` holds the weights AEMC and DMPC share (and
//! the game terms only AEMC uses), `[algorithm.smc]` the sliding-mode gains. A table (or key) the
//! selected method does not use may stay in the file and is ignored.
//!
//! The controllers' model of an MU — the orbit radius of its CW equations, its mass and its thrust
//! bound — is the `tsnr-net` plant's (one source of truth in the file; [`TsnrModel::of`]). A
//! model-mismatch study would add keys here.

use std::sync::Arc;

use cohort_runtime::model::Algorithm;
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, section_as, table_of,
};
use cohort_scenario::{Checker, Problem, Scenario, fmt_f64};
use serde::{Deserialize, Serialize};

use crate::config::net_plant::{TsnrNetKind, TsnrNetPlant, TsnrNetSetup};

/// Readings of the state and measured tension an MU's controller needs: [r; v] (6) and T (3).
pub const READINGS_USED: usize = 9;
/// Leading values of every tsnr-formation share: own state [r; v] at t_k (6) and the thrust
/// commanded at t_k (3) (what the tension predictor needs of a neighbour).
pub const SHARE_HEADER: usize = 9;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TsnrFormation {
    /// The controller; see [`Method`].
    pub method: Method,
    pub trajectory: TsnrTrajectory,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mpc: Option<TsnrMpc>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smc: Option<TsnrSmc>,
}

/// What the controllers know of an MU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TsnrModel {
    /// Radius of the target's circular orbit, m: the Clohessy–Wiltshire mean motion.
    pub orbit_radius_m: f64,
    pub mass_kg: f64,
    /// Every controller keeps |uₓ|, |u_y|, |u_z| ≤ this, N.
    pub thrust_max_n: f64,
}

impl TsnrModel {
    /// The `tsnr-net` plant's values.
    pub fn of(p: &TsnrNetPlant) -> Self {
        Self { orbit_radius_m: p.orbit_radius_m, mass_kg: p.mu_mass_kg, thrust_max_n: p.thrust_bound_n }
    }
}

/// `algorithm.method`: the three controllers of Sec. 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Cooperative-game DMPC with tension prediction (Sec. 3).
    Aemc,
    /// The same MPC per MU, no game terms, measured tension compensated.
    Dmpc,
    /// Force-compensation sliding mode.
    Smc,
}

impl Method {
    /// Every method, in the paper's order.
    pub const ALL: [Method; 3] = [Method::Aemc, Method::Dmpc, Method::Smc];
    pub fn name(self) -> &'static str {
        match self {
            Method::Aemc => "aemc",
            Method::Dmpc => "dmpc",
            Method::Smc => "smc",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown method {s:?} (expected {})", Method::ALL.map(Method::name).join(", ")))
    }
}

/// `algorithm.mpc.tension_forecast`: what AEMC takes for the net tension over its horizon.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Forecast {
    /// The latest measurement held over the horizon.
    HoldMeasured,
    /// The paper's estimator (7)–(11), weights from `tension_weights`.
    Dnn,
    /// The tension an earlier run recorded (`tension_oracle`, its plant telemetry), replayed:
    /// an upper bound on what a forecast can give (`crate::oracle_forecast`).
    Oracle,
}

impl Forecast {
    pub fn name(self) -> &'static str {
        match self {
            Forecast::HoldMeasured => "hold-measured",
            Forecast::Dnn => "dnn",
            Forecast::Oracle => "oracle",
        }
    }
}

/// Desired trajectories: one waypoint per knot for every MU, joined by quintic segments.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TsnrTrajectory {
    /// Knot times, s, strictly increasing (at least 2).
    pub knots_s: Vec<f64>,
    /// One entry per agent.
    pub agents: Vec<TsnrWaypoints>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TsnrWaypoints {
    /// The agent these waypoints are for.
    pub id: u32,
    /// Position at each knot, LVLH, m.
    pub r_m: Vec<[f64; 3]>,
    /// Velocity at each knot, LVLH, m/s (absent: zero at every knot).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v_mps: Option<Vec<[f64; 3]>>,
}

impl TsnrWaypoints {
    /// Velocities at the knots (zeros when not given).
    pub fn velocities(&self) -> Vec<[f64; 3]> {
        self.v_mps.clone().unwrap_or_else(|| vec![[0.0; 3]; self.r_m.len()])
    }
}

/// The receding-horizon controllers (AEMC and DMPC). Q = diag(q_position·I₃, q_velocity·I₃)
/// weighs the (consensus) error, R = r_force·I₃ the total force ûᵢ = uᵢ + T̂ᵢ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TsnrMpc {
    /// Prediction horizon N_p, control steps of scenario.dt_s (1..=1000).
    pub horizon_steps: u32,
    /// Weight on position error, 1/m².
    pub q_position: f64,
    /// Weight on velocity error, 1/(m/s)².
    pub q_velocity: f64,
    /// R_i, weight on the MU's own total force, 1/N².
    pub r_force: f64,
    /// AEMC: R_ij, the weight MU i puts on a neighbour's total force, 1/N² (≥ 0).
    pub r_neighbour_force: f64,
    /// AEMC: a_ij > 0 for every listed neighbour j (the graph is the scenario's neighbour lists).
    pub adjacency_weight: f64,
    /// AEMC: b_i > 0, the pinning of every MU to its own desired trajectory.
    pub pinning_weight: f64,
    /// AEMC: Pareto weights λ_i of (18), one per agent in id order, each in (0, 1), summing to 1
    /// (absent: 1/N each).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pareto_weights: Option<Vec<f64>>,
    /// AEMC: whether MU i's QP includes its neighbours' costs J_j (the terms of (18) that depend
    /// on Uᵢ: their consensus errors and R_ji). false: only its own J_i, exactly (25)–(26).
    #[serde(default = "default_true")]
    pub neighbour_costs: bool,
    /// AEMC: the tension forecast T̂ᵢ; see [`Forecast`].
    #[serde(default = "default_forecast")]
    pub tension_forecast: Forecast,
    /// With `tension_forecast = "dnn"`: the weights file (safetensors, from `orchestrator tsnr
    /// train`), relative to the scenario file. Its Δt must be `scenario.dt_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tension_weights: Option<String>,
    /// With `tension_forecast = "oracle"`: an earlier run's `telemetry/plant.csv`, relative to
    /// the scenario file; it must cover this run's steps at this Δt.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tension_oracle: Option<String>,
    /// That file's tension series, loaded by validation.
    #[serde(skip)]
    pub oracle_series: Option<Arc<crate::oracle_forecast::Series>>,
    /// Which force R (and R_ij) weighs; see [`ForceCost`].
    #[serde(default)]
    pub force_cost: ForceCost,
    /// Iteration limit per QP (of the active-set method, and of Clarabel's interior point).
    #[serde(default = "default_max_iter")]
    pub max_iter: u32,
    /// How the QP is solved; see [`QpSolver`].
    #[serde(default)]
    pub qp_solver: QpSolver,
}

/// `algorithm.mpc.force_cost`: the force the MPCs' weight R is on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ForceCost {
    /// The total force ûᵢ = uᵢ + T̂ᵢ, as the paper's cost (23) writes it.
    #[default]
    Total,
    /// The MU's own thrust uᵢ = ûᵢ − T̂ᵢ (what it spends fuel on): R|û − T̂|², the same Hessian
    /// and a linear term −2R T̂.
    Thrust,
}

/// `algorithm.mpc.qp_solver`: how AEMC and DMPC solve their box-constrained QP (25).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum QpSolver {
    /// Exact primal–dual active set, warm-started from the previous step's active set; Clarabel
    /// when it stalls (`crate::agents::active_set`).
    #[default]
    ActiveSet,
    /// Clarabel's interior point alone (tolerances 1e-10).
    Clarabel,
}

fn default_true() -> bool {
    true
}
fn default_forecast() -> Forecast {
    Forecast::HoldMeasured
}
fn default_max_iter() -> u32 {
    100
}

impl TsnrMpc {
    /// λ_i of agent `id` (1-based) among `n`.
    pub fn pareto_weight(&self, id: u32, n: u32) -> f64 {
        self.pareto_weights.as_ref().map_or(1.0 / f64::from(n), |w| w[id as usize - 1])
    }
}

/// Force-compensation sliding mode: s = ė + λe, u = −T_meas + m(r̈_d − f_CW − λė − k·sat(s/φ)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TsnrSmc {
    /// λ of the sliding surface, 1/s.
    pub lambda_per_s: f64,
    /// k, the switching gain, m/s².
    pub switching_gain_mps2: f64,
    /// φ, the boundary-layer half-width on s, m/s.
    pub boundary_layer_mps: f64,
}

impl TsnrFormation {
    /// Values per share for a graph whose largest neighbour list has `max_degree` entries:
    /// the header, plus for AEMC Uᵢ (3N_p) and each neighbour's age, state and plan (7 + 3N_p;
    /// `crate::agents::aemc` has the layout).
    pub fn share_values(&self, max_degree: usize) -> usize {
        match (self.method, &self.mpc) {
            (Method::Aemc, Some(m)) => crate::agents::aemc::share_len(m.horizon_steps as usize, max_degree),
            _ => SHARE_HEADER,
        }
    }
}

impl TsnrFormation {
    /// AEMC agent `id`'s tension forecast, as `mpc.tension_forecast` selects it (validated: the
    /// MPC table is present and its files load).
    pub fn forecast_of(&self, id: u32) -> Box<dyn crate::forecast::TensionForecast> {
        let m = self.mpc.as_ref().expect("validated: aemc needs [algorithm.mpc]");
        match m.tension_forecast {
            Forecast::HoldMeasured => Box::new(crate::forecast::HoldMeasured),
            Forecast::Oracle => {
                let series = m.oracle_series.clone().expect("validated: oracle needs tension_oracle, loaded");
                Box::new(crate::oracle_forecast::OracleForecast::new(series, id))
            }
            Forecast::Dnn => {
                let path = m.tension_weights.as_deref().expect("validated: dnn needs tension_weights");
                // Validation loaded this file already; it can only fail here if it changed since.
                let predictor = crate::predictor::TensionPredictor::load(std::path::Path::new(path))
                    .unwrap_or_else(|e| panic!("{e}"));
                Box::new(crate::dnn_forecast::DnnForecast::new(Arc::new(predictor), id))
            }
        }
    }
}

/// Check the section; resolves a relative `tension_weights` path against the scenario file.
fn validate_algorithm(c: &mut Checker, s: &Scenario, a: &mut TsnrFormation) {
    trajectory(c, s, &a.trajectory);
    let n = s.agents.len();
    if let Some(m) = &mut a.mpc {
        // The condensed QP is dense in 3N_p variables: past 1000 steps it would not fit a control step.
        if m.horizon_steps == 0 || m.horizon_steps > 1000 {
            c.fail("algorithm.mpc.horizon_steps", m.horizon_steps, "must be 1..=1000");
        }
        c.positive("algorithm.mpc.q_position", m.q_position);
        c.non_negative("algorithm.mpc.q_velocity", m.q_velocity);
        c.positive("algorithm.mpc.r_force", m.r_force);
        c.non_negative("algorithm.mpc.r_neighbour_force", m.r_neighbour_force);
        c.positive("algorithm.mpc.adjacency_weight", m.adjacency_weight);
        c.positive("algorithm.mpc.pinning_weight", m.pinning_weight);
        if let Some(w) = &m.pareto_weights {
            let path = "algorithm.mpc.pareto_weights";
            if w.len() != n {
                c.fail(path, format!("{} entries", w.len()), format!("one per agent: {n}"));
            } else if c.all_finite(path, w) {
                for (k, x) in w.iter().enumerate() {
                    if !(*x > 0.0 && *x < 1.0) {
                        c.fail(format!("{path}[{k}]"), fmt_f64(*x), "must be in (0, 1)");
                    }
                }
                let sum: f64 = w.iter().sum();
                if (sum - 1.0).abs() > 1e-9 {
                    c.fail(path, format!("{w:?}"), format!("must sum to 1 (sums to {sum})"));
                }
            }
        }
        if let Some(path) = &mut m.tension_weights {
            *path = s.resolve_path(path);
        }
        if let Some(path) = &mut m.tension_oracle {
            *path = s.resolve_path(path);
        }
        match (m.tension_forecast, &m.tension_oracle) {
            (Forecast::Oracle, None) => c.problems.push(Problem::new(
                "algorithm.mpc.tension_oracle",
                None,
                "required by tension_forecast = \"oracle\" (an earlier run's telemetry/plant.csv)",
            )),
            (Forecast::Oracle, Some(path)) => {
                let steps = s.n_steps();
                match crate::oracle_forecast::load(std::path::Path::new(path), n as u32, steps, s.scenario.dt_s) {
                    Ok(series) => m.oracle_series = Some(Arc::new(series)),
                    Err(e) => c.fail("algorithm.mpc.tension_oracle", format!("{path:?}"), e),
                }
            }
            (_, Some(path)) => c.fail(
                "algorithm.mpc.tension_oracle",
                format!("{path:?}"),
                "only used with tension_forecast = \"oracle\"",
            ),
            _ => {}
        }
        match (m.tension_forecast, &m.tension_weights) {
            (Forecast::Dnn, None) => c.problems.push(Problem::new(
                "algorithm.mpc.tension_weights",
                None,
                "required by tension_forecast = \"dnn\" (e.g. \"../papers/tsnr/weights/tension.safetensors\")",
            )),
            (Forecast::Dnn, Some(path)) => match crate::predictor::TensionPredictor::load(std::path::Path::new(path)) {
                Err(e) => c.fail("algorithm.mpc.tension_weights", format!("{path:?}"), e.to_string()),
                Ok(p) if (p.dt_s() - s.scenario.dt_s).abs() > 1e-12 => c.fail(
                    "algorithm.mpc.tension_weights",
                    format!("{path:?}"),
                    format!(
                        "trained for Δt = {} s, the control step (scenario.dt_s) is {} s",
                        p.dt_s(),
                        s.scenario.dt_s
                    ),
                ),
                Ok(_) => {}
            },
            (_, Some(path)) => c.fail(
                "algorithm.mpc.tension_weights",
                format!("{path:?}"),
                "only used with tension_forecast = \"dnn\"",
            ),
            _ => {}
        }
        if m.max_iter == 0 || m.max_iter > 10_000 {
            c.fail("algorithm.mpc.max_iter", m.max_iter, "must be 1..=10000");
        }
    } else if a.method != Method::Smc {
        c.problems.push(Problem::new(
            "algorithm.mpc",
            None,
            format!("required by algorithm.method = {:?} (horizon and weights)", a.method.name()),
        ));
    }
    if let Some(g) = &a.smc {
        c.positive("algorithm.smc.lambda_per_s", g.lambda_per_s);
        c.positive("algorithm.smc.switching_gain_mps2", g.switching_gain_mps2);
        c.positive("algorithm.smc.boundary_layer_mps", g.boundary_layer_mps);
    } else if a.method == Method::Smc {
        c.problems.push(Problem::new("algorithm.smc", None, "required by algorithm.method = \"smc\" (gains)"));
    }
    if a.method == Method::Aemc {
        // The game needs each neighbour's share and, for its Pareto terms, to be read back.
        for (k, ag) in s.agents.iter().enumerate() {
            if ag.neighbours.is_empty() && n > 1 {
                c.fail(format!("agents[{k}].neighbours"), "[]", "AEMC: every MU needs at least one neighbour");
            }
        }
    }
}

fn trajectory(c: &mut Checker, s: &Scenario, t: &TsnrTrajectory) {
    let path = "algorithm.trajectory.knots_s";
    let knots_ok = if t.knots_s.len() < 2 {
        c.fail(path, format!("{:?}", t.knots_s), "at least 2 knots");
        false
    } else if c.all_finite(path, &t.knots_s) {
        let mut ok = true;
        for k in 1..t.knots_s.len() {
            if t.knots_s[k] <= t.knots_s[k - 1] {
                c.fail(
                    format!("{path}[{k}]"),
                    fmt_f64(t.knots_s[k]),
                    format!("knots must increase strictly (previous {})", fmt_f64(t.knots_s[k - 1])),
                );
                ok = false;
            }
        }
        ok
    } else {
        false
    };
    let n = s.agents.len();
    let mut seen = vec![false; n + 1];
    for (k, w) in t.agents.iter().enumerate() {
        let p = format!("algorithm.trajectory.agents[{k}]");
        if w.id == 0 || w.id as usize > n {
            c.fail(format!("{p}.id"), w.id, format!("not an agent of this scenario (ids 1..={n})"));
        } else if seen[w.id as usize] {
            c.fail(format!("{p}.id"), w.id, "waypoints given twice for this agent");
        } else {
            seen[w.id as usize] = true;
        }
        if knots_ok && w.r_m.len() != t.knots_s.len() {
            c.fail(
                format!("{p}.r_m"),
                format!("{} waypoints", w.r_m.len()),
                format!("one per knot of algorithm.trajectory.knots_s ({})", t.knots_s.len()),
            );
        }
        for (m, r) in w.r_m.iter().enumerate() {
            c.all_finite(&format!("{p}.r_m[{m}]"), r);
        }
        if let Some(v) = &w.v_mps {
            if knots_ok && v.len() != t.knots_s.len() {
                c.fail(
                    format!("{p}.v_mps"),
                    format!("{} velocities", v.len()),
                    format!("one per knot of algorithm.trajectory.knots_s ({})", t.knots_s.len()),
                );
            }
            for (m, x) in v.iter().enumerate() {
                c.all_finite(&format!("{p}.v_mps[{m}]"), x);
            }
        }
    }
    for (id, seen) in seen.iter().enumerate().skip(1) {
        if !seen {
            c.problems.push(Problem::new(
                "algorithm.trajectory.agents",
                None,
                format!("no waypoints for agent {id}: every agent needs its desired trajectory"),
            ));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Kind and setup

pub struct TsnrFormationKind;

impl AlgorithmKind for TsnrFormationKind {
    fn kind(&self) -> &'static str {
        "tsnr-formation"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        _plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<TsnrFormation>(&ctx.scenario.algorithm.body, "algorithm", c);
        if ctx.scenario.plant.kind != TsnrNetKind.kind() {
            c.fail("algorithm.kind", "\"tsnr-formation\"", "needs plant.kind = \"tsnr-net\"");
        }
        let mut a = a?;
        validate_algorithm(c, ctx.scenario, &mut a);
        Some(Arc::new(a))
    }
}

impl AlgorithmSetup for TsnrFormation {
    fn kind(&self) -> &'static str {
        TsnrFormationKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn share_values(&self, s: &Scenario) -> usize {
        self.share_values(s.agents.iter().map(|a| a.neighbours.len()).max().unwrap_or(0))
    }
    /// The method `method` names. AEMC's tension forecast is chosen by `mpc.tension_forecast`.
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        use crate::agents::{aemc::TsnrAemc, dmpc::TsnrDmpc, smc::TsnrSmc};
        let dt_s = setup.scenario.dt_s;
        let plant = setup.plant_as::<TsnrNetSetup>().expect("validated: tsnr-formation needs the tsnr-net plant");
        let model = TsnrModel::of(&plant.config);
        match self.method {
            Method::Aemc => {
                let forecast = self.forecast_of(id);
                let graph = setup.topology().neighbours;
                Box::new(TsnrAemc::new(self, &model, dt_s, setup.run.link_delay_steps, id, &graph, forecast))
            }
            Method::Dmpc => Box::new(TsnrDmpc::new(self, &model, dt_s, id)),
            Method::Smc => Box::new(TsnrSmc::new(self, &model, id)),
        }
    }
}

/// A scenario's raw `algorithm.method` replaced (what `orchestrator tsnr compare --algorithms`
/// does to each run), before it is configured and validated like a file. Another algorithm kind
/// is an error: it has no method to replace.
pub fn with_method(mut s: Scenario, method: Method) -> Result<Scenario, Problem> {
    if s.algorithm.kind != TsnrFormationKind.kind() {
        return Err(Problem::new(
            "algorithm.kind",
            Some(format!("{:?}", s.algorithm.kind)),
            "--algorithms needs a tsnr-formation scenario",
        ));
    }
    s.algorithm.body.insert("method".into(), toml::Value::String(method.name().into()));
    Ok(s)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use cohort_runtime::paper::{Paper, configure};
    use cohort_scenario::{Overrides, parse};

    use super::*;

    const PAPERS: &[&dyn Paper] = &[&crate::Tsnr, &cohort_kinds_generic::Generic];

    fn case(n: u32) -> String {
        std::fs::read_to_string(format!("{}/../../topologies/tsnr-case{n}.toml", env!("CARGO_MANIFEST_DIR"))).unwrap()
    }

    /// The text configured as a file of the topologies directory (so its weights path resolves).
    fn configured(text: &str) -> Result<Setup, String> {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/x.toml");
        let s = parse(text, &file, &Overrides::default()).map_err(|e| e.to_string())?;
        configure(s, PAPERS).map_err(|p| p.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n"))
    }

    fn problems(text: &str) -> String {
        configured(text).unwrap_err()
    }

    #[test]
    fn both_cases_parse_and_round_trip() {
        for n in [1, 2] {
            let s = configured(&case(n)).unwrap();
            let a = s.algorithm_as::<TsnrFormation>().expect("tsnr-formation");
            assert_eq!(a.method, Method::Aemc);
            assert_eq!(a.trajectory.agents.len(), 4);
            let again = configured(&s.to_toml().unwrap()).unwrap();
            assert_eq!(s.to_toml().unwrap(), again.to_toml().unwrap());
            assert_eq!(again.algorithm_as::<TsnrFormation>(), Some(a));
        }
    }

    #[test]
    fn the_clarabel_case_differs_from_case_1_in_its_solver_alone() {
        let read = |name: &str| -> toml::Table {
            let path = format!("{}/../../topologies/{name}", env!("CARGO_MANIFEST_DIR"));
            std::fs::read_to_string(path).unwrap().parse().unwrap()
        };
        let (mut a, mut b) = (read("tsnr-case1.toml"), read("tsnr-case1-clarabel.toml"));
        for t in [&mut a, &mut b] {
            let sc = t["scenario"].as_table_mut().unwrap();
            sc.remove("name");
            sc.remove("description");
        }
        let solver = |t: &mut toml::Table| {
            t["algorithm"].as_table_mut().unwrap()["mpc"].as_table_mut().unwrap().remove("qp_solver")
        };
        assert_eq!(solver(&mut a), Some(toml::Value::String("active-set".into())));
        assert_eq!(solver(&mut b), Some(toml::Value::String("clarabel".into())));
        assert_eq!(a, b);
    }

    #[test]
    fn an_oracle_forecast_needs_a_readable_series_covering_the_run() {
        let base = case(1).replace("tension_forecast = \"dnn\"", "tension_forecast = \"oracle\"");
        let e = problems(&base);
        assert!(
            e.contains("algorithm.mpc.tension_weights") && e.contains("only used with tension_forecast = \"dnn\""),
            "{e}"
        );
        let no_weights = base.replace("tension_weights = \"../papers/tsnr/weights/tension.safetensors\"\n", "");
        let e = problems(&no_weights);
        assert!(e.contains("algorithm.mpc.tension_oracle: required by tension_forecast = \"oracle\""), "{e}");
        let missing = no_weights.replace("max_iter = 100", "max_iter = 100\ntension_oracle = \"no/such/plant.csv\"");
        let e = problems(&missing);
        assert!(e.contains("algorithm.mpc.tension_oracle = ") && e.contains("no/such/plant.csv"), "{e}");
    }

    #[test]
    fn bad_values_are_each_reported_with_their_key_path() {
        let bad = case(2)
            .replace("knots_s = [0.0, 10.0, 20.0, 30.0]", "knots_s = [0.0, 10.0, 10.0, 30.0]")
            .replace("adjacency_weight = 0.25", "adjacency_weight = 0.25\npareto_weights = [0.5, 0.5, 0.5, 0.5]")
            .replace("lambda_per_s = 1.5", "lambda_per_s = -1.5")
            .replace("\nid = 3\nr_m", "\nid = 5\nr_m");
        let e = problems(&bad);
        for want in [
            "algorithm.trajectory.knots_s[2] = 10.0: knots must increase strictly",
            "algorithm.mpc.pareto_weights = [0.5, 0.5, 0.5, 0.5]: must sum to 1",
            "algorithm.smc.lambda_per_s = -1.5: must be > 0",
            "algorithm.trajectory.agents[2].id = 5: not an agent of this scenario",
            "algorithm.trajectory.agents: no waypoints for agent 3",
        ] {
            assert!(e.contains(want), "missing {want:?} in\n{e}");
        }
    }

    #[test]
    fn the_selected_method_needs_its_table_and_the_net_plant() {
        let text = case(1);
        let start = text.find("[algorithm.smc]").unwrap();
        let end =
            start + text[start..].find("boundary_layer_mps = 0.2\n").unwrap() + "boundary_layer_mps = 0.2\n".len();
        let no_smc = format!("{}{}", &text[..start], &text[end..]);
        // Without the SMC table AEMC is still fine; SMC is not.
        assert!(configured(&no_smc).is_ok());
        let e = problems(&no_smc.replace("method = \"aemc\"", "method = \"smc\""));
        assert!(e.contains("algorithm.smc: required by algorithm.method = \"smc\""), "{e}");
        let e = problems(
            &text
                .replace("kind = \"tsnr-net\"\n", "kind = \"null\"\nreadings = 9\n")
                .replace("orbit_radius_m = 42164e3\nmu_mass_kg = 10.0\nthrust_bound_n = 5.0\n", ""),
        );
        assert!(e.contains("algorithm.kind = \"tsnr-formation\": needs plant.kind = \"tsnr-net\""), "{e}");
    }

    #[test]
    fn the_method_override_replaces_the_files_method_and_is_validated() {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/x.toml");
        let raw = |text: &str| parse(text, &file, &Overrides::default()).unwrap();
        let s = configure(with_method(raw(&case(2)), Method::Smc).unwrap(), PAPERS).unwrap();
        assert_eq!(s.algorithm_as::<TsnrFormation>().unwrap().method, Method::Smc);
        let e = "pid".parse::<Method>().unwrap_err();
        assert!(e.contains("unknown method \"pid\""), "{e}");
        let mut pid = raw(&case(1));
        pid.algorithm.body.insert("method".into(), toml::Value::String("pid".into()));
        let e = configure(pid, PAPERS).unwrap_err().iter().map(|p| p.to_string()).collect::<String>();
        assert!(e.contains("algorithm.method = \"pid\": must be"), "{e}");
        let ring =
            std::fs::read_to_string(format!("{}/../../topologies/consensus-ring.toml", env!("CARGO_MANIFEST_DIR")))
                .unwrap();
        let e = with_method(raw(&ring), Method::Aemc).unwrap_err().to_string();
        assert!(
            e.contains("algorithm.kind = \"consensus-formation\": --algorithms needs a tsnr-formation scenario"),
            "{e}"
        );
    }
}
