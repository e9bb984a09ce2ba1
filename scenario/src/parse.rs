//! Parsing: TOML text → table → typed sections. Each section is deserialised on its own with
//! `serde_path_to_error`, so one file reports every section's problem at once and each problem
//! carries its full key path (including inside the `kind`-tagged `plant` and `algorithm` tables).

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Problem, ScenarioError};
use crate::schema::*;
use crate::validate::validate;

/// Values the command line may override before validation.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    pub seed: Option<u64>,
    pub duration_s: Option<f64>,
    pub step_timeout_s: Option<f64>,
    pub wait: Option<String>,
    pub spin_us: Option<f64>,
    pub link_delay_steps: Option<u32>,
    pub transport: Option<String>,
    pub realtime_rate: Option<f64>,
    /// `--fault` entries, appended to the file's `[[faults]]`.
    pub faults: Vec<crate::faults::FaultSpec>,
    pub on_agent_loss: Option<String>,
    /// `compare --algorithms`: replaces `algorithm.method` of a tsnr-formation scenario (another
    /// algorithm kind is an error: it has no method to replace).
    pub method: Option<String>,
}

/// Read, parse and validate a scenario file.
pub fn load(file: &Path, overrides: &Overrides) -> Result<Scenario, ScenarioError> {
    let text = std::fs::read_to_string(file).map_err(|e| ScenarioError {
        file: file.to_path_buf(),
        problems: vec![Problem::new("(file)", None, format!("cannot read: {e}"))],
    })?;
    parse(&text, file, overrides)
}

/// Parse and validate scenario text; `file` is only used in messages.
pub fn parse(text: &str, file: &Path, overrides: &Overrides) -> Result<Scenario, ScenarioError> {
    let err = |problems| ScenarioError { file: file.to_path_buf(), problems };
    let mut s = parse_only(text).map_err(err)?;
    if let Some(seed) = overrides.seed {
        s.scenario.seed = seed;
    }
    if let Some(d) = overrides.duration_s {
        s.scenario.duration_s = d;
    }
    if let Some(t) = overrides.step_timeout_s {
        s.run.step_timeout_s = t;
    }
    if let Some(w) = &overrides.wait {
        s.run.wait = w.clone();
    }
    if let Some(us) = overrides.spin_us {
        s.run.spin_us = Some(us);
    }
    if let Some(d) = overrides.link_delay_steps {
        s.run.link_delay_steps = d;
    }
    if let Some(t) = &overrides.transport {
        s.run.transport = t.clone();
    }
    if let Some(r) = overrides.realtime_rate {
        s.run.realtime_rate = Some(r);
    }
    s.faults.extend(overrides.faults.iter().cloned());
    // Files a scenario names are relative to the scenario file; the resolved scenario (which the
    // child processes read from the run directory) carries them absolute.
    for path in s.file_paths_mut() {
        if Path::new(path.as_str()).is_relative() {
            let joined = file.parent().unwrap_or(Path::new("")).join(path.as_str());
            *path = std::fs::canonicalize(&joined).unwrap_or(joined).display().to_string();
        }
    }
    if let Some(x) = &overrides.on_agent_loss {
        s.run.on_agent_loss = x.clone();
    }
    if let Some(m) = &overrides.method {
        match &mut s.algorithm {
            // The value itself is checked by validation, like a method written in the file.
            AlgorithmConfig::TsnrFormation(a) => a.method = m.clone(),
            other => {
                let kind = format!("{:?}", other.kind());
                return Err(err(vec![Problem::new(
                    "algorithm.kind",
                    Some(kind),
                    "--algorithms needs a tsnr-formation scenario",
                )]));
            }
        }
    }
    let problems = validate(&s);
    if problems.is_empty() { Ok(s) } else { Err(err(problems)) }
}

const TOP_KEYS: &[&str] = &["scenario", "run", "plant", "algorithm", "agents", "faults"];

fn parse_only(text: &str) -> Result<Scenario, Vec<Problem>> {
    let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        vec![Problem::new("(file)", None, format!("not valid TOML: {}", one_line(&e.to_string())))]
    })?;
    let mut problems = Vec::new();
    for k in table.keys() {
        if !TOP_KEYS.contains(&k.as_str()) {
            problems.push(Problem::new(
                k.clone(),
                None,
                format!("unknown key (expected one of: {})", TOP_KEYS.join(", ")),
            ));
        }
    }
    let mut required = |key: &str, problems: &mut Vec<Problem>| {
        let v = table.remove(key);
        if v.is_none() {
            problems.push(Problem::new(key, None, "required key is missing"));
        }
        v
    };
    let meta = required("scenario", &mut problems).and_then(|v| section::<Meta>(v, "scenario", &mut problems));
    let plant = required("plant", &mut problems).and_then(|v| tagged(v, "plant", PlantConfig::KINDS, &mut problems));
    let algorithm = required("algorithm", &mut problems)
        .and_then(|v| tagged(v, "algorithm", AlgorithmConfig::KINDS, &mut problems));
    let agents =
        required("agents", &mut problems).and_then(|v| section::<Vec<AgentConfig>>(v, "agents", &mut problems));
    let faults = match table.remove("faults") {
        Some(v) => section::<Vec<crate::faults::FaultSpec>>(v, "faults", &mut problems),
        None => Some(Vec::new()),
    };
    let run = match table.remove("run") {
        Some(v) => section::<RunSettings>(v, "run", &mut problems),
        None => Some(RunSettings::default()),
    };

    let plant = plant.and_then(|(kind, body)| match kind.as_str() {
        "double-integrator" => section(body, "plant", &mut problems).map(PlantConfig::DoubleIntegrator),
        "orbital" => section(body, "plant", &mut problems).map(PlantConfig::Orbital),
        "null" => section(body, "plant", &mut problems).map(PlantConfig::Null),
        "rigid-body" => section(body, "plant", &mut problems).map(PlantConfig::RigidBody),
        "tsnr-net" => section(body, "plant", &mut problems).map(PlantConfig::TsnrNet),
        _ => unreachable!("tagged() only returns known kinds"),
    });
    let algorithm = algorithm.and_then(|(kind, body)| match kind.as_str() {
        "consensus-formation" => section(body, "algorithm", &mut problems).map(AlgorithmConfig::ConsensusFormation),
        "lb-dnn-servicing" => section(body, "algorithm", &mut problems).map(AlgorithmConfig::LbDnnServicing),
        "coast" => section(body, "algorithm", &mut problems).map(AlgorithmConfig::Coast),
        "null" => section(body, "algorithm", &mut problems).map(AlgorithmConfig::Null),
        "dai-attitude" => section(body, "algorithm", &mut problems).map(AlgorithmConfig::DaiAttitude),
        "tsnr-formation" => section(body, "algorithm", &mut problems).map(AlgorithmConfig::TsnrFormation),
        _ => unreachable!("tagged() only returns known kinds"),
    });
    match (meta, run, plant, algorithm, agents, faults) {
        (Some(scenario), Some(run), Some(plant), Some(algorithm), Some(agents), Some(faults))
            if problems.is_empty() =>
        {
            Ok(Scenario { scenario, run, plant, algorithm, agents, faults })
        }
        _ => Err(problems),
    }
}

/// Split a `kind`-tagged table into its kind and the rest.
fn tagged(v: toml::Value, path: &str, kinds: &[&str], problems: &mut Vec<Problem>) -> Option<(String, toml::Value)> {
    let toml::Value::Table(mut t) = v else {
        problems.push(Problem::new(path, Some(short(&v)), format!("must be a table, found a {}", v.type_str())));
        return None;
    };
    let expected = format!("expected one of: {}", kinds.join(", "));
    match t.remove("kind") {
        None => {
            problems.push(Problem::new(format!("{path}.kind"), None, format!("required key is missing ({expected})")));
            None
        }
        Some(toml::Value::String(k)) if kinds.contains(&k.as_str()) => Some((k, toml::Value::Table(t))),
        Some(other) => {
            problems.push(Problem::new(
                format!("{path}.kind"),
                Some(short(&other)),
                format!("unknown kind ({expected})"),
            ));
            None
        }
    }
}

/// Deserialise one section, recording a problem with its full key path on failure.
fn section<T: DeserializeOwned>(v: toml::Value, path: &str, problems: &mut Vec<Problem>) -> Option<T> {
    match serde_path_to_error::deserialize::<_, T>(v) {
        Ok(t) => Some(t),
        Err(e) => {
            let inner = e.path().to_string();
            let mut full = join(path, &inner);
            let mut reason = one_line(&e.inner().to_string());
            // toml's messages end with " in `key`", which the path already says.
            if let Some((head, _)) = reason.rsplit_once(" in `") {
                reason = head.to_string();
            }
            // serde reports a missing field at the enclosing table: name the key itself.
            if let Some(rest) = reason.strip_prefix("missing field `")
                && let Some(field) = rest.strip_suffix('`')
            {
                full = join(&full, field);
                reason = "required key is missing".into();
            } else if let Some(rest) = reason.strip_prefix("unknown field `")
                && let Some((field, tail)) = rest.split_once('`')
            {
                if !full.ends_with(field) {
                    full = join(&full, field);
                }
                let expected = tail.trim_start_matches(',').trim();
                reason = if expected.is_empty() { "unknown key".into() } else { format!("unknown key ({expected})") };
            }
            problems.push(Problem::new(full, None, reason));
            None
        }
    }
}

fn join(path: &str, inner: &str) -> String {
    if inner.is_empty() || inner == "." {
        path.to_string()
    } else if inner.starts_with('[') {
        format!("{path}{inner}")
    } else {
        format!("{path}.{inner}")
    }
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

fn short(v: &toml::Value) -> String {
    let s = v.to_string();
    if s.len() > 60 { format!("{}…", &s[..s.char_indices().nth(60).map_or(s.len(), |(i, _)| i)]) } else { s }
}
