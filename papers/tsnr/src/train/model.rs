//! The network Φ of eq. (8) in candle (f32, CPU), the loss (9)–(11) and the training loop.
//!
//! Loss on normalised outputs y = T / scale (a per-axis scale, no shift, so sign(y) = sign(T)):
//! - L_e (10), on the first predicted step (T(t_e + Δt), the tension an agent measures when it
//!   decides): Σ_axes w·|y − ŷ| with w = 1 − γ where the prediction falls short of the truth in
//!   magnitude (sign(y)·(y − ŷ) > 0: "T > T̂" read per component, towards larger |T|) and w = γ
//!   otherwise, γ ∈ (0, 0.5): under-prediction costs more. This is the pinball loss of the
//!   (1 − γ)-quantile of |T|, so about a share γ of the first-step components end under-predicted.
//! - L_p (11): Σ_{n=1}^{N_t} η_n Σ_axes |y_n − ŷ_n| with η_n = η^{n−1} / Σ_m η^{m−1} (a decay
//!   constant η; normalised so that L_p is a weighted mean over the horizon, of the size of L_e).
//! - L = α L_e + β L_p, averaged over the batch.

use candle_core::{DType, Device, Tensor, Var};
use candle_nn::{AdamW, Linear, Module, Optimizer, ParamsAdamW};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Hyper-parameters of the loss and the optimiser.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Hyper {
    pub hidden: Vec<usize>,
    pub gamma: f64,
    pub eta: f64,
    pub alpha: f64,
    pub beta: f64,
    pub batch: usize,
    pub lr_start: f64,
    pub lr_end: f64,
}

impl Default for Hyper {
    fn default() -> Self {
        Self {
            hidden: vec![128, 128, 128],
            gamma: 0.3,
            eta: 0.9,
            alpha: 1.0,
            beta: 3.0,
            batch: 512,
            lr_start: 1e-3,
            lr_end: 2e-5,
        }
    }
}

pub struct Mlp {
    vars: Vec<(Var, Var)>,
    layers: Vec<Linear>,
}

impl Mlp {
    /// He-uniform weights (ReLU), zero biases, drawn from `rng`.
    pub fn new(sizes: &[usize], rng: &mut ChaCha8Rng, dev: &Device) -> candle_core::Result<Self> {
        let mut vars = Vec::new();
        let mut layers = Vec::new();
        for w in sizes.windows(2) {
            let (n_in, n_out) = (w[0], w[1]);
            let bound = (6.0 / n_in as f64).sqrt();
            let data: Vec<f32> = (0..n_in * n_out).map(|_| rng.random_range(-bound..bound) as f32).collect();
            let wv = Var::from_tensor(&Tensor::from_vec(data, (n_out, n_in), dev)?)?;
            let bv = Var::from_tensor(&Tensor::zeros(n_out, DType::F32, dev)?)?;
            layers.push(Linear::new(wv.as_tensor().clone(), Some(bv.as_tensor().clone())));
            vars.push((wv, bv));
        }
        Ok(Self { vars, layers })
    }

    pub fn forward(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        let mut h = x.clone();
        let last = self.layers.len() - 1;
        for (l, layer) in self.layers.iter().enumerate() {
            h = layer.forward(&h)?;
            if l < last {
                h = h.relu()?;
            }
        }
        Ok(h)
    }

    fn all_vars(&self) -> Vec<Var> {
        self.vars.iter().flat_map(|(w, b)| [w.clone(), b.clone()]).collect()
    }

    /// (weight row-major, bias, out, in) per layer, for the weights file.
    pub fn export(&self) -> candle_core::Result<Vec<crate::predictor::LayerData>> {
        self.vars
            .iter()
            .map(|(w, b)| {
                let (out, inp) = w.as_tensor().dims2()?;
                Ok((w.as_tensor().flatten_all()?.to_vec1()?, b.as_tensor().to_vec1()?, out, inp))
            })
            .collect()
    }
}

/// Normalised training data on the device.
pub struct Data {
    /// (N, 27·N_t) f32, already normalised.
    pub x: Tensor,
    /// (N, 3·N_t) f32, T / scale.
    pub y: Tensor,
    pub n: usize,
}

/// The loss (9) for predictions `yhat` of targets `y` (both (B, 3·N_t)).
pub fn loss(yhat: &Tensor, y: &Tensor, h: &Hyper, n_t: usize) -> candle_core::Result<Tensor> {
    let dev = y.device();
    let b = y.dims2()?.0 as f64;
    let e = (y - yhat)?;
    let e0 = e.narrow(1, 0, 3)?;
    // The weights are piecewise constant: no gradient flows through the comparison.
    let under = (e0.detach() * y.narrow(1, 0, 3)?.sign()?)?.gt(0.0)?.to_dtype(DType::F32)?;
    let w = under.affine(1.0 - 2.0 * h.gamma, h.gamma)?;
    let l_e = ((w * e0.abs()?)?.sum_all()? / b)?;
    // Normalised so that L_p is a weighted mean over the horizon, comparable in size to L_e.
    let eta_sum: f64 = (0..n_t).map(|n| h.eta.powi(n as i32)).sum();
    let eta: Vec<f32> = (0..n_t).flat_map(|n| [(h.eta.powi(n as i32) / eta_sum) as f32; 3]).collect();
    let eta = Tensor::from_vec(eta, (1, 3 * n_t), dev)?;
    let l_p = (e.abs()?.broadcast_mul(&eta)?.sum_all()? / b)?;
    (l_e.affine(h.alpha, 0.0)? + l_p.affine(h.beta, 0.0)?)?.to_dtype(DType::F32)
}

/// Train for `epochs` passes over `data` with shuffled mini-batches (order from `rng`), the
/// learning rate decaying along a cosine from `lr_start` to `lr_end`. Returns the mean loss of
/// each epoch.
pub fn train(
    mlp: &Mlp,
    data: &Data,
    h: &Hyper,
    n_t: usize,
    epochs: usize,
    rng: &mut ChaCha8Rng,
    mut on_epoch: impl FnMut(usize, f64),
) -> candle_core::Result<Vec<f64>> {
    let dev = data.x.device().clone();
    let params = ParamsAdamW { lr: h.lr_start, weight_decay: 0.0, ..Default::default() };
    let mut opt = AdamW::new(mlp.all_vars(), params)?;
    let mut order: Vec<u32> = (0..data.n as u32).collect();
    let batches = data.n.div_ceil(h.batch);
    let total = (epochs * batches).max(1) as f64;
    let mut history = Vec::new();
    for epoch in 0..epochs {
        order.shuffle(rng);
        let mut sum = 0.0;
        for (bi, chunk) in order.chunks(h.batch).enumerate() {
            let progress = (epoch * batches + bi) as f64 / total;
            let lr = h.lr_end + 0.5 * (h.lr_start - h.lr_end) * (1.0 + (std::f64::consts::PI * progress).cos());
            opt.set_learning_rate(lr);
            let idx = Tensor::from_slice(chunk, chunk.len(), &dev)?;
            let (x, y) = (data.x.index_select(&idx, 0)?, data.y.index_select(&idx, 0)?);
            let l = loss(&mlp.forward(&x)?, &y, h, n_t)?;
            opt.backward_step(&l)?;
            sum += l.to_scalar::<f32>()? as f64 * chunk.len() as f64;
        }
        let mean = sum / data.n as f64;
        on_epoch(epoch, mean);
        history.push(mean);
    }
    Ok(history)
}

/// A generator for the initial weights and the batch order.
pub fn rng(seed: u64) -> ChaCha8Rng {
    // Stream 1: the data set uses stream = trajectory index from its own seed derivation.
    let mut r = ChaCha8Rng::seed_from_u64(seed ^ 0x7e75_1017_7e75_1017);
    r.set_stream(1);
    r
}
