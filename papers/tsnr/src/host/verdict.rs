//! Seed 001's verdict (Ma et al., *An active energy management distributed formation control for
//! tethered space net robot via cooperative game theory*): the paper states no numeric bound, so
//! the run is held to what its Sec. 4 shows and prints:
//!
//! - capture: "at 30 s, the debris is finally captured" (Figs. 6–7) — every MU ends at its
//!   terminal state (`mu_<i>.terminal_ok`, within 0.1 m and 0.05 m/s: tolerances of ours, the
//!   paper gives none; see [`crate::host::analysis`]);
//! - fuel: Tables 1–2's total "control input generated" for this case and method, beside our
//!   Σₖ‖uᵢ(t_k)‖ summed over the MUs (N). Always n/a: the paper does not say how its figure is
//!   summed, and ours is ≈ 34× larger (Case 1 AEMC: 4750 against 140.77); the paper's claim is the order of the methods,
//!   which one run cannot show (`orchestrator tsnr compare` does, by ratio).
//!
//! Both n/a for a run shorter than the paper's 30 s, a fault run or one that did not end
//! normally.

use cohort_host::{Criterion, VerdictInput, VerdictLine};

use crate::config::formation::TsnrFormation;

/// The paper's capture time, s (Sec. 4).
pub const PAPER_DURATION_S: f64 = 30.0;

pub fn lines(input: &VerdictInput<'_>) -> Vec<VerdictLine> {
    let setup = input.run.setup;
    let Some(a) = setup.algorithm_as::<TsnrFormation>() else { return Vec::new() };
    let n = setup.n_agents();
    let ok: Option<f64> = (1..=n).map(|i| input.metric(&format!("mu_{i}.terminal_ok"))).sum();
    let mut out = vec![
        VerdictLine::compare(
            "MUs at their terminal state at the end (net closed)",
            "Ma et al., Sec. 4, Figs. 6–7",
            f64::from(n),
            ok,
            "MUs",
            Criterion::AtLeast,
        )
        .with_note("terminal tolerance 0.1 m, 0.05 m/s is ours"),
    ];
    let case = crate::host::compare::paper_case(&setup.scenario.name);
    if let Some(paper) = case.and_then(|c| crate::host::compare::paper_fuel_total_n(c, a.method.name())) {
        let ours = input.metric("fuel_total_ns").map(|f| f / setup.scenario.dt_s);
        out.push(
            VerdictLine::compare(
                format!("total control input, {} (Σ over steps and MUs)", a.method.name().to_uppercase()),
                format!("Ma et al., Table {}", case.unwrap_or_default()),
                paper,
                ours,
                "N",
                Criterion::WithinRelative { rel: 0.3 },
            )
            .not_applicable(format!(
                "the paper does not say how its figure is summed (ours: Σₖ‖uᵢ(t_k)‖ at Δt = {} s); its claim is the \
                 order of the methods, which `orchestrator tsnr compare` checks by ratio",
                setup.scenario.dt_s
            )),
        );
    }
    let why = input.not_judgeable().or_else(|| {
        (input.duration_s() < PAPER_DURATION_S)
            .then(|| format!("run shortened to {} s: the capture ends at {PAPER_DURATION_S} s", input.duration_s()))
    });
    match why {
        Some(why) => out.into_iter().map(|l| l.not_applicable(why.clone())).collect(),
        None => out,
    }
}
