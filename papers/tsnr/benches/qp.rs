//! Seed 001's QP solve times in one process, on the problems a Case 1 AEMC run really poses:
//! the closed loop (net plant, four AEMC agents, DNN forecast) runs once and records every
//! agent's QP of every step; the 4 × 300 problems are then replayed, in step order, through
//! each solver of `algorithm.mpc.qp_solver`. Printed first: per solver the p50/p99/max solve
//! time (data update and solve, as the agents measure it), the mean iterations, and the largest
//! difference from the exact solution; for Clarabel also where the time goes — its fixed cost and
//! cost per interior-point iteration (least squares over all solves) and its own timers (setup,
//! default start, KKT factorisation "kkt update", KKT solves with iterative refinement "kkt
//! solve", post-process) for one solve of the median iteration count (the solver built fresh, so
//! its one-time setup shows too). Then criterion times the replay of agent 1's 300 problems with
//! each solver, the solver built outside the timed part.
//!
//! `cargo bench -p cohort-paper-tsnr --bench qp` (from the repository root or anywhere: the
//! scenario is found from this crate's directory).

use std::path::Path;
use std::time::Instant;

use clarabel::solver::IPSolver;
use cohort_paper_tsnr::agents::aemc::TsnrAemc;
use cohort_paper_tsnr::agents::mpc::{BoxQp, QpSolver, clarabel_box_qp, clarabel_settings};
use cohort_paper_tsnr::config::formation::{TsnrFormation, TsnrModel};
use cohort_paper_tsnr::config::net_plant::TsnrNetSetup;
use cohort_report::stats::quantile;
use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};
use cohort_runtime::paper::Paper;
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use nalgebra::DMatrix;
use rand::SeedableRng;

const PAPERS: &[&dyn Paper] = &[&cohort_paper_tsnr::Tsnr, &cohort_kinds_generic::Generic];

/// One agent's QPs in step order, with what it takes to build its solver.
struct AgentQps {
    h: DMatrix<f64>,
    bound_n: f64,
    max_iter: u32,
    problems: Vec<(Vec<f64>, Vec<f64>)>,
}

/// Run Case 1 with AEMC in-process (the lockstep protocol of the drivers, no transport) and
/// record every QP.
fn record() -> Vec<AgentQps> {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/tsnr-case1.toml");
    let setup = cohort_runtime::paper::load(&file, &Default::default(), PAPERS).expect("tsnr-case1.toml is valid");
    let cfg = setup.algorithm_as::<TsnrFormation>().expect("tsnr-formation").clone();
    let model = TsnrModel::of(&setup.plant_as::<TsnrNetSetup>().expect("tsnr-net").config);
    let graph = setup.topology().neighbours;
    let dt_s = setup.scenario.dt_s;
    let mut plant = setup.plant.build(&setup);
    let mut agents: Vec<TsnrAemc> = (1..=setup.n_agents())
        .map(|id| TsnrAemc::new(&cfg, &model, dt_s, 0, id, &graph, cfg.forecast_of(id)))
        .collect();
    let mut out: Vec<AgentQps> = agents
        .iter()
        .map(|a| {
            let (h, bound_n) = a.qp().hessian();
            AgentQps { h: h.clone(), bound_n, max_iter: cfg.mpc.as_ref().unwrap().max_iter, problems: Vec::new() }
        })
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(setup.scenario.seed);
    let mut shares = vec![ShareOut::default(); agents.len()];
    let mut readings = Vec::new();
    for k in 0..setup.n_steps() {
        for (i, a) in agents.iter_mut().enumerate() {
            readings.clear();
            plant.readings(i as u32 + 1, &mut rng, &mut readings);
            shares[i] = ShareOut::default();
            a.share(&AgentInput { k, t_s: k as f64 * dt_s, readings: &readings }, &mut shares[i]);
            let (q, offset) = a.qp().last_problem();
            out[i].problems.push((q.to_vec(), offset.to_vec()));
        }
        for (i, a) in agents.iter_mut().enumerate() {
            let nb: Vec<Neighbour<'_>> = graph[i]
                .iter()
                .map(|&j| Neighbour { id: j, values: &shares[j as usize - 1].values, age_steps: 0 })
                .collect();
            a.step(dt_s, &nb);
            plant.apply_command(i as u32 + 1, &shares[i].command);
        }
        plant.advance(dt_s);
    }
    out
}

/// Replay every agent's problems through `solver`: per-solve wall times (µs), iterations, and
/// the solutions.
fn replay(qps: &[AgentQps], solver: QpSolver) -> (Vec<f64>, Vec<u32>, Vec<Vec<f64>>) {
    let (mut times, mut iters, mut xs) = (Vec::new(), Vec::new(), Vec::new());
    for a in qps {
        let mut qp = BoxQp::new(&a.h, a.bound_n, a.max_iter, solver);
        for (q, offset) in &a.problems {
            let started = Instant::now();
            let (_, it, x) = qp.solve(q, offset);
            times.push(started.elapsed().as_secs_f64() * 1e6);
            iters.push(it);
            xs.push(x.expect("every recorded problem is solvable").to_vec());
        }
    }
    (times, iters, xs)
}

/// Clarabel's fixed and per-iteration cost (least squares of time on iterations), and its
/// timers for one solve with the median iteration count.
fn clarabel_breakdown(qps: &[AgentQps], iters: &[u32], times: &[f64]) {
    let n = times.len() as f64;
    let (mx, my) = (iters.iter().map(|&i| f64::from(i)).sum::<f64>() / n, times.iter().sum::<f64>() / n);
    let sxy: f64 = iters.iter().zip(times).map(|(&i, t)| (f64::from(i) - mx) * (t - my)).sum();
    let sxx: f64 = iters.iter().map(|&i| (f64::from(i) - mx).powi(2)).sum();
    let per_iter = sxy / sxx;
    println!(
        "clarabel: time ≈ {:.0} µs + {:.0} µs per iteration (least squares over {} solves, mean {:.2} iterations)",
        my - per_iter * mx,
        per_iter,
        times.len(),
        mx
    );
    let mut sorted = iters.to_vec();
    sorted.sort_unstable();
    let median = sorted[sorted.len() / 2];
    let a = &qps[0];
    let idx = iters.iter().position(|&i| i == median).unwrap_or(0) % a.problems.len();
    let (q, offset) = &a.problems[idx];
    let mut s = clarabel_box_qp(&a.h, a.bound_n, clarabel_settings(a.max_iter));
    let mut b = vec![0.0; 2 * q.len()];
    for i in 0..q.len() {
        b[i] = a.bound_n + offset[i];
        b[q.len() + i] = a.bound_n - offset[i];
    }
    s.update_q(q).unwrap();
    s.update_b(&b).unwrap();
    s.solve();
    println!("clarabel timers of one solve ({} iterations, agent 1's problem {idx}):", s.solution.iterations);
    if let Some(t) = &s.timers {
        t.print();
    }
}

fn summary(qps: &[AgentQps]) {
    let mut exact = None;
    for solver in [QpSolver::ActiveSet, QpSolver::Clarabel] {
        let (mut times, iters, xs) = replay(qps, solver);
        let diff = match &exact {
            None => 0.0,
            Some(ex) => xs
                .iter()
                .zip(ex)
                .flat_map(|(a, b): (&Vec<f64>, &Vec<f64>)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
                .fold(0.0, f64::max),
        };
        if solver == QpSolver::Clarabel {
            clarabel_breakdown(qps, &iters, &times);
        }
        let mean_iter = iters.iter().map(|&i| f64::from(i)).sum::<f64>() / iters.len() as f64;
        times.sort_by(f64::total_cmp);
        println!(
            "{solver:?}: {} solves, p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, {mean_iter:.2} iterations on average, \
             largest difference from the active set's solution {diff:.1e} N",
            times.len(),
            quantile(&times, 0.5),
            quantile(&times, 0.99),
            times.last().copied().unwrap_or(f64::NAN),
        );
        if exact.is_none() {
            exact = Some(xs);
        }
    }
}

fn bench(c: &mut Criterion) {
    let qps = record();
    summary(&qps);
    let agent1 = &qps[..1];
    let mut g = c.benchmark_group("tsnr_qp_case1_agent1_300_solves");
    g.sample_size(10);
    let a = &agent1[0];
    for solver in [QpSolver::ActiveSet, QpSolver::Clarabel] {
        // The solver is built outside the timed part (once per run in an agent).
        g.bench_function(format!("{solver:?}"), |b| {
            b.iter_batched(
                || BoxQp::new(&a.h, a.bound_n, a.max_iter, solver),
                |mut qp| {
                    for (q, offset) in &a.problems {
                        std::hint::black_box(qp.solve(q, offset).2.map(|x| x[0]));
                    }
                },
                BatchSize::PerIteration,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
