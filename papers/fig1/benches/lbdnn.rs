//! The Lb-DNN kernels of seed 000 (p = 103): forward pass with its Jacobian ∇θΦ, and one whole
//! fig1 agent step (`share` + RK4 `step` with two neighbours).

use std::hint::black_box;

use cohort_paper_fig1::lbdnn_network::LbDnn;
use cohort_runtime::model::{AgentInput, Neighbour, ShareOut};
use criterion::{Criterion, criterion_group, criterion_main};
use rand::SeedableRng;

fn network(c: &mut Criterion) {
    let mut net = LbDnn::new(&[6, 4, 4, 4, 4, 3]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let theta = net.kaiming_he(&mut rng);
    let kappa = [1200.0, -300.0, 45.0, 1.5, -0.2, 0.03];
    let mut out = [0.0; 3];
    let mut jac = vec![0.0; 3 * net.n_weights()];
    c.bench_function("Lb-DNN forward (p = 103)", |b| b.iter(|| net.forward(black_box(&kappa), &theta, &mut out)));
    c.bench_function("Lb-DNN forward + Jacobian (p = 103)", |b| {
        b.iter(|| net.forward_jacobian(black_box(&kappa), &theta, &mut out, &mut jac))
    });
}

fn agent_step(c: &mut Criterion) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../topologies/fig1-fixed.toml");
    let papers: &[&'static dyn cohort_runtime::paper::Paper] =
        &[&cohort_paper_fig1::Fig1, &cohort_kinds_generic::Generic];
    let s =
        cohort_runtime::paper::load(std::path::Path::new(path), &Default::default(), papers).expect("fig1-fixed.toml");
    let mut algo = s.algorithm.build(&s, 2);
    let readings = [120.0, -80.0, 3000.0, 10.0, -5.0, -2500.0, 40.0, 60.0];
    let mut nb_values = vec![0.1, -0.2, 0.05];
    nb_values.extend(std::iter::repeat_n(0.2, 103));
    let mut k = 0u64;
    c.bench_function("fig1 agent step (share + RK4 step, 2 neighbours)", |b| {
        b.iter(|| {
            let mut out = ShareOut::default();
            algo.share(&AgentInput { k, t_s: k as f64 * 0.01, readings: black_box(&readings) }, &mut out);
            let nb = [
                Neighbour { id: 1, values: &nb_values, age_steps: 0 },
                Neighbour { id: 3, values: &nb_values, age_steps: 0 },
            ];
            algo.step(0.01, &nb);
            k += 1;
        })
    });
}

criterion_group!(benches, network, agent_step);
criterion_main!(benches);
