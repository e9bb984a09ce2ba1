//! Seed 000 (Nino et al.): one servicer's ρ-filter velocity observer (24)–(26), Lb-DNN controller
//! (27) and distributed adaptation (28), as a pure `Algorithm`.
//!
//! Read as papers/fig1/README.md sets out:
//! - ηᵢ = Σⱼ dᵢⱼ + bᵢ Cᵢᵀ yᵢ (12), from this agent's own (noisy) readings.
//! - Observer state: the estimate η̂ᵢ with dη̂ᵢ/dt = ζ̂ᵢ, η̃ᵢ = ηᵢ − η̂ᵢ; ρᵢ from (25) with the two
//!   integrator states ∫η̃ᵢ and ∫ρᵢ (both starting at 0).
//! - dζ̂ᵢ/dt = Σⱼ (gⱼuⱼ − gᵢuᵢ) − bᵢ CᵢᵀCᵢ gᵢuᵢ − (k₃² − 2) η̃ᵢ − (2k₃ + k₄ + k₅) ρᵢ (26): the
//!   neighbours' gⱼuⱼ come from their shares.
//! - uᵢ = Φᵢ(κᵢ, θ̂ᵢ) + k₂ (k₁ηᵢ + ζ̂ᵢ − k₃η̃ᵢ − ρᵢ) (27) with g = I₃ and κᵢ = [ηᵢ; ζ̂ᵢ].
//! - dθ̂ᵢ/dt = proj(Γ(∇θΦᵀ(ζ̂ᵢ + k₁ηᵢ) − k₆((1 + |Nᵢ|)θ̂ᵢ − Σⱼθ̂ⱼ))) (28), with the smooth projection
//!   on the ball ‖θ‖ ≤ θ̄ (Krstić–Kanellakopoulos–Kokotović, App. E): it starts to act at
//!   (1 − band)·θ̄ and removes the whole outward component at θ̄.
//!
//! Discrete-time: every internal state advances with one RK4 step per lockstep step, ηᵢ, uᵢ and
//! the neighbours' shares held. Early on κ ~ 1e4 m and the adaptation is stiff enough that one
//! fixed step can leave the ball although the continuous projection never would, so after each
//! step θ̂ᵢ is clipped radially back to ‖θ̂ᵢ‖ ≤ θ̄ (counted in `projection_clips`).
//!
//! When a neighbour disappears (issue 7) its terms are left out of the sums and |Nᵢ| counts the
//! neighbours actually heard this step; once it is off the roster, its relative measurement dᵢⱼ
//! is left out of ηᵢ too (12), so the survivors run the same law on the live graph. A neighbour
//! whose share is only late or lost keeps its dᵢⱼ, and its last valid share stands in.

use crate::config::{LbDnnServicing as Gains, ObserverInit};
use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};
use rand_chacha::ChaCha8Rng;

use crate::lbdnn_network::LbDnn;

type V3 = [f64; 3];

/// Offsets in the state vector x = [η̂, ζ̂, ∫η̃, ∫ρ, θ̂].
const ETA_HAT: usize = 0;
const ZETA_HAT: usize = 3;
const INT_ETA_TILDE: usize = 6;
const INT_RHO: usize = 9;
const THETA: usize = 12;

#[derive(serde::Serialize, serde::Deserialize)]
pub struct LbDnnServicing {
    #[serde(with = "cohort_runtime::checkpoint::as_json")]
    g: Gains,
    /// Cᵢ rows and bᵢ.
    c: Vec<V3>,
    b: bool,
    neighbours: Vec<u32>,
    /// Per neighbour: on the roster (a dead one's relative measurement is left out of ηᵢ).
    live: Vec<bool>,
    net: LbDnn,
    p: usize,
    /// Internal state x (12 + p).
    x: Vec<f64>,
    /// Held over the step: ηᵢ, the command uᵢ, Σⱼ gⱼuⱼ, Σⱼ θ̂ⱼ, |Nᵢ| heard.
    eta: V3,
    u: V3,
    phi: V3,
    sum_gu: V3,
    sum_theta: Vec<f64>,
    n_heard: usize,
    started: bool,
    /// How often the radial clip after a step was needed.
    pub projection_clips: u64,
    // Scratch (no allocation per step).
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
    jac: Vec<f64>,
}

fn add(a: &V3, b: &V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(s: f64, a: &V3) -> V3 {
    [s * a[0], s * a[1], s * a[2]]
}
fn dot(a: &V3, b: &V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn v3(x: &[f64]) -> V3 {
    [x[0], x[1], x[2]]
}

impl LbDnnServicing {
    pub fn new(g: Gains, output_matrix: Vec<V3>, b: bool, neighbours: Vec<u32>, rng: &mut ChaCha8Rng) -> Self {
        let net = LbDnn::new(&g.layers());
        let p = net.n_weights();
        let mut x = vec![0.0; THETA + p];
        // Kaiming-He initial weights, seeded per agent (Sec. 6).
        x[THETA..].copy_from_slice(&net.kaiming_he(rng));
        let n = x.len();
        Self {
            g,
            c: output_matrix,
            b,
            live: vec![true; neighbours.len()],
            neighbours,
            net,
            p,
            x,
            eta: [0.0; 3],
            u: [0.0; 3],
            phi: [0.0; 3],
            sum_gu: [0.0; 3],
            sum_theta: vec![0.0; p],
            n_heard: 0,
            started: false,
            projection_clips: 0,
            k: [vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            tmp: vec![0.0; n],
            jac: vec![0.0; 3 * p],
        }
    }

    pub fn theta(&self) -> &[f64] {
        &self.x[THETA..]
    }
    pub fn state(&self) -> &[f64] {
        &self.x
    }

    /// ηᵢ = Σⱼ dᵢⱼ + bᵢ Cᵢᵀ yᵢ from the readings [yᵢ (mᵢ), dᵢⱼ (3 per neighbour)].
    fn eta_from(&self, readings: &[f64]) -> V3 {
        let m = self.c.len();
        let mut eta = [0.0; 3];
        for j in 0..self.neighbours.len() {
            if !self.live[j] {
                continue;
            }
            if let Some(d) = readings.get(m + 3 * j..m + 3 * j + 3) {
                eta = add(&eta, &v3(d));
            }
        }
        if self.b {
            for (row, y) in self.c.iter().zip(readings) {
                eta = add(&eta, &scale(*y, row));
            }
        }
        eta
    }

    /// ρᵢ (25) at state `x`.
    fn rho(&self, x: &[f64]) -> V3 {
        let (k3, k4, k5) = (self.g.k3, self.g.k4, self.g.k5);
        let mut r = [0.0; 3];
        for a in 0..3 {
            let et = self.eta[a] - x[ETA_HAT + a];
            r[a] = -(k3 + k4) * et + (1.0 - k3 * k3 - k3 * k4) * x[INT_ETA_TILDE + a] - (k3 + k4 + k5) * x[INT_RHO + a];
        }
        r
    }

    /// The command (27) at the current state, given ηᵢ.
    fn command(&mut self) -> V3 {
        let x = &self.x;
        let rho = self.rho(x);
        let kappa = [self.eta[0], self.eta[1], self.eta[2], x[ZETA_HAT], x[ZETA_HAT + 1], x[ZETA_HAT + 2]];
        let mut phi = [0.0; 3];
        self.net.forward(&kappa, &self.x[THETA..], &mut phi);
        self.phi = phi;
        let (k1, k2, k3) = (self.g.k1, self.g.k2, self.g.k3);
        let mut u = [0.0; 3];
        for a in 0..3 {
            let et = self.eta[a] - self.x[ETA_HAT + a];
            u[a] = phi[a] + k2 * (k1 * self.eta[a] + self.x[ZETA_HAT + a] - k3 * et - rho[a]);
            if let Some(lim) = self.g.thrust_limit_mps2 {
                u[a] = u[a].clamp(-lim, lim);
            }
        }
        u
    }

    /// dx/dt at `x` with ηᵢ, uᵢ and the neighbours' values held; written into `out`.
    fn deriv(&mut self, x: &[f64], out: &mut [f64]) {
        let (k1, k3, k4, k5, k6) = (self.g.k1, self.g.k3, self.g.k4, self.g.k5, self.g.k6);
        let rho = self.rho(x);
        // −(H g u)ᵢ, the known part: Σⱼ gⱼuⱼ − |Nᵢ| gᵢuᵢ − bᵢ CᵢᵀCᵢ gᵢuᵢ.
        let mut hgu = add(&self.sum_gu, &scale(-(self.n_heard as f64), &self.u));
        if self.b {
            for row in &self.c {
                hgu = add(&hgu, &scale(-dot(row, &self.u), row));
            }
        }
        let mut w = [0.0; 3]; // ζ̂ᵢ + k₁ηᵢ
        for a in 0..3 {
            let et = self.eta[a] - x[ETA_HAT + a];
            out[ETA_HAT + a] = x[ZETA_HAT + a];
            out[ZETA_HAT + a] = hgu[a] - (k3 * k3 - 2.0) * et - (2.0 * k3 + k4 + k5) * rho[a];
            out[INT_ETA_TILDE + a] = et;
            out[INT_RHO + a] = rho[a];
            w[a] = x[ZETA_HAT + a] + k1 * self.eta[a];
        }
        let kappa = [self.eta[0], self.eta[1], self.eta[2], x[ZETA_HAT], x[ZETA_HAT + 1], x[ZETA_HAT + 2]];
        let mut phi = [0.0; 3];
        self.net.forward_jacobian(&kappa, &x[THETA..], &mut phi, &mut self.jac);
        let p = self.p;
        let theta = &x[THETA..];
        let n1 = 1.0 + self.n_heard as f64;
        let gamma = self.g.gamma;
        let dtheta = &mut out[THETA..];
        for m in 0..p {
            let jt_w = self.jac[m] * w[0] + self.jac[p + m] * w[1] + self.jac[2 * p + m] * w[2];
            dtheta[m] = gamma * (jt_w - k6 * (n1 * theta[m] - self.sum_theta[m]));
        }
        project(theta, dtheta, self.g.theta_bar, self.g.projection_band);
    }
}

/// Smooth projection of the update `d` at `theta` onto the ball ‖θ‖ ≤ θ̄ (App. E of Krstić et
/// al. for P(θ) = ‖θ‖² with Γ = γI): inside (1 − band)·θ̄ nothing changes; beyond it, a growing
/// fraction c ∈ (0, 1] of the outward radial component is removed, all of it at θ̄.
pub fn project(theta: &[f64], d: &mut [f64], theta_bar: f64, band: f64) {
    let r2: f64 = theta.iter().map(|t| t * t).sum();
    let inner = (1.0 - band) * theta_bar;
    if r2 <= inner * inner {
        return;
    }
    let outward: f64 = theta.iter().zip(d.iter()).map(|(t, x)| t * x).sum();
    if outward <= 0.0 {
        return;
    }
    let c = ((r2 - inner * inner) / (theta_bar * theta_bar - inner * inner)).min(1.0);
    let f = c * outward / r2;
    for (x, t) in d.iter_mut().zip(theta) {
        *x -= f * t;
    }
}

impl Algorithm for LbDnnServicing {
    cohort_runtime::serde_checkpoint!();

    fn roster(&mut self, live: &[bool]) {
        self.live = live.to_vec();
    }

    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for ax in ["x", "y", "z"] {
            c.push(format!("u_{ax}_mps2"));
        }
        c.push("theta_norm".into());
        for (q, unit) in [("eta_hat", "m"), ("zeta_hat", "mps"), ("eta", "m"), ("phi", "mps2")] {
            for ax in ["x", "y", "z"] {
                c.push(format!("{q}_{ax}_{unit}"));
            }
        }
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        self.eta = self.eta_from(input.readings);
        if !self.started {
            self.started = true;
            if self.g.observer_init == ObserverInit::Measured {
                self.x[ETA_HAT..ETA_HAT + 3].copy_from_slice(&self.eta);
            }
        }
        self.u = self.command();
        // What (26) and (28) need from this agent: gᵢuᵢ (g = I₃) and θ̂ᵢ.
        out.command.extend_from_slice(&self.u);
        out.values.extend_from_slice(&self.u);
        out.values.extend_from_slice(&self.x[THETA..]);
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        let p = self.p;
        self.sum_gu = [0.0; 3];
        self.sum_theta.iter_mut().for_each(|s| *s = 0.0);
        self.n_heard = 0;
        for nb in neighbours {
            // A share of another shape (another network size) cannot be used: leave it out.
            if nb.values.len() != 3 + p {
                continue;
            }
            self.n_heard += 1;
            self.sum_gu = add(&self.sum_gu, &v3(nb.values));
            for (s, t) in self.sum_theta.iter_mut().zip(&nb.values[3..]) {
                *s += t;
            }
        }
        // Classic RK4 on x with the inputs held.
        let n = self.x.len();
        let x0 = self.x.clone();
        let mut k = std::mem::take(&mut self.k);
        let mut tmp = std::mem::take(&mut self.tmp);
        self.deriv(&x0, &mut k[0]);
        for i in 0..n {
            tmp[i] = x0[i] + 0.5 * dt_s * k[0][i];
        }
        self.deriv(&tmp, &mut k[1]);
        for i in 0..n {
            tmp[i] = x0[i] + 0.5 * dt_s * k[1][i];
        }
        self.deriv(&tmp, &mut k[2]);
        for i in 0..n {
            tmp[i] = x0[i] + dt_s * k[2][i];
        }
        self.deriv(&tmp, &mut k[3]);
        for i in 0..n {
            self.x[i] = x0[i] + dt_s / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
        }
        self.k = k;
        self.tmp = tmp;
        // Keep θ̂ in the ball (see the module docs).
        let theta = &mut self.x[THETA..];
        let norm = theta.iter().map(|t| t * t).sum::<f64>().sqrt();
        if norm > self.g.theta_bar {
            let f = self.g.theta_bar / norm;
            theta.iter_mut().for_each(|t| *t *= f);
            self.projection_clips += 1;
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&self.u);
        out.push(self.x[THETA..].iter().map(|t| t * t).sum::<f64>().sqrt());
        out.extend_from_slice(&self.x[ETA_HAT..ETA_HAT + 3]);
        out.extend_from_slice(&self.x[ZETA_HAT..ZETA_HAT + 3]);
        out.extend_from_slice(&self.eta);
        out.extend_from_slice(&self.phi);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn gains() -> Gains {
        Gains {
            k1: 0.65,
            k2: 0.65,
            k3: 0.65,
            k4: 0.65,
            k5: 0.65,
            k6: 0.0001,
            gamma: 0.01,
            theta_bar: 50.0,
            hidden_layers: vec![4, 4, 4, 4],
            projection_band: 0.1,
            observer_init: ObserverInit::Zero,
            thrust_limit_mps2: None,
        }
    }

    fn agent() -> LbDnnServicing {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        LbDnnServicing::new(gains(), vec![[1.5124, -1.8904, 0.6818]], true, vec![2, 6], &mut rng)
    }

    #[test]
    fn shares_carry_gu_and_theta_of_the_configured_size() {
        let mut a = agent();
        assert_eq!(a.p, 103);
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &[10.0, 1.0, 2.0, 3.0, -1.0, 0.0, 0.5] }, &mut out);
        assert_eq!(out.values.len(), 3 + 103);
        assert_eq!(&out.values[..3], &out.command[..]);
        assert_eq!(&out.values[3..], a.theta());
    }

    #[test]
    fn eta_is_neighbour_offsets_plus_ct_y() {
        let a = agent();
        let eta = a.eta_from(&[2.0, 1.0, 2.0, 3.0, -1.0, 0.0, 0.5]);
        let want = [1.0 - 1.0 + 2.0 * 1.5124, 2.0 + 0.0 - 2.0 * 1.8904, 3.0 + 0.5 + 2.0 * 0.6818];
        for k in 0..3 {
            assert!((eta[k] - want[k]).abs() < 1e-12, "{eta:?} vs {want:?}");
        }
    }

    #[test]
    fn initial_command_is_the_papers_large_kick() {
        // With η̂(0) = 0: η̃ = η, ρ = −(k₃+k₄)η, so u = Φ + k₂(k₁ + k₄)η exactly.
        let mut a = agent();
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &[1000.0, 10.0, 0.0, 0.0, 0.0, 0.0, 0.0] }, &mut out);
        let g = gains();
        for k in 0..3 {
            let want = a.phi[k] + g.k2 * (g.k1 + g.k4) * a.eta[k];
            assert!((out.command[k] - want).abs() < 1e-9 * want.abs().max(1.0), "{:?}", out.command);
        }
    }

    #[test]
    fn projection_keeps_theta_in_the_ball_even_from_the_boundary() {
        // Continuous part: on the boundary, an outward update loses its whole radial component.
        let theta = vec![50.0 / (103f64).sqrt(); 103];
        let mut d = vec![1.0; 103];
        project(&theta, &mut d, 50.0, 0.1);
        let radial: f64 = theta.iter().zip(&d).map(|(t, x)| t * x).sum();
        assert!(radial.abs() < 1e-9, "radial component left: {radial}");
        // Inside the inner radius nothing changes; an inward update is never touched.
        let small = vec![0.1; 103];
        let mut d2 = vec![1.0; 103];
        project(&small, &mut d2, 50.0, 0.1);
        assert!(d2.iter().all(|&x| x == 1.0));
        let mut d3 = vec![-1.0; 103];
        project(&theta, &mut d3, 50.0, 0.1);
        assert!(d3.iter().all(|&x| x == -1.0));
        // Discrete: huge stiff inputs for many steps never leave the ball.
        let mut a = agent();
        a.x[THETA..].iter_mut().for_each(|t| *t = 50.0 / (103f64).sqrt()); // start on the boundary
        for k in 0..200 {
            let mut out = ShareOut::default();
            let r = [3e4, 2e4, -1e4, 5e3, 0.0, 0.0, -4e3, 1e3, 2e3];
            a.share(&AgentInput { k, t_s: k as f64 * 0.01, readings: &r[..7] }, &mut out);
            let th: Vec<f64> = vec![3.0; 103];
            let mut nb = vec![1e3, -1e3, 0.0];
            nb.extend(th);
            a.step(
                0.01,
                &[Neighbour { id: 2, values: &nb, age_steps: 0 }, Neighbour { id: 6, values: &nb, age_steps: 0 }],
            );
            let norm = a.theta().iter().map(|t| t * t).sum::<f64>().sqrt();
            assert!(norm <= 50.0 + 1e-9, "step {k}: ‖θ̂‖ = {norm}");
            assert!(a.x.iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn observer_tracks_a_constant_eta_with_no_commands() {
        // With uᵢ = Σⱼgⱼuⱼ = 0 and a constant η, (24)–(26) drive η̃ → 0 and ζ̂ → 0.
        let mut a = agent();
        let eta = a.eta_from(&[5.0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
        a.eta = eta;
        a.u = [0.0; 3];
        for _ in 0..6000 {
            a.step(0.01, &[]);
            a.eta = eta;
            a.u = [0.0; 3];
        }
        for k in 0..3 {
            assert!((a.x[ETA_HAT + k] - eta[k]).abs() < 1e-3, "η̂ {:?} vs η {eta:?}", &a.x[..3]);
            assert!(a.x[ZETA_HAT + k].abs() < 1e-3, "ζ̂ {:?}", &a.x[3..6]);
        }
    }
}
