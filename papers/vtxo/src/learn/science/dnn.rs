//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! The science-phase DNN of Sec. 3.2.2, inference side: one network per science law (Sec. 6.1
//! reports one MSE for PD and one for SMC), each (x₀, w) → (E, e, k̂) as Sec. 3 defines the ML's
//! inputs and outputs, "with 10 neurons in the first layer, 5 neurons in the second layer, and 3
//! neurons in the last layer", sigmoid. A plain f64 forward pass with no training stack, so a
//! supervisor can call [`ScienceDnn::predict`] at the entry to s3; the training is
//! `crate::learn::science::train`.
//!
//! Our reading of the print (where it does not say):
//! - **inputs, 8**: x₀ = (q₀ (4, scalar last, relative to the target), ω₀ (3, rad/s)) and w — the
//!   ML's inputs of Sec. 3 ("the inputs to ML are w and x₀"; x_f is the target, identity here).
//!   The "10" of Sec. 3.2.2 is the first layer's neurons, not the input size.
//! - **layers**: 10–5–3 sigmoid hidden layers, then a linear output layer of 2 + |k̂| (4 for PD:
//!   E, e, k_P, k_D; 5 for SMC: E, e, z, k_SMC, ε). A last layer of 3 cannot hold 2 + |k̂| outputs
//!   for either law, so the printed "3 neurons in the last layer" is taken as the last hidden one.
//! - **scaling**: w enters as ln w, and every output is learned as its logarithm (E, e and the
//!   gains span decades and are positive: exp keeps every prediction positive, the role of the
//!   transient DNN's output ReLU); inputs and log-outputs are standardised with the training
//!   statistics, stored in the file. Predicted gains are clamped to (79)'s box [0.01, 3].
//!
//! **Weights file** (safetensors, F32 as trained), per law `L` ∈ {pd, smc}: `L.w1` [8, 10],
//! `L.b1` [10], `L.w2` [10, 5], `L.b2` [5], `L.w3` [5, 3], `L.b3` [3], `L.w4` [3, n], `L.b4` [n],
//! `L.input_mean` [8], `L.input_std` [8], `L.output_mean` [n], `L.output_std` [n] (n = 2 + |k̂|;
//! a layer maps x ↦ x·w + b). Loading checks every name, dtype, shape and value; every failure is
//! a [`WeightsError`] naming the file and the reason.

use std::path::Path;

pub use cohort_runtime::weights::WeightsError;
use cohort_runtime::weights::{self, Precision, Tensor, Values, WeightsFile};

use crate::flight::attitude_control::AttitudeLaw;
use crate::learn::science::sim::{K_MAX, K_MIN, ScienceLaw};
use crate::learn::transient::gains::MeasuredState;
use crate::model::quaternion::{Quat, V3};

/// Inputs of every network.
pub const N_IN: usize = 8;
/// Hidden layer widths (Sec. 3.2.2).
pub const HIDDEN: [usize; 3] = [10, 5, 3];
/// The committed weights, relative to the repository root.
pub const COMMITTED: &str = "papers/vtxo/weights/science.safetensors";

/// Outputs of `law`'s network: E, e, then k̂.
pub fn n_out(law: ScienceLaw) -> usize {
    2 + law.n_gains()
}

/// Layer shapes [in, out] of `law`'s network.
pub fn layer_shapes(law: ScienceLaw) -> [(usize, usize); 4] {
    [(N_IN, HIDDEN[0]), (HIDDEN[0], HIDDEN[1]), (HIDDEN[1], HIDDEN[2]), (HIDDEN[2], n_out(law))]
}

/// The model name of its weights errors.
pub const MODEL: &str = "science DNN";

/// One law's network, f64 (row-major [in, out] as in the file).
#[derive(Debug, Clone, PartialEq)]
pub struct Net {
    pub law: ScienceLaw,
    pub w: [Vec<f64>; 4],
    pub b: [Vec<f64>; 4],
    pub input_mean: Vec<f64>,
    pub input_std: Vec<f64>,
    pub output_mean: Vec<f64>,
    pub output_std: Vec<f64>,
}

/// The network input of (q₀ relative to the target, ω₀, w): q₄ made ≥ 0, ln w (w floored at 1e-300).
pub fn input(q: &Quat, omega_rad_s: &V3, w: f64) -> [f64; N_IN] {
    let q = if q[3] < 0.0 { -q } else { *q };
    [q[0], q[1], q[2], q[3], omega_rad_s[0], omega_rad_s[1], omega_rad_s[2], w.max(1e-300).ln()]
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

impl Net {
    /// The standardised log-outputs of a network input (the quantity trained on).
    pub fn forward_standardised(&self, x: &[f64; N_IN]) -> Vec<f64> {
        let mut a: Vec<f64> = (0..N_IN).map(|i| (x[i] - self.input_mean[i]) / self.input_std[i]).collect();
        for (l, (n_in, n_o)) in layer_shapes(self.law).into_iter().enumerate() {
            let mut z = self.b[l].clone();
            for i in 0..n_in {
                for o in 0..n_o {
                    z[o] += a[i] * self.w[l][i * n_o + o];
                }
            }
            a = if l < 3 { z.into_iter().map(sigmoid).collect() } else { z };
        }
        a
    }

    /// (E (J), e (deg), k̂…) of a network input, unclamped.
    pub fn forward(&self, x: &[f64; N_IN]) -> Vec<f64> {
        let y = self.forward_standardised(x);
        y.iter().enumerate().map(|(k, v)| (self.output_mean[k] + self.output_std[k] * v).exp()).collect()
    }

    /// (name suffix, shape, values) of every tensor, in file order.
    fn tensors(&self) -> Vec<(String, Vec<usize>, &[f64])> {
        let mut t = Vec::new();
        for (l, (i, o)) in layer_shapes(self.law).into_iter().enumerate() {
            t.push((format!("w{}", l + 1), vec![i, o], self.w[l].as_slice()));
            t.push((format!("b{}", l + 1), vec![o], self.b[l].as_slice()));
        }
        let n = n_out(self.law);
        t.push(("input_mean".into(), vec![N_IN], &self.input_mean));
        t.push(("input_std".into(), vec![N_IN], &self.input_std));
        t.push(("output_mean".into(), vec![n], &self.output_mean));
        t.push(("output_std".into(), vec![n], &self.output_std));
        t
    }
}

/// What the science DNN answers for one law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScienceGains {
    /// The law with the predicted gains, clamped to [0.01, 3].
    pub law: AttitudeLaw,
    /// The predicted E (J) and e (deg) of the phase under it (the explainable part).
    pub energy_j: f64,
    pub error_deg: f64,
}

/// (law, x₀, w) → k̂ (and Ê, ê): the interface a supervisor uses at the entry to s3. `x.q_body_eci`
/// is the attitude relative to the target (δq = q ⊗ q_f⁻¹), as in the data.
pub trait ScienceGainPredictor: Send + Sync {
    fn predict(&self, law: ScienceLaw, x: &MeasuredState, w: f64) -> ScienceGains;
}

/// Both laws' networks.
#[derive(Debug, Clone, PartialEq)]
pub struct ScienceDnn {
    pub pd: Net,
    pub smc: Net,
}

impl ScienceDnn {
    pub fn net(&self, law: ScienceLaw) -> &Net {
        match law {
            ScienceLaw::Pd => &self.pd,
            ScienceLaw::Smc => &self.smc,
        }
    }

    /// k̂, Ê and ê for a science phase of `law` from (q₀ relative to the target, ω₀) with weight w
    /// (deg/J); gains clamped to [0.01, 3].
    pub fn predict(&self, law: ScienceLaw, q: &Quat, omega_rad_s: &V3, w: f64) -> ScienceGains {
        let y = self.net(law).forward(&input(q, omega_rad_s, w));
        let k: Vec<f64> = y[2..].iter().map(|k| k.clamp(K_MIN, K_MAX)).collect();
        ScienceGains { law: law.law(&k), energy_j: y[0], error_deg: y[1] }
    }

    /// The weights file's bytes (F32, deterministic).
    pub fn to_bytes(&self) -> Vec<u8> {
        let tensors: Vec<Tensor<'_>> = [&self.pd, &self.smc]
            .into_iter()
            .flat_map(|net| {
                net.tensors()
                    .into_iter()
                    .map(|(n, s, v)| Tensor::new(format!("{}.{n}", net.law.name()), s, Values::F64AsF32(v)))
            })
            .collect();
        weights::to_bytes(MODEL, &tensors, None).expect("the shapes are the networks' own")
    }

    /// Read and check a weights file.
    pub fn load(path: &Path) -> Result<Self, WeightsError> {
        Self::from_bytes(&weights::read(MODEL, path)?, path)
    }

    /// Check and load a weights file's bytes; `file` only names it in errors.
    pub fn from_bytes(bytes: &[u8], file: &Path) -> Result<Self, WeightsError> {
        let st = WeightsFile::parse(MODEL, bytes, file)?;
        let names = st.names();
        if !names.iter().any(|n| n.starts_with("pd.") || n.starts_with("smc.")) {
            return Err(st.invalid(format!(
                "holds no science DNN (no pd.* or smc.* tensor; it has {names:?}): another model's file?"
            )));
        }
        let get = |name: &str, shape: &[usize]| st.tensor(name, Precision::F32, shape);
        let net = |law: ScienceLaw| -> Result<Net, WeightsError> {
            let p = law.name();
            let shapes = layer_shapes(law);
            let layer = |l: usize| -> Result<(Vec<f64>, Vec<f64>), WeightsError> {
                let (i, o) = shapes[l];
                Ok((get(&format!("{p}.w{}", l + 1), &[i, o])?, get(&format!("{p}.b{}", l + 1), &[o])?))
            };
            let (l1, l2, l3, l4) = (layer(0)?, layer(1)?, layer(2)?, layer(3)?);
            let n = n_out(law);
            let net = Net {
                law,
                w: [l1.0, l2.0, l3.0, l4.0],
                b: [l1.1, l2.1, l3.1, l4.1],
                input_mean: get(&format!("{p}.input_mean"), &[N_IN])?,
                input_std: get(&format!("{p}.input_std"), &[N_IN])?,
                output_mean: get(&format!("{p}.output_mean"), &[n])?,
                output_std: get(&format!("{p}.output_std"), &[n])?,
            };
            if let Some(s) = net.input_std.iter().chain(&net.output_std).find(|s| **s <= 0.0) {
                return Err(st.invalid(format!("{p}: a standard deviation is {s}: they must be positive")));
            }
            Ok(net)
        };
        Ok(Self { pd: net(ScienceLaw::Pd)?, smc: net(ScienceLaw::Smc)? })
    }
}

impl ScienceGainPredictor for ScienceDnn {
    fn predict(&self, law: ScienceLaw, x: &MeasuredState, w: f64) -> ScienceGains {
        let [q1, q2, q3, q4] = x.q_body_eci;
        let [w1, w2, w3] = x.omega_body_rad_s;
        ScienceDnn::predict(self, law, &Quat::new(q1, q2, q3, q4), &V3::new(w1, w2, w3), w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use safetensors::Dtype;

    pub(crate) fn tiny_net(law: ScienceLaw, k: f64) -> Net {
        let f = |n: usize, s: f64| (0..n).map(|i| ((i as f64 + 1.0) * s * k).sin()).collect::<Vec<_>>();
        let sh = layer_shapes(law);
        let n = n_out(law);
        Net {
            law,
            w: std::array::from_fn(|l| f(sh[l].0 * sh[l].1, 0.7 + 0.1 * l as f64)),
            b: std::array::from_fn(|l| f(sh[l].1, 0.3 + 0.2 * l as f64)),
            input_mean: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 6.0],
            input_std: vec![2e-4, 2e-4, 2e-4, 1e-8, 9e-4, 8e-4, 1e-3, 2.0],
            output_mean: (0..n).map(|i| -1.0 - i as f64).collect(),
            output_std: vec![0.5; n],
        }
    }

    fn tiny() -> ScienceDnn {
        ScienceDnn { pd: tiny_net(ScienceLaw::Pd, 1.0), smc: tiny_net(ScienceLaw::Smc, 1.3) }
    }

    fn serialise(owned: &[(String, Vec<usize>, Vec<u8>)]) -> Vec<u8> {
        let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = owned
            .iter()
            .map(|(n, sh, b)| {
                (n.clone(), safetensors::tensor::TensorView::new(Dtype::F32, sh.clone(), b).expect("view"))
            })
            .collect();
        safetensors::serialize(views, None).expect("serialise")
    }

    #[test]
    fn weights_round_trip_and_predictions_are_positive_and_clamped() {
        let d = tiny();
        let back = ScienceDnn::from_bytes(&d.to_bytes(), Path::new("x.safetensors")).expect("loads");
        let (q, w) = (Quat::new(1e-4, -2e-4, 3e-4, 1.0).normalize(), V3::new(1e-3, -5e-4, 8e-4));
        for law in ScienceLaw::ALL {
            let x = input(&q, &w, 40.0);
            let (a, b) = (d.net(law).forward(&x), back.net(law).forward(&x));
            assert_eq!(a.len(), n_out(law));
            for k in 0..a.len() {
                assert!((a[k] - b[k]).abs() <= 1e-5 * a[k].abs(), "{law:?} {a:?} vs {b:?}");
                assert!(a[k] > 0.0);
            }
            let g = back.predict(law, &q, &w, 40.0);
            let gains = match g.law {
                AttitudeLaw::Pd { k_p, k_d } => vec![k_p, k_d],
                AttitudeLaw::Smc { z, k, epsilon } => vec![z, k, epsilon],
                other => panic!("{other:?}"),
            };
            assert_eq!(gains.len(), law.n_gains());
            assert!(gains.iter().all(|k| (K_MIN..=K_MAX).contains(k)), "{g:?}");
            // −q is the same attitude; the trait answers as the direct call.
            assert_eq!(g, back.predict(law, &-q, &w, 40.0));
            let x = MeasuredState { q_body_eci: [q[0], q[1], q[2], q[3]], omega_body_rad_s: [w[0], w[1], w[2]] };
            let via: &dyn ScienceGainPredictor = &back;
            assert_eq!(via.predict(law, &x, 40.0), g);
        }
    }

    #[test]
    fn the_committed_weights_load_and_predict_positive_gains_in_the_box() {
        let d = ScienceDnn::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("weights/science.safetensors"))
            .expect("committed weights");
        let (q, w) = (Quat::new(2e-4, -1e-4, 3e-4, 1.0).normalize(), V3::new(9e-4, -8e-4, 1e-3));
        for (law, weight) in [(ScienceLaw::Pd, 450.0), (ScienceLaw::Smc, 100.0)] {
            let g = d.predict(law, &q, &w, weight);
            assert!(g.energy_j > 0.0 && g.energy_j < 1e-2 && g.error_deg > 0.0 && g.error_deg < 1.0, "{g:?}");
        }
    }

    #[test]
    fn missing_or_malformed_weights_are_errors_naming_the_file_and_the_reason() {
        let e = ScienceDnn::load(Path::new("/nonexistent/science.safetensors")).expect_err("missing");
        assert!(
            e.to_string().contains("/nonexistent/science.safetensors") && e.problem.to_string().contains("cannot read"),
            "{e}"
        );
        let e = ScienceDnn::from_bytes(b"garbage", Path::new("bad.safetensors")).expect_err("garbage");
        assert!(
            e.to_string().contains("bad.safetensors") && e.problem.to_string().contains("not a safetensors"),
            "{e}"
        );
        // The transient DNN's committed file is another model's.
        let t = Path::new(env!("CARGO_MANIFEST_DIR")).join("weights/transient.safetensors");
        let e = ScienceDnn::load(&t).expect_err("transient weights");
        assert!(
            e.to_string().contains("transient.safetensors") && e.problem.to_string().contains("holds no science DNN"),
            "{e}"
        );
        assert!(e.problem.to_string().contains("\"w1\""), "{e}");
        // Every tensor of the file, then one changed at a time.
        let d = tiny();
        let mut owned: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
        for net in [&d.pd, &d.smc] {
            for (n, s, v) in net.tensors() {
                owned.push((
                    format!("{}.{n}", net.law.name()),
                    s,
                    v.iter().flat_map(|x| (*x as f32).to_le_bytes()).collect(),
                ));
            }
        }
        let mut missing = owned.clone();
        missing.retain(|t| t.0 != "smc.w3");
        let e = ScienceDnn::from_bytes(&serialise(&missing), Path::new("m.safetensors")).expect_err("missing tensor");
        assert!(
            e.problem.to_string().contains("tensor \"smc.w3\" is missing") && e.to_string().contains("m.safetensors"),
            "{e}"
        );
        let mut shape = owned.clone();
        let i = shape.iter().position(|t| t.0 == "pd.w4").unwrap();
        shape[i] = ("pd.w4".into(), vec![3, 5], vec![0u8; 60]);
        let e = ScienceDnn::from_bytes(&serialise(&shape), Path::new("s.safetensors")).expect_err("shape");
        assert!(e.problem.to_string().contains("pd.w4") && e.problem.to_string().contains("shape"), "{e}");
        let mut d2 = tiny();
        d2.smc.output_std[1] = 0.0;
        let e = ScienceDnn::from_bytes(&d2.to_bytes(), Path::new("z.safetensors")).expect_err("zero std");
        assert!(e.problem.to_string().contains("smc") && e.problem.to_string().contains("standard deviation"), "{e}");
        let mut d3 = tiny();
        d3.pd.w[1][3] = f64::NAN;
        let e = ScienceDnn::from_bytes(&d3.to_bytes(), Path::new("n.safetensors")).expect_err("nan");
        assert!(e.problem.to_string().contains("\"pd.w2\"") && e.problem.to_string().contains("not finite"), "{e}");
        // F16 where F32 is expected.
        let mut dtype = owned.clone();
        let i = dtype.iter().position(|t| t.0 == "pd.b1").unwrap();
        let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = dtype
            .iter_mut()
            .enumerate()
            .map(|(k, (n, sh, b))| {
                let (dt, bytes): (Dtype, &[u8]) = if k == i { (Dtype::F16, &b[..20]) } else { (Dtype::F32, b) };
                (n.clone(), safetensors::tensor::TensorView::new(dt, sh.clone(), bytes).expect("view"))
            })
            .collect();
        let bytes = safetensors::serialize(views, None).expect("serialise");
        let e = ScienceDnn::from_bytes(&bytes, Path::new("d.safetensors")).expect_err("dtype");
        assert!(e.problem.to_string().contains("pd.b1") && e.problem.to_string().contains("F32"), "{e}");
    }
}
