//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! The transient-phase DNN of Sec. 3.2.1, inference side: ℝ⁸ → ℝ⁵, inputs (q₀ (4, scalar last),
//! ω₀ (3, rad/s), w), outputs (E (J), e (deg), T (s), k₁, k₂), one head of 3 layers per output
//! ("3 layers for each output"), ReLU hidden and output activations (the output ReLU keeps every
//! prediction ≥ 0, Sec. 5.1). A plain f64 forward pass with no training stack, so an agent can call
//! [`TransientDnn::predict`] every step; the training is `crate::learn::transient::train`.
//!
//! Departures from the print, and why:
//! - the prediction is clamped before use: T to [7.2, 72] s (80) — the paper's own DNN P99 of T is
//!   129 s, beyond (80) — and the gains to [0.01, 0.5], the range of the data (Table 2);
//! - q and −q are the same attitude; the data has q₄ ≥ 0, so an input with q₄ < 0 is negated;
//! - inputs are standardised (training mean and standard deviation) and outputs scaled by the
//!   training mean of each output; both are stored in the weights file.
//!
//! **Weights file** (safetensors, F32 as trained): `w1` [5, 8, H], `b1` [5, H], `w2` [5, H, H],
//! `b2` [5, H], `w3` [5, H, 1], `b3` [5, 1] (head h maps x ↦ relu(relu(relu(x·w1ₕ + b1ₕ)·w2ₕ + b2ₕ)
//! ·w3ₕ + b3ₕ)), `input_mean` [8], `input_std` [8], `output_scale` [5]. Loading checks every
//! name, dtype, shape and value (`cohort_runtime::weights`); every failure is a [`WeightsError`]
//! naming the file, the tensor and what was expected.

use std::path::Path;

pub use cohort_runtime::weights::WeightsError;
use cohort_runtime::weights::{self, Precision, Tensor, Values, WeightsFile};

use crate::learn::transient::sim::{K_MAX, K_MIN, T_MAX_S, T_MIN_S};
use crate::model::quaternion::{Quat, V3};

/// Inputs and outputs.
pub const N_IN: usize = 8;
pub const N_OUT: usize = 5;
/// Output order (as in the print's ℝ⁵).
pub const OUTPUTS: [&str; N_OUT] = ["E_J", "e_deg", "T_s", "k1_N_m", "k2_N_m_s"];
/// Widest hidden layer accepted.
pub const MAX_HIDDEN: usize = 256;

/// The model name of its weights errors.
pub const MODEL: &str = "transient DNN";

/// The network's parameters, f64 (row-major as in the file).
#[derive(Debug, Clone, PartialEq)]
pub struct TransientDnn {
    pub hidden: usize,
    pub w1: Vec<f64>,
    pub b1: Vec<f64>,
    pub w2: Vec<f64>,
    pub b2: Vec<f64>,
    pub w3: Vec<f64>,
    pub b3: Vec<f64>,
    pub input_mean: Vec<f64>,
    pub input_std: Vec<f64>,
    pub output_scale: Vec<f64>,
}

/// A prediction, clamped to the ranges the transient may use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    pub energy_j: f64,
    pub error_deg: f64,
    pub duration_s: f64,
    pub k1: f64,
    pub k2: f64,
}

/// The network input of (q₀, ω₀, w) (q₄ made ≥ 0).
pub fn input(q: &Quat, omega_rad_s: &V3, w: f64) -> [f64; N_IN] {
    let q = if q[3] < 0.0 { -q } else { *q };
    [q[0], q[1], q[2], q[3], omega_rad_s[0], omega_rad_s[1], omega_rad_s[2], w]
}

impl TransientDnn {
    /// The raw outputs (E, e, T, k₁, k₂) of a raw input, unclamped.
    pub fn forward(&self, x: &[f64; N_IN]) -> [f64; N_OUT] {
        let h = self.hidden;
        let mut z = [0.0; N_IN];
        for i in 0..N_IN {
            z[i] = (x[i] - self.input_mean[i]) / self.input_std[i];
        }
        let mut out = [0.0; N_OUT];
        let (mut a, mut b) = ([0.0; MAX_HIDDEN], [0.0; MAX_HIDDEN]);
        for o in 0..N_OUT {
            for u in 0..h {
                let mut s = self.b1[o * h + u];
                for i in 0..N_IN {
                    s += z[i] * self.w1[(o * N_IN + i) * h + u];
                }
                a[u] = s.max(0.0);
            }
            for u in 0..h {
                let mut s = self.b2[o * h + u];
                for i in 0..h {
                    s += a[i] * self.w2[(o * h + i) * h + u];
                }
                b[u] = s.max(0.0);
            }
            let mut s = self.b3[o];
            for i in 0..h {
                s += b[i] * self.w3[o * h + i];
            }
            out[o] = s.max(0.0) * self.output_scale[o];
        }
        out
    }

    /// (E, e, T, k₁, k₂) for a transient from (q₀, ω₀) with weight w; T and the gains clamped.
    pub fn predict(&self, q: &Quat, omega_rad_s: &V3, w: f64) -> Prediction {
        let y = self.forward(&input(q, omega_rad_s, w));
        Prediction {
            energy_j: y[0],
            error_deg: y[1],
            duration_s: y[2].clamp(T_MIN_S, T_MAX_S),
            k1: y[3].clamp(K_MIN, K_MAX),
            k2: y[4].clamp(K_MIN, K_MAX),
        }
    }

    /// (name, shape, values) of every tensor, in file order.
    fn tensors(&self) -> Vec<(&'static str, Vec<usize>, &[f64])> {
        let h = self.hidden;
        vec![
            ("w1", vec![N_OUT, N_IN, h], &self.w1),
            ("b1", vec![N_OUT, h], &self.b1),
            ("w2", vec![N_OUT, h, h], &self.w2),
            ("b2", vec![N_OUT, h], &self.b2),
            ("w3", vec![N_OUT, h, 1], &self.w3),
            ("b3", vec![N_OUT, 1], &self.b3),
            ("input_mean", vec![N_IN], &self.input_mean),
            ("input_std", vec![N_IN], &self.input_std),
            ("output_scale", vec![N_OUT], &self.output_scale),
        ]
    }

    /// The weights file's bytes (F32, deterministic).
    pub fn to_bytes(&self) -> Vec<u8> {
        let tensors: Vec<Tensor<'_>> =
            self.tensors().into_iter().map(|(n, s, v)| Tensor::new(n, s, Values::F64AsF32(v))).collect();
        weights::to_bytes(MODEL, &tensors, None).expect("the shapes are the network's own")
    }

    /// Read and check a weights file.
    pub fn load(path: &Path) -> Result<Self, WeightsError> {
        Self::from_bytes(&weights::read(MODEL, path)?, path)
    }

    /// Check and load a weights file's bytes; `file` only names it in errors.
    pub fn from_bytes(bytes: &[u8], file: &Path) -> Result<Self, WeightsError> {
        let st = WeightsFile::parse(MODEL, bytes, file)?;
        let get = |name: &str, shape: &[usize]| st.tensor(name, Precision::F32, shape);
        let hidden = match st.shape("b1")?.as_slice() {
            [N_OUT, h] if (1..=MAX_HIDDEN).contains(h) => *h,
            s => {
                return Err(st.invalid(format!(
                    "tensor \"b1\" has shape {s:?}, expected [{N_OUT}, H] with 1 ≤ H ≤ {MAX_HIDDEN}"
                )));
            }
        };
        let h = hidden;
        let dnn = Self {
            hidden,
            w1: get("w1", &[N_OUT, N_IN, h])?,
            b1: get("b1", &[N_OUT, h])?,
            w2: get("w2", &[N_OUT, h, h])?,
            b2: get("b2", &[N_OUT, h])?,
            w3: get("w3", &[N_OUT, h, 1])?,
            b3: get("b3", &[N_OUT, 1])?,
            input_mean: get("input_mean", &[N_IN])?,
            input_std: get("input_std", &[N_IN])?,
            output_scale: get("output_scale", &[N_OUT])?,
        };
        if let Some(s) = dnn.input_std.iter().chain(&dnn.output_scale).find(|s| **s <= 0.0) {
            return Err(st.invalid(format!("a scale (input_std or output_scale) is {s}: scales must be positive")));
        }
        Ok(dnn)
    }
}

/// The committed weights, relative to the repository root.
pub const COMMITTED: &str = "papers/vtxo/weights/transient.safetensors";

/// The DNN as the supervisor's source of u2 = T and the transient gains
/// ([`crate::learn::transient::gains`]), each spacecraft predicting from its own measured state.
impl crate::learn::transient::gains::TransientPredictor for TransientDnn {
    fn predict(
        &self,
        x: &crate::learn::transient::gains::MeasuredState,
        w: f64,
    ) -> crate::learn::transient::gains::TransientGains {
        let [q1, q2, q3, q4] = x.q_body_eci;
        let [w1, w2, w3] = x.omega_body_rad_s;
        let p = TransientDnn::predict(self, &Quat::new(q1, q2, q3, q4), &V3::new(w1, w2, w3), w);
        crate::learn::transient::gains::TransientGains { k1: p.k1, k2: p.k2, t_s: p.duration_s }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use safetensors::Dtype;

    fn tiny() -> TransientDnn {
        let h = 3;
        let f = |n: usize, k: f64| (0..n).map(|i| ((i as f64 + 1.0) * k).sin()).collect::<Vec<_>>();
        TransientDnn {
            hidden: h,
            w1: f(N_OUT * N_IN * h, 0.7),
            b1: f(N_OUT * h, 0.3).iter().map(|x| x.abs()).collect(),
            w2: f(N_OUT * h * h, 1.1),
            b2: vec![0.5; N_OUT * h],
            w3: f(N_OUT * h, 0.9).iter().map(|x| x.abs()).collect(),
            b3: vec![0.25; N_OUT],
            input_mean: vec![0.0; N_IN],
            input_std: vec![1.0; N_IN],
            output_scale: vec![1.0, 0.02, 50.0, 0.1, 0.3],
        }
    }

    #[test]
    fn weights_round_trip_through_the_file_and_predictions_are_clamped() {
        let d = tiny();
        let back = TransientDnn::from_bytes(&d.to_bytes(), Path::new("x.safetensors")).expect("loads");
        let x = input(&Quat::new(0.1, 0.2, -0.3, 0.9), &V3::new(0.1, -0.2, 0.3), 4.0);
        let (a, b) = (d.forward(&x), back.forward(&x));
        for o in 0..N_OUT {
            assert!((a[o] - b[o]).abs() <= 1e-6 * a[o].abs().max(1.0), "{a:?} vs {b:?}");
            assert!(a[o] >= 0.0);
        }
        let p = back.predict(&Quat::new(0.1, 0.2, -0.3, 0.9), &V3::new(0.1, -0.2, 0.3), 4.0);
        assert!((T_MIN_S..=T_MAX_S).contains(&p.duration_s));
        assert!((K_MIN..=K_MAX).contains(&p.k1) && (K_MIN..=K_MAX).contains(&p.k2));
        // −q is the same attitude: the same prediction.
        assert_eq!(p, back.predict(&Quat::new(-0.1, -0.2, 0.3, -0.9), &V3::new(0.1, -0.2, 0.3), 4.0));
    }

    #[test]
    fn the_committed_weights_load_and_predict_within_the_ranges() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("weights/transient.safetensors");
        let d = TransientDnn::load(&path).expect("committed weights");
        let p = d.predict(&Quat::new(0.3, -0.2, 0.5, 0.78).normalize(), &V3::new(0.4, -0.6, 0.2), 4.5);
        assert!(p.energy_j.is_finite() && p.energy_j >= 0.0 && p.error_deg >= 0.0, "{p:?}");
        assert!((T_MIN_S..=T_MAX_S).contains(&p.duration_s), "{p:?}");
        assert!((K_MIN..=K_MAX).contains(&p.k1) && (K_MIN..=K_MAX).contains(&p.k2), "{p:?}");
    }

    #[test]
    fn missing_or_malformed_weights_are_errors_naming_the_file_and_the_fault() {
        let path = Path::new("/nonexistent/transient.safetensors");
        let e = TransientDnn::load(path).expect_err("missing file");
        assert!(
            e.to_string().contains("/nonexistent/transient.safetensors")
                && e.problem.to_string().contains("cannot read"),
            "{e}"
        );
        let e = TransientDnn::from_bytes(b"not a weights file", Path::new("bad.safetensors")).expect_err("garbage");
        assert!(
            e.to_string().contains("bad.safetensors") && e.problem.to_string().contains("not a safetensors"),
            "{e}"
        );
        // A well-formed file with a wrong shape and one with a missing tensor.
        let d = tiny();
        let mut owned: Vec<(&str, Vec<usize>, Vec<u8>)> = d
            .tensors()
            .into_iter()
            .map(|(n, sh, v)| (n, sh, v.iter().flat_map(|x| (*x as f32).to_le_bytes()).collect()))
            .collect();
        owned[6] = ("input_mean", vec![7], vec![0u8; 28]);
        let views: Vec<(String, safetensors::tensor::TensorView<'_>)> = owned
            .iter()
            .map(|(n, sh, b)| {
                (n.to_string(), safetensors::tensor::TensorView::new(Dtype::F32, sh.clone(), b).expect("view"))
            })
            .collect();
        let bytes = safetensors::serialize(views, None).expect("serialise");
        let e = TransientDnn::from_bytes(&bytes, Path::new("s.safetensors")).expect_err("shape");
        assert!(e.problem.to_string().contains("input_mean") && e.problem.to_string().contains("shape"), "{e}");
        let mut d = tiny();
        d.input_std[2] = 0.0;
        let e = TransientDnn::from_bytes(&d.to_bytes(), Path::new("z.safetensors")).expect_err("zero scale");
        assert!(e.problem.to_string().contains("scale"), "{e}");
        let mut d = tiny();
        d.w2[4] = f64::NAN;
        let e = TransientDnn::from_bytes(&d.to_bytes(), Path::new("n.safetensors")).expect_err("nan");
        assert!(e.problem.to_string().contains("\"w2\"") && e.problem.to_string().contains("not finite"), "{e}");
    }

    #[test]
    fn the_dnn_is_the_supervisors_transient_predictor() {
        use crate::learn::transient::gains::{MeasuredState, TransientPredictor};
        let d =
            TransientDnn::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("weights/transient.safetensors")).unwrap();
        let x = MeasuredState { q_body_eci: [0.3, -0.2, 0.5, 0.78], omega_body_rad_s: [0.4, -0.6, 0.2] };
        let direct = TransientDnn::predict(&d, &Quat::new(0.3, -0.2, 0.5, 0.78), &V3::new(0.4, -0.6, 0.2), 4.5);
        let via: &dyn TransientPredictor = &d;
        let g = via.predict(&x, 4.5);
        assert_eq!((g.k1, g.k2, g.t_s), (direct.k1, direct.k2, direct.duration_s));
    }
}
