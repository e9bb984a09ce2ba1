//! The SN-DNN for training, in candle (f32, CPU): Ω_l and b_l are the parameters, the weights
//! used are W_l = C_sn Ω_l/σ_l with σ_l = u_lᵀΩ_l v_l from one power-iteration step per training
//! step on persistent vectors (Miyato et al., the paper's [4]; u, v held constant in the
//! gradient, as there). tanh after every layer, the output's included. Generic in the sizes (the
//! swarm policy reuses it); [`SnMlp::export`] gives the f64 network of [`crate::nn::sn_dnn`] with σ_l
//! from power iteration run to convergence, so ‖W_l‖₂ = C_sn there.

use candle_core::{DType, Device, Tensor, Var};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::nn::sn_dnn::{Layer, SnDnn, spectral_norm};

pub struct SnMlp {
    pub sizes: Vec<usize>,
    pub c_sn: f64,
    omegas: Vec<Var>,
    biases: Vec<Var>,
    /// Persistent left singular vector estimates, one per layer.
    u: Vec<Vec<f64>>,
}

fn normalise(v: &mut [f64]) {
    let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n > 0.0 {
        v.iter_mut().for_each(|x| *x /= n);
    }
}

impl SnMlp {
    /// Ω uniform in ±√(6/(n_in + n_out)) (Glorot, for tanh), zero biases, from `rng`.
    pub fn new(sizes: &[usize], c_sn: f64, rng: &mut ChaCha8Rng, dev: &Device) -> candle_core::Result<Self> {
        let (mut omegas, mut biases, mut u) = (Vec::new(), Vec::new(), Vec::new());
        for w in sizes.windows(2) {
            let (n_in, n_out) = (w[0], w[1]);
            let bound = (6.0 / (n_in + n_out) as f64).sqrt();
            let data: Vec<f32> = (0..n_in * n_out).map(|_| rng.random_range(-bound..bound) as f32).collect();
            omegas.push(Var::from_tensor(&Tensor::from_vec(data, (n_out, n_in), dev)?)?);
            biases.push(Var::from_tensor(&Tensor::zeros(n_out, DType::F32, dev)?)?);
            let mut v: Vec<f64> = (0..n_out).map(|_| rng.random_range(-1.0..1.0)).collect();
            normalise(&mut v);
            u.push(v);
        }
        Ok(Self { sizes: sizes.to_vec(), c_sn, omegas, biases, u })
    }

    pub fn vars(&self) -> Vec<Var> {
        self.omegas.iter().zip(&self.biases).flat_map(|(w, b)| [w.clone(), b.clone()]).collect()
    }

    /// One power-iteration step per layer on the current Ω, then W_l = C_sn Ω_l/(u_lᵀΩ_l v_l).
    pub fn weights(&mut self) -> candle_core::Result<Vec<Tensor>> {
        let mut out = Vec::with_capacity(self.omegas.len());
        for (l, om) in self.omegas.iter().enumerate() {
            let (rows, cols) = om.as_tensor().dims2()?;
            let w: Vec<f64> = om.as_tensor().flatten_all()?.to_vec1::<f32>()?.into_iter().map(f64::from).collect();
            let mut v: Vec<f64> = (0..cols).map(|c| (0..rows).map(|r| w[r * cols + c] * self.u[l][r]).sum()).collect();
            normalise(&mut v);
            let mut u: Vec<f64> = (0..rows).map(|r| (0..cols).map(|c| w[r * cols + c] * v[c]).sum()).collect();
            normalise(&mut u);
            let dev = om.as_tensor().device();
            let ut = Tensor::from_vec(u.iter().map(|x| *x as f32).collect::<Vec<_>>(), (1, rows), dev)?;
            let vt = Tensor::from_vec(v.iter().map(|x| *x as f32).collect::<Vec<_>>(), (cols, 1), dev)?;
            let sigma = ut.matmul(om.as_tensor())?.matmul(&vt)?;
            out.push((om.as_tensor().broadcast_div(&sigma)? * self.c_sn)?);
            self.u[l] = u;
        }
        Ok(out)
    }

    /// The network on normalised inputs `z` (B, n_in) with weights from [`SnMlp::weights`].
    pub fn forward(&self, ws: &[Tensor], z: &Tensor) -> candle_core::Result<Tensor> {
        let mut h = z.clone();
        for (w, b) in ws.iter().zip(&self.biases) {
            h = h.matmul(&w.t()?)?.broadcast_add(b.as_tensor())?.tanh()?;
        }
        Ok(h)
    }

    /// The f64 network: exact normalisation of the trained Ω, the given scales and metadata.
    pub fn export(
        &self,
        input_scale: Vec<f64>,
        output_scale: Vec<f64>,
        metadata: serde_json::Value,
    ) -> Result<SnDnn, String> {
        let e = |err: candle_core::Error| err.to_string();
        let mut layers = Vec::new();
        for (om, b) in self.omegas.iter().zip(&self.biases) {
            let (n_out, n_in) = om.as_tensor().dims2().map_err(e)?;
            let w: Vec<f64> = om
                .as_tensor()
                .flatten_all()
                .and_then(|t| t.to_vec1::<f32>())
                .map_err(e)?
                .into_iter()
                .map(f64::from)
                .collect();
            let sn = spectral_norm(&w, n_out, n_in);
            let w = w.iter().map(|x| self.c_sn * x / sn).collect();
            let b = b.as_tensor().to_vec1::<f32>().map_err(e)?.into_iter().map(f64::from).collect();
            layers.push(Layer { n_in, n_out, w, b });
        }
        SnDnn::new(layers, input_scale, output_scale, self.c_sn, metadata)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::sn_dnn::tests::random_net;
    use rand::SeedableRng;

    /// The f64 network evaluated by candle (f64 tensors), for the parity test.
    fn candle_forward(net: &SnDnn, input: &[f64]) -> Vec<f64> {
        let dev = Device::Cpu;
        let z: Vec<f64> = input.iter().zip(net.input_scale()).map(|(x, s)| x / s).collect();
        let mut h = Tensor::from_vec(z, (1, net.n_in()), &dev).unwrap();
        for l in net.layers() {
            let w = Tensor::from_vec(l.w.clone(), (l.n_out, l.n_in), &dev).unwrap();
            let b = Tensor::from_vec(l.b.clone(), l.n_out, &dev).unwrap();
            h = h.matmul(&w.t().unwrap()).unwrap().broadcast_add(&b).unwrap().tanh().unwrap();
        }
        let out: Vec<f64> = h.flatten_all().unwrap().to_vec1().unwrap();
        out.iter().zip(net.output_scale()).map(|(y, s)| y * s).collect()
    }

    #[test]
    fn plain_f64_inference_matches_candle() {
        let net = random_net(&[18, 64, 64, 64, 3], 2.0, 21);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..100 {
            let input: Vec<f64> = (0..18).map(|i| rng.random_range(-2.0..2.0) * (1.0 + i as f64)).collect();
            let mut mine = [0.0; 3];
            net.forward(&input, &mut mine);
            let theirs = candle_forward(&net, &input);
            for o in 0..3 {
                assert!((mine[o] - theirs[o]).abs() <= 1e-12, "{o}: {} vs {}", mine[o], theirs[o]);
            }
        }
    }

    #[test]
    fn export_normalises_exactly_and_matches_the_training_forward_pass() {
        let dev = Device::Cpu;
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut mlp = SnMlp::new(&[18, 64, 64, 3], 2.0, &mut rng, &dev).unwrap();
        // Converge the running power iteration, as training does over its steps.
        let mut ws = Vec::new();
        for _ in 0..300 {
            ws = mlp.weights().unwrap();
        }
        let net = mlp.export(vec![1.0; 18], vec![1.0; 3], serde_json::json!({})).unwrap();
        for l in net.layers() {
            let sn = spectral_norm(&l.w, l.n_out, l.n_in);
            assert!((sn - 2.0).abs() < 1e-9, "‖W‖₂ = {sn}");
        }
        let z: Vec<f32> = (0..18).map(|i| ((i as f32) * 0.3).sin()).collect();
        let zt = Tensor::from_vec(z.clone(), (1, 18), &dev).unwrap();
        let y: Vec<f32> = mlp.forward(&ws, &zt).unwrap().flatten_all().unwrap().to_vec1().unwrap();
        let mut out = [0.0; 3];
        net.forward(&z.iter().map(|x| f64::from(*x)).collect::<Vec<_>>(), &mut out);
        for o in 0..3 {
            assert!((f64::from(y[o]) - out[o]).abs() < 1e-5, "{o}: f32 training {} vs f64 export {}", y[o], out[o]);
        }
    }
}
