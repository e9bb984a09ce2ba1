//! Fully connected feedforward network of the Lyapunov-based DNN (Lb-DNN), with its analytic
//! Jacobian with respect to the weights (Sec. 2.2, eqs. (2)–(3)).
//!
//! Layer sizes L₀ (input), L₁ … L_k (hidden), L_{k+1} (output). With a_0 = κ and
//! a_j = swish(φ_{j−1}) for the hidden layers,
//!
//!   φ_j = V_{j+1}ᵀ [a_j; 1],   V_{j+1} ∈ R^{(L_j + 1) × L_{j+1}},   j = 0 … k,
//!   Φ(κ, θ) = tanh(φ_k)   (elementwise; the paper's Sec. 6 puts tanh on the output layer),
//!
//! where the last row of each V_{j+1} holds the bias terms (augmented input [a_j; 1]) and
//! swish(x) = x·σ(x). The weight vector is θ = [vec(V_1); …; vec(V_{k+1})] with vec stacking
//! columns, so V_j[r][c] sits at θ[offset_j + c·(L_{j−1} + 1) + r] (see [`LbDnn::theta_index`]);
//! p = Σ_j (L_j + 1)·L_{j+1}.
//!
//! ∇_θΦ (eq. (3)) is built by one backward sweep: with M_j = ∂Φ/∂φ_j ∈ R^{L_{k+1} × L_{j+1}},
//! M_k = diag(tanh′(φ_k)), the block of V_{j+1} is ∂Φ_o/∂V_{j+1}[r][c] = M_j[o][c]·[a_j; 1][r]
//! (the rows of I ⊗ ϱ_j), and M_{j−1}[o][i] = swish′(φ_{j−1}[i])·Σ_c M_j[o][c]·V_{j+1}[i][c]
//! (the bias row does not propagate).
//!
//! Inputs are used raw, so pre-activations can be ~1e4 or more: σ, swish′ and tanh′ are all
//! evaluated from e^{−|x|} (never e^{+|x|}), so they stay finite for any finite argument.
//!
//! All buffers are allocated in [`LbDnn::new`]; [`LbDnn::forward`] and
//! [`LbDnn::forward_jacobian`] allocate nothing.

use rand_distr::StandardNormal;

/// A fully connected Lb-DNN of fixed shape plus the scratch buffers for evaluating it.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct LbDnn {
    /// L₀ … L_{k+1}.
    sizes: Vec<usize>,
    /// Start of vec(V_{m+1}) in θ for m = 0 … k, then p.
    w_off: Vec<usize>,
    /// Start of the augmented layer input [a_m; 1] in `act` for m = 0 … k.
    act_off: Vec<usize>,
    /// Augmented inputs of every weight matrix: [κ; 1], [swish(φ_0); 1], …
    act: Vec<f64>,
    /// Start of the activation derivatives of φ_m in `dact` for m = 0 … k.
    dact_off: Vec<usize>,
    /// swish′(φ_m) for the hidden layers, tanh′(φ_k) for the output layer.
    dact: Vec<f64>,
    /// Back-propagation scratch, each L_{k+1} × max_j L_{j+1}, row-major.
    back_cur: Vec<f64>,
    back_prev: Vec<f64>,
}

impl LbDnn {
    /// A network with layer sizes `layers` = [L₀, L₁, …, L_k, L_{k+1}] (input, hidden…, output),
    /// e.g. `&[6, 4, 4, 4, 4, 3]` for the paper's Sec. 6 (p = 103). Zero hidden layers (two
    /// sizes) is allowed and gives Φ = tanh(V_1ᵀ [κ; 1]).
    ///
    /// # Panics
    /// If fewer than two sizes are given or any size is zero.
    pub fn new(layers: &[usize]) -> Self {
        assert!(layers.len() >= 2, "LbDnn needs at least an input and an output size, got {layers:?}");
        assert!(layers.iter().all(|&l| l > 0), "LbDnn layer sizes must be positive, got {layers:?}");
        let n_mats = layers.len() - 1;
        let mut w_off = Vec::with_capacity(n_mats + 1);
        let mut act_off = Vec::with_capacity(n_mats);
        let mut dact_off = Vec::with_capacity(n_mats);
        let (mut p, mut n_act, mut n_dact) = (0, 0, 0);
        for m in 0..n_mats {
            w_off.push(p);
            act_off.push(n_act);
            dact_off.push(n_dact);
            p += (layers[m] + 1) * layers[m + 1];
            n_act += layers[m] + 1;
            n_dact += layers[m + 1];
        }
        w_off.push(p);
        let n_out = layers[n_mats];
        let max_width = layers[1..].iter().copied().max().unwrap_or(0);
        Self {
            sizes: layers.to_vec(),
            w_off,
            act_off,
            act: vec![0.0; n_act],
            dact_off,
            dact: vec![0.0; n_dact],
            back_cur: vec![0.0; n_out * max_width],
            back_prev: vec![0.0; n_out * max_width],
        }
    }

    /// p, the number of weights (biases included).
    pub fn n_weights(&self) -> usize {
        self.w_off[self.w_off.len() - 1]
    }

    /// L₀, the input size.
    pub fn n_inputs(&self) -> usize {
        self.sizes[0]
    }

    /// L_{k+1}, the output size.
    pub fn n_outputs(&self) -> usize {
        self.sizes[self.sizes.len() - 1]
    }

    /// [L₀, …, L_{k+1}] as given to [`LbDnn::new`].
    pub fn layer_sizes(&self) -> &[usize] {
        &self.sizes
    }

    /// Index in θ of V_{m+1}[r][c] (so `m = 0` is V_1, the input layer's matrix); r = L_m is the
    /// bias row.
    ///
    /// # Panics
    /// If `m`, `r` or `c` is out of range.
    pub fn theta_index(&self, m: usize, r: usize, c: usize) -> usize {
        assert!(m + 1 < self.sizes.len() && r <= self.sizes[m] && c < self.sizes[m + 1], "no V_{}[{r}][{c}]", m + 1);
        self.w_off[m] + c * (self.sizes[m] + 1) + r
    }

    /// Φ(κ, θ) into `out` (length L_{k+1}).
    ///
    /// # Panics
    /// If `kappa`, `theta` or `out` has the wrong length.
    pub fn forward(&mut self, kappa: &[f64], theta: &[f64], out: &mut [f64]) {
        self.run_forward::<false>(kappa, theta, out);
    }

    /// Φ(κ, θ) into `out` and ∇_θΦ(κ, θ) into `jac`, row-major L_{k+1} × p
    /// (`jac[o * p + i] = ∂Φ_o/∂θ_i`); every entry of `jac` is written. `out` is bit-for-bit
    /// what [`LbDnn::forward`] gives.
    ///
    /// # Panics
    /// If `kappa`, `theta`, `out` or `jac` has the wrong length.
    pub fn forward_jacobian(&mut self, kappa: &[f64], theta: &[f64], out: &mut [f64], jac: &mut [f64]) {
        let p = self.n_weights();
        let n_out = self.n_outputs();
        assert_eq!(jac.len(), n_out * p, "LbDnn: jacobian length must be n_outputs * n_weights");
        self.run_forward::<true>(kappa, theta, out);

        let n_mats = self.sizes.len() - 1;
        // M_k = diag(tanh′(φ_k)).
        let d_out = &self.dact[self.dact_off[n_mats - 1]..][..n_out];
        for o in 0..n_out {
            let row = &mut self.back_cur[o * n_out..][..n_out];
            row.fill(0.0);
            row[o] = d_out[o];
        }
        for m in (0..n_mats).rev() {
            let rows = self.sizes[m] + 1;
            let cols = self.sizes[m + 1];
            let w = &theta[self.w_off[m]..self.w_off[m + 1]];
            let a = &self.act[self.act_off[m]..][..rows];
            // Block of V_{m+1}: ∂Φ_o/∂V[r][c] = M[o][c]·a[r].
            for o in 0..n_out {
                let mrow = &self.back_cur[o * cols..][..cols];
                let jrow = &mut jac[o * p + self.w_off[m]..o * p + self.w_off[m + 1]];
                for (jcol, &g) in jrow.chunks_exact_mut(rows).zip(mrow) {
                    for (jv, &av) in jcol.iter_mut().zip(a) {
                        *jv = g * av;
                    }
                }
            }
            if m == 0 {
                break;
            }
            // M_{m−1}[o][i] = swish′(φ_{m−1}[i])·Σ_c M_m[o][c]·V[i][c], i < L_m.
            let width = self.sizes[m];
            let d = &self.dact[self.dact_off[m - 1]..][..width];
            for o in 0..n_out {
                let mrow = &self.back_cur[o * cols..][..cols];
                let prow = &mut self.back_prev[o * width..][..width];
                // Accumulate in a register (a column-wise `+=` into `prow` stalls on
                // store-to-load forwarding).
                for (i, (pv, &dv)) in prow.iter_mut().zip(d).enumerate() {
                    *pv = dv * w.chunks_exact(rows).zip(mrow).fold(0.0, |s, (wcol, &g)| s + g * wcol[i]);
                }
            }
            std::mem::swap(&mut self.back_cur, &mut self.back_prev);
        }
    }

    /// Kaiming-He initial weights: every weight of V_j ~ N(0, 2/L_{j−1}) (fan-in = the layer's
    /// inputs, bias excluded), bias rows zero. Normals are drawn in θ order, one per weight and
    /// none for biases, so the result depends only on the shape and the RNG state.
    pub fn kaiming_he<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> Vec<f64> {
        let mut theta = vec![0.0; self.n_weights()];
        for m in 0..self.sizes.len() - 1 {
            let rows = self.sizes[m] + 1;
            let std = (2.0 / self.sizes[m] as f64).sqrt();
            for col in theta[self.w_off[m]..self.w_off[m + 1]].chunks_exact_mut(rows) {
                for v in &mut col[..rows - 1] {
                    let z: f64 = rng.sample(StandardNormal);
                    *v = std * z;
                }
            }
        }
        theta
    }

    /// The shared forward pass; with `DERIV` it also stores the activation derivatives. The
    /// arithmetic producing `out` is identical in both instantiations.
    fn run_forward<const DERIV: bool>(&mut self, kappa: &[f64], theta: &[f64], out: &mut [f64]) {
        assert_eq!(kappa.len(), self.n_inputs(), "LbDnn: input length");
        assert_eq!(theta.len(), self.n_weights(), "LbDnn: weight vector length");
        assert_eq!(out.len(), self.n_outputs(), "LbDnn: output length");
        let n_mats = self.sizes.len() - 1;
        self.act[..kappa.len()].copy_from_slice(kappa);
        self.act[kappa.len()] = 1.0;
        for m in 0..n_mats {
            let rows = self.sizes[m] + 1;
            let cols = self.sizes[m + 1];
            let w = &theta[self.w_off[m]..self.w_off[m + 1]];
            let (lower, upper) = self.act.split_at_mut(self.act_off[m] + rows);
            let a = &lower[self.act_off[m]..];
            let d = &mut self.dact[self.dact_off[m]..][..cols];
            if m + 1 < n_mats {
                let next = &mut upper[..cols + 1];
                for ((nv, dv), wcol) in next.iter_mut().zip(d.iter_mut()).zip(w.chunks_exact(rows)) {
                    let z = dot(wcol, a);
                    let (s, ds) = swish(z);
                    *nv = s;
                    if DERIV {
                        *dv = ds;
                    }
                }
                next[cols] = 1.0;
            } else {
                for ((ov, dv), wcol) in out.iter_mut().zip(d.iter_mut()).zip(w.chunks_exact(rows)) {
                    let z = dot(wcol, a);
                    *ov = z.tanh();
                    if DERIV {
                        *dv = sech2(z);
                    }
                }
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0, |s, (x, y)| s + x * y)
}

/// e^{−a} for a ≥ 0. Beyond 746 the result is exactly 0.0 anyway; returning it directly skips
/// libm's underflow/errno path, which otherwise dominates the cost at κ ~ 1e4.
#[inline]
fn decaying_exp(a: f64) -> f64 {
    if a < 746.0 { (-a).exp() } else { 0.0 }
}

/// (swish(x), swish′(x)) with swish(x) = x·σ(x), swish′(x) = σ(x) + x·σ(x)·(1 − σ(x)).
/// σ and 1 − σ both come from e^{−|x|} ∈ (0, 1], so nothing overflows and 1 − σ keeps its
/// relative accuracy for large positive x.
#[inline]
fn swish(x: f64) -> (f64, f64) {
    let e = decaying_exp(x.abs());
    let inv = 1.0 / (1.0 + e);
    let (sig, sig_c) = if x >= 0.0 { (inv, e * inv) } else { (e * inv, inv) };
    (x * sig, sig + x * sig * sig_c)
}

/// tanh′(x) = sech²(x) = 4e/(1 + e)² with e = e^{−2|x|}: accurate in the tails (where 1 − tanh²
/// cancels to 0 long before sech² underflows) and never overflows.
#[inline]
fn sech2(x: f64) -> f64 {
    let e = decaying_exp(2.0 * x.abs());
    let d = 1.0 + e;
    4.0 * e / (d * d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const PAPER: [usize; 6] = [6, 4, 4, 4, 4, 3];

    fn eval(net: &mut LbDnn, kappa: &[f64], theta: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; net.n_outputs()];
        net.forward(kappa, theta, &mut out);
        out
    }

    fn jacobian(net: &mut LbDnn, kappa: &[f64], theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let mut out = vec![0.0; net.n_outputs()];
        let mut jac = vec![f64::NAN; net.n_outputs() * net.n_weights()];
        net.forward_jacobian(kappa, theta, &mut out, &mut jac);
        (out, jac)
    }

    /// Central differences with steps `h[i]`, dividing by the step actually taken (θ ± h is
    /// rounded). With `richardson`, (4·D(h) − D(2h))/3, whose truncation error is O(h⁴).
    fn fd_jacobian(net: &mut LbDnn, kappa: &[f64], theta: &[f64], h: &[f64], richardson: bool) -> Vec<f64> {
        let (p, n_out) = (net.n_weights(), net.n_outputs());
        let mut jac = vec![0.0; n_out * p];
        let mut t = theta.to_vec();
        let mut quotient = |t: &mut Vec<f64>, i: usize, h: f64| {
            t[i] = theta[i] + h;
            let plus = eval(net, kappa, t);
            t[i] = theta[i] - h;
            let minus = eval(net, kappa, t);
            t[i] = theta[i];
            let dh = (theta[i] + h) - (theta[i] - h);
            plus.iter().zip(&minus).map(|(a, b)| (a - b) / dh).collect::<Vec<_>>()
        };
        for i in 0..p {
            let d1 = quotient(&mut t, i, h[i]);
            let d = if richardson {
                let d2 = quotient(&mut t, i, 2.0 * h[i]);
                d1.iter().zip(&d2).map(|(a, b)| (4.0 * a - b) / 3.0).collect()
            } else {
                d1
            };
            for o in 0..n_out {
                jac[o * p + i] = d[o];
            }
        }
        jac
    }

    /// Roundoff floor of a difference quotient, in units of Φ: Φ itself carries a few ε of
    /// absolute error (|Φ| ≤ 1), so a quotient with step h cannot resolve below ~η/h.
    const ETA: f64 = 1e-15;

    /// FD criterion, per entry: |J − J_fd| ≤ 1e-6·|J| + η/h. Tracks the worst ratio of error to
    /// that bound (must be ≤ 1), the worst absolute error, and the worst relative error over the
    /// entries with |J| ≥ 1e-3.
    #[derive(Default)]
    struct FdStats {
        ratio: f64,
        abs: f64,
        rel_large: f64,
    }

    impl FdStats {
        fn add(&mut self, jac: &[f64], fd: &[f64], h: &[f64]) {
            let p = h.len();
            for (k, (&j, &f)) in jac.iter().zip(fd).enumerate() {
                let e = (j - f).abs();
                self.ratio = self.ratio.max(e / (1e-6 * j.abs() + ETA / h[k % p]));
                self.abs = self.abs.max(e);
                if j.abs() >= 1e-3 {
                    self.rel_large = self.rel_large.max(e / j.abs());
                }
            }
        }
    }

    /// Which input of its layer θ_i multiplies: (matrix m, row r).
    fn theta_row(net: &LbDnn, i: usize) -> (usize, usize) {
        let m = (0..net.sizes.len() - 1).find(|&m| i < net.w_off[m + 1]).unwrap();
        (m, (i - net.w_off[m]) % (net.sizes[m] + 1))
    }

    /// max_i |J_i − R_i| / max(|J_i|, floor).
    fn rel_error(jac: &[f64], reference: &[f64], floor: f64) -> f64 {
        jac.iter().zip(reference).fold(0.0, |m, (j, r)| m.max((j - r).abs() / j.abs().max(floor)))
    }

    #[test]
    fn weight_count() {
        assert_eq!(LbDnn::new(&PAPER).n_weights(), 103);
        assert_eq!(LbDnn::new(&[2, 3, 1]).n_weights(), 3 * 3 + 4);
        assert_eq!(LbDnn::new(&[5, 2]).n_weights(), 6 * 2);
        assert_eq!(LbDnn::new(&[3, 7, 2, 4]).n_weights(), 4 * 7 + 8 * 2 + 3 * 4);
        let net = LbDnn::new(&PAPER);
        assert_eq!((net.n_inputs(), net.n_outputs()), (6, 3));
        assert_eq!(net.theta_index(0, 0, 0), 0);
        assert_eq!(net.theta_index(0, 6, 0), 6);
        assert_eq!(net.theta_index(0, 0, 1), 7);
        assert_eq!(net.theta_index(1, 0, 0), 28);
        assert_eq!(net.theta_index(4, 4, 2), 102);
    }

    #[test]
    #[should_panic]
    fn rejects_zero_width() {
        LbDnn::new(&[3, 0, 2]);
    }

    /// [1, 1, 1]: Φ = tanh(w₂·swish(w₁κ + b₁) + b₂), θ = [w₁, b₁, w₂, b₂].
    #[test]
    fn hand_computed_scalar_network() {
        let mut net = LbDnn::new(&[1, 1, 1]);
        // z₁ = 0.5·2 − 1 = 0: swish(0) = 0, swish′(0) = ½; z₂ = 0.25.
        let theta = [0.5, -1.0, 3.0, 0.25];
        let (out, jac) = jacobian(&mut net, &[2.0], &theta);
        let sech2_025 = 1.0 / 0.25f64.cosh().powi(2);
        assert!((out[0] - 0.25f64.tanh()).abs() < 1e-15);
        let want = [sech2_025 * 3.0 * 0.5 * 2.0, sech2_025 * 3.0 * 0.5, 0.0, sech2_025];
        for (j, w) in jac.iter().zip(want) {
            assert!((j - w).abs() < 1e-15, "{jac:?} vs {want:?}");
        }

        // z₁ = 1.5·(−0.8) + 0.3 = −0.9, independent formulae.
        let theta = [1.5, 0.3, -0.7, 0.1];
        let kappa = -0.8;
        let z1: f64 = 1.5 * kappa + 0.3;
        let sig = 1.0 / (1.0 + (-z1).exp());
        let h = z1 * sig;
        let dh = sig * (1.0 + z1 * (1.0 - sig));
        let z2 = -0.7 * h + 0.1;
        let t = z2.tanh();
        let dt = 1.0 - t * t;
        let (out, jac) = jacobian(&mut net, &[kappa], &theta);
        assert!((out[0] - t).abs() < 1e-15);
        let want = [dt * -0.7 * dh * kappa, dt * -0.7 * dh, dt * h, dt];
        for (j, w) in jac.iter().zip(want) {
            assert!((j - w).abs() < 1e-14, "{jac:?} vs {want:?}");
        }
    }

    /// [2, 2, 1] written out with explicit V[r][c] indexing: checks the column-major θ layout.
    #[test]
    fn hand_computed_layout() {
        let mut net = LbDnn::new(&[2, 2, 1]);
        // V1 (3×2) and V2 (3×1), row r = 2 is the bias.
        let v1 = [[0.4, -0.3], [0.2, 0.9], [-0.1, 0.05]];
        let v2 = [[1.1], [-0.6], [0.2]];
        let mut theta = vec![0.0; 9];
        for (r, row) in v1.iter().enumerate() {
            for (c, &v) in row.iter().enumerate() {
                theta[c * 3 + r] = v;
            }
        }
        for (r, row) in v2.iter().enumerate() {
            theta[6 + r] = row[0];
        }
        let kappa = [0.7, -1.3];
        let ka = [kappa[0], kappa[1], 1.0];
        let swish_d = |z: f64| {
            let s = 1.0 / (1.0 + (-z).exp());
            (z * s, s + z * s * (1.0 - s))
        };
        let mut a1 = [0.0, 0.0, 1.0];
        let mut d1 = [0.0; 2];
        for c in 0..2 {
            let z: f64 = (0..3).map(|r| v1[r][c] * ka[r]).sum();
            (a1[c], d1[c]) = swish_d(z);
        }
        let z2: f64 = (0..3).map(|r| v2[r][0] * a1[r]).sum();
        let t = z2.tanh();
        let dt = 1.0 - t * t;
        let mut want = [0.0; 9];
        for c in 0..2 {
            for r in 0..3 {
                want[c * 3 + r] = dt * v2[c][0] * d1[c] * ka[r];
            }
        }
        for r in 0..3 {
            want[6 + r] = dt * a1[r];
        }
        let (out, jac) = jacobian(&mut net, &kappa, &theta);
        assert!((out[0] - t).abs() < 1e-15);
        for (j, w) in jac.iter().zip(want) {
            assert!((j - w).abs() < 1e-14, "{jac:?} vs {want:?}");
        }
    }

    fn random_theta(net: &LbDnn, rng: &mut ChaCha8Rng) -> Vec<f64> {
        let mut theta = net.kaiming_he(rng);
        for v in &mut theta {
            *v += 0.3 * (rng.random::<f64>() - 0.5);
        }
        theta
    }

    /// Central differences, h = 1e-6·max(1, |θ_i|), criterion of [`FdStats`]: the η/h = 1e-9
    /// term is ~10× the roundoff of the quotient (ε/h ≈ 1e-10), so entries above ~1e-3 are held
    /// to a pure 1e-6 relative error.
    #[test]
    fn jacobian_matches_finite_differences() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut stats = FdStats::default();
        for shape in [&PAPER[..], &[2, 3, 1], &[3, 5, 2, 4], &[4, 2], &[1, 8, 8, 8, 2]] {
            let mut net = LbDnn::new(shape);
            for _ in 0..20 {
                let theta = random_theta(&net, &mut rng);
                let kappa: Vec<f64> = (0..net.n_inputs()).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
                let (out, jac) = jacobian(&mut net, &kappa, &theta);
                assert_eq!(out, eval(&mut net, &kappa, &theta));
                let h: Vec<f64> = theta.iter().map(|t| 1e-6 * t.abs().max(1.0)).collect();
                let fd = fd_jacobian(&mut net, &kappa, &theta, &h, false);
                stats.add(&jac, &fd, &h);
                assert!(stats.ratio <= 1.0, "shape {shape:?}: error/bound {:.2}", stats.ratio);
            }
        }
        println!(
            "FD (|κ| ≤ 1): max error/bound {:.2}, max abs error {:.2e}, max rel error (|J| ≥ 1e-3) {:.2e}",
            stats.ratio, stats.abs, stats.rel_large
        );
    }

    /// Minimal complex numbers for the complex-step reference derivative.
    #[derive(Clone, Copy, Debug)]
    struct C(f64, f64);
    impl C {
        fn add(self, o: C) -> C {
            C(self.0 + o.0, self.1 + o.1)
        }
        fn mul(self, o: C) -> C {
            C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
        }
        fn div(self, o: C) -> C {
            let d = o.0 * o.0 + o.1 * o.1;
            C((self.0 * o.0 + self.1 * o.1) / d, (self.1 * o.0 - self.0 * o.1) / d)
        }
        fn exp(self) -> C {
            let m = self.0.exp();
            C(m * self.1.cos(), m * self.1.sin())
        }
        fn neg(self) -> C {
            C(-self.0, -self.1)
        }
    }
    const ONE: C = C(1.0, 0.0);

    /// Complex forward pass with only the (analytic) activations, no derivative formulae:
    /// swish(z) = z·σ(z), tanh(z) = (1 − e^{−2z})/(1 + e^{−2z}), each evaluated from the decaying
    /// exponential so huge real parts stay finite.
    fn forward_complex(sizes: &[usize], kappa: &[f64], theta: &[C]) -> Vec<C> {
        let mut a: Vec<C> = kappa.iter().map(|&k| C(k, 0.0)).collect();
        let mut off = 0;
        for m in 0..sizes.len() - 1 {
            let rows = sizes[m] + 1;
            a.push(ONE);
            let last = m + 2 == sizes.len();
            a = (0..sizes[m + 1])
                .map(|c| {
                    let z = (0..rows).fold(C(0.0, 0.0), |s, r| s.add(theta[off + c * rows + r].mul(a[r])));
                    if last {
                        let (w, flip) = if z.0 >= 0.0 { (z, false) } else { (z.neg(), true) };
                        let e = C(-2.0 * w.0, -2.0 * w.1).exp();
                        let t = ONE.add(e.neg()).div(ONE.add(e));
                        if flip { t.neg() } else { t }
                    } else {
                        let sig = if z.0 >= 0.0 {
                            ONE.div(ONE.add(z.neg().exp()))
                        } else {
                            let e = z.exp();
                            e.div(ONE.add(e))
                        };
                        z.mul(sig)
                    }
                })
                .collect();
            off += rows * sizes[m + 1];
        }
        a
    }

    /// ∂Φ/∂θ_i = Im Φ(θ + i·h·e_i)/h: no subtractive cancellation, so it is accurate to roundoff
    /// even where the forward pass cancels large terms.
    fn complex_step_jacobian(net: &LbDnn, kappa: &[f64], theta: &[f64]) -> Vec<f64> {
        let (p, n_out) = (net.n_weights(), net.n_outputs());
        let mut jac = vec![0.0; n_out * p];
        let mut t: Vec<C> = theta.iter().map(|&v| C(v, 0.0)).collect();
        for i in 0..p {
            let h = 1e-30 * theta[i].abs().max(1.0);
            t[i].1 = h;
            let out = forward_complex(&net.sizes, kappa, &t);
            t[i].1 = 0.0;
            for o in 0..n_out {
                jac[o * p + i] = out[o].1 / h;
            }
        }
        jac
    }

    /// The complex-step reference agrees with the analytic Jacobian at moderate inputs (so it can
    /// serve as the reference where finite differences drown in roundoff).
    #[test]
    fn complex_step_reference_agrees_at_moderate_inputs() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let mut net = LbDnn::new(&PAPER);
        for _ in 0..20 {
            let theta = random_theta(&net, &mut rng);
            let kappa: Vec<f64> = (0..6).map(|_| 2.0 * rng.random::<f64>() - 1.0).collect();
            let (out, jac) = jacobian(&mut net, &kappa, &theta);
            let cs_out = forward_complex(&net.sizes, &kappa, &theta.iter().map(|&v| C(v, 0.0)).collect::<Vec<_>>());
            for (o, c) in out.iter().zip(&cs_out) {
                assert!((o - c.0).abs() < 1e-14);
            }
            let rel = rel_error(&jac, &complex_step_jacobian(&net, &kappa, &theta), 1e-4);
            assert!(rel <= 1e-12, "relative error vs complex step {rel:e}");
        }
    }

    /// κ ~ 1e4 (raw inputs): first-layer pre-activations ~1e4, deep in both swish tails. Odd trials
    /// shrink the output layer so tanh is not saturated.
    ///
    /// Two references:
    /// * a complex-step derivative (no subtractive cancellation, independent of the analytic
    ///   derivative formulae): |J − J_cs| ≤ 1e-9·max(|J|, 1e-4·s), s = max |J| of that output row;
    /// * central differences with Richardson extrapolation, each step scaled down by the
    ///   magnitude of the input its weight multiplies (so the pre-activation moves by ~1e-4, not
    ///   ~1), checked with the [`FdStats`] criterion |J − J_fd| ≤ 1e-6·|J| + η/h. For first-layer
    ///   weights h ~ 1e-8, so the roundoff floor η/h ~ 1e-7 is what limits that comparison.
    #[test]
    fn huge_inputs_stay_finite_and_match() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut net = LbDnn::new(&PAPER);
        let p = net.n_weights();
        let mut worst_cs = 0.0f64;
        let mut stats = FdStats::default();
        let mut unsaturated = 0;
        for trial in 0..40 {
            let mut theta = random_theta(&net, &mut rng);
            let kappa: Vec<f64> = (0..6).map(|_| 1e4 * (2.0 * rng.random::<f64>() - 1.0)).collect();
            if trial % 2 == 1 {
                for v in &mut theta[net.w_off[4]..p] {
                    *v *= 1e-5;
                }
            }
            let (out, jac) = jacobian(&mut net, &kappa, &theta);
            assert!(out.iter().chain(&jac).all(|v| v.is_finite()), "non-finite output or jacobian");
            assert_eq!(out, eval(&mut net, &kappa, &theta));
            if out.iter().any(|o| o.abs() < 0.99) {
                unsaturated += 1;
            }
            let cs = complex_step_jacobian(&net, &kappa, &theta);
            for o in 0..3 {
                let row = o * p..(o + 1) * p;
                let s = jac[row.clone()].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let e = rel_error(&jac[row.clone()], &cs[row], (1e-4 * s).max(f64::MIN_POSITIVE));
                assert!(e <= 1e-9, "trial {trial}, output {o}: error vs complex step {e:e}");
                worst_cs = worst_cs.max(e);
            }
            let h: Vec<f64> = (0..p)
                .map(|i| {
                    let (m, r) = theta_row(&net, i);
                    1e-4 * theta[i].abs().max(1.0) / net.act[net.act_off[m] + r].abs().max(1.0)
                })
                .collect();
            let fd = fd_jacobian(&mut net, &kappa, &theta, &h, true);
            stats.add(&jac, &fd, &h);
            assert!(stats.ratio <= 1.0, "trial {trial}: error/bound vs FD {:.2}", stats.ratio);
        }
        assert!(unsaturated >= 10, "only {unsaturated} unsaturated trials");
        println!(
            "|κ| ~ 1e4 ({unsaturated}/40 unsaturated): max rel error vs complex step {worst_cs:.2e}; Richardson FD: \
             max error/bound {:.2}, max abs error {:.2e}, max rel error (|J| ≥ 1e-3) {:.2e}",
            stats.ratio, stats.abs, stats.rel_large
        );
    }

    #[test]
    fn activations_finite_in_the_tails() {
        for x in [-1e300, -1e4, -745.0, -710.0, -40.0, -1e-300, 0.0, 1e-300, 40.0, 710.0, 1e4, 1e300] {
            let (s, ds) = swish(x);
            let d2 = sech2(x);
            assert!(s.is_finite() && ds.is_finite() && d2.is_finite(), "x = {x}: {s} {ds} {d2}");
            assert!((-0.3..=1.1).contains(&ds), "swish′({x}) = {ds}");
        }
        for a in [0.0, 700.0, 708.5, 745.0, 745.1, 745.2, 745.9, 746.0, 800.0, 1e4] {
            assert_eq!(decaying_exp(a).to_bits(), (-a).exp().to_bits(), "e^-{a}");
        }
        assert_eq!(swish(1e4), (1e4, 1.0));
        assert_eq!(swish(-1e4).1, 0.0);
        assert_eq!(sech2(0.0), 1.0);
        // 1 − tanh² would be exactly 0 here.
        assert!((sech2(20.0) / (4.0 * (-40.0f64).exp()) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn forward_equals_forward_jacobian_bitwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut net = LbDnn::new(&PAPER);
        let mut other = LbDnn::new(&PAPER);
        for i in 0..200 {
            let theta = random_theta(&net, &mut rng);
            let scale = if i % 2 == 0 { 1.0 } else { 1e4 };
            let kappa: Vec<f64> = (0..6).map(|_| scale * (2.0 * rng.random::<f64>() - 1.0)).collect();
            let (out_j, _) = jacobian(&mut net, &kappa, &theta);
            let out_f = eval(&mut other, &kappa, &theta);
            assert_eq!(
                out_j.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                out_f.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
        }
    }

    #[test]
    fn kaiming_he_init() {
        let net = LbDnn::new(&PAPER);
        let a = net.kaiming_he(&mut ChaCha8Rng::seed_from_u64(42));
        let b = net.kaiming_he(&mut ChaCha8Rng::seed_from_u64(42));
        let c = net.kaiming_he(&mut ChaCha8Rng::seed_from_u64(43));
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_eq!(a.len(), 103);
        for m in 0..5 {
            for col in 0..PAPER[m + 1] {
                assert_eq!(a[net.theta_index(m, PAPER[m], col)], 0.0);
                assert_ne!(a[net.theta_index(m, 0, col)], 0.0);
            }
        }

        // Exactly std·z in θ order, one standard normal per weight, none for biases.
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        for m in 0..5 {
            let std = (2.0 / PAPER[m] as f64).sqrt();
            for c in 0..PAPER[m + 1] {
                for r in 0..PAPER[m] {
                    let z: f64 = rng.sample(StandardNormal);
                    assert_eq!(a[net.theta_index(m, r, c)], std * z);
                }
            }
        }

        // Wide layers: 200 inputs → 100 (20 000 weights, var 2/200) and 100 → 50 (var 2/100).
        let wide = LbDnn::new(&[200, 100, 50]);
        let theta = wide.kaiming_he(&mut ChaCha8Rng::seed_from_u64(5));
        for (m, fan_in) in [(0, 200), (1, 100)] {
            let mut w = Vec::new();
            for c in 0..wide.sizes[m + 1] {
                for r in 0..fan_in {
                    w.push(theta[wide.theta_index(m, r, c)]);
                }
                assert_eq!(theta[wide.theta_index(m, fan_in, c)], 0.0);
            }
            let n = w.len() as f64;
            let mean = w.iter().sum::<f64>() / n;
            let var = w.iter().map(|v| v * v).sum::<f64>() / n;
            let want = 2.0 / fan_in as f64;
            // Sample variance of n normals: relative sd √(2/n) (1 % for n = 20 000); allow 5 sd.
            assert!((var / want - 1.0).abs() < 5.0 * (2.0 / n).sqrt(), "layer {m}: var {var} vs {want}");
            assert!(mean.abs() < 5.0 * (want / n).sqrt(), "layer {m}: mean {mean}");
        }
    }

    #[test]
    #[ignore]
    fn bench_forward_jacobian() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut net = LbDnn::new(&PAPER);
        let theta = net.kaiming_he(&mut rng);
        let mut out = [0.0; 3];
        let mut jac = vec![0.0; 3 * 103];
        let n = 2_000_000;
        let mut acc = 0.0;
        for (label, big) in [("|κ|~1", 1.0), ("|κ|~1e4", 1e4)] {
            let inputs: Vec<[f64; 6]> =
                (0..256).map(|_| std::array::from_fn(|_| big * (2.0 * rng.random::<f64>() - 1.0))).collect();
            let start = std::time::Instant::now();
            for i in 0..n {
                let kappa = std::hint::black_box(&inputs[i % 256]);
                net.forward_jacobian(kappa, std::hint::black_box(&theta), &mut out, &mut jac);
                acc += jac[i % 309];
            }
            let per_jac = start.elapsed().as_nanos() as f64 / n as f64;
            let start = std::time::Instant::now();
            for i in 0..n {
                let kappa = std::hint::black_box(&inputs[i % 256]);
                net.forward(kappa, std::hint::black_box(&theta), &mut out);
                acc += out[i % 3];
            }
            let per_fwd = start.elapsed().as_nanos() as f64 / n as f64;
            println!("[6,4,4,4,4,3] {label}: forward_jacobian {per_jac:.0} ns/call, forward {per_fwd:.0} ns/call");
        }
        std::hint::black_box(acc);
    }
}
