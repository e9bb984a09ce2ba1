//! Sanity checks on a parsed scenario. Every check runs, so a file reports all its problems at
//! once, each with its key path, value and reason. Nothing starts before these pass.

use cohort_wire::msg::{MAX_AGENTS, MAX_COMMAND, MAX_READINGS, MAX_SHARE_VALUES};

use crate::error::Problem;
use crate::schema::*;

/// Longest run we accept, in steps (keeps telemetry and counters sane).
const MAX_STEPS: u64 = 1_000_000_000;

struct Checker {
    problems: Vec<Problem>,
}

impl Checker {
    fn fail(&mut self, path: impl Into<String>, value: impl ToString, reason: impl Into<String>) {
        self.problems.push(Problem::new(path, Some(value.to_string()), reason));
    }
    fn finite(&mut self, path: &str, x: f64) -> bool {
        if x.is_finite() {
            true
        } else {
            self.fail(path, fmt_f64(x), "must be a finite number");
            false
        }
    }
    fn positive(&mut self, path: &str, x: f64) {
        if self.finite(path, x) && x <= 0.0 {
            self.fail(path, fmt_f64(x), "must be > 0");
        }
    }
    fn non_negative(&mut self, path: &str, x: f64) {
        if self.finite(path, x) && x < 0.0 {
            self.fail(path, fmt_f64(x), "must be ≥ 0");
        }
    }
    fn vec3(&mut self, path: &str, v: &[f64; 3]) {
        for (k, x) in v.iter().enumerate() {
            self.finite(&format!("{path}[{k}]"), *x);
        }
    }
}

fn fmt_f64(x: f64) -> String {
    if x.is_nan() { "nan".into() } else { format!("{x:?}") }
}

pub fn validate(s: &Scenario) -> Vec<Problem> {
    let mut c = Checker { problems: Vec::new() };
    meta(&mut c, &s.scenario);
    run(&mut c, &s.run);
    let ids_ok = agents(&mut c, &s.agents);
    plant(&mut c, s);
    algorithm(&mut c, s);
    if ids_ok {
        bounds(&mut c, s);
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
    let n = agents.len();
    let mut adj = vec![Vec::new(); n + 1];
    for a in agents {
        for &j in &a.neighbours {
            adj[a.id as usize].push(j as usize);
            adj[j as usize].push(a.id as usize);
        }
    }
    let mut comp = vec![0usize; n + 1];
    let mut n_comp = 0;
    for start in 1..=n {
        if comp[start] != 0 {
            continue;
        }
        n_comp += 1;
        let mut stack = vec![start];
        comp[start] = n_comp;
        while let Some(v) = stack.pop() {
            for &w in &adj[v] {
                if comp[w] == 0 {
                    comp[w] = n_comp;
                    stack.push(w);
                }
            }
        }
    }
    if n_comp > 1 {
        let groups: Vec<String> = (1..=n_comp)
            .map(|g| {
                let ids: Vec<String> = (1..=n).filter(|&v| comp[v] == g).map(|v| v.to_string()).collect();
                format!("{{{}}}", ids.join(", "))
            })
            .collect();
        c.fail(
            "agents[].neighbours",
            format!("{n_comp} components"),
            format!("the communication graph is disconnected: {}", groups.join(" and ")),
        );
    }
}

fn plant(c: &mut Checker, s: &Scenario) {
    match &s.plant {
        PlantConfig::DoubleIntegrator(p) => {
            c.non_negative("plant.position_noise_std_m", p.position_noise_std_m);
            for (k, a) in s.agents.iter().enumerate() {
                match &a.r0_m {
                    Some(r) => c.vec3(&format!("agents[{k}].r0_m"), r),
                    None => c.problems.push(Problem::new(
                        format!("agents[{k}].r0_m"),
                        None,
                        "required by plant.kind = \"double-integrator\" (initial position, m)",
                    )),
                }
                match &a.v0_mps {
                    Some(v) => c.vec3(&format!("agents[{k}].v0_mps"), v),
                    None => c.problems.push(Problem::new(
                        format!("agents[{k}].v0_mps"),
                        None,
                        "required by plant.kind = \"double-integrator\" (initial velocity, m/s)",
                    )),
                }
            }
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
        }
    }
}

/// Message sizes this scenario needs, against the fixed bounds of the wire format.
pub fn message_sizes(s: &Scenario) -> MessageSizes {
    match (&s.plant, &s.algorithm) {
        (PlantConfig::DoubleIntegrator(_), AlgorithmConfig::ConsensusFormation(_)) => {
            MessageSizes { readings: 3, command: 3, share_values: 6 }
        }
    }
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
