//! Every case of the bench, in the order the tables list them: each paper's headline scenario
//! (multi-process and reference), the ring rows by N and waiting, UDP, authentication, loaded,
//! scale, long and idle rows, then the zenoh and Python rows of their own modules.

use std::path::Path;

use cohort_runtime::paper::Setup;
use cohort_scenario::Overrides;

use super::ring::{RING, RingRun, ring};
use super::types::Case;
use super::{python, zenoh};

/// Every case; the Python rows only when `only` may choose one of them (building them imports
/// their modules, numpy included, so a Rust case must not need a Python environment).
pub(super) fn cases(
    quick: bool,
    repo: &Path,
    lab_dir: Option<&Path>,
    scratch: &Path,
    only: Option<&str>,
) -> Result<Vec<Case>, String> {
    let ns: &[u32] = if quick { &[6, 20] } else { &[6, 20, 50, 100] };
    let steps = if quick { 500 } else { 2000 };
    let mut out = Vec::new();
    let mut push = |group: &'static str, n: u32, variant: &str, label: &str, scenario: Setup, reference: bool| {
        // A headline case is named by its scenario; the others by group alone.
        let key = if group == "headline" {
            format!("{group}/{label}/N={n}/{variant}")
        } else {
            format!("{group}/N={n}/{variant}")
        };
        let hogs = group == "loaded";
        out.push(Case {
            key,
            group,
            n,
            variant: variant.into(),
            label: label.into(),
            scenario,
            reference,
            hogs,
            lab: None,
            live: None,
        });
    };
    let mut live = Vec::new();
    for file in cohort_registry::HOSTS.iter().flat_map(|h| h.bench_scenarios()) {
        // Quick mode shortens a headline run to 20 s; a scenario that is not valid shortened (its
        // own times reach past 20 s) runs whole.
        let o = Overrides { duration_s: quick.then_some(20.0), ..Default::default() };
        let s = match crate::load(&repo.join(file), &o) {
            Ok(s) => s,
            Err(_) if quick => crate::load(&repo.join(file), &Overrides::default()).map_err(|e| e.to_string())?,
            Err(e) => return Err(e.to_string()),
        };
        let (name, n) = (s.scenario.name.clone(), s.n_agents());
        push("headline", n, "multi-process", &name, s.clone(), false);
        push("headline", n, "reference", &name, s.clone(), true);
        // `--live` against none, on each headline with a 3-D scene.
        live.extend(super::live::cases(&name, &s));
    }
    for &n in ns {
        for wait in ["event", "poll", "adaptive"] {
            push("ring", n, wait, "ring", ring(n, steps, RingRun { wait, ..RING })?, false);
        }
        let delayed = ring(n, steps, RingRun { link_delay_steps: 1, ..RING })?;
        push("ring", n, "adaptive+link-delay", "ring", delayed, false);
        push("null", n, "adaptive", "null", ring(n, steps, RingRun { null: true, ..RING })?, false);
        if n == 6 || n == 50 || quick {
            for wait in ["event", "adaptive"] {
                push("udp", n, wait, "udp", ring(n, steps, RingRun { wait, transport: "udp", ..RING })?, false);
            }
        }
    }
    // The cost of run.authenticate at N = 6.
    let sealed = ring(6, steps, RingRun { authenticate: true, ..RING })?;
    push("mac", 6, "adaptive+authenticate", "mac", sealed, false);
    // A loaded machine: two busy-loop hogs the bench starts and stops around each of these runs;
    // every waiting strategy, so the default can be held against the best fixed one under load
    // as the ring rows do idle.
    let loaded_ns: &[u32] = if quick { &[6] } else { &[6, 50, 100] };
    for &n in loaded_ns {
        for wait in ["event", "poll", "adaptive"] {
            push("loaded", n, wait, "loaded", ring(n, steps, RingRun { wait, ..RING })?, false);
        }
    }
    // Scale: N = 200, 256 and 1 000 agent processes at the machine's own open-file limit (the
    // orchestrator raises its soft limit to the hard one); start-up, steps/s and PSS against N,
    // 200 steps. A thousand-agent run takes minutes on two cores: only when asked for by name
    // (`--only scale/N=1000`).
    if !quick {
        for n in [200, 256] {
            push("scale", n, "adaptive", "scale", ring(n, 200, RING)?, false);
        }
        if only.is_some_and(|o| o.starts_with("scale/N=1000")) {
            for wait in ["adaptive", "event", "poll"] {
                push("scale", 1000, wait, "scale", ring(1000, 200, RingRun { wait, ..RING })?, false);
            }
        }
    }
    let (n_long, steps_long) = if quick { (20, 1000) } else { (100, 10_000) };
    push("long", n_long, "adaptive", "long", ring(n_long, steps_long, RING)?, false);
    // Agents behind a plant paced at 10 Hz (dt 0.1 s, real time): how much CPU do they burn?
    let idle = ring(6, if quick { 20 } else { 50 }, RingRun { dt_s: 0.1, realtime: true, ..RING })?;
    push("idle", 6, "10Hz", "idle", idle, false);
    out.extend(live);
    out.extend(zenoh::zenoh_cases(quick, repo, lab_dir, only)?);
    if only.is_none_or(python::may_choose) {
        out.extend(python::cases(quick, repo, scratch)?);
    }
    Ok(out)
}
