//! The terms of Lemma 1 (13)–(14) of "Neural-Rendezvous" (arXiv:2208.04883), computed on the
//! trained network (the f64 one the agents fly):
//!
//!   sup_test ‖u_ℓ − u_mpc‖ ≤ ε_train + r (L_ℓ + L_mpc),
//!
//! ε_train the largest training error, r the largest distance from a test input to its nearest
//! training input (normalised inputs), L_ℓ the SN-DNN's Lipschitz bound (C_sn^L times the output
//! scale) and L_mpc the MPC's, estimated empirically (its largest difference quotient between a
//! test input and its nearest training input). Also reported: the measured left side and the
//! empirical L_ℓ over the same pairs. All in N and N per unit of normalised input.

use serde::Serialize;

use crate::nn::sn_dnn::SnDnn;

use super::data::Sample;

#[derive(Debug, Clone, Serialize)]
pub struct Lemma1 {
    pub training_samples: usize,
    pub test_samples: usize,
    pub eps_train_n: f64,
    pub rms_train_n: f64,
    pub r: f64,
    pub l_ell_bound_n: f64,
    pub l_ell_empirical_n: f64,
    pub l_mpc_empirical_n: f64,
    /// ε_train + r(L_ℓ + L_mpc).
    pub bound_n: f64,
    /// The measured sup over the test samples.
    pub sup_test_n: f64,
    pub rms_test_n: f64,
}

fn normalised(net: &SnDnn, s: &Sample) -> Vec<f64> {
    s.f0.iter().zip(net.input_scale()).map(|(x, k)| x / k).collect()
}

fn err(net: &SnDnn, s: &Sample) -> f64 {
    let mut u = [0.0; 3];
    net.forward(&s.f0[..net.n_in()], &mut u);
    (crate::iso::dynamics::two_body::V3::from(u) - s.u0_n).norm()
}

/// Every term on `train` and `test` (samples as generated).
pub fn lemma1(net: &SnDnn, train: &[Sample], test: &[Sample]) -> Lemma1 {
    let ztr: Vec<Vec<f64>> = train.iter().map(|s| normalised(net, s)).collect();
    let etr: Vec<f64> = train.iter().map(|s| err(net, s)).collect();
    let ete: Vec<f64> = test.iter().map(|s| err(net, s)).collect();
    let (mut r, mut l_ell, mut l_mpc) = (0.0f64, 0.0f64, 0.0f64);
    let mut out = [0.0; 3];
    for s in test {
        let z = normalised(net, s);
        let (j, d) = ztr
            .iter()
            .enumerate()
            .map(|(j, zt)| (j, zt.iter().zip(&z).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("a training set");
        r = r.max(d);
        if d > 0.0 {
            l_mpc = l_mpc.max((s.u0_n - train[j].u0_n).norm() / d);
            net.forward(&s.f0[..net.n_in()], &mut out);
            let a = crate::iso::dynamics::two_body::V3::from(out);
            net.forward(&train[j].f0[..net.n_in()], &mut out);
            l_ell = l_ell.max((a - crate::iso::dynamics::two_body::V3::from(out)).norm() / d);
        }
    }
    let max = |v: &[f64]| v.iter().copied().fold(0.0f64, f64::max);
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let out_scale = net.output_scale().iter().copied().fold(0.0f64, f64::max);
    let l_ell_bound_n = net.lipschitz_normalised() * out_scale;
    let eps_train_n = max(&etr);
    Lemma1 {
        training_samples: train.len(),
        test_samples: test.len(),
        eps_train_n,
        rms_train_n: rms(&etr),
        r,
        l_ell_bound_n,
        l_ell_empirical_n: l_ell,
        l_mpc_empirical_n: l_mpc,
        bound_n: eps_train_n + r * (l_ell_bound_n + l_mpc),
        sup_test_n: max(&ete),
        rms_test_n: rms(&ete),
    }
}
