//! Sanity checks on a parsed scenario. Every check runs, so a file reports all its problems at
//! once, each with its key path, value and reason. Nothing starts before these pass.

use cohort_wire::msg::{MAX_AGENTS, MAX_COMMAND, MAX_READINGS, MAX_SHARE_VALUES};

use crate::error::Problem;
use crate::schema::*;

/// Longest run we accept, in steps (keeps telemetry and counters sane).
const MAX_STEPS: u64 = 1_000_000_000;

/// Collects problems; every check records its own (path, value, reason) and returns whether it
/// passed, so callers can skip checks that depend on it.
pub(crate) struct Checker {
    pub(crate) problems: Vec<Problem>,
}

impl Checker {
    pub(crate) fn new() -> Self {
        Self { problems: Vec::new() }
    }
    pub(crate) fn fail(&mut self, path: impl Into<String>, value: impl ToString, reason: impl Into<String>) {
        self.problems.push(Problem::new(path, Some(value.to_string()), reason));
    }
    pub(crate) fn finite(&mut self, path: &str, x: f64) -> bool {
        if x.is_finite() {
            true
        } else {
            self.fail(path, fmt_f64(x), "must be a finite number");
            false
        }
    }
    pub(crate) fn positive(&mut self, path: &str, x: f64) -> bool {
        if !self.finite(path, x) {
            return false;
        }
        if x <= 0.0 {
            self.fail(path, fmt_f64(x), "must be > 0");
            return false;
        }
        true
    }
    pub(crate) fn non_negative(&mut self, path: &str, x: f64) {
        if self.finite(path, x) && x < 0.0 {
            self.fail(path, fmt_f64(x), "must be ≥ 0");
        }
    }
    pub(crate) fn all_finite(&mut self, path: &str, v: &[f64]) -> bool {
        let mut ok = true;
        for (k, x) in v.iter().enumerate() {
            ok &= self.finite(&format!("{path}[{k}]"), *x);
        }
        ok
    }
    pub(crate) fn vec3(&mut self, path: &str, v: &[f64; 3]) {
        self.all_finite(path, v);
    }
}

pub(crate) fn fmt_f64(x: f64) -> String {
    if x.is_nan() { "nan".into() } else { format!("{x:?}") }
}

pub fn validate(s: &Scenario) -> Vec<Problem> {
    let mut c = Checker::new();
    meta(&mut c, &s.scenario);
    run(&mut c, &s.run);
    let ids_ok = agents(&mut c, &s.agents);
    plant(&mut c, s);
    algorithm(&mut c, s);
    if ids_ok {
        bounds(&mut c, s);
    }
    let (dt, dur) = (s.scenario.dt_s, s.scenario.duration_s);
    if dt.is_finite() && dt > 0.0 && dur.is_finite() && dur > 0.0 {
        crate::faults::check(&mut c, &s.faults, s.n_agents(), dt, dur);
    }
    if s.run.checkpoint_every_steps == 0
        && let Some(k) = s.faults.iter().position(|f| f.kind == "restart")
    {
        c.fail(
            "run.checkpoint_every_steps",
            0,
            format!("faults[{k}] restarts an agent, which resumes from its latest checkpoint: must be > 0"),
        );
    }
    c.problems
}

fn meta(c: &mut Checker, m: &Meta) {
    if m.name.is_empty() || !m.name.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_') {
        c.fail("scenario.name", format!("{:?}", m.name), "must be non-empty and use only letters, digits, '-' and '_'");
    }
    let dt_ok = m.dt_s.is_finite() && m.dt_s > 0.0;
    c.positive("scenario.dt_s", m.dt_s);
    c.positive("scenario.duration_s", m.duration_s);
    if dt_ok && m.duration_s.is_finite() && m.duration_s > 0.0 {
        let steps = m.duration_s / m.dt_s;
        if steps < 1.0 - 1e-9 {
            c.fail(
                "scenario.dt_s",
                fmt_f64(m.dt_s),
                format!("longer than scenario.duration_s = {}", fmt_f64(m.duration_s)),
            );
        } else if steps.round() > MAX_STEPS as f64 {
            c.fail("scenario.duration_s", fmt_f64(m.duration_s), format!("more than {MAX_STEPS} steps of dt_s"));
        } else if (steps - steps.round()).abs() > 1e-6 * steps.max(1.0) {
            c.fail(
                "scenario.duration_s",
                fmt_f64(m.duration_s),
                format!("must be a whole number of steps of scenario.dt_s = {} ({steps} is not)", fmt_f64(m.dt_s)),
            );
        }
    }
}

fn run(c: &mut Checker, r: &RunSettings) {
    if !["adaptive", "event", "poll"].contains(&r.wait.as_str()) {
        c.fail("run.wait", format!("{:?}", r.wait), "must be \"adaptive\", \"event\" or \"poll\"");
    }
    if let Some(us) = r.spin_us
        && c.finite("run.spin_us", us)
        && !(0.0..=1e6).contains(&us)
    {
        c.fail("run.spin_us", fmt_f64(us), "must be in [0, 1e6] µs");
    }
    if r.transport != "iceoryx2" && r.transport != "udp" {
        c.fail("run.transport", format!("{:?}", r.transport), "must be \"iceoryx2\" or \"udp\"");
    }
    if let Some(rate) = r.realtime_rate {
        c.positive("run.realtime_rate", rate);
    }
    if r.on_agent_loss != "degrade" && r.on_agent_loss != "abort" {
        c.fail("run.on_agent_loss", format!("{:?}", r.on_agent_loss), "must be \"degrade\" or \"abort\"");
    }
    if r.link_delay_steps > 1 {
        c.fail("run.link_delay_steps", r.link_delay_steps, "must be 0 or 1");
    }
    for (path, x) in [("run.step_timeout_s", r.step_timeout_s), ("run.startup_timeout_s", r.startup_timeout_s)] {
        c.positive(path, x);
        if x.is_finite() && x > 3600.0 {
            c.fail(path, fmt_f64(x), "must be at most 3600 s");
        }
    }
}

/// Ids, neighbour lists and connectivity. Returns whether ids are exactly 1..=N (later checks
/// index agents by id).
fn agents(c: &mut Checker, agents: &[AgentConfig]) -> bool {
    let n = agents.len();
    if n == 0 {
        c.fail("agents", "[]", "at least one agent is required");
        return false;
    }
    if n > MAX_AGENTS {
        c.fail("agents", format!("{n} entries"), format!("at most {MAX_AGENTS} agents are supported"));
        return false;
    }
    let mut ids_ok = true;
    let mut seen = vec![false; n + 1];
    for (k, a) in agents.iter().enumerate() {
        if a.id == 0 || a.id as usize > n {
            c.fail(format!("agents[{k}].id"), a.id, format!("out of range: ids must be 1..={n}, one per agent"));
            ids_ok = false;
        } else if seen[a.id as usize] {
            c.fail(format!("agents[{k}].id"), a.id, "duplicate id");
            ids_ok = false;
        } else {
            seen[a.id as usize] = true;
        }
    }
    let mut nbrs_ok = true;
    for (k, a) in agents.iter().enumerate() {
        let mut listed = Vec::new();
        for (m, &j) in a.neighbours.iter().enumerate() {
            let path = format!("agents[{k}].neighbours[{m}]");
            if !agents.iter().any(|b| b.id == j) {
                c.fail(path, j, "not an agent of this scenario");
                nbrs_ok = false;
            } else if j == a.id {
                c.fail(path, j, "an agent cannot be its own neighbour");
                nbrs_ok = false;
            } else if listed.contains(&j) {
                c.fail(path, j, "listed twice");
                nbrs_ok = false;
            }
            listed.push(j);
        }
    }
    if ids_ok && nbrs_ok && n > 1 {
        connectivity(c, agents);
    }
    ids_ok
}

/// The (undirected) communication graph must be connected (Assumption 2 of seed 000, and
/// what every formation algorithm here needs).
fn connectivity(c: &mut Checker, agents: &[AgentConfig]) {
    let groups = crate::live_graph::components(agents, &vec![true; agents.len()]);
    if groups.len() > 1 {
        let g: Vec<String> = groups
            .iter()
            .map(|g| format!("{{{}}}", g.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", ")))
            .collect();
        c.fail(
            "agents[].neighbours",
            format!("{} components", groups.len()),
            format!(
                "the communication graph is disconnected (Assumption 2 of seed 000; every method here needs it \
                 connected): {}",
                g.join(" and ")
            ),
        );
    }
}

fn plant(c: &mut Checker, s: &Scenario) {
    let require = |c: &mut Checker, k: usize, key: &str, present: bool, what: &str, kind: &str| {
        if !present {
            c.problems.push(Problem::new(
                format!("agents[{k}].{key}"),
                None,
                format!("required by plant.kind = \"{kind}\" ({what})"),
            ));
        }
    };
    match &s.plant {
        PlantConfig::DoubleIntegrator(p) => {
            c.non_negative("plant.position_noise_std_m", p.position_noise_std_m);
            for (k, a) in s.agents.iter().enumerate() {
                let kind = "double-integrator";
                require(c, k, "r0_m", a.r0_m.is_some(), "initial position, m", kind);
                require(c, k, "v0_mps", a.v0_mps.is_some(), "initial velocity, m/s", kind);
                if let Some(r) = &a.r0_m {
                    c.vec3(&format!("agents[{k}].r0_m"), r);
                }
                if let Some(v) = &a.v0_mps {
                    c.vec3(&format!("agents[{k}].v0_mps"), v);
                }
            }
        }
        PlantConfig::Orbital(p) => orbital(c, s, p),
        PlantConfig::Null(_) => {}
        PlantConfig::RigidBody(p) => c.problems.extend(crate::dai::validate_plant(s, p)),
        PlantConfig::TsnrNet(p) => c.problems.extend(crate::tsnr_net::validate_plant(s, p)),
    }
}

fn orbital(c: &mut Checker, s: &Scenario, p: &OrbitalPlant) {
    c.non_negative("plant.noise_std_m", p.noise_std_m);
    if p.substeps == 0 || p.substeps > 10_000 {
        c.fail("plant.substeps", p.substeps, "must be 1..=10000");
    }
    c.positive("plant.drag_coeff", p.drag_coeff);
    if p.density_hold != "step" && p.density_hold != "stage" {
        c.fail("plant.density_hold", format!("{:?}", p.density_hold), "must be \"step\" or \"stage\"");
    }
    let d = &p.defunct;
    c.positive("plant.defunct.periapsis_alt_m", d.periapsis_alt_m);
    c.positive("plant.defunct.apoapsis_alt_m", d.apoapsis_alt_m);
    if d.periapsis_alt_m.is_finite() && d.apoapsis_alt_m.is_finite() && d.apoapsis_alt_m < d.periapsis_alt_m {
        c.fail(
            "plant.defunct.apoapsis_alt_m",
            fmt_f64(d.apoapsis_alt_m),
            format!("below plant.defunct.periapsis_alt_m = {}", fmt_f64(d.periapsis_alt_m)),
        );
    }
    if c.finite("plant.defunct.inclination_rad", d.inclination_rad)
        && !(0.0..=std::f64::consts::PI).contains(&d.inclination_rad)
    {
        c.fail("plant.defunct.inclination_rad", fmt_f64(d.inclination_rad), "must be in [0, π]");
    }
    c.finite("plant.defunct.raan_rad", d.raan_rad);
    c.finite("plant.defunct.arg_periapsis_rad", d.arg_periapsis_rad);
    c.positive("plant.defunct.mass_kg", d.mass_kg);
    c.non_negative("plant.defunct.area_m2", d.area_m2);
    if let Some(r) = &p.random_offsets {
        for (key, lo_min) in [("range_m", Some(0.0)), ("azimuth_rad", None), ("elevation_rad", None)] {
            let v = match key {
                "range_m" => r.range_m,
                "azimuth_rad" => r.azimuth_rad,
                _ => r.elevation_rad,
            };
            let path = format!("plant.random_offsets.{key}");
            if c.finite(&format!("{path}[0]"), v[0]) && c.finite(&format!("{path}[1]"), v[1]) {
                if v[0] > v[1] {
                    c.fail(&path, format!("[{}, {}]", fmt_f64(v[0]), fmt_f64(v[1])), "lower bound above upper bound");
                }
                if lo_min.is_some_and(|m| v[0] <= m) {
                    c.fail(&path, format!("[{}, {}]", fmt_f64(v[0]), fmt_f64(v[1])), "ranges must be > 0");
                }
            }
        }
    }
    let kind = "orbital";
    let mut sum = nalgebra::Matrix3::<f64>::zeros();
    let mut rows_ok = true;
    for (k, a) in s.agents.iter().enumerate() {
        let req = |c: &mut Checker, key: &str, present: bool, what: &str| {
            if !present {
                c.problems.push(Problem::new(
                    format!("agents[{k}].{key}"),
                    None,
                    format!("required by plant.kind = \"{kind}\" ({what})"),
                ));
            }
        };
        req(c, "mass_kg", a.mass_kg.is_some(), "spacecraft mass, kg");
        req(c, "area_m2", a.area_m2.is_some(), "drag cross-section, m²");
        req(c, "output_matrix", a.output_matrix.is_some(), "Cᵢ of yᵢ = Cᵢ(q₀ − qᵢ), 1–4 rows of 3");
        if p.random_offsets.is_none() {
            req(
                c,
                "offset_lvlh_m",
                a.offset_lvlh_m.is_some(),
                "start offset from the defunct in its LVLH frame, m; or give plant.random_offsets",
            );
        }
        if let Some(m) = a.mass_kg {
            c.positive(&format!("agents[{k}].mass_kg"), m);
        }
        if let Some(x) = a.area_m2 {
            c.non_negative(&format!("agents[{k}].area_m2"), x);
        }
        if let Some(o) = &a.offset_lvlh_m {
            c.vec3(&format!("agents[{k}].offset_lvlh_m"), o);
        }
        if a.b() > 1 {
            c.fail(format!("agents[{k}].b"), a.b(), "must be 0 or 1");
        }
        if let Some(cm) = &a.output_matrix {
            let path = format!("agents[{k}].output_matrix");
            if cm.is_empty() || cm.len() > 4 {
                c.fail(&path, format!("{} rows", cm.len()), "must have 1 to 4 rows of 3");
                rows_ok = false;
            }
            for (r, row) in cm.iter().enumerate() {
                for (col, x) in row.iter().enumerate() {
                    rows_ok &= c.finite(&format!("{path}[{r}][{col}]"), *x);
                }
            }
            if rows_ok && a.b() == 1 {
                for row in cm {
                    let v = nalgebra::Vector3::from_row_slice(row);
                    sum += v * v.transpose();
                }
            }
        }
    }
    let all_given = s.agents.iter().all(|a| a.output_matrix.is_some());
    if rows_ok && all_given {
        let eig = sum.symmetric_eigenvalues();
        let max = eig.iter().cloned().fold(0.0, f64::max);
        let rank = eig.iter().filter(|&&e| e > 1e-9 * max.max(1e-300)).count();
        if rank < 3 {
            c.fail(
                "agents[].output_matrix",
                format!("rank {rank}"),
                format!(
                    "the defunct spacecraft is not trackable (Def. 1 of seed 000): rank(Σ bᵢ CᵢᵀCᵢ) = {rank} < 3 \
                     (eigenvalues {:.3e}, {:.3e}, {:.3e})",
                    eig[0], eig[1], eig[2]
                ),
            );
        }
    }
}

fn algorithm(c: &mut Checker, s: &Scenario) {
    match &s.algorithm {
        AlgorithmConfig::ConsensusFormation(a) => {
            c.non_negative("algorithm.formation_radius_m", a.formation_radius_m);
            c.positive("algorithm.kp_per_s2", a.kp_per_s2);
            c.non_negative("algorithm.kd_per_s", a.kd_per_s);
            c.positive("algorithm.observer_l1_per_s", a.observer_l1_per_s);
            c.positive("algorithm.observer_l2_per_s2", a.observer_l2_per_s2);
            if !matches!(s.plant, PlantConfig::DoubleIntegrator(_)) {
                c.fail("algorithm.kind", "\"consensus-formation\"", "needs plant.kind = \"double-integrator\"");
            }
        }
        AlgorithmConfig::LbDnnServicing(a) => {
            for (key, x) in [("k1", a.k1), ("k2", a.k2), ("k3", a.k3), ("k4", a.k4), ("k5", a.k5), ("k6", a.k6)] {
                c.positive(&format!("algorithm.{key}"), x);
            }
            c.positive("algorithm.gamma", a.gamma);
            c.positive("algorithm.theta_bar", a.theta_bar);
            if c.finite("algorithm.projection_band", a.projection_band)
                && !(a.projection_band > 0.0 && a.projection_band < 1.0)
            {
                c.fail("algorithm.projection_band", fmt_f64(a.projection_band), "must be in (0, 1)");
            }
            if a.observer_init != "zero" && a.observer_init != "measured" {
                c.fail("algorithm.observer_init", format!("{:?}", a.observer_init), "must be \"zero\" or \"measured\"");
            }
            if a.hidden_layers.is_empty() {
                c.fail("algorithm.hidden_layers", "[]", "at least one hidden layer");
            }
            for (k, w) in a.hidden_layers.iter().enumerate() {
                if *w == 0 || *w > 256 {
                    c.fail(format!("algorithm.hidden_layers[{k}]"), w, "widths must be 1..=256");
                }
            }
            if let Some(l) = a.thrust_limit_mps2 {
                c.positive("algorithm.thrust_limit_mps2", l);
            }
            if !matches!(s.plant, PlantConfig::Orbital(_)) {
                c.fail("algorithm.kind", "\"lb-dnn-servicing\"", "needs plant.kind = \"orbital\"");
            }
        }
        AlgorithmConfig::Coast(_) | AlgorithmConfig::Null(_) => {}
        AlgorithmConfig::DaiAttitude(a) => c.problems.extend(crate::dai::validate_algorithm(s, a)),
        AlgorithmConfig::TsnrFormation(a) => c.problems.extend(crate::tsnr_formation::validate_algorithm(s, a)),
    }
}

/// Message sizes this scenario needs, against the fixed bounds of the wire format.
pub fn message_sizes(s: &Scenario) -> MessageSizes {
    let readings = s
        .agents
        .iter()
        .map(|a| match &s.plant {
            PlantConfig::DoubleIntegrator(_) => 3,
            PlantConfig::Orbital(_) => a.output_matrix.as_ref().map_or(0, |m| m.len()) + 3 * a.neighbours.len(),
            PlantConfig::Null(p) => p.readings,
            PlantConfig::RigidBody(_) => crate::dai::READINGS,
            PlantConfig::TsnrNet(_) => crate::tsnr_net::READINGS,
        })
        .max()
        .unwrap_or(0);
    let share_values = match &s.algorithm {
        AlgorithmConfig::ConsensusFormation(_) => 6,
        AlgorithmConfig::LbDnnServicing(a) => 3 + a.n_weights(),
        AlgorithmConfig::Coast(_) => 0,
        AlgorithmConfig::Null(a) => a.share_values,
        AlgorithmConfig::DaiAttitude(_) => 0,
        AlgorithmConfig::TsnrFormation(a) => {
            a.share_values(s.agents.iter().map(|a| a.neighbours.len()).max().unwrap_or(0))
        }
    };
    MessageSizes { readings, command: 3, share_values }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageSizes {
    pub readings: usize,
    pub command: usize,
    pub share_values: usize,
}

fn bounds(c: &mut Checker, s: &Scenario) {
    let m = message_sizes(s);
    for (what, need, max) in [
        ("readings per measurement", m.readings, MAX_READINGS),
        ("command components per share", m.command, MAX_COMMAND),
        ("values per share", m.share_values, MAX_SHARE_VALUES),
    ] {
        if need > max {
            c.fail("algorithm", format!("{need} {what}"), format!("exceeds the wire format's bound of {max}"));
        }
    }
}
