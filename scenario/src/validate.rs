//! Sanity checks on a parsed scenario. Every check runs, so a file reports all its problems at
//! once, each with its key path, value and reason. Nothing starts before these pass.

use cohort_wire::msg::{MAX_AGENTS, MAX_COMMAND, MAX_LINKS_IN, MAX_READINGS, MAX_SHARE_VALUES};

use crate::checker::{Checker, fmt_f64};
use crate::error::Problem;
use crate::schema::*;

/// Longest run we accept, in steps (keeps telemetry and counters sane).
const MAX_STEPS: u64 = 1_000_000_000;
/// The largest seed: seeds are written back into the resolved scenario as TOML integers, which
/// are signed 64-bit.
pub const MAX_SEED: u64 = i64::MAX as u64;
/// The shortest step timeout, s: a wait re-polls every 10 ms and a process needs milliseconds to
/// be scheduled on a busy machine, so anything shorter only declares healthy processes dead.
pub const MIN_STEP_TIMEOUT_S: f64 = 0.1;

/// The checks of what every scenario has (meta, run settings, agents and their graph, the fault
/// plan). The paper sections are checked by their papers. Returns whether agent ids are exactly
/// 1..=N (later checks index agents by id) with the problems found.
pub fn validate(s: &Scenario) -> (bool, Vec<Problem>) {
    let mut c = Checker::new();
    meta(&mut c, &s.scenario);
    run(&mut c, &s.run);
    let ids_ok = agents(&mut c, &s.agents);
    crate::hosts::check(&mut c, s);
    let (dt, dur) = (s.scenario.dt_s, s.scenario.duration_s);
    if dt.is_finite() && dt > 0.0 && dur.is_finite() && dur > 0.0 {
        crate::faults::check(&mut c, &s.faults, s.faults_in_file, s.n_agents(), dt, dur);
    }
    crate::links::check(&mut c, &s.links, dt);
    if s.links.is_geometric()
        && let Some(a) = s.agents.iter().find(|a| a.neighbours.len() > MAX_LINKS_IN)
    {
        c.fail(
            format!("agents[{}].neighbours", s.agents.iter().position(|b| b.id == a.id).unwrap_or(0)),
            format!("{} neighbours", a.neighbours.len()),
            format!(
                "links.model = \"geometric\" carries each agent's links in its measurement: at most {MAX_LINKS_IN}"
            ),
        );
    }
    if s.run.checkpoint_every_steps == 0
        && let Some(k) = s.faults.iter().position(|f| f.kind == "restart")
    {
        c.fail(
            "run.checkpoint_every_steps",
            0,
            format!(
                "{} restarts an agent, which resumes from its latest checkpoint: must be > 0",
                crate::faults::fault_name(k, s.faults_in_file)
            ),
        );
    }
    (ids_ok, c.problems)
}

fn meta(c: &mut Checker, m: &Meta) {
    if m.name.is_empty() || !m.name.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_') {
        c.fail("scenario.name", format!("{:?}", m.name), "must be non-empty and use only letters, digits, '-' and '_'");
    }
    if m.seed > MAX_SEED {
        c.fail("scenario.seed", m.seed, format!("must be in 0..={MAX_SEED} (2^63 − 1: seeds are TOML integers)"));
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
    if let Some(us) = r.spin_us
        && c.finite("run.spin_us", us)
        && !(0.0..=1e6).contains(&us)
    {
        c.fail("run.spin_us", fmt_f64(us), "must be in [0, 1e6] µs");
    }
    if let Some(rate) = r.realtime_rate {
        c.positive("run.realtime_rate", rate);
    }
    if r.link_delay_steps > 1 {
        c.fail("run.link_delay_steps", r.link_delay_steps, "must be 0 or 1");
    }
    if r.telemetry_every_steps == 0 {
        c.fail("run.telemetry_every_steps", 0, "must be ≥ 1 (1: a telemetry row at every step)");
    }
    for (path, x) in [("run.step_timeout_s", r.step_timeout_s), ("run.startup_timeout_s", r.startup_timeout_s)] {
        if !c.positive(path, x) {
            continue;
        }
        if x > 3600.0 {
            c.fail(path, fmt_f64(x), "must be at most 3600 s");
        } else if x < MIN_STEP_TIMEOUT_S {
            c.fail(path, fmt_f64(x), format!("must be at least {MIN_STEP_TIMEOUT_S} s"));
        }
    }
}

/// Ids and neighbour lists ([`connectivity`] is separate). Returns whether ids are exactly 1..=N (later checks
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
    // Every process validates the whole scenario at its start, so nothing here should grow as N²
    // (a search of the agents for each neighbour did; a key path was formatted for each one).
    // Not what makes a thousand-agent start-up slow: `orchestrator check` of a 1 000-agent ring
    // took 16–20 ms of CPU before and after.
    let mut ids: Vec<u32> = agents.iter().map(|a| a.id).collect();
    ids.sort_unstable();
    let mut listed = Vec::new();
    for (k, a) in agents.iter().enumerate() {
        listed.clear();
        for (m, &j) in a.neighbours.iter().enumerate() {
            let why = if ids.binary_search(&j).is_err() {
                Some("not an agent of this scenario")
            } else if j == a.id {
                Some("an agent cannot be its own neighbour")
            } else if listed.contains(&j) {
                Some("listed twice")
            } else {
                None
            };
            if let Some(why) = why {
                c.fail(format!("agents[{k}].neighbours[{m}]"), j, why);
            }
            listed.push(j);
        }
    }
    ids_ok
}

/// The (undirected) communication graph must be connected: a decentralised method needs it
/// (information must be able to reach every agent). Not part of [`validate`]: the runtime asks
/// the algorithm whether its agents talk at all (independent spacecraft do not). Checks nothing
/// when the ids or neighbour lists are wrong ([`validate`] reports those).
pub fn connectivity(c: &mut Checker, agents: &[AgentConfig]) {
    let n = agents.len();
    let ids_ok = {
        let mut ids: Vec<u32> = agents.iter().map(|a| a.id).collect();
        ids.sort_unstable();
        ids.iter().enumerate().all(|(k, id)| *id as usize == k + 1)
    };
    let nbrs_ok = agents.iter().all(|a| a.neighbours.iter().all(|j| *j != a.id && (1..=n as u32).contains(j)));
    if n < 2 || !ids_ok || !nbrs_ok {
        return;
    }
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
                "the communication graph is disconnected (a decentralised method needs it connected): {}",
                g.join(" and ")
            ),
        );
    }
}

/// Message sizes a scenario needs (from its paper sections), against the fixed bounds of the wire
/// format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MessageSizes {
    pub readings: usize,
    pub command: usize,
    pub share_values: usize,
}

impl MessageSizes {
    /// Every size over its bound, as a problem at `algorithm` (the share) or `plant`.
    pub fn check(&self, c: &mut Checker) {
        for (path, what, need, max) in [
            ("plant", "readings per measurement", self.readings, MAX_READINGS),
            ("plant", "command components per share", self.command, MAX_COMMAND),
            ("algorithm", "values per share", self.share_values, MAX_SHARE_VALUES),
        ] {
            if need > max {
                c.fail(path, format!("{need} {what}"), format!("exceeds the wire format's bound of {max}"));
            }
        }
    }
}
