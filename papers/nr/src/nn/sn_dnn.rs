//! The spectrally-normalised DNN (SN-DNN) of Sec. 3.2 of "Neural-Rendezvous" (arXiv:2208.04883):
//! layers h_l = tanh(W_l h_{l−1} + b_l) with W_l = C_sn Ω_l/‖Ω_l‖₂ (Definition 6.2 of the paper's
//! [20], Miyato et al. [4]), so the network is Lipschitz with constant ≤ C_sn^{L} from its
//! normalised input to its normalised output (tanh is 1-Lipschitz). tanh is also the output
//! activation, "not to violate the input constraint" (6.2.4); inputs are divided by their
//! training maxima and outputs multiplied by theirs (6.2.3).
//!
//! This module is the inference side, a plain f64 forward pass with no training stack, plus the
//! weights file and the spectral norm by power iteration. Generic in the sizes (the swarm policy
//! reuses it).
//!
//! **Weights file** (safetensors): `layers.<l>.weight` ([out, in], F64: the normalised W_l, not
//! Ω_l), `layers.<l>.bias` ([out], F64), `input_scale` ([n_in], F64: the divisor of each input),
//! `output_scale` ([n_out], F64: the factor of each output), and one metadata entry
//! [`METADATA_KEY`] holding a JSON object with at least `format` = [`FORMAT`] and `c_sn`. Loading
//! checks every shape, every number, the layer chain and ‖W_l‖₂ ≤ C_sn; any failure is a
//! [`WeightsError`] (`cohort_runtime::weights`, the one reader of every paper's weights) naming the
//! file, the tensor and the reason.

use std::path::Path;

pub use cohort_runtime::weights::WeightsError;
use cohort_runtime::weights::{self, Precision, Tensor, Values, WeightsFile};

/// The one metadata key of a weights file.
pub const METADATA_KEY: &str = "cohort_sn_dnn";
/// Value of the metadata's `format`.
pub const FORMAT: &str = "cohort-sn-dnn-v1";
/// Widest layer the stack buffers of the forward pass hold.
pub const MAX_WIDTH: usize = 256;

/// The model name of its weights errors.
pub const MODEL: &str = "SN-DNN";

/// One layer: W row-major [n_out][n_in], b.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    pub n_in: usize,
    pub n_out: usize,
    pub w: Vec<f64>,
    pub b: Vec<f64>,
}

/// A checked network.
#[derive(Debug, Clone, PartialEq)]
pub struct SnDnn {
    layers: Vec<Layer>,
    input_scale: Vec<f64>,
    output_scale: Vec<f64>,
    c_sn: f64,
    metadata: serde_json::Value,
}

/// ‖W‖₂ of a row-major `rows` × `cols` matrix by power iteration on WᵀW from a fixed start,
/// to a relative change below 1e-15 (or 20 000 iterations). A lower bound that converges to the
/// largest singular value (tests: against an SVD).
pub fn spectral_norm(w: &[f64], rows: usize, cols: usize) -> f64 {
    assert_eq!(w.len(), rows * cols, "matrix size");
    let mut v: Vec<f64> = (0..cols).map(|i| 1.0 + 0.01 * i as f64).collect();
    let mut u = vec![0.0; rows];
    let mut sigma = 0.0;
    for _ in 0..20_000 {
        let nv = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if nv == 0.0 {
            return 0.0;
        }
        v.iter_mut().for_each(|x| *x /= nv);
        for (r, ur) in u.iter_mut().enumerate() {
            *ur = (0..cols).map(|c| w[r * cols + c] * v[c]).sum();
        }
        let s = u.iter().map(|x| x * x).sum::<f64>().sqrt();
        for (c, vc) in v.iter_mut().enumerate() {
            *vc = (0..rows).map(|r| w[r * cols + c] * u[r]).sum();
        }
        if (s - sigma).abs() <= 1e-15 * s {
            return s;
        }
        sigma = s;
    }
    sigma
}

/// Σ aᵢbᵢ in eight interleaved partial sums (a fixed order, so deterministic, and one the
/// compiler vectorises; a single running sum cannot be reordered and runs ≈ 4× slower).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            s[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7])) + tail
}

impl SnDnn {
    /// Check and assemble; the reason names what is wrong.
    pub fn new(
        layers: Vec<Layer>,
        input_scale: Vec<f64>,
        output_scale: Vec<f64>,
        c_sn: f64,
        metadata: serde_json::Value,
    ) -> Result<Self, String> {
        if !(c_sn.is_finite() && c_sn > 0.0) {
            return Err(format!("c_sn = {c_sn}: must be a positive number"));
        }
        let first = layers.first().ok_or("no layers")?;
        if input_scale.len() != first.n_in {
            return Err(format!("input_scale has {} values, the first layer takes {}", input_scale.len(), first.n_in));
        }
        if output_scale.len() != layers.last().expect("non-empty").n_out {
            return Err(format!(
                "output_scale has {} values, the last layer gives {}",
                output_scale.len(),
                layers.last().expect("non-empty").n_out
            ));
        }
        if let Some(s) = input_scale.iter().chain(&output_scale).find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(format!("a scale is {s}: every input and output scale must be positive"));
        }
        for (l, layer) in layers.iter().enumerate() {
            if layer.w.len() != layer.n_in * layer.n_out || layer.b.len() != layer.n_out {
                return Err(format!("layer {l}: weight or bias size does not match [{}, {}]", layer.n_out, layer.n_in));
            }
            if l > 0 && layer.n_in != layers[l - 1].n_out {
                return Err(format!(
                    "layer {l} takes {} inputs, layer {} gives {}",
                    layer.n_in,
                    l - 1,
                    layers[l - 1].n_out
                ));
            }
            if layer.n_in > MAX_WIDTH || layer.n_out > MAX_WIDTH {
                return Err(format!("layer {l} is wider than {MAX_WIDTH}"));
            }
            if layer.w.iter().chain(&layer.b).any(|x| !x.is_finite()) {
                return Err(format!("layer {l} holds a value that is not finite"));
            }
            let sn = spectral_norm(&layer.w, layer.n_out, layer.n_in);
            if sn > c_sn * (1.0 + 1e-6) {
                return Err(format!("layer {l}: ‖W‖₂ = {sn} exceeds C_sn = {c_sn} (not spectrally normalised)"));
            }
        }
        Ok(Self { layers, input_scale, output_scale, c_sn, metadata })
    }

    pub fn n_in(&self) -> usize {
        self.input_scale.len()
    }
    pub fn n_out(&self) -> usize {
        self.output_scale.len()
    }
    pub fn c_sn(&self) -> f64 {
        self.c_sn
    }
    pub fn layers(&self) -> &[Layer] {
        &self.layers
    }
    pub fn input_scale(&self) -> &[f64] {
        &self.input_scale
    }
    pub fn output_scale(&self) -> &[f64] {
        &self.output_scale
    }
    pub fn metadata(&self) -> &serde_json::Value {
        &self.metadata
    }

    /// Lipschitz bound from the normalised input to the normalised output: C_sn^L.
    pub fn lipschitz_normalised(&self) -> f64 {
        self.c_sn.powi(self.layers.len() as i32)
    }

    /// The network on an already normalised input; the normalised output (before the output
    /// scale) goes to `out`.
    pub fn forward_normalised(&self, z: &[f64], out: &mut [f64]) {
        assert!(z.len() == self.n_in() && out.len() == self.n_out(), "input and output sizes");
        let (mut a, mut b) = ([0.0; MAX_WIDTH], [0.0; MAX_WIDTH]);
        a[..z.len()].copy_from_slice(z);
        for layer in &self.layers {
            for (o, bo) in b.iter_mut().enumerate().take(layer.n_out) {
                let row = &layer.w[o * layer.n_in..(o + 1) * layer.n_in];
                *bo = (dot(row, &a[..layer.n_in]) + layer.b[o]).tanh();
            }
            std::mem::swap(&mut a, &mut b);
        }
        out.copy_from_slice(&a[..self.n_out()]);
    }

    /// The network on a raw input: divided by the input scales, outputs times the output scales.
    pub fn forward(&self, input: &[f64], out: &mut [f64]) {
        let mut z = [0.0; MAX_WIDTH];
        for (i, (x, s)) in input.iter().zip(&self.input_scale).enumerate() {
            z[i] = x / s;
        }
        self.forward_normalised(&z[..self.n_in()], out);
        out.iter_mut().zip(&self.output_scale).for_each(|(o, s)| *o *= s);
    }

    /// The weights file's bytes (deterministic: one metadata key).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut tensors = Vec::new();
        push_tensors(self, "", &mut tensors);
        serialise(MODEL, &tensors, METADATA_KEY, FORMAT, &self.metadata, self.c_sn)
    }

    /// Read and check a weights file.
    pub fn load(path: &Path) -> Result<Self, WeightsError> {
        Self::from_bytes(&weights::read(MODEL, path)?, path)
    }

    /// Check and load a weights file's bytes; `file` only names it in errors.
    pub fn from_bytes(bytes: &[u8], file: &Path) -> Result<Self, WeightsError> {
        let (st, metadata, c_sn) = open(MODEL, bytes, file, METADATA_KEY, FORMAT, "an SN-DNN")?;
        let net = read_net(&st, "", c_sn)?;
        Ok(Self { metadata, ..net })
    }
}

/// The tensors of `net` in the layout above (F64), each name prefixed by `prefix` (`""`, or
/// `"phi."` for one of several networks in a file), appended to `out`.
pub fn push_tensors<'n>(net: &'n SnDnn, prefix: &str, out: &mut Vec<Tensor<'n>>) {
    for (l, layer) in net.layers.iter().enumerate() {
        out.push(Tensor::new(
            format!("{prefix}layers.{l}.weight"),
            vec![layer.n_out, layer.n_in],
            Values::F64(&layer.w),
        ));
        out.push(Tensor::new(format!("{prefix}layers.{l}.bias"), vec![layer.n_out], Values::F64(&layer.b)));
    }
    out.push(Tensor::new(format!("{prefix}input_scale"), vec![net.n_in()], Values::F64(&net.input_scale)));
    out.push(Tensor::new(format!("{prefix}output_scale"), vec![net.n_out()], Values::F64(&net.output_scale)));
}

/// A weights file of `tensors` and one metadata entry `key`: `metadata` with `format` and `c_sn`
/// set; `model` names the kind of network.
pub fn serialise(
    model: &'static str,
    tensors: &[Tensor<'_>],
    key: &str,
    format: &str,
    metadata: &serde_json::Value,
    c_sn: f64,
) -> Vec<u8> {
    let mut meta = metadata.clone();
    if let Some(o) = meta.as_object_mut() {
        o.insert("format".into(), format.into());
        o.insert("c_sn".into(), c_sn.into());
    }
    weights::to_bytes(model, tensors, Some((key, &meta))).expect("the shapes are the network's own")
}

/// A weights file's tensors, its metadata entry `key` (a JSON object whose `format` must be
/// `format`) and that metadata's `c_sn`; `what` names the kind of file in the error.
pub fn open<'a>(
    model: &'static str,
    bytes: &'a [u8],
    file: &Path,
    key: &str,
    format: &str,
    what: &str,
) -> Result<(WeightsFile<'a>, serde_json::Value, f64), WeightsError> {
    let st = WeightsFile::parse(model, bytes, file)?;
    let metadata = st.metadata_json(key, format, what)?;
    let c_sn =
        metadata.get("c_sn").and_then(|c| c.as_f64()).ok_or_else(|| st.invalid("metadata has no number c_sn"))?;
    Ok((st, metadata, c_sn))
}

/// The network whose tensors are named with `prefix` (see [`push_tensors`]), checked by
/// [`SnDnn::new`]; its metadata is empty.
pub fn read_net(st: &WeightsFile<'_>, prefix: &str, c_sn: f64) -> Result<SnDnn, WeightsError> {
    let mut layers = Vec::new();
    while st.contains(&format!("{prefix}layers.{}.weight", layers.len())) {
        let l = layers.len();
        let (shape, w) = st.tensor_dims(&format!("{prefix}layers.{l}.weight"), Precision::F64, &[None, None])?;
        let (_, b) = st.tensor_dims(&format!("{prefix}layers.{l}.bias"), Precision::F64, &[None])?;
        layers.push(Layer { n_in: shape[1], n_out: shape[0], w, b });
    }
    let (_, input_scale) = st.tensor_dims(&format!("{prefix}input_scale"), Precision::F64, &[None])?;
    let (_, output_scale) = st.tensor_dims(&format!("{prefix}output_scale"), Precision::F64, &[None])?;
    let named = |e: String| if prefix.is_empty() { e } else { format!("{}: {e}", prefix.trim_end_matches('.')) };
    SnDnn::new(layers, input_scale, output_scale, c_sn, serde_json::json!({})).map_err(|e| st.invalid(named(e)))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random network with exactly normalised weights and the given scales.
    pub(crate) fn random_net_scaled(
        sizes: &[usize],
        c_sn: f64,
        seed: u64,
        input_scale: Vec<f64>,
        output_scale: Vec<f64>,
    ) -> SnDnn {
        let n = random_net(sizes, c_sn, seed);
        SnDnn::new(n.layers, input_scale, output_scale, c_sn, serde_json::json!({})).unwrap()
    }

    /// A random network with exactly normalised weights.
    pub(crate) fn random_net(sizes: &[usize], c_sn: f64, seed: u64) -> SnDnn {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let layers = sizes
            .windows(2)
            .map(|s| {
                let w: Vec<f64> = (0..s[0] * s[1]).map(|_| rng.random_range(-1.0..1.0)).collect();
                let sn = spectral_norm(&w, s[1], s[0]);
                Layer {
                    n_in: s[0],
                    n_out: s[1],
                    w: w.iter().map(|x| c_sn * x / sn).collect(),
                    b: (0..s[1]).map(|_| rng.random_range(-0.5..0.5)).collect(),
                }
            })
            .collect();
        let input_scale = (0..sizes[0]).map(|i| 1.0 + i as f64).collect();
        let output_scale = vec![0.7; *sizes.last().unwrap()];
        SnDnn::new(layers, input_scale, output_scale, c_sn, serde_json::json!({})).unwrap()
    }

    #[test]
    fn power_iteration_matches_the_largest_singular_value() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for (r, c) in [(64, 15), (64, 64), (3, 64), (1, 5), (7, 1)] {
            let w: Vec<f64> = (0..r * c).map(|_| rng.random_range(-1.0..1.0)).collect();
            let svd = DMatrix::from_row_slice(r, c, &w).singular_values().max();
            let pi = spectral_norm(&w, r, c);
            assert!((pi - svd).abs() <= 1e-9 * svd, "{r}×{c}: power iteration {pi}, SVD {svd}");
        }
    }

    #[test]
    fn file_round_trips_exactly_and_the_forward_pass_is_the_documented_network() {
        let net = random_net(&[18, 64, 64, 64, 3], 2.0, 7);
        let bytes = net.to_bytes();
        assert_eq!(bytes, net.to_bytes(), "deterministic bytes");
        let back = SnDnn::from_bytes(&bytes, Path::new("x.safetensors")).unwrap();
        assert_eq!(back.layers, net.layers);
        let input: Vec<f64> = (0..18).map(|i| (i as f64 * 0.37).sin() * 3.0).collect();
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        net.forward(&input, &mut a);
        back.forward(&input, &mut b);
        assert_eq!(a, b);
        // By hand with nalgebra.
        let mut h = nalgebra::DVector::from_iterator(18, input.iter().zip(net.input_scale()).map(|(x, s)| x / s));
        for l in net.layers() {
            h = (DMatrix::from_row_slice(l.n_out, l.n_in, &l.w) * h + nalgebra::DVector::from_column_slice(&l.b))
                .map(|x| x.tanh());
        }
        for o in 0..3 {
            assert!((a[o] - 0.7 * h[o]).abs() < 1e-14);
        }
        assert!(a.iter().all(|x| x.abs() <= 0.7), "tanh output times the scale stays within it");
    }

    #[test]
    fn empirical_lipschitz_constant_stays_below_c_sn_to_the_l() {
        let net = random_net(&[18, 64, 64, 64, 3], 2.0, 8);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let bound = net.lipschitz_normalised();
        assert_eq!(bound, 16.0);
        for _ in 0..2000 {
            let z: Vec<f64> = (0..18).map(|_| rng.random_range(-1.0..1.0)).collect();
            let dz: Vec<f64> = (0..18).map(|_| rng.random_range(-1e-3..1e-3)).collect();
            let z2: Vec<f64> = z.iter().zip(&dz).map(|(a, b)| a + b).collect();
            let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
            net.forward_normalised(&z, &mut a);
            net.forward_normalised(&z2, &mut b);
            let num = a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
            let den = dz.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!(num / den <= bound);
        }
    }

    #[test]
    fn a_missing_or_malformed_file_is_an_error_naming_the_file_and_the_reason() {
        let dir = std::env::temp_dir().join(format!("nr-weights-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing.safetensors");
        let e = SnDnn::load(&missing).unwrap_err().to_string();
        assert!(e.contains("missing.safetensors") && e.contains("cannot read"), "{e}");
        let junk = dir.join("junk.safetensors");
        std::fs::write(&junk, b"not a weights file at all").unwrap();
        let e = SnDnn::load(&junk).unwrap_err().to_string();
        assert!(e.contains("junk.safetensors") && e.contains("not a safetensors file"), "{e}");
        // A well-formed file whose weights break the normalisation.
        let mut net = random_net(&[4, 8, 2], 2.0, 1);
        net.layers[1].w.iter_mut().for_each(|w| *w *= 3.0);
        let e = SnDnn::from_bytes(&net.to_bytes(), Path::new("big.safetensors")).unwrap_err().to_string();
        assert!(e.contains("big.safetensors") && e.contains("exceeds C_sn"), "{e}");
        let mut net = random_net(&[4, 8, 2], 2.0, 1);
        net.output_scale[0] = -1.0;
        let e = SnDnn::from_bytes(&net.to_bytes(), Path::new("neg.safetensors")).unwrap_err().to_string();
        assert!(e.contains("must be positive"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
