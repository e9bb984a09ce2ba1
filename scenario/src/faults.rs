//! The fault plan: what goes wrong, to whom, and when (`[[faults]]` in a scenario, or repeatable
//! `--fault KIND:agent=ID@t=SECONDS[,for=SECONDS][,p=PROB][,steps=N]` on the command line).
//!
//! Two families, injected from outside the algorithms:
//! - **process faults** (`kill`, `freeze`, `restart`): the orchestrator signals the agent's
//!   process. They happen at a step boundary: the plant holds before sending the measurements of
//!   that step until the orchestrator has acted, so in lockstep mode they are deterministic.
//! - **link faults** (`delay`, `drop`, `corrupt`): the sending agent's transport layer delays,
//!   withholds or garbles its shares. Which share suffers is a pure function of (seed, fault,
//!   step) — [`FaultPlan::fate`] — so every process of the run agrees on it without a message.
//!
//! All times are simulation times (s), rounded to the step: in lockstep mode wall time has no
//! meaning for the run's results, and in real-time mode the two agree up to the rate.

use serde::{Deserialize, Serialize};

use crate::checker::{Checker, fmt_f64};

/// One entry of the fault plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FaultSpec {
    /// kill | freeze | restart | delay | drop | corrupt
    pub kind: String,
    /// Agent id (1..=N).
    pub agent: u32,
    /// When it starts, sim time (s), rounded to the nearest step.
    pub t_s: f64,
    /// freeze: how long the process stays stopped; restart: how long before the relaunch;
    /// delay, drop, corrupt: how long the link fault lasts (absent: to the end of the run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub for_s: Option<f64>,
    /// drop, corrupt: the probability that a share in the window is hit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p: Option<f64>,
    /// delay: how many steps late each share arrives.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay_steps: Option<u32>,
}

pub const FAULT_KINDS: [&str; 6] = ["kill", "freeze", "restart", "delay", "drop", "corrupt"];

/// Longest link delay accepted, steps (receivers keep this many shares per neighbour).
pub const MAX_DELAY_STEPS: u32 = 64;

impl FaultSpec {
    pub fn is_process_fault(&self) -> bool {
        matches!(self.kind.as_str(), "kill" | "freeze" | "restart")
    }

    /// Parse one `--fault` argument: `KIND:agent=ID@t=SECONDS[,for=SECONDS][,p=PROB][,steps=N]`.
    pub fn parse_cli(arg: &str) -> Result<Self, ParseFaultError> {
        use ParseFaultError as E;
        let (kind, rest) = arg.split_once(':').ok_or_else(|| E::NoKind { arg: arg.into() })?;
        if !FAULT_KINDS.contains(&kind) {
            return Err(E::UnknownKind { arg: arg.into(), kind: kind.into() });
        }
        let (who, when) = rest.split_once('@').ok_or_else(|| E::NoTime { arg: arg.into() })?;
        let agent = who
            .strip_prefix("agent=")
            .ok_or_else(|| E::NotAgent { arg: arg.into(), who: who.into() })?
            .parse::<u32>()
            .map_err(|source| E::AgentId { arg: arg.into(), who: who.into(), source })?;
        let mut spec = FaultSpec { kind: kind.into(), agent, t_s: f64::NAN, for_s: None, p: None, delay_steps: None };
        let mut seen_t = false;
        for item in when.split(',') {
            let (key, value) =
                item.split_once('=').ok_or_else(|| E::NotKeyValue { arg: arg.into(), item: item.into() })?;
            let num = || {
                value.parse::<f64>().map_err(|source| E::Number {
                    arg: arg.into(),
                    key: key.into(),
                    value: value.into(),
                    source,
                })
            };
            match key {
                "t" => {
                    spec.t_s = num()?;
                    seen_t = true;
                }
                "for" => spec.for_s = Some(num()?),
                "p" => spec.p = Some(num()?),
                "steps" => {
                    spec.delay_steps = Some(value.parse().map_err(|source| E::Steps {
                        arg: arg.into(),
                        value: value.into(),
                        source,
                    })?)
                }
                _ => return Err(E::UnknownKey { arg: arg.into(), key: key.into() }),
            }
        }
        if !seen_t {
            return Err(E::TimeRequired { arg: arg.into() });
        }
        Ok(spec)
    }
}

/// The form of a `--fault` argument, for messages.
const FAULT_FORM: &str = "expected KIND:agent=ID@t=SECONDS[,for=SECONDS][,p=PROB][,steps=N], \
                          e.g. kill:agent=3@t=120 or drop:agent=2@t=10,for=5,p=0.2";

/// Why a `--fault` argument does not parse ([`FaultSpec::parse_cli`]): each names the argument
/// and the part of it that is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParseFaultError {
    #[error("{arg:?}: no ':' after the kind; {FAULT_FORM}")]
    NoKind { arg: String },
    #[error("{arg:?}: unknown fault kind {kind:?} (expected one of: {})", FAULT_KINDS.join(", "))]
    UnknownKind { arg: String, kind: String },
    #[error("{arg:?}: no '@' before the time; {FAULT_FORM}")]
    NoTime { arg: String },
    #[error("{arg:?}: {who:?} must be agent=ID; {FAULT_FORM}")]
    NotAgent { arg: String, who: String },
    #[error("{arg:?}: agent id {who:?}: {source}")]
    AgentId { arg: String, who: String, source: std::num::ParseIntError },
    #[error("{arg:?}: {item:?} is not KEY=VALUE")]
    NotKeyValue { arg: String, item: String },
    #[error("{arg:?}: {key}={value:?}: {source}")]
    Number { arg: String, key: String, value: String, source: std::num::ParseFloatError },
    #[error("{arg:?}: steps={value:?}: {source}")]
    Steps { arg: String, value: String, source: std::num::ParseIntError },
    #[error("{arg:?}: unknown key {key:?} (expected t, for, p or steps)")]
    UnknownKey { arg: String, key: String },
    #[error("{arg:?}: the time t=SECONDS is required; {FAULT_FORM}")]
    TimeRequired { arg: String },
}

/// How fault `k` is named in messages: `faults[k]` when the file has it, `--fault #n` when the
/// n-th `--fault` argument added it (the first `in_file` entries are the file's).
pub fn fault_name(k: usize, in_file: usize) -> String {
    if k < in_file { format!("faults[{k}]") } else { format!("--fault #{}", k - in_file + 1) }
}

/// Check the plan against the scenario; the first `in_file` entries are the file's, the rest
/// the command line's.
pub(crate) fn check(c: &mut Checker, faults: &[FaultSpec], in_file: usize, n_agents: u32, dt_s: f64, duration_s: f64) {
    for (k, f) in faults.iter().enumerate() {
        let name = fault_name(k, in_file);
        let at = |key: &str| format!("{name}.{key}");
        if !FAULT_KINDS.contains(&f.kind.as_str()) {
            c.fail(at("kind"), format!("{:?}", f.kind), format!("must be one of: {}", FAULT_KINDS.join(", ")));
            continue;
        }
        if f.agent == 0 || f.agent > n_agents {
            c.fail(at("agent"), f.agent, format!("not an agent of this scenario (ids are 1..={n_agents})"));
        }
        if c.finite(&at("t_s"), f.t_s) && !(0.0..duration_s).contains(&f.t_s) {
            c.fail(at("t_s"), fmt_f64(f.t_s), format!("must be in [0, scenario.duration_s = {})", fmt_f64(duration_s)));
        }
        if f.is_process_fault() && f.t_s.is_finite() && (f.t_s / dt_s).round() < 1.0 {
            c.fail(at("t_s"), fmt_f64(f.t_s), "a process fault cannot happen before step 1");
        }
        let needs_for = matches!(f.kind.as_str(), "freeze" | "restart");
        match f.for_s {
            Some(d) => {
                if c.positive(&at("for_s"), d) && d < dt_s {
                    c.fail(
                        at("for_s"),
                        fmt_f64(d),
                        format!("shorter than one step (scenario.dt_s = {})", fmt_f64(dt_s)),
                    );
                }
                if f.kind == "kill" {
                    c.fail(at("for_s"), fmt_f64(d), "a kill has no duration (use restart to bring the agent back)");
                }
            }
            None if needs_for => c.problems.push(crate::Problem::new(
                at("for_s"),
                None,
                format!("required for {} (how long before the agent comes back)", f.kind),
            )),
            None => {}
        }
        let needs_p = matches!(f.kind.as_str(), "drop" | "corrupt");
        match f.p {
            Some(p) if !needs_p => c.fail(at("p"), fmt_f64(p), format!("only drop and corrupt take p, not {}", f.kind)),
            Some(p) if c.finite(&at("p"), p) && !(0.0..=1.0).contains(&p) => {
                c.fail(at("p"), fmt_f64(p), "must be a probability in [0, 1]")
            }
            Some(_) => {}
            None if needs_p => c.problems.push(crate::Problem::new(at("p"), None, format!("required for {}", f.kind))),
            None => {}
        }
        match (f.delay_steps, f.kind == "delay") {
            (Some(d), true) if d == 0 || d > MAX_DELAY_STEPS => {
                c.fail(at("delay_steps"), d, format!("must be in 1..={MAX_DELAY_STEPS}"))
            }
            (Some(d), false) => c.fail(at("delay_steps"), d, format!("only delay takes delay_steps, not {}", f.kind)),
            (None, true) => c.problems.push(crate::Problem::new(at("delay_steps"), None, "required for delay")),
            _ => {}
        }
    }
    // One link fault of a kind per agent at a time, and no process fault while the agent is
    // already down: overlapping windows would make "what happened to this share" ambiguous.
    let plan = FaultPlan::new(faults, 0, dt_s);
    for (a, fa) in plan.faults.iter().enumerate() {
        for fb in plan.faults.iter().skip(a + 1) {
            if fa.agent != fb.agent {
                continue;
            }
            let overlap = fa.start < fb.end && fb.start < fa.end;
            let both_link = !fa.spec.is_process_fault() && !fb.spec.is_process_fault();
            let both_proc = fa.spec.is_process_fault() && fb.spec.is_process_fault();
            if overlap && ((both_link && fa.spec.kind == fb.spec.kind) || both_proc) {
                c.fail(
                    fault_name(fb.index, in_file),
                    format!("{}:agent={}@t={}", fb.spec.kind, fb.agent, fmt_f64(fb.spec.t_s)),
                    format!("overlaps {} ({}) on the same agent", fault_name(fa.index, in_file), fa.spec.kind),
                );
            }
        }
    }
}

/// A fault resolved to steps.
#[derive(Debug, Clone)]
pub struct PlannedFault {
    pub index: usize,
    pub spec: FaultSpec,
    pub agent: u32,
    /// First step affected.
    pub start: u64,
    /// First step no longer affected (u64::MAX: to the end). For freeze and restart: the step at
    /// which the agent comes back. For kill: u64::MAX.
    pub end: u64,
}

/// What happens to one share on its way out (see [`FaultPlan::fate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    Deliver,
    /// Arrives at its readers `n` steps late.
    Delay(u32),
    /// Not published.
    Drop,
    /// Published garbled; its readers reject it.
    Corrupt(Corruption),
}

/// How a corrupted share is garbled: each makes the receivers' validation reject it for a
/// different reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Corruption {
    /// The header's step is far from any step a receiver accepts.
    WrongStep,
    /// The header names another sender than the service's owner.
    WrongSender,
    /// A NaN in the command and the values.
    NonFinite,
}

impl Corruption {
    pub const ALL: [Corruption; 3] = [Corruption::WrongStep, Corruption::WrongSender, Corruption::NonFinite];
    pub fn name(self) -> &'static str {
        match self {
            Corruption::WrongStep => "step",
            Corruption::WrongSender => "sender",
            Corruption::NonFinite => "non_finite",
        }
    }
}

/// The plan of one run, resolved to steps; shared (read-only) by every process.
#[derive(Debug, Clone, Default)]
pub struct FaultPlan {
    pub faults: Vec<PlannedFault>,
    seed: u64,
}

/// SplitMix64: a tiny, well-mixed hash of (seed, fault, step) — the same in every process, so
/// every reader knows which shares were hit without being told.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn to_step(t_s: f64, dt_s: f64) -> u64 {
    (t_s / dt_s).round().max(0.0) as u64
}

impl FaultPlan {
    pub fn new(faults: &[FaultSpec], seed: u64, dt_s: f64) -> Self {
        let faults = faults
            .iter()
            .enumerate()
            .map(|(index, f)| {
                let start = to_step(f.t_s, dt_s);
                let end = match f.for_s {
                    Some(d) if d.is_finite() && f.kind != "kill" => start + to_step(d, dt_s).max(1),
                    _ => u64::MAX,
                };
                PlannedFault { index, spec: f.clone(), agent: f.agent, start, end }
            })
            .collect();
        Self { faults, seed }
    }

    pub fn from_scenario(s: &crate::Scenario) -> Self {
        Self::new(&s.faults, s.scenario.seed, s.scenario.dt_s)
    }

    pub fn is_empty(&self) -> bool {
        self.faults.is_empty()
    }

    pub fn has_process_faults(&self) -> bool {
        self.faults.iter().any(|f| f.spec.is_process_fault())
    }

    /// Steps at which the plant holds for the orchestrator (a process fault starts or ends).
    pub fn hold_steps(&self) -> Vec<u64> {
        let mut v: Vec<u64> = self
            .faults
            .iter()
            .filter(|f| f.spec.is_process_fault())
            .flat_map(|f| [Some(f.start), (f.end != u64::MAX).then_some(f.end)])
            .flatten()
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// Largest link delay in the plan (receivers look back this many steps).
    pub fn max_delay(&self) -> u32 {
        self.faults.iter().filter_map(|f| f.spec.delay_steps).max().unwrap_or(0)
    }

    /// What happens to agent `agent`'s share of step `step`. Drop is decided before corrupt,
    /// and a delayed share can still be dropped or corrupted.
    pub fn fate(&self, agent: u32, step: u64) -> Fate {
        let mut fate = Fate::Deliver;
        for f in self.faults.iter().filter(|f| f.agent == agent && f.start <= step && step < f.end) {
            let u = || {
                let h = mix(self.seed ^ mix((f.index as u64) << 32 ^ u64::from(agent)) ^ mix(step.wrapping_mul(3)));
                (h >> 11) as f64 / (1u64 << 53) as f64
            };
            match f.spec.kind.as_str() {
                "drop" if u() < f.spec.p.unwrap_or(0.0) => return Fate::Drop,
                "corrupt" if u() < f.spec.p.unwrap_or(0.0) => {
                    let h = mix(self.seed.wrapping_add(step) ^ 0xC0_4455);
                    fate = Fate::Corrupt(Corruption::ALL[(h % 3) as usize]);
                }
                "delay" if fate == Fate::Deliver => fate = Fate::Delay(f.spec.delay_steps.unwrap_or(0)),
                _ => {}
            }
        }
        fate
    }

    /// The step at which agent `agent`'s share of `step` reaches its readers, if it does (a
    /// corrupted one reaches them but is rejected, so it counts as lost).
    pub fn arrival(&self, agent: u32, step: u64) -> Option<u64> {
        match self.fate(agent, step) {
            Fate::Deliver => Some(step),
            Fate::Delay(n) => Some(step + u64::from(n)),
            Fate::Drop | Fate::Corrupt(_) => None,
        }
    }

    /// The steps of agent `agent`'s shares that arrive at step `k` (oldest first).
    pub fn arriving_at(&self, agent: u32, k: u64, out: &mut Vec<u64>) {
        out.clear();
        let back = u64::from(self.max_delay());
        for s in k.saturating_sub(back)..=k {
            if self.arrival(agent, s) == Some(k) {
                out.push(s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(kind: &str, agent: u32, t_s: f64) -> FaultSpec {
        FaultSpec { kind: kind.into(), agent, t_s, for_s: None, p: None, delay_steps: None }
    }

    #[test]
    fn cli_form_parses_and_names_its_errors() {
        let f = FaultSpec::parse_cli("drop:agent=2@t=10,for=5,p=0.2").unwrap();
        assert_eq!((f.kind.as_str(), f.agent, f.t_s, f.for_s, f.p), ("drop", 2, 10.0, Some(5.0), Some(0.2)));
        let f = FaultSpec::parse_cli("delay:agent=1@t=3,steps=4").unwrap();
        assert_eq!(f.delay_steps, Some(4));
        for (bad, says) in [
            ("explode:agent=1@t=3", "unknown fault kind"),
            ("kill:agent=x@t=3", "agent id"),
            ("kill:agent=1", "no '@'"),
            ("kill:agent=1@for=3", "t=SECONDS is required"),
            ("kill:agent=1@t=3,q=1", "unknown key"),
            ("kill:3@t=3", "must be agent=ID"),
        ] {
            let e = FaultSpec::parse_cli(bad).unwrap_err().to_string();
            assert!(e.contains(says) && e.contains(bad), "{bad}: {e}");
        }
    }

    #[test]
    fn drop_fraction_is_seeded_and_near_p() {
        let mut f = spec("drop", 2, 0.0);
        f.p = Some(0.2);
        let plan = FaultPlan::new(&[f], 7, 0.01);
        let dropped = (0..100_000).filter(|&k| plan.fate(2, k) == Fate::Drop).count();
        assert!((19_000..21_000).contains(&dropped), "{dropped}");
        assert!((0..1000).all(|k| plan.fate(1, k) == Fate::Deliver), "other agents untouched");
        let again = FaultPlan::new(&plan.faults.iter().map(|f| f.spec.clone()).collect::<Vec<_>>(), 7, 0.01);
        assert!((0..1000).all(|k| plan.fate(2, k) == again.fate(2, k)));
        let other_seed = FaultPlan::new(&plan.faults.iter().map(|f| f.spec.clone()).collect::<Vec<_>>(), 8, 0.01);
        assert!((0..1000).any(|k| plan.fate(2, k) != other_seed.fate(2, k)));
    }

    #[test]
    fn corruption_uses_every_kind_and_delay_shifts_arrival() {
        let mut c = spec("corrupt", 1, 1.0);
        c.p = Some(0.5);
        c.for_s = Some(10.0);
        let mut d = spec("delay", 3, 1.0);
        d.delay_steps = Some(3);
        d.for_s = Some(1.0);
        let plan = FaultPlan::new(&[c, d], 1, 0.1);
        let kinds: Vec<Fate> = (10..110).map(|k| plan.fate(1, k)).collect();
        for kind in Corruption::ALL {
            assert!(kinds.contains(&Fate::Corrupt(kind)), "{kind:?} never drawn");
        }
        assert_eq!(plan.fate(1, 9), Fate::Deliver, "before the window");
        assert_eq!(plan.fate(1, 110), Fate::Deliver, "after the window");
        // Delay window: steps 10..20 arrive 3 later; nothing arrives at 10..12; two at 20..22.
        let mut v = Vec::new();
        plan.arriving_at(3, 11, &mut v);
        assert!(v.is_empty(), "{v:?}");
        plan.arriving_at(3, 13, &mut v);
        assert_eq!(v, vec![10]);
        plan.arriving_at(3, 21, &mut v);
        assert_eq!(v, vec![18, 21]);
        assert_eq!(plan.hold_steps(), Vec::<u64>::new());
    }

    #[test]
    fn process_faults_hold_the_plant_at_their_edges() {
        let mut fr = spec("freeze", 2, 1.0);
        fr.for_s = Some(5.0);
        let plan = FaultPlan::new(&[spec("kill", 3, 12.0), fr], 0, 0.01);
        assert_eq!(plan.hold_steps(), vec![100, 600, 1200]);
    }
}
