//! `[[dispersions]]` entries read and checked against the nominal scenario: the key must be one
//! the scenario sets, the distribution's parameters must fit it (each a number, or one per
//! component of a vector key), and nothing is skipped — every problem is reported with its key
//! path (`dispersions[2].sigma`).

use serde::Deserialize;

use super::keypath::KeyPath;
use super::law::Law;
use crate::error::Problem;

/// A distribution's name as written (`dist = "truncated-normal"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DistName {
    Normal,
    TruncatedNormal,
    Uniform,
    LogUniform,
    UniformInt,
    Choice,
}

/// A parameter: one number for every component, or one per component.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum Param {
    One(f64),
    Each(Vec<f64>),
}

/// One `[[dispersions]]` entry as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDispersion {
    pub key: String,
    pub dist: DistName,
    pub mean: Option<Param>,
    pub sigma: Option<Param>,
    /// σ as a fraction of the nominal value's magnitude (per component).
    pub sigma_rel: Option<Param>,
    pub low: Option<Param>,
    pub high: Option<Param>,
    pub values: Option<Vec<toml::Value>>,
    pub weights: Option<Vec<f64>>,
    pub group: Option<String>,
    pub correlation: Option<f64>,
}

/// A checked dispersion: where it writes and what it draws there.
#[derive(Debug, Clone, PartialEq)]
pub struct Dispersion {
    pub key: KeyPath,
    /// One law per component (one for a scalar key).
    pub laws: Vec<Law>,
    /// The key holds an array of numbers, dispersed component by component.
    pub vector: bool,
    pub group: Option<String>,
    /// Correlation with its group's common factor (Gaussian copula), 0..=1.
    pub correlation: f64,
}

impl RawDispersion {
    /// The parameters this entry gives, by name.
    fn given(&self) -> Vec<&'static str> {
        let mut g = Vec::new();
        for (on, name) in [
            (self.mean.is_some(), "mean"),
            (self.sigma.is_some(), "sigma"),
            (self.sigma_rel.is_some(), "sigma_rel"),
            (self.low.is_some(), "low"),
            (self.high.is_some(), "high"),
            (self.values.is_some(), "values"),
            (self.weights.is_some(), "weights"),
        ] {
            if on {
                g.push(name);
            }
        }
        g
    }
}

/// What each distribution takes: (required, optional). `sigma`/`sigma_rel` are one requirement.
fn parameters(d: DistName) -> (&'static [&'static str], &'static [&'static str]) {
    match d {
        DistName::Normal => (&["sigma"], &["mean", "sigma_rel"]),
        DistName::TruncatedNormal => (&["sigma", "low", "high"], &["mean", "sigma_rel"]),
        DistName::Uniform | DistName::LogUniform | DistName::UniformInt => (&["low", "high"], &[]),
        DistName::Choice => (&["values"], &["weights"]),
    }
}

/// Check entry `k` against the nominal table; every problem at `dispersions[k]…`.
pub fn check(k: usize, raw: &RawDispersion, nominal: &toml::Table) -> Result<Dispersion, Vec<Problem>> {
    let at = |field: &str| format!("dispersions[{k}].{field}");
    let mut problems = Vec::new();
    let key = match KeyPath::parse(&raw.key) {
        Ok(p) => p,
        Err(why) => return Err(vec![Problem::new(at("key"), Some(format!("{:?}", raw.key)), why)]),
    };
    let refuse = |why: String| Err(vec![Problem::new(at("key"), Some(format!("{:?}", raw.key)), why)]);
    if matches!(key.0.first(), Some(super::keypath::Seg::Key(s)) if s == "dispersions") {
        return refuse("a dispersion cannot change the dispersions".into());
    }
    if key.to_string() == "scenario.seed" {
        return refuse("the campaign sets each case's seed (its --seed and the case index)".into());
    }
    let Some(nominal_value) = key.get(nominal) else {
        return refuse(format!(
            "{} (a dispersion changes a value the scenario sets: write the nominal value in the file)",
            key.why_missing(nominal)
        ));
    };
    let shape = match Shape::of(nominal_value) {
        Ok(s) => s,
        Err(why) => return refuse(why),
    };
    check_parameters(raw, &at, &mut problems);
    if let Some(c) = raw.correlation {
        if raw.group.is_none() {
            problems.push(Problem::new(at("correlation"), Some(c.to_string()), "a correlation needs a group"));
        } else if !(0.0..=1.0).contains(&c) {
            problems.push(Problem::new(at("correlation"), Some(c.to_string()), "must be in [0, 1]"));
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let laws = laws(raw, &shape, &at)?;
    Ok(Dispersion {
        key,
        laws,
        vector: matches!(shape, Shape::Vector(_)),
        group: raw.group.clone(),
        correlation: raw.correlation.unwrap_or(1.0),
    })
}

/// Parameters the distribution does not take, and required ones missing.
fn check_parameters(raw: &RawDispersion, at: &dyn Fn(&str) -> String, problems: &mut Vec<Problem>) {
    let (required, optional) = parameters(raw.dist);
    let name = format!("{:?}", raw.dist).to_lowercase();
    let takes: Vec<&str> = required.iter().chain(optional).copied().collect();
    for p in raw.given() {
        if !takes.contains(&p) {
            problems.push(Problem::new(
                at(p),
                None,
                format!("not a parameter of {} (it takes {})", name, takes.join(", ")),
            ));
        }
    }
    for r in required {
        let given = match *r {
            "sigma" => raw.sigma.is_some() || raw.sigma_rel.is_some(),
            p => raw.given().contains(&p),
        };
        if !given {
            let what = if *r == "sigma" { "sigma or sigma_rel" } else { r };
            problems.push(Problem::new(at(r), None, format!("required for {name}: {what}")));
        }
    }
    if raw.sigma.is_some() && raw.sigma_rel.is_some() {
        problems.push(Problem::new(at("sigma_rel"), None, "give sigma or sigma_rel, not both"));
    }
}

/// The nominal value's shape: what can be drawn for it.
enum Shape {
    Float(f64),
    Int(i64),
    /// A string or a boolean: only a choice.
    Other(toml::Value),
    Vector(Vec<f64>),
}

impl Shape {
    fn of(v: &toml::Value) -> Result<Self, String> {
        match v {
            toml::Value::Float(x) => Ok(Shape::Float(*x)),
            toml::Value::Integer(i) => Ok(Shape::Int(*i)),
            toml::Value::String(_) | toml::Value::Boolean(_) => Ok(Shape::Other(v.clone())),
            toml::Value::Array(a) if !a.is_empty() => a
                .iter()
                .map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                .collect::<Option<Vec<f64>>>()
                .map(Shape::Vector)
                .ok_or_else(|| "an array of other than numbers: disperse its elements by their paths ([i])".into()),
            other => Err(format!(
                "a {} cannot be drawn: disperse a number, a vector of numbers or a string",
                other.type_str()
            )),
        }
    }

    fn nominals(&self) -> Vec<f64> {
        match self {
            Shape::Float(x) => vec![*x],
            Shape::Int(i) => vec![*i as f64],
            Shape::Other(_) => vec![f64::NAN],
            Shape::Vector(v) => v.clone(),
        }
    }
}

/// One law per component, with the parameters' values checked.
fn laws(raw: &RawDispersion, shape: &Shape, at: &dyn Fn(&str) -> String) -> Result<Vec<Law>, Vec<Problem>> {
    let nominal = shape.nominals();
    let n = nominal.len();
    let mut problems = Vec::new();
    let dist = raw.dist;
    let continuous = !matches!(dist, DistName::UniformInt | DistName::Choice);
    match shape {
        Shape::Int(_) if continuous => problems.push(Problem::new(
            at("dist"),
            None,
            "the key holds a whole number: draw it with uniform-int or choice".to_string(),
        )),
        Shape::Other(v) if dist != DistName::Choice => problems.push(Problem::new(
            at("dist"),
            None,
            format!("the key holds a {}: only a choice can be drawn for it", v.type_str()),
        )),
        Shape::Vector(_) if dist == DistName::Choice => problems.push(Problem::new(
            at("dist"),
            None,
            "a choice draws one value: disperse a vector's components by their paths ([i])",
        )),
        _ => {}
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    if dist == DistName::Choice {
        return choice(raw, shape, at).map(|l| vec![l]);
    }
    let mut param = |name: &str, p: &Option<Param>| -> Vec<f64> {
        match p {
            None => Vec::new(),
            Some(Param::One(x)) => vec![*x; n],
            Some(Param::Each(v)) if v.len() == n => v.clone(),
            Some(Param::Each(v)) => {
                problems.push(Problem::new(
                    at(name),
                    None,
                    format!("{} values for a key of {n} component(s): give one number or {n}", v.len()),
                ));
                Vec::new()
            }
        }
    };
    let (mean, sigma, sigma_rel) =
        (param("mean", &raw.mean), param("sigma", &raw.sigma), param("sigma_rel", &raw.sigma_rel));
    let (low, high) = (param("low", &raw.low), param("high", &raw.high));
    if !problems.is_empty() {
        return Err(problems);
    }
    let mut out = Vec::with_capacity(n);
    for (i, nom) in nominal.iter().enumerate() {
        let m = mean.get(i).copied().unwrap_or(*nom);
        let s = sigma.get(i).copied().or_else(|| sigma_rel.get(i).map(|r| r * nom.abs()));
        let (lo, hi) = (low.get(i).copied(), high.get(i).copied());
        let comp = if n > 1 { format!(" (component {i})") } else { String::new() };
        match component(dist, m, s, lo, hi) {
            Ok(l) => out.push(l),
            Err((field, why)) => {
                // σ from sigma_rel: blame the key the user wrote.
                let (field, why) = match (field, &raw.sigma_rel) {
                    ("sigma", Some(_)) => ("sigma_rel", format!("{why} (sigma_rel × |nominal {nom}|)")),
                    _ => (field, why),
                };
                problems.push(Problem::new(at(field), None, format!("{why}{comp}")))
            }
        }
    }
    if problems.is_empty() { Ok(out) } else { Err(problems) }
}

/// One component's law; the parameter at fault and why otherwise.
fn component(
    dist: DistName,
    mean: f64,
    sigma: Option<f64>,
    low: Option<f64>,
    high: Option<f64>,
) -> Result<Law, (&'static str, String)> {
    let finite =
        |name: &'static str, x: f64| if x.is_finite() { Ok(x) } else { Err((name, format!("{x} is not finite"))) };
    let sigma_ok = |s: Option<f64>| -> Result<f64, (&'static str, String)> {
        let s = finite("sigma", s.unwrap_or(f64::NAN))?;
        if s > 0.0 {
            Ok(s)
        } else {
            Err(("sigma", format!("σ = {s}: must be > 0 (a σ from sigma_rel of a zero nominal is 0)")))
        }
    };
    let bounds = || -> Result<(f64, f64), (&'static str, String)> {
        let (l, h) = (finite("low", low.unwrap_or(f64::NAN))?, finite("high", high.unwrap_or(f64::NAN))?);
        if l < h { Ok((l, h)) } else { Err(("high", format!("high = {h} must be above low = {l}"))) }
    };
    Ok(match dist {
        DistName::Normal => Law::Normal { mean: finite("mean", mean)?, sigma: sigma_ok(sigma)? },
        DistName::TruncatedNormal => {
            let (l, h) = bounds()?;
            let law = Law::TruncatedNormal { mean: finite("mean", mean)?, sigma: sigma_ok(sigma)?, low: l, high: h };
            if law.kept_mass() < 1e-9 {
                return Err(("low", format!("[{l}, {h}] holds almost none of the normal's mass (mean {mean})")));
            }
            law
        }
        DistName::Uniform => {
            let (low, high) = bounds()?;
            Law::Uniform { low, high }
        }
        DistName::LogUniform => {
            let (low, high) = bounds()?;
            if low <= 0.0 {
                return Err(("low", format!("low = {low}: a log-uniform needs low > 0")));
            }
            Law::LogUniform { low, high }
        }
        DistName::UniformInt => {
            let (l, h) = bounds()?;
            if l.fract() != 0.0 || h.fract() != 0.0 || l.abs() > 2f64.powi(53) || h.abs() > 2f64.powi(53) {
                return Err(("low", format!("uniform-int bounds are whole numbers (low = {l}, high = {h})")));
            }
            Law::UniformInt { low: l as i64, high: h as i64 }
        }
        DistName::Choice => unreachable!("a choice is built by choice()"),
    })
}

/// A choice among scalar values of the nominal value's type, with optional weights.
fn choice(raw: &RawDispersion, shape: &Shape, at: &dyn Fn(&str) -> String) -> Result<Law, Vec<Problem>> {
    let values = raw.values.clone().unwrap_or_default();
    let mut problems = Vec::new();
    if values.is_empty() {
        problems.push(Problem::new(at("values"), None, "a choice needs at least one value"));
    }
    let kind = match shape {
        Shape::Float(_) | Shape::Int(_) => "number",
        Shape::Other(v) => v.type_str(),
        Shape::Vector(_) => unreachable!("refused before"),
    };
    for (i, v) in values.iter().enumerate() {
        let fits = match (kind, v) {
            ("number", toml::Value::Float(_)) => !matches!(shape, Shape::Int(_)),
            ("number", toml::Value::Integer(_)) => true,
            (k, v) => v.type_str() == k,
        };
        if !fits {
            let want = if matches!(shape, Shape::Int(_)) { "integer" } else { kind };
            problems.push(Problem::new(
                format!("{}[{i}]", at("values")),
                Some(v.to_string()),
                format!("the key holds a {want}: every value must be one"),
            ));
        }
    }
    let weights = raw.weights.clone().unwrap_or_else(|| vec![1.0; values.len()]);
    if weights.len() != values.len() {
        problems.push(Problem::new(
            at("weights"),
            None,
            format!("{} weights for {} values", weights.len(), values.len()),
        ));
    } else if weights.iter().any(|w| !w.is_finite() || *w < 0.0) || weights.iter().sum::<f64>() <= 0.0 {
        problems.push(Problem::new(at("weights"), None, "weights are finite, ≥ 0, and not all 0"));
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let total: f64 = weights.iter().sum();
    let mut acc = 0.0;
    let mut cumulative: Vec<f64> = weights
        .iter()
        .map(|w| {
            acc += w / total;
            acc
        })
        .collect();
    if let Some(last) = cumulative.last_mut() {
        *last = 1.0;
    }
    Ok(Law::Choice { values, cumulative })
}
