//! The DNN tension predictor Φ of eqs. (7)–(8), inference only: load a weights file written by
//! `orchestrator train tsnr-tension`, check it, and run the ReLU network in f64. No training
//! stack here (the trainer uses candle; this needs only the `safetensors` parser).
//!
//! **Input** (eq. (7)): the history X_i(t_e − N_tΔt | t_e) of MU i, the last N_t samples
//! X_{i,m}, m = e−N_t+1 … e, oldest first, each [`FEATURES_PER_STEP`] = 27 values in this order:
//!
//! | offset | values | what (LVLH frame of the target, SI units) |
//! |--------|--------|-------------------------------------------|
//! | 0      | 6      | x_i(t_m) = [x, y, z, vx, vy, vz] of MU i, m and m/s |
//! | 6      | 6      | x_j1(t_m), the lower-id MU adjacent to i along the net ([`adjacent_mus`]) |
//! | 12     | 6      | x_j2(t_m), the higher-id adjacent MU |
//! | 18     | 3      | u_i[m], MU i's thrust held over [t_m, t_{m+1}), N |
//! | 21     | 3      | u_j1[m], N |
//! | 24     | 3      | u_j2[m], N |
//!
//! The diagonal MU is not an input: on the square net the tension on a corner comes through its
//! two edges, whose far ends are driven by the adjacent MUs (and the diagonal MU only through
//! them). Samples are Δt apart (the weights' `dt_s`, 0.1 s).
//!
//! **Output**: T̂_i(t_e + nΔt) for n = 1 … N_t, N (3 values per step), the net tension on MU i
//! over the N_t steps after the newest sample. An agent deciding at t_k knows the complete
//! sample up to e = k − 1 (its neighbours' step-k shares are not in yet), so the output is
//! T̂_i(t_k … t_{k+N_t−1}): exactly the horizon an MPC starting at t_k needs ([`crate::forecast`]).
//!
//! **Network** (eq. (8), with biases): the history is first re-expressed with the adjacent MUs'
//! states relative to MU i's ([`relative_features`]: x_j − x_i in place of x_j, a fixed invertible
//! linear map, so the input is still eq. (7)'s X — the tension depends on the net's geometry, not
//! on where it is), then z = (X' − mean)/std, h_l = ReLU(W_l h_{l−1} + b_l) for the
//! hidden layers, y = W_L h + b_L (linear output), T̂ = scale ⊙ y (a per-output scale, no shift, so
//! that the sign of y is the sign of T̂ — the asymmetric loss (10) needs it).
//!
//! **Weights file**: safetensors, tensors `layers.<l>.weight` ([out, in], f32) and
//! `layers.<l>.bias` ([out], f32) for l = 0…L−1, `input_mean` and `input_std` ([27·N_t], f64),
//! `output_scale` ([3·N_t], f64), and one metadata entry [`METADATA_KEY`] holding a JSON object
//! with at least `format` = [`FORMAT`], `n_t`, `dt_s`, `features_per_step` (one key, so the file's
//! bytes do not depend on hash-map order: retraining with the same seed rewrites the same file).

use std::collections::BTreeMap;
use std::path::Path;

pub use cohort_runtime::weights::WeightsError;
use cohort_runtime::weights::{self, Precision, Tensor, Values, WeightsFile};

pub use crate::net::adjacent_mus;

/// Values per history sample X_{i,m}.
pub const FEATURES_PER_STEP: usize = 27;
/// The one metadata key of a weights file.
pub const METADATA_KEY: &str = "cohort_tsnr_tension";
/// Value of the metadata's `format`.
pub const FORMAT: &str = "cohort-tsnr-tension-v1";

/// The model name of its weights errors.
pub const MODEL: &str = "tension predictor";

/// One history sample X_{i,m} (see the module notes for its meaning and units).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    pub own_state: [f64; 6],
    /// The two adjacent MUs in ascending id order.
    pub neighbour_states: [[f64; 6]; 2],
    pub own_thrust_n: [f64; 3],
    pub neighbour_thrust_n: [[f64; 3]; 2],
}

impl Sample {
    /// Append the 27 features in the documented order.
    pub fn extend_features(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&self.own_state);
        out.extend_from_slice(&self.neighbour_states[0]);
        out.extend_from_slice(&self.neighbour_states[1]);
        out.extend_from_slice(&self.own_thrust_n);
        out.extend_from_slice(&self.neighbour_thrust_n[0]);
        out.extend_from_slice(&self.neighbour_thrust_n[1]);
    }
}

#[derive(Debug, Clone)]
struct Layer {
    n_in: usize,
    n_out: usize,
    /// Row-major [n_out][n_in].
    w: Vec<f64>,
    b: Vec<f64>,
}

/// A loaded, checked predictor.
#[derive(Debug, Clone)]
pub struct TensionPredictor {
    n_t: usize,
    dt_s: f64,
    layers: Vec<Layer>,
    input_mean: Vec<f64>,
    input_std: Vec<f64>,
    output_scale: Vec<f64>,
    metadata: serde_json::Value,
}

impl TensionPredictor {
    /// Read and check a weights file.
    pub fn load(path: &Path) -> Result<Self, WeightsError> {
        Self::from_bytes(&weights::read(MODEL, path)?, path)
    }

    /// Check and load the bytes of a weights file; `file` only names it in errors.
    pub fn from_bytes(bytes: &[u8], file: &Path) -> Result<Self, WeightsError> {
        let st = WeightsFile::parse(MODEL, bytes, file)?;
        let metadata = st.metadata_json(METADATA_KEY, FORMAT, "a tension-predictor")?;
        let uint = |key: &str| {
            metadata
                .get(key)
                .and_then(|v| v.as_u64())
                .ok_or_else(|| st.invalid(format!("metadata `{key}` is missing or not a whole number")))
        };
        let n_t = uint("n_t")? as usize;
        let per_step = uint("features_per_step")? as usize;
        let dt_s = metadata
            .get("dt_s")
            .and_then(|v| v.as_f64())
            .ok_or_else(|| st.invalid("metadata `dt_s` is missing or not a number"))?;
        if !(1..=1000).contains(&n_t) {
            return Err(st.invalid(format!("metadata n_t = {n_t}: must be 1..=1000")));
        }
        if per_step != FEATURES_PER_STEP {
            return Err(st.invalid(format!(
                "metadata features_per_step = {per_step}: this build reads {FEATURES_PER_STEP} per step"
            )));
        }
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(st.invalid(format!("metadata dt_s = {dt_s}: must be a finite number > 0")));
        }
        let (n_in, n_out) = (FEATURES_PER_STEP * n_t, 3 * n_t);
        let names = st.names();
        let tensor = |name: &str, precision: Precision, shape: &[usize]| st.tensor(name, precision, shape);
        let input_mean = tensor("input_mean", Precision::F64, &[n_in])?;
        let input_std = tensor("input_std", Precision::F64, &[n_in])?;
        let output_scale = tensor("output_scale", Precision::F64, &[n_out])?;
        for (name, v) in [("input_std", &input_std), ("output_scale", &output_scale)] {
            if let Some(i) = v.iter().position(|x| *x <= 0.0) {
                return Err(st.invalid(format!("tensor `{name}` has a value ≤ 0 at index {i}")));
            }
        }
        let mut layers = Vec::new();
        let mut width = n_in;
        while st.contains(&format!("layers.{}.weight", layers.len())) {
            let l = layers.len();
            let wname = format!("layers.{l}.weight");
            let (shape, w) = st.tensor_dims(&wname, Precision::F32, &[None, Some(width)])?;
            let out = shape[0];
            let b = tensor(&format!("layers.{l}.bias"), Precision::F32, &[out])?;
            layers.push(Layer { n_in: width, n_out: out, w, b });
            width = out;
        }
        if layers.is_empty() {
            return Err(st.error(weights::Problem::MissingTensor { name: "layers.0.weight".into() }));
        }
        if width != n_out {
            return Err(st.invalid(format!("the last layer has {width} outputs, expected 3·n_t = {n_out}")));
        }
        let known = 3 + 2 * layers.len();
        if names.len() != known {
            let expected: Vec<String> = (0..layers.len())
                .flat_map(|l| [format!("layers.{l}.weight"), format!("layers.{l}.bias")])
                .chain(["input_mean", "input_std", "output_scale"].map(String::from))
                .collect();
            let extra: Vec<&&str> = names.iter().filter(|n| !expected.iter().any(|e| e == *n)).collect();
            return Err(st.invalid(format!("unexpected tensors {extra:?}")));
        }
        Ok(Self { n_t, dt_s, layers, input_mean, input_std, output_scale, metadata })
    }

    /// N_t: samples of history in, steps of tension out.
    pub fn horizon_steps(&self) -> usize {
        self.n_t
    }
    /// Δt between samples and between predicted steps, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }
    /// Length of the history vector [`TensionPredictor::predict`] takes: 27·N_t.
    pub fn history_len(&self) -> usize {
        FEATURES_PER_STEP * self.n_t
    }
    /// Hidden-layer widths.
    pub fn hidden(&self) -> Vec<usize> {
        self.layers[..self.layers.len() - 1].iter().map(|l| l.n_out).collect()
    }
    /// The file's metadata (training settings, the command that made it, …).
    pub fn metadata(&self) -> &serde_json::Value {
        &self.metadata
    }

    /// T̂_i(t_e + nΔt), n = 1…N_t, N, from the history ending at sample e (module notes).
    /// `history` must hold 27·N_t finite values; anything else is an error, never a NaN.
    pub fn predict(&self, history: &[f64]) -> Result<Vec<[f64; 3]>, String> {
        if history.len() != self.history_len() {
            return Err(format!("history of {} values, expected 27·N_t = {}", history.len(), self.history_len()));
        }
        if let Some(i) = history.iter().position(|v| !v.is_finite()) {
            return Err(format!("history value {i} is not finite ({})", history[i]));
        }
        let mut x = Vec::with_capacity(history.len());
        relative_features(history, &mut x);
        x.iter_mut().zip(&self.input_mean).zip(&self.input_std).for_each(|((v, m), s)| *v = (*v - m) / s);
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            let mut y = layer.b.clone();
            for (o, yo) in y.iter_mut().enumerate() {
                let row = &layer.w[o * layer.n_in..(o + 1) * layer.n_in];
                *yo += row.iter().zip(&x).map(|(w, v)| w * v).sum::<f64>();
                if l < last {
                    *yo = yo.max(0.0);
                }
            }
            debug_assert_eq!(y.len(), layer.n_out);
            x = y;
        }
        Ok((0..self.n_t).map(|n| std::array::from_fn(|a| x[3 * n + a] * self.output_scale[3 * n + a])).collect())
    }
}

/// The network's input: `history` (27·N_t values in the documented order) with each sample's
/// adjacent-MU states replaced by their offsets from MU i's state, x_j − x_i (appended to `out`).
pub fn relative_features(history: &[f64], out: &mut Vec<f64>) {
    for sample in history.chunks(FEATURES_PER_STEP) {
        out.extend_from_slice(&sample[0..6]);
        for j in [6, 12] {
            out.extend((0..6).map(|a| sample[j + a] - sample[a]));
        }
        out.extend_from_slice(&sample[18..]);
    }
}

/// One layer as trained: (weight [out][in] row-major, bias, out, in).
pub type LayerData = (Vec<f32>, Vec<f32>, usize, usize);

/// The bytes of a weights file (the trainer's writer; also what the tests build files with).
pub fn weights_file_bytes(
    layers: &[LayerData],
    input_mean: &[f64],
    input_std: &[f64],
    output_scale: &[f64],
    metadata: &serde_json::Value,
) -> Result<Vec<u8>, String> {
    let mut tensors = Vec::new();
    for (l, (w, b, out, inp)) in layers.iter().enumerate() {
        tensors.push(Tensor::new(format!("layers.{l}.weight"), vec![*out, *inp], Values::F32(w)));
        tensors.push(Tensor::new(format!("layers.{l}.bias"), vec![*out], Values::F32(b)));
    }
    tensors.push(Tensor::new("input_mean", vec![input_mean.len()], Values::F64(input_mean)));
    tensors.push(Tensor::new("input_std", vec![input_std.len()], Values::F64(input_std)));
    tensors.push(Tensor::new("output_scale", vec![output_scale.len()], Values::F64(output_scale)));
    weights::to_bytes(MODEL, &tensors, Some((METADATA_KEY, metadata))).map_err(|e| e.to_string())
}

/// Settings of a weights file's metadata that the predictor reads, for writers.
pub fn base_metadata(n_t: usize, dt_s: f64) -> BTreeMap<String, serde_json::Value> {
    let mut m = BTreeMap::new();
    m.insert("format".into(), FORMAT.into());
    m.insert("n_t".into(), n_t.into());
    m.insert("dt_s".into(), dt_s.into());
    m.insert("features_per_step".into(), FEATURES_PER_STEP.into());
    m.insert(
        "feature_layout".into(),
        "per sample, oldest first: x_i[6], x_j1[6], x_j2[6], u_i[3], u_j1[3], u_j2[3]; x = [r; v] in the \
         target's LVLH frame (m, m/s), u = thrust (N) held over [t_m, t_m+dt); j1 < j2 the MUs adjacent to i \
         along the net"
            .into(),
    );
    m.insert("output_layout".into(), "T_i(t_e + n dt), n = 1..n_t, 3 values each (N, LVLH)".into());
    m.insert("activation".into(), "relu".into());
    m.insert(
        "input_transform".into(),
        "x_j - x_i for the adjacent MUs' states, then (. - input_mean) / input_std".into(),
    );
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metadata(n_t: usize) -> serde_json::Value {
        serde_json::Value::Object(base_metadata(n_t, 0.1).into_iter().collect())
    }

    /// A tiny network: N_t = 2 (54 inputs), one hidden layer of 4.
    fn tiny() -> (Vec<LayerData>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let (n_in, h, n_out) = (54, 4, 6);
        let w1: Vec<f32> = (0..h * n_in).map(|i| ((i * 37 % 101) as f32 - 50.0) / 200.0).collect();
        let b1: Vec<f32> = vec![0.1, -0.2, 0.3, 0.05];
        let w2: Vec<f32> = (0..n_out * h).map(|i| ((i * 13 % 17) as f32 - 8.0) / 10.0).collect();
        let b2: Vec<f32> = vec![0.5; n_out];
        let mean: Vec<f64> = (0..n_in).map(|i| i as f64 * 0.01).collect();
        let std: Vec<f64> = (0..n_in).map(|i| 1.0 + i as f64 * 0.1).collect();
        let scale = vec![2.0, 3.0, 4.0, 2.0, 3.0, 4.0];
        (vec![(w1, b1, h, n_in), (w2, b2, n_out, h)], mean, std, scale)
    }

    fn tiny_bytes() -> Vec<u8> {
        let (layers, mean, std, scale) = tiny();
        weights_file_bytes(&layers, &mean, &std, &scale, &metadata(2)).unwrap()
    }

    #[test]
    fn the_forward_pass_is_the_documented_relu_network() {
        let p = TensionPredictor::from_bytes(&tiny_bytes(), Path::new("tiny.safetensors")).unwrap();
        assert_eq!((p.horizon_steps(), p.history_len(), p.hidden()), (2, 54, vec![4]));
        let history: Vec<f64> = (0..54).map(|i| (i as f64 * 0.37).sin() * 3.0).collect();
        let got = p.predict(&history).unwrap();
        // The same network written out by hand.
        let (layers, mean, std, scale) = tiny();
        let mut rel = Vec::new();
        relative_features(&history, &mut rel);
        assert_eq!(rel[6], history[6] - history[0]);
        assert_eq!(rel[17], history[17] - history[5]);
        assert_eq!(rel[18], history[18]);
        assert_eq!(rel[27 + 8], history[27 + 8] - history[27 + 2]);
        let z: Vec<f64> = (0..54).map(|i| (rel[i] - mean[i]) / std[i]).collect();
        let (w1, b1, _, _) = &layers[0];
        let h: Vec<f64> = (0..4)
            .map(|o| (b1[o] as f64 + (0..54).map(|i| w1[o * 54 + i] as f64 * z[i]).sum::<f64>()).max(0.0))
            .collect();
        assert!(h.contains(&0.0) && h.iter().any(|v| *v > 0.0), "exercise both ReLU sides: {h:?}");
        let (w2, b2, _, _) = &layers[1];
        for n in 0..2 {
            for a in 0..3 {
                let o = 3 * n + a;
                let y = b2[o] as f64 + (0..4).map(|j| w2[o * 4 + j] as f64 * h[j]).sum::<f64>();
                assert!((got[n][a] - y * scale[o]).abs() < 1e-12, "step {n} axis {a}");
            }
        }
        assert!(p.predict(&history[1..]).unwrap_err().contains("expected 27·N_t = 54"));
        let mut bad = history.clone();
        bad[7] = f64::NAN;
        assert!(p.predict(&bad).unwrap_err().contains("history value 7 is not finite"));
    }

    #[test]
    fn a_missing_file_names_the_file() {
        let e = TensionPredictor::load(Path::new("/nonexistent/tension.safetensors")).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("/nonexistent/tension.safetensors") && msg.contains("cannot read"), "{msg}");
    }

    #[test]
    fn malformed_files_say_what_is_wrong() {
        let f = Path::new("w.safetensors");
        let check = |bytes: &[u8], want: &str| {
            let e = TensionPredictor::from_bytes(bytes, f).unwrap_err();
            assert!(e.to_string().contains("w.safetensors") && e.to_string().contains(want), "{e} (want {want})");
        };
        check(b"not a weights file", "not a safetensors file");
        let good = tiny_bytes();
        check(&good[..good.len() - 10], "not a safetensors file");
        let (layers, mean, std, scale) = tiny();
        let write = |layers: &[LayerData], std: &[f64], meta: serde_json::Value| {
            weights_file_bytes(layers, &mean, std, &scale, &meta).unwrap()
        };
        // Wrong format tag, missing n_t, n_t that does not match the tensors.
        let mut m = metadata(2);
        m["format"] = "something-else".into();
        check(&write(&layers, &std, m), "metadata format");
        let mut m = metadata(2);
        m.as_object_mut().unwrap().remove("n_t");
        check(&write(&layers, &std, m), "metadata `n_t` is missing");
        check(&write(&layers, &std, metadata(3)), "tensor \"input_mean\" has shape [54], expected [81]");
        // A non-finite weight, a zero standard deviation, a layer of the wrong width.
        let mut l = layers.clone();
        l[1].0[3] = f32::NAN;
        check(&write(&l, &std, metadata(2)), "tensor \"layers.1.weight\" value 3 (flat index) is not finite (NaN)");
        let mut s = std.clone();
        s[5] = 0.0;
        check(&write(&layers, &s, metadata(2)), "tensor `input_std` has a value ≤ 0 at index 5");
        let mut l = layers.clone();
        l[1].0.truncate(5 * 4);
        l[1].1.truncate(5);
        l[1].2 = 5;
        check(&write(&l, &std, metadata(2)), "the last layer has 5 outputs, expected 3·n_t = 6");
        // No metadata at all.
        let bytes = safetensors::serialize(Vec::<(String, safetensors::tensor::TensorView)>::new(), None).unwrap();
        check(&bytes, "no \"cohort_tsnr_tension\" metadata: not a tension-predictor weights file");
    }

    #[test]
    fn the_file_is_byte_for_byte_reproducible() {
        assert_eq!(tiny_bytes(), tiny_bytes());
    }

    /// A history of N_t identical samples: the four MUs held still on a square of half-width
    /// `h_m` at x = −5 m, each pushing outward in y and z with `push_n`.
    fn held_square(p: &TensionPredictor, mu: u32, h_m: f64, push_n: f64) -> Vec<f64> {
        let corner = |id: u32| {
            let (sy, sz) = [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)][(id - 1) as usize];
            ([-5.0, sy * h_m, sz * h_m, 0.0, 0.0, 0.0], [0.0, sy * push_n, sz * push_n])
        };
        let [j1, j2] = adjacent_mus(mu);
        let s = Sample {
            own_state: corner(mu).0,
            neighbour_states: [corner(j1).0, corner(j2).0],
            own_thrust_n: corner(mu).1,
            neighbour_thrust_n: [corner(j1).1, corner(j2).1],
        };
        let mut h = Vec::new();
        for _ in 0..p.horizon_steps() {
            s.extend_features(&mut h);
        }
        h
    }

    #[test]
    fn the_committed_weights_load_and_know_slack_from_taut() {
        let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/weights/tension.safetensors"));
        let p = TensionPredictor::load(path).unwrap();
        assert_eq!((p.horizon_steps(), p.dt_s(), p.history_len()), (10, 0.1, 270));
        assert_eq!(p.metadata()["training"]["seed"], 1);
        for mu in 1..=4u32 {
            // Folded (1.5 m square, every edge slack), coasting: hardly any tension.
            let slack = p.predict(&held_square(&p, mu, 0.75, 0.0)).unwrap();
            // Deployed at 2 % stretch, the MUs holding the net open: pulled back inward.
            let taut = p.predict(&held_square(&p, mu, 2.55, 5.0)).unwrap();
            let (sy, sz) = [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)][(mu - 1) as usize];
            for n in 0..10 {
                assert!(slack[n].iter().all(|t| t.abs() < 0.2), "MU {mu} step {n}: slack net {:?}", slack[n]);
                // Each corner's two edges pull with ≈ 4–6 N at 2 % (papers/tsnr/README.md), inward.
                let (ty, tz) = (taut[n][1] * -sy, taut[n][2] * -sz);
                assert!((3.0..8.0).contains(&ty) && (3.0..8.0).contains(&tz), "MU {mu} step {n}: {:?}", taut[n]);
            }
        }
    }

    #[test]
    fn samples_lay_out_in_the_documented_order() {
        let s = Sample {
            own_state: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            neighbour_states: [[7.0; 6], [8.0; 6]],
            own_thrust_n: [9.0; 3],
            neighbour_thrust_n: [[10.0; 3], [11.0; 3]],
        };
        let mut v = Vec::new();
        s.extend_features(&mut v);
        assert_eq!(v.len(), FEATURES_PER_STEP);
        assert_eq!(v[0..6], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!((v[6], v[12], v[18], v[21], v[24], v[26]), (7.0, 8.0, 9.0, 10.0, 11.0, 11.0));
    }
}
