//! Per-step compute of seed 003's agents (`cargo bench -p cohort-paper-nr --bench nr_step`): one
//! agent step (`share` + `step`) of Neural-Rendezvous and of NMPC at the steps that differ in
//! work, on `topologies/nr-iso.toml` (test ISO 203, its navigation errors). Each case restores the
//! agent's checkpoint taken just before that step of a real flight and feeds it that step's
//! readings, so the work is the flight's; the restore is outside the measured time.
//!
//! Neural-Rendezvous: k = 0 (SN-DNN guidance), k = 108 = t_s (the desired trajectory (21)–(23)
//! built: 36 forward SN-DNN steps and the backward pass, plus the bound's L̄: 12 more control
//! evaluations), k = 109 (min-norm tracking), k = 114 (the hourly rebuild). 6 of the 144 steps
//! build a trajectory, so these set NR's per-step p99. NMPC: k = 0 (144-step horizon), k = 108
//! (36 steps) and k = 140 (4 steps), each a full SCP.

use std::hint::black_box;
use std::path::Path;

use cohort_paper_nr::iso::config::Method;
use cohort_paper_nr::iso::host::kinds::NrSetup;
use cohort_runtime::model::{AgentInput, Algorithm, ShareOut};
use cohort_runtime::paper::{Paper, Setup, load};
use cohort_runtime::rng::process_rng;
use cohort_wire::transport::Proc;
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};

fn setup() -> Setup {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../topologies/nr-iso.toml");
    let papers: &[&'static dyn Paper] = &[&cohort_paper_nr::Nr];
    load(Path::new(path), &Default::default(), papers).expect("nr-iso.toml")
}

/// A fresh agent flying `method` with the scenario's settings.
fn agent(s: &Setup, method: Method) -> Box<dyn Algorithm> {
    let nr = s.algorithm_as::<NrSetup>().expect("neural-rendezvous");
    let mut alg = nr.config.clone();
    alg.method = method;
    Box::new(cohort_paper_nr::iso::control::agent::NrAgent::new(alg, s.scenario.dt_s, nr.net.clone()).expect("valid"))
}

/// (checkpoint before step k's `share`, readings of step k) for each k of `at`, from one flight
/// of `method` in the scenario's lockstep order.
fn states(s: &Setup, method: Method, at: &[u64]) -> Vec<(u64, Vec<u8>, Vec<f64>)> {
    let mut plant = s.plant.build(s);
    let mut a = agent(s, method);
    let mut rng = process_rng(s.scenario.seed, Proc::Plant);
    let (mut out, mut readings, mut kept) = (ShareOut::default(), Vec::new(), Vec::new());
    for k in 0..=*at.iter().max().expect("a step") {
        readings.clear();
        plant.readings(1, &mut rng, &mut readings);
        if at.contains(&k) {
            kept.push((k, a.save_state(), readings.clone()));
        }
        a.share(&AgentInput { k, t_s: k as f64 * s.scenario.dt_s, readings: &readings }, &mut out);
        a.step(s.scenario.dt_s, &[]);
        plant.apply_command(1, &out.command);
        plant.advance(s.scenario.dt_s);
    }
    kept
}

fn bench_steps(c: &mut Criterion, s: &Setup, method: Method, cases: &[(u64, &str)]) {
    let at: Vec<u64> = cases.iter().map(|c| c.0).collect();
    let dt = s.scenario.dt_s;
    for ((k, state, readings), (_, what)) in states(s, method, &at).iter().zip(cases) {
        c.bench_function(&format!("{} step k = {k} ({what})", method.name()), |b| {
            b.iter_batched(
                || {
                    let mut a = agent(s, method);
                    a.restore_state(state).expect("own checkpoint");
                    a
                },
                |mut a| {
                    let mut out = ShareOut::default();
                    a.share(&AgentInput { k: *k, t_s: *k as f64 * dt, readings: black_box(readings) }, &mut out);
                    a.step(dt, &[]);
                    (a, out)
                },
                BatchSize::SmallInput,
            )
        });
    }
}

fn steps(c: &mut Criterion) {
    let s = setup();
    let nr = [(0, "guidance"), (108, "t_s: desired trajectory built"), (109, "tracking"), (114, "hourly rebuild")];
    bench_steps(c, &s, Method::NeuralRendezvous, &nr);
    bench_steps(c, &s, Method::Nmpc, &[(0, "SCP, 144 steps"), (108, "SCP, 36 steps"), (140, "SCP, 4 steps")]);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_secs(1))
        .measurement_time(std::time::Duration::from_secs(3));
    targets = steps
}
criterion_main!(benches);
