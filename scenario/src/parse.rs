//! Parsing: TOML text → table → typed sections. Each section is deserialised on its own with
//! `serde_path_to_error`, so one file reports every section's problem at once and each problem
//! carries its full key path. `[plant]` and `[algorithm]` are split into their `kind` and the rest
//! ([`Section`]); the paper that registered the kind deserialises the rest with [`section`], so
//! its problems carry full key paths too.

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::{Problem, ScenarioError};
use crate::schema::*;

/// Values the command line may override before validation. They are written into the file's
/// table before it is deserialised, so a bad value is reported like one written in the file,
/// with its key path.
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
    pub authenticate: Option<bool>,
}

/// Read and parse a scenario file: the generic sections typed and checked for their own form
/// (not yet validated: see [`crate::validate::validate`]), the paper sections raw.
pub fn load(file: &Path, overrides: &Overrides) -> Result<Scenario, ScenarioError> {
    let text = std::fs::read_to_string(file).map_err(|e| ScenarioError {
        file: file.to_path_buf(),
        problems: vec![Problem::new("(file)", None, format!("cannot read: {e}"))],
    })?;
    parse(&text, file, overrides)
}

/// Parse scenario text; `file` names it in messages, and its directory is the base of relative
/// paths inside paper sections.
pub fn parse(text: &str, file: &Path, overrides: &Overrides) -> Result<Scenario, ScenarioError> {
    let err = |problems| ScenarioError { file: file.to_path_buf(), problems };
    let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        err(vec![Problem::new("(file)", None, format!("not valid TOML: {}", one_line(&e.to_string())))])
    })?;
    apply_overrides(&mut table, overrides);
    let base_dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
    parse_table(table, base_dir).map_err(err)
}

/// Write the command line's overrides into the file's table.
fn apply_overrides(table: &mut toml::Table, o: &Overrides) {
    use toml::Value;
    let mut set = |section: &str, key: &str, v: Value| {
        let entry = table.entry(section).or_insert_with(|| Value::Table(toml::Table::new()));
        // A section that is not a table is reported as such by the section parser.
        if let Value::Table(t) = entry {
            t.insert(key.into(), v);
        }
    };
    if let Some(seed) = o.seed {
        // Beyond i64 a TOML integer cannot hold it; a float makes the seed's parser report it.
        set("scenario", "seed", i64::try_from(seed).map_or(Value::Float(seed as f64), Value::Integer));
    }
    if let Some(d) = o.duration_s {
        set("scenario", "duration_s", Value::Float(d));
    }
    if let Some(t) = o.step_timeout_s {
        set("run", "step_timeout_s", Value::Float(t));
    }
    if let Some(w) = &o.wait {
        set("run", "wait", Value::String(w.clone()));
    }
    if let Some(us) = o.spin_us {
        set("run", "spin_us", Value::Float(us));
    }
    if let Some(d) = o.link_delay_steps {
        set("run", "link_delay_steps", Value::Integer(i64::from(d)));
    }
    if let Some(t) = &o.transport {
        set("run", "transport", Value::String(t.clone()));
    }
    if let Some(r) = o.realtime_rate {
        set("run", "realtime_rate", Value::Float(r));
    }
    if let Some(x) = &o.on_agent_loss {
        set("run", "on_agent_loss", Value::String(x.clone()));
    }
    if let Some(a) = o.authenticate {
        set("run", "authenticate", Value::Boolean(a));
    }
    if !o.faults.is_empty() {
        let entry = table.entry("faults").or_insert_with(|| Value::Array(Vec::new()));
        if let Value::Array(list) = entry {
            for f in &o.faults {
                list.push(Value::Table(toml::Table::try_from(f).expect("a fault spec is a plain table")));
            }
        }
    }
}

const TOP_KEYS: &[&str] = &["scenario", "run", "plant", "algorithm", "agents", "faults"];

fn parse_table(mut table: toml::Table, base_dir: std::path::PathBuf) -> Result<Scenario, Vec<Problem>> {
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
    let plant = required("plant", &mut problems).and_then(|v| tagged(v, "plant", &mut problems));
    let algorithm = required("algorithm", &mut problems).and_then(|v| tagged(v, "algorithm", &mut problems));
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
    match (meta, run, plant, algorithm, agents, faults) {
        (Some(scenario), Some(run), Some(plant), Some(algorithm), Some(agents), Some(faults))
            if problems.is_empty() =>
        {
            Ok(Scenario { scenario, run, plant, algorithm, agents, faults, base_dir })
        }
        _ => Err(problems),
    }
}

/// Split a `kind`-tagged table into its kind and the rest.
fn tagged(v: toml::Value, path: &str, problems: &mut Vec<Problem>) -> Option<Section> {
    let toml::Value::Table(mut t) = v else {
        problems.push(Problem::new(path, Some(short(&v)), format!("must be a table, found a {}", v.type_str())));
        return None;
    };
    match t.remove("kind") {
        None => {
            problems.push(Problem::new(format!("{path}.kind"), None, "required key is missing"));
            None
        }
        Some(toml::Value::String(kind)) => Some(Section { kind, body: t }),
        Some(other) => {
            problems.push(Problem::new(
                format!("{path}.kind"),
                Some(short(&other)),
                format!("must be a string, found a {}", other.type_str()),
            ));
            None
        }
    }
}

/// Deserialise one section (or any value inside one) at key path `path`, recording a problem with
/// its full key path on failure. Papers parse their `[plant]`/`[algorithm]` bodies and per-agent
/// keys with it.
pub fn section<T: DeserializeOwned>(v: toml::Value, path: &str, problems: &mut Vec<Problem>) -> Option<T> {
    match serde_path_to_error::deserialize::<_, T>(v) {
        Ok(t) => Some(t),
        Err(e) => {
            let inner = e.path().to_string();
            problems.push(problem_of(join(path, &inner), &one_line(&e.inner().to_string())));
            None
        }
    }
}

/// A serde error message at `full` as a [`Problem`], in the scenario's words.
fn problem_of(mut full: String, message: &str) -> Problem {
    let mut reason = message.to_string();
    // toml's messages end with " in `key`", which the path already says.
    if let Some((head, _)) = reason.rsplit_once(" in `") {
        reason = head.to_string();
    }
    // serde reports a missing field at the enclosing table: name the key itself.
    if let Some(rest) = reason.strip_prefix("missing field `")
        && let Some(field) = rest.strip_suffix('`')
    {
        return Problem::new(join(&full, field), None, "required key is missing");
    }
    if let Some(rest) = reason.strip_prefix("unknown field `")
        && let Some((field, tail)) = rest.split_once('`')
    {
        if !full.ends_with(field) {
            full = join(&full, field);
        }
        let expected = tail.trim_start_matches(',').trim();
        let reason = if expected.is_empty() { "unknown key".into() } else { format!("unknown key ({expected})") };
        return Problem::new(full, None, reason);
    }
    // A choice written as a string that names none of its options (a serde enum).
    if let Some(rest) = reason.strip_prefix("unknown variant `")
        && let Some((value, tail)) = rest.split_once('`')
    {
        let options: Vec<String> = tail.split('`').skip(1).step_by(2).map(|o| format!("{o:?}")).collect();
        return Problem::new(full, Some(format!("{value:?}")), format!("must be {}", choice_list(&options)));
    }
    Problem::new(full, None, reason)
}

/// `"a"`, `"a" or "b"`, `"a", "b" or "c"`; more than four: `one of: "a", "b", …`.
pub fn choice_list(options: &[String]) -> String {
    match options {
        [] => "nothing (no options)".into(),
        [one] => one.clone(),
        [init @ .., last] if options.len() <= 4 => format!("{} or {last}", init.join(", ")),
        _ => format!("one of: {}", options.join(", ")),
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
