//! Multi-host placement: the `[[hosts]]` of a scenario (name and daemon endpoint of each
//! machine), `host = "NAME"` on each agent and `run.plant_host`, or the same from a hosts file
//! (`orchestrator launch … --hosts FILE`), so one scenario runs unchanged on different machines.
//!
//! A hosts file holds `[[hosts]]` entries with `name` and `endpoint`, and optionally where the
//! processes go: `plant = true` on the plant's host, `agents = [ids]` on each agent's. It
//! replaces the scenario's `[[hosts]]`; when it places processes, its placement replaces the
//! scenario's too. Its own problems name the file and their key path in it.
//!
//! The checks ([`check`]), before anything starts: hosts need `run.transport = "zenoh"`; names
//! are unique words; endpoints are `tcp/<address>:<port>` or `tls/<address>:<port>` (which of the
//! two the run's security settings allow is checked where they are known, before any link opens);
//! every agent names a host of the list (when there is one), the plant's host is on the list, and every host is named by a process.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::checker::Checker;
use crate::error::{Problem, ScenarioError};
use crate::schema::{Scenario, TransportKind};

/// A parsed `--hosts FILE`.
#[derive(Debug, Clone, PartialEq)]
pub struct HostsFile {
    pub file: PathBuf,
    pub hosts: Vec<HostEntry>,
}

/// One `[[hosts]]` entry of a hosts file.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HostEntry {
    pub name: String,
    pub endpoint: String,
    /// The plant runs on this host.
    #[serde(default)]
    pub plant: bool,
    /// The agents that run on this host.
    #[serde(default)]
    pub agents: Vec<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileTop {
    hosts: Vec<HostEntry>,
}

impl HostsFile {
    /// Read and parse a hosts file; its problems carry its own name and key paths.
    pub fn load(file: &Path) -> Result<Self, ScenarioError> {
        let fail = |problems| ScenarioError { file: file.to_path_buf(), problems };
        let text =
            crate::parse::read_bounded(file).map_err(|reason| fail(vec![Problem::new("(file)", None, reason)]))?;
        let value: toml::Value = text
            .parse::<toml::Table>()
            .map_err(|e| fail(vec![Problem::new("(file)", None, format!("not valid TOML: {}", e.message()))]))?
            .into();
        let mut problems = Vec::new();
        let Some(top) = crate::parse::section::<FileTop>(value, "", &mut problems) else {
            let problems = problems
                .into_iter()
                .map(|mut p| {
                    p.path = p.path.trim_start_matches('.').to_string();
                    p
                })
                .collect();
            return Err(fail(problems).located(&text));
        };
        if top.hosts.is_empty() {
            return Err(fail(vec![Problem::new("hosts", Some("[]".into()), "at least one host is required")]));
        }
        let mut c = Checker::new();
        let mut plant_on = Vec::new();
        for (k, h) in top.hosts.iter().enumerate() {
            if h.plant {
                plant_on.push(k);
            }
            for (m, id) in h.agents.iter().enumerate() {
                let elsewhere = top.hosts[..k].iter().position(|o| o.agents.contains(id));
                let twice = h.agents[..m].contains(id);
                if let Some(j) = elsewhere.filter(|_| !twice) {
                    c.fail(
                        format!("hosts[{k}].agents[{m}]"),
                        id,
                        format!("agent {id} is placed on hosts[{j}] already"),
                    );
                } else if twice {
                    c.fail(format!("hosts[{k}].agents[{m}]"), id, "listed twice");
                }
            }
        }
        if plant_on.len() > 1 {
            c.fail(
                format!("hosts[{}].plant", plant_on[1]),
                true,
                format!("the plant is placed on hosts[{}] already", plant_on[0]),
            );
        }
        if !c.problems.is_empty() {
            return Err(fail(c.problems).located(&text));
        }
        Ok(Self { file: file.to_path_buf(), hosts: top.hosts })
    }

    /// Whether the file says where processes go (else the scenario's placement stays).
    pub fn places(&self) -> bool {
        self.hosts.iter().any(|h| h.plant || !h.agents.is_empty())
    }
}

/// Write a hosts file into a scenario's table (see the module docs). Agent ids the scenario
/// lacks are left for [`unplaced_ids`] to report.
pub fn apply(table: &mut toml::Table, h: &HostsFile) {
    use toml::Value;
    let hosts: Vec<Value> = h
        .hosts
        .iter()
        .map(|e| {
            let mut t = toml::Table::new();
            t.insert("name".into(), Value::String(e.name.clone()));
            t.insert("endpoint".into(), Value::String(e.endpoint.clone()));
            Value::Table(t)
        })
        .collect();
    table.insert("hosts".into(), Value::Array(hosts));
    if !h.places() {
        return;
    }
    if let Some(Value::Table(run)) = table.get_mut("run") {
        run.remove("plant_host");
    }
    if let Some(plant) = h.hosts.iter().find(|e| e.plant) {
        let run = table.entry("run").or_insert_with(|| Value::Table(toml::Table::new()));
        if let Value::Table(run) = run {
            run.insert("plant_host".into(), Value::String(plant.name.clone()));
        }
    }
    if let Some(Value::Array(agents)) = table.get_mut("agents") {
        for a in agents.iter_mut() {
            let Value::Table(a) = a else { continue };
            a.remove("host");
            let id = a.get("id").and_then(Value::as_integer).and_then(|i| u32::try_from(i).ok());
            if let Some(e) = id.and_then(|id| h.hosts.iter().find(|e| e.agents.contains(&id))) {
                a.insert("host".into(), Value::String(e.name.clone()));
            }
        }
    }
}

/// Agent ids a hosts file places that the scenario does not have, as problems of that file.
pub fn unplaced_ids(h: &HostsFile, s: &Scenario) -> Vec<Problem> {
    let mut out = Vec::new();
    for (k, e) in h.hosts.iter().enumerate() {
        for (m, id) in e.agents.iter().enumerate() {
            if !s.agents.iter().any(|a| a.id == *id) {
                out.push(Problem::new(
                    format!("{}: hosts[{k}].agents[{m}]", h.file.display()),
                    Some(id.to_string()),
                    format!("not an agent of this scenario (ids are 1..={})", s.n_agents()),
                ));
            }
        }
    }
    out
}

/// Whether `e` is a zenoh TCP endpoint `tcp/<address>:<port>` (an IPv4 or IPv6 address in
/// brackets, or a host name), port 1..=65535.
pub fn endpoint_problem(e: &str) -> Option<String> {
    let Some(rest) = e.strip_prefix("tcp/").or_else(|| e.strip_prefix("tls/")) else {
        return Some(
            "must be a zenoh TCP or TLS endpoint, tcp/<address>:<port> or tls/<address>:<port> (e.g. tcp/192.0.2.2:7447)"
                .into(),
        );
    };
    let Some((addr, port)) = rest.rsplit_once(':') else {
        return Some("has no port: tcp/<address>:<port> (or tls/…)".into());
    };
    if addr.is_empty() || addr.contains(['/', '?', '#', ' ']) {
        return Some(format!("address {addr:?} is not an address or host name"));
    }
    match port.parse::<u16>() {
        Ok(p) if p > 0 => None,
        _ => Some(format!("port {port:?} must be 1..=65535")),
    }
}

fn is_word(s: &str) -> bool {
    !s.is_empty() && s.len() <= 64 && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// The checks of a scenario's placement (see the module docs).
pub fn check(c: &mut Checker, s: &Scenario) {
    let names: Vec<&str> = s.hosts.iter().map(|h| h.name.as_str()).collect();
    for (k, h) in s.hosts.iter().enumerate() {
        if !is_word(&h.name) {
            c.fail(format!("hosts[{k}].name"), format!("{:?}", h.name), "must be 1 to 64 letters, digits, '-' or '_'");
        } else if names[..k].contains(&h.name.as_str()) {
            c.fail(format!("hosts[{k}].name"), format!("{:?}", h.name), "duplicate host name");
        }
        if let Some(why) = endpoint_problem(&h.endpoint) {
            c.fail(format!("hosts[{k}].endpoint"), format!("{:?}", h.endpoint), why);
        }
    }
    if !s.hosts.is_empty() && s.run.transport != TransportKind::Zenoh {
        c.fail(
            "run.transport",
            format!("{:?}", format!("{:?}", s.run.transport).to_lowercase()),
            "the scenario places processes on [[hosts]], which needs \"zenoh\" (--transport zenoh)",
        );
    }
    if s.run.zenoh_links == crate::schema::ZenohLinks::Peers && s.run.transport != TransportKind::Zenoh {
        c.fail(
            "run.zenoh_links",
            "\"peers\"",
            "says how zenoh runs link their processes; this run's transport is not zenoh",
        );
    }
    let known = |n: &str| names.contains(&n);
    for (k, a) in s.agents.iter().enumerate() {
        match &a.host {
            Some(h) if s.hosts.is_empty() => {
                c.fail(format!("agents[{k}].host"), format!("{h:?}"), "names a host, but the scenario has no [[hosts]]")
            }
            Some(h) if !known(h) => c.fail(
                format!("agents[{k}].host"),
                format!("{h:?}"),
                format!("no [[hosts]] entry has this name (hosts: {})", names.join(", ")),
            ),
            None if !s.hosts.is_empty() => c.missing(
                format!("agents[{k}].host"),
                format!(
                    "agent {} names no host: with [[hosts]], every agent must name one of {}",
                    a.id,
                    names.join(", ")
                ),
            ),
            _ => {}
        }
    }
    if let Some(p) = &s.run.plant_host {
        if s.hosts.is_empty() {
            c.fail("run.plant_host", format!("{p:?}"), "names a host, but the scenario has no [[hosts]]");
        } else if !known(p) {
            c.fail(
                "run.plant_host",
                format!("{p:?}"),
                format!("no [[hosts]] entry has this name (hosts: {})", names.join(", ")),
            );
        }
    }
    for (k, h) in s.hosts.iter().enumerate() {
        let used =
            s.run.plant_host.as_deref() == Some(&h.name) || s.agents.iter().any(|a| a.host.as_deref() == Some(&h.name));
        if !used && is_word(&h.name) {
            c.fail(
                format!("hosts[{k}].name"),
                format!("{:?}", h.name),
                "no process is placed on this host (no agent's host, nor run.plant_host, names it)",
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_are_tcp_with_a_port() {
        assert_eq!(endpoint_problem("tcp/192.0.2.2:7447"), None);
        assert_eq!(endpoint_problem("tcp/[::1]:7447"), None);
        assert_eq!(endpoint_problem("tcp/box-b:7447"), None);
        assert_eq!(endpoint_problem("tls/192.0.2.2:7447"), None);
        for bad in [
            "udp/192.0.2.2:7447",
            "tcp/192.0.2.2",
            "tcp/:7447",
            "tcp/192.0.2.2:0",
            "tcp/192.0.2.2:70000",
            "192.0.2.2:7447",
            "tls/192.0.2.2",
            "quic/192.0.2.2:7447",
        ] {
            assert!(endpoint_problem(bad).is_some(), "{bad}");
        }
    }
}
