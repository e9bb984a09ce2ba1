//! Parsing: TOML text → table → typed sections. Each section is deserialised on its own with
//! `serde_path_to_error`, so one file reports every section's problem at once and each problem
//! carries its full key path. `[plant]` and `[algorithm]` are split into their `kind` and the rest
//! ([`Section`]); the paper that registered the kind deserialises the rest with [`section`], so
//! its problems carry full key paths too.

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::digest::DigestError;
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
    /// `--zenoh-links`: run.zenoh_links (gateway or peers).
    pub zenoh_links: Option<String>,
    pub realtime_rate: Option<f64>,
    /// `--fault` entries, appended to the file's `[[faults]]`.
    pub faults: Vec<crate::faults::FaultSpec>,
    pub on_agent_loss: Option<String>,
    pub authenticate: Option<bool>,
    /// `--record`: sets `run.record`.
    pub record: Option<bool>,
    /// `--hosts FILE`: replaces the scenario's `[[hosts]]`, and its placement when it gives one.
    pub hosts: Option<crate::hosts::HostsFile>,
    /// `--telemetry`: run.telemetry (parquet or csv).
    pub telemetry: Option<String>,
}

impl Overrides {
    /// The key paths this command line sets, each with the flag that set it.
    pub fn flags(&self) -> Vec<(&'static str, &'static str)> {
        let set = [
            (self.seed.is_some(), "scenario.seed", "--seed"),
            (self.duration_s.is_some(), "scenario.duration_s", "--duration"),
            (self.step_timeout_s.is_some(), "run.step_timeout_s", "--step-timeout"),
            (self.wait.is_some(), "run.wait", "--wait"),
            (self.spin_us.is_some(), "run.spin_us", "--spin-us"),
            (self.link_delay_steps.is_some(), "run.link_delay_steps", "--link-delay"),
            (self.transport.is_some(), "run.transport", "--transport"),
            (self.zenoh_links.is_some(), "run.zenoh_links", "--zenoh-links"),
            (self.realtime_rate.is_some(), "run.realtime_rate", "--rate"),
            (self.on_agent_loss.is_some(), "run.on_agent_loss", "--on-agent-loss"),
            (self.authenticate.is_some(), "run.authenticate", "--authenticate"),
            (self.record.is_some(), "run.record", "--record"),
            (self.telemetry.is_some(), "run.telemetry", "--telemetry"),
        ];
        set.into_iter().filter(|(on, _, _)| *on).map(|(_, path, flag)| (path, flag)).collect()
    }

    /// Mark the problems of values this command line set with their flag (see [`Problem::flag`]).
    pub fn mark(&self, problems: &mut [Problem]) {
        let flags = self.flags();
        for p in problems.iter_mut().filter(|p| p.flag.is_none()) {
            p.flag = flags.iter().find(|(path, _)| p.path == *path).map(|(_, flag)| *flag);
        }
    }
}

/// A scenario with the problems of its `[run]` and `[[faults]]` ([`load_all`]).
pub type Parsed = (Scenario, Vec<Problem>);

/// Read and parse a scenario file: the generic sections typed and checked for their own form
/// (not yet validated: see [`crate::validate::validate`]), the paper sections raw.
pub fn load(file: &Path, overrides: &Overrides) -> Result<Scenario, ScenarioError> {
    let (s, problems) = load_all(file, overrides)?;
    if problems.is_empty() {
        Ok(s)
    } else {
        Err(ScenarioError { file: file.to_path_buf(), problems }.located(&s.source))
    }
}

/// Like [`load`], but a file whose `[run]` or `[[faults]]` has problems still gives a scenario
/// (with the defaults there) together with those problems, so the paper sections can be checked
/// too and every problem of the file reported at once.
pub fn load_all(file: &Path, overrides: &Overrides) -> Result<(Scenario, Vec<Problem>), ScenarioError> {
    parse_all(&read_text(file)?, file, overrides)
}

/// A scenario's text ([`read_bounded`]), its problem as the file's.
fn read_text(file: &Path) -> Result<String, ScenarioError> {
    read_bounded(file).map_err(|reason| ScenarioError {
        file: file.to_path_buf(),
        problems: vec![Problem::new("(file)", None, reason)],
    })
}

/// The largest scenario or hosts file read, bytes (the largest in `topologies/` is ≈ 6 kB; a
/// generated scenario of hundreds of agents stays far below).
pub const MAX_INPUT_BYTES: u64 = 4 << 20;

/// A scenario or hosts file's text: a regular file of at most [`MAX_INPUT_BYTES`], read whole.
/// A FIFO, a device (`/dev/zero`) or a directory is refused before it is opened (opening a FIFO
/// would block, reading a device would never end), and so is a larger file; the reason is the
/// error's text.
pub fn read_bounded(file: &Path) -> Result<String, String> {
    use std::io::Read as _;
    let kind = |m: &std::fs::Metadata| {
        use std::os::unix::fs::FileTypeExt as _;
        let t = m.file_type();
        if t.is_dir() {
            "a directory"
        } else if t.is_fifo() {
            "a FIFO (named pipe)"
        } else if t.is_char_device() || t.is_block_device() {
            "a device"
        } else if t.is_socket() {
            "a socket"
        } else {
            "not a regular file"
        }
    };
    let check = |m: &std::fs::Metadata| {
        if !m.is_file() {
            return Err(format!("cannot read: {}, not a regular file", kind(m)));
        }
        if m.len() > MAX_INPUT_BYTES {
            return Err(format!(
                "cannot read: {} bytes, more than the {MAX_INPUT_BYTES} bytes (4 MiB) a scenario file may have",
                m.len()
            ));
        }
        Ok(())
    };
    check(&std::fs::metadata(file).map_err(|e| format!("cannot read: {e}"))?)?;
    let f = std::fs::File::open(file).map_err(|e| format!("cannot read: {e}"))?;
    // The file opened may not be the one looked at (replaced in between): look again.
    check(&f.metadata().map_err(|e| format!("cannot read: {e}"))?)?;
    let mut bytes = Vec::new();
    f.take(MAX_INPUT_BYTES + 1).read_to_end(&mut bytes).map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > MAX_INPUT_BYTES {
        return Err(format!(
            "cannot read: grew past the {MAX_INPUT_BYTES} bytes (4 MiB) a scenario file may have while read"
        ));
    }
    String::from_utf8(bytes).map_err(|e| format!("cannot read: not UTF-8 text (byte {})", e.utf8_error().valid_up_to()))
}

/// Parse scenario text; `file` names it in messages, and its directory is the base of relative
/// paths inside paper sections.
pub fn parse(text: &str, file: &Path, overrides: &Overrides) -> Result<Scenario, ScenarioError> {
    let (s, problems) = parse_all(text, file, overrides)?;
    if problems.is_empty() { Ok(s) } else { Err(ScenarioError { file: file.to_path_buf(), problems }.located(text)) }
}

/// [`parse`], keeping going past problems of `[run]` and `[[faults]]` (see [`load_all`]).
pub fn parse_all(text: &str, file: &Path, overrides: &Overrides) -> Result<(Scenario, Vec<Problem>), ScenarioError> {
    let table: toml::Table =
        text.parse().map_err(|e: toml::de::Error| failed(vec![syntax_problem(text, &e)], text, file, overrides))?;
    from_table(table, text, file, overrides)
}

/// The error of a scenario that did not parse: its problems marked with the flags that set
/// them, located in its text.
fn failed(mut problems: Vec<Problem>, text: &str, file: &Path, overrides: &Overrides) -> ScenarioError {
    overrides.mark(&mut problems);
    ScenarioError { file: file.to_path_buf(), problems }.located(text)
}

/// [`load_all`] for a run's processes: the table from the file's digest ([`crate::digest`]) when
/// it has one made from its text, else parsed from the text; with why the digest was not used.
pub fn load_all_digested(file: &Path, overrides: &Overrides) -> Result<(Parsed, Option<DigestError>), ScenarioError> {
    let text = read_text(file)?;
    match crate::digest::read(&crate::digest::path_for(file), file, &text) {
        Ok(table) => Ok((from_table(table, &text, file, overrides)?, None)),
        Err(e) => Ok((parse_all(&text, file, overrides)?, Some(e))),
    }
}

/// [`parse_all`] from the table `text` parses to.
fn from_table(mut table: toml::Table, text: &str, file: &Path, overrides: &Overrides) -> Result<Parsed, ScenarioError> {
    let faults_in_file = match table.get("faults") {
        Some(toml::Value::Array(a)) => a.len(),
        _ => 0,
    };
    apply_overrides(&mut table, overrides);
    let base_dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
    let (s, mut problems) = parse_table(table, base_dir);
    let Some(mut s) = s else { return Err(failed(problems, text, file, overrides)) };
    if let Some(h) = &overrides.hosts {
        problems.extend(crate::hosts::unplaced_ids(h, &s));
    }
    overrides.mark(&mut problems);
    s.source = text.into();
    s.faults_in_file = faults_in_file;
    s.duration_from_command_line = overrides.duration_s.is_some();
    Ok((s, problems))
}

/// A TOML syntax error as a problem at its line and column, with the offending line and a caret
/// under the place.
fn syntax_problem(text: &str, e: &toml::de::Error) -> Problem {
    let mut p = Problem::new("(file)", None, format!("not valid TOML: {}", one_line(e.message())));
    if let Some(span) = e.span() {
        let (line, col) = crate::locate::line_col(text, span.start);
        p.at = Some((line, col));
        if let Some(src) = text.lines().nth(line - 1) {
            let caret = " ".repeat(col.saturating_sub(1));
            p.reason.push_str(&format!("\n      | {src}\n      | {caret}^"));
        }
    }
    p
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
    if let Some(l) = &o.zenoh_links {
        set("run", "zenoh_links", Value::String(l.clone()));
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
    if let Some(r) = o.record {
        set("run", "record", Value::Boolean(r));
    }
    if let Some(f) = &o.telemetry {
        set("run", "telemetry", Value::String(f.clone()));
    }
    if let Some(h) = &o.hosts {
        crate::hosts::apply(table, h);
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

const TOP_KEYS: &[&str] =
    &["scenario", "run", "plant", "algorithm", "agents", "faults", "hosts", "links", "dispersions"];

/// The typed scenario, if its meta, paper sections and agents parsed (a bad `[run]` or
/// `[[faults]]` falls back to the defaults), with every problem found.
fn parse_table(mut table: toml::Table, base_dir: std::path::PathBuf) -> (Option<Scenario>, Vec<Problem>) {
    let mut problems = Vec::new();
    // `[[dispersions]]` are a campaign's (`crate::dispersion`): a run flies the nominal values.
    crate::dispersion::split(&mut table);
    for k in table.keys() {
        if !TOP_KEYS.contains(&k.as_str()) {
            problems.push(Problem::new(
                k.clone(),
                None,
                format!("unknown key{} (expected one of: {})", did_you_mean(k, TOP_KEYS), TOP_KEYS.join(", ")),
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
    let hosts = match table.remove("hosts") {
        Some(v) => section::<Vec<HostSpec>>(v, "hosts", &mut problems).unwrap_or_default(),
        None => Vec::new(),
    };
    let run = match table.remove("run") {
        Some(v) => section::<RunSettings>(v, "run", &mut problems),
        None => Some(RunSettings::default()),
    };
    let links = match table.remove("links") {
        Some(v) => section::<crate::links::Links>(v, "links", &mut problems).unwrap_or_default(),
        None => crate::links::Links::default(),
    };
    let s = match (meta, plant, algorithm, agents) {
        (Some(scenario), Some(plant), Some(algorithm), Some(agents)) => {
            let faults = faults.unwrap_or_default();
            let faults_in_file = faults.len();
            let run = run.unwrap_or_default();
            Some(Scenario {
                scenario,
                run,
                plant,
                algorithm,
                agents,
                hosts,
                faults,
                links,
                base_dir,
                source: "".into(),
                faults_in_file,
                duration_from_command_line: false,
            })
        }
        _ => None,
    };
    (s, problems)
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

/// [`section`] of a table the caller keeps, its key path made only when it has a problem: one
/// copy of the table instead of the caller's and [`section`]'s (`runtime::paper::agent_keys`
/// reads every agent's per-agent keys in every process).
pub fn section_of<T: DeserializeOwned>(
    t: &toml::Table,
    path: impl FnOnce() -> String,
    problems: &mut Vec<Problem>,
) -> Option<T> {
    match T::deserialize(toml::Value::Table(t.clone())) {
        Ok(x) => Some(x),
        Err(_) => tracked(toml::Value::Table(t.clone()), &path(), problems),
    }
}

/// Deserialise one section (or any value inside one) at key path `path`, recording a problem with
/// its full key path on failure. Papers parse their `[plant]`/`[algorithm]` bodies and per-agent
/// keys with it.
///
/// A bad key does not hide the section's other problems: it is reported, taken out, and the
/// section read again (a misspelt key is the commonest mistake, and often not the only one). A
/// required key taken out this way is not reported again as missing.
///
/// A section that reads is read once without key-path tracking: every process reads the whole
/// scenario at its start (a thousand `[[agents]]` tables in each of a thousand processes), and
/// only a section with a problem needs the paths (`perf stat -r 40 orchestrator check` of a
/// 1 000-agent ring, three interleaved pairs: 17.0, 16.1, 17.6 → 16.1, 15.5, 14.0 ms of CPU;
/// page faults 2 290 → 2 340, within their spread between builds).
pub fn section<T: DeserializeOwned>(v: toml::Value, path: &str, problems: &mut Vec<Problem>) -> Option<T> {
    match T::deserialize(v.clone()) {
        Ok(t) => Some(t),
        Err(_) => tracked(v, path, problems),
    }
}

/// [`section`] with every attempt's key path tracked: each bad key reported and taken out.
fn tracked<T: DeserializeOwned>(v: toml::Value, path: &str, problems: &mut Vec<Problem>) -> Option<T> {
    let mut v = v;
    let before = problems.len();
    let mut removed: Vec<String> = Vec::new();
    // Each retry removes one key, so this ends; the bound only guards against a surprise.
    for _ in 0..64 {
        match serde_path_to_error::deserialize::<_, T>(v.clone()) {
            // Read without the bad keys: the section still failed, but every problem is out.
            Ok(t) => return (problems.len() == before).then_some(t),
            Err(e) => {
                let inner = e.path().to_string();
                let message = one_line(&e.inner().to_string());
                let p = problem_of(join(path, &inner), &message);
                if removed.contains(&p.path) {
                    return None;
                }
                let rel = strip_prefix_path(&p.path, path);
                let taken_out = !rel.is_empty() && remove_key(&mut v, &rel);
                removed.push(p.path.clone());
                problems.push(p);
                if !taken_out {
                    return None;
                }
            }
        }
    }
    None
}

/// `path` relative to the section's own path `base` (`plant.foo.bar` under `plant` → `foo.bar`).
fn strip_prefix_path(path: &str, base: &str) -> String {
    path.strip_prefix(base).unwrap_or(path).trim_start_matches('.').to_string()
}

/// Remove the key at relative path `rel` (`a.b[2].c`) from `v`; whether it was there.
fn remove_key(v: &mut toml::Value, rel: &str) -> bool {
    let mut parts: Vec<&str> = rel.split('.').collect();
    let Some(last) = parts.pop() else { return false };
    let mut cur = v;
    for part in parts {
        let (key, idx) = match part.split_once('[') {
            Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (part, None),
        };
        if !key.is_empty() {
            let Some(next) = cur.get_mut(key) else { return false };
            cur = next;
        }
        if let Some(i) = idx {
            let Some(next) = cur.get_mut(i) else { return false };
            cur = next;
        }
    }
    match cur {
        toml::Value::Table(t) => t.remove(last).is_some(),
        _ => false,
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
        let options: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
        let hint = did_you_mean(field, &options);
        let reason =
            if expected.is_empty() { format!("unknown key{hint}") } else { format!("unknown key{hint} ({expected})") };
        return Problem::new(full, None, reason);
    }
    // A choice written as a string that names none of its options (a serde enum).
    if let Some(rest) = reason.strip_prefix("unknown variant `")
        && let Some((value, tail)) = rest.split_once('`')
    {
        let options: Vec<String> = tail.split('`').skip(1).step_by(2).map(|o| format!("{o:?}")).collect();
        return Problem::new(full, Some(format!("{value:?}")), format!("must be {}", choice_list(&options)));
    }
    Problem::new(full, None, in_toml_words(&reason))
}

/// ` (did you mean "x"?)` when one of `options` is close to `key`, else nothing.
pub fn did_you_mean(key: &str, options: &[&str]) -> String {
    let best = options
        .iter()
        .map(|o| (strsim::jaro_winkler(key, o), *o))
        .filter(|(score, _)| *score >= 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    best.map(|(_, o)| format!(" (did you mean {o:?}?)")).unwrap_or_default()
}

/// serde's type names in the words of a TOML file: a float, an integer, an array, a table.
fn in_toml_words(reason: &str) -> String {
    let mut r = reason.to_string();
    for (rust, toml) in [
        ("expected f64", "expected a float"),
        ("expected f32", "expected a float"),
        ("expected u64", "expected an integer ≥ 0"),
        ("expected u32", "expected an integer ≥ 0"),
        ("expected u8", "expected an integer ≥ 0"),
        ("expected usize", "expected an integer ≥ 0"),
        ("expected i64", "expected an integer"),
        ("expected i32", "expected an integer"),
        ("expected a sequence", "expected an array"),
        ("expected a map", "expected a table"),
        ("invalid type: floating point", "invalid type: float"),
        ("invalid type: sequence", "invalid type: array"),
        ("invalid type: map", "invalid type: table"),
    ] {
        r = r.replace(rust, toml);
    }
    // "expected struct Meta" and the like: a table.
    if let Some(i) = r.find("expected struct ") {
        r.replace_range(i.., "expected a table");
    }
    r.replace('`', "")
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
