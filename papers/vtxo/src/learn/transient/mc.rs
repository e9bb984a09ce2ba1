//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! `orchestrator vtxo transient-mc`: the closed-loop transient Monte Carlo of Sec. 5 and 5.1 —
//! fresh draws of (q₀, ω₀, w) as in the data ([`crate::learn::transient::data::draw`], from a seed the
//! table does not use), each flown with the Lyapunov law (57) twice: with the gains and duration
//! the transient DNN predicts ([`crate::learn::transient::dnn`]), and with those simulated annealing finds
//! for that draw ([`crate::learn::transient::sa`]). Reports P99(e) and P99(E) of both beside Table 2's
//! 0.067° and 0.37 J and checks Sec. 5.1's bounds P99(e) < 0.2°, P99(E) < 2 J, and the DNN's own
//! predictions against P99(ê) < 0.09°, P99(Ê) < 0.5 J.
//!
//! Departure: the flights are those of [`crate::learn::transient::sim`] (truth feedback, no noise or
//! disturbance), the dynamics the data was optimised on; the noisy MEKF loop is the plant's.

use std::path::Path;

use cohort_host::campaign::Campaign;

use crate::learn::transient::data::draw;
use crate::learn::transient::dnn::TransientDnn;
use crate::learn::transient::sa;
use crate::learn::transient::sim::{self, DT_S};
use cohort_report::stats::quantile;

/// Table 2's P99 of e (deg) and E (J); Sec. 5.1's closed-loop bounds and the DNN's.
const PAPER_P99: (f64, f64) = (0.067, 0.37);
const BOUND: (f64, f64) = (0.2, 2.0);
const DNN_BOUND: (f64, f64) = (0.09, 0.5);

/// One draw's outcomes: (e, E) with the DNN's choice, (e, E) with SA's, and the DNN's (ê, Ê).
type Row = [f64; 6];

fn p99(rows: &[Row], k: usize) -> f64 {
    let mut v: Vec<f64> = rows.iter().map(|r| r[k]).collect();
    v.sort_by(f64::total_cmp);
    quantile(&v, 0.99)
}

/// Fly `draws` draws of seed `seed` (parallel over `threads`); markdown of the result.
pub fn run(weights: &Path, draws: usize, seed: u64, iterations: u32, threads: usize) -> Result<String, String> {
    let dnn = TransientDnn::load(weights).map_err(|e| e.to_string())?;
    let rows: Vec<Row> = Campaign::new(draws).workers(threads).map(|i| {
        let (start, w, mut rng) = draw(seed, i as u64);
        let p = dnn.predict(&start.q, &start.omega_rad_s, w);
        let f = sim::fly(&start, p.k1, p.k2, p.duration_s, DT_S);
        let o = f.outcome(p.duration_s, w);
        let sa = sa::anneal(&start, w, iterations, DT_S, &mut rng).outcome;
        [o.error_deg, o.energy_j, sa.error_deg, sa.energy_j, p.error_deg, p.energy_j]
    });
    let ok = |x: f64, b: f64| if x < b { "yes" } else { "**no**" };
    let mut md = format!(
        "Transient Monte Carlo: {draws} draws, seed {seed}, SA {iterations} iterations, step {DT_S} s\n\n\
         | gains and T from | P99(e) deg | P99(E) J | P99(e) < {} | P99(E) < {} |\n|---|---|---|---|---|\n",
        BOUND.0, BOUND.1
    );
    for (name, k) in [("DNN (flown)", 0), ("SA optimum (flown)", 2)] {
        let (e, en) = (p99(&rows, k), p99(&rows, k + 1));
        md += &format!("| {name} | {e:.4} | {en:.4} | {} | {} |\n", ok(e, BOUND.0), ok(en, BOUND.1));
    }
    let (pe, pen) = (p99(&rows, 4), p99(&rows, 5));
    md += &format!(
        "| DNN's own prediction ê, Ê | {pe:.4} | {pen:.4} | < {}: {} | < {}: {} |\n| paper, Table 2 (data) | {} | {} | | |\n",
        DNN_BOUND.0,
        ok(pe, DNN_BOUND.0),
        DNN_BOUND.1,
        ok(pen, DNN_BOUND.1),
        PAPER_P99.0,
        PAPER_P99.1
    );
    Ok(md)
}
