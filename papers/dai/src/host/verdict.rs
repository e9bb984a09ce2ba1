//! Seed 004's verdict (Huang, Sands, *Novel learning for control of nonlinear spacecraft
//! dynamics*): the run's tracking-error deviation against the paper's Table 2 (r = 3, each law)
//! or Table 4 (the specific law at r = 0.5, 1, 2, 4), within 30 % (the rule `orchestrator dai
//! tables` reports by), and its final state-error ratio against Sec. 4's orders of magnitude
//! (≈ 1e−8 specific, ≈ 1e−3 original, the argument of the log in (15)), within one decade.
//!
//! n/a for a sampled-data run (the paper's values are for its continuous-time loop), a run
//! shorter than the paper's 5 s, or one that did not end normally.

use cohort_host::{Criterion, VerdictInput, VerdictLine};

use crate::config::{DaiAttitude, Law};
use crate::host::campaign::{T4_R, T4_TRACK_DEV};
use crate::host::tables::{FINAL_ORIGINAL, FINAL_SPECIFIC, T2_TRACK_DEV};

/// The paper's run length, s (Appendix A: t = 0:0.001:5).
pub const PAPER_DURATION_S: f64 = 5.0;
/// Table 2's r.
const TABLE2_R: f64 = 3.0;

/// (published deviation, where) for a law and r, if the paper prints one.
fn published_dev(law: Law, r: f64) -> Option<(f64, String)> {
    let i = match law {
        Law::Original => 0,
        Law::General => 1,
        Law::Specific => 2,
    };
    if law == Law::Original || r == TABLE2_R {
        return Some((T2_TRACK_DEV[i], "Huang, Sands, Table 2".into()));
    }
    let k = T4_R.iter().position(|x| *x == r)?;
    (law == Law::Specific).then(|| (T4_TRACK_DEV[k + 1], format!("Huang, Sands, Table 4 (r = {r})")))
}

pub fn lines(input: &VerdictInput<'_>) -> Vec<VerdictLine> {
    let setup = input.run.setup;
    let Some(a) = setup.algorithm_as::<DaiAttitude>() else { return Vec::new() };
    // One spacecraft: unprefixed metrics (several get `agent_<i>.`, no published counterpart).
    if setup.n_agents() != 1 {
        return Vec::new();
    }
    let mut out = Vec::new();
    if let Some((paper, source)) = published_dev(a.law, a.r) {
        out.push(VerdictLine::compare(
            format!("tracking-error deviation, {} law, r = {}", a.law.name(), a.r),
            source,
            paper,
            input.metric("tracking_error_dev"),
            "rad/s",
            Criterion::WithinRelative { rel: 0.3 },
        ));
    }
    let order = match a.law {
        Law::Specific => Some(FINAL_SPECIFIC),
        Law::Original => Some(FINAL_ORIGINAL),
        Law::General => None,
    };
    if let Some(paper) = order {
        out.push(VerdictLine::compare(
            format!("final state-error ratio ‖ω′‖²/‖ω_d‖², {} law", a.law.name()),
            "Huang, Sands, Sec. 4, (15)",
            paper,
            input.metric("final_state_error_norm_ratio_eq15"),
            "",
            Criterion::WithinDecades { decades: 1.0 },
        ));
    }
    let why = input.not_judgeable().or_else(|| {
        if !a.is_continuous() {
            Some(format!(
                "sampled-data run (control period {} s): the paper's values are for its continuous-time loop",
                setup.scenario.dt_s
            ))
        } else if input.duration_s() < PAPER_DURATION_S {
            Some(format!("run shortened to {} s: the paper's run is {PAPER_DURATION_S} s", input.duration_s()))
        } else {
            None
        }
    });
    match why {
        Some(why) => out.into_iter().map(|l| l.not_applicable(why.clone())).collect(),
        None => out,
    }
}
