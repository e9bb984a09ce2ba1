//! Training data for the tension predictor, generated with our own net plant
//! (`crate::net`, our parameters (papers/tsnr/README.md), 1 ms RK4 sub-steps).
//!
//! Each trajectory is a random capture manoeuvre in the paper's three phases (Sec. 4: "capture
//! trajectories with random position of the target"), flown by a simple tracker:
//! - start: the folded net at the paper's start ([−10, ±0.75, ±0.75] m), each coordinate
//!   perturbed by up to ±5 cm, at rest;
//! - deploy (to t₁ ≈ 10 s): a square of half-width 2.2–2.7 m (slack to 8 % stretch; 2.55 m is
//!   the 2 % "micro-tension") centred near x = −5 m, turned by up to ±0.15 rad;
//! - approach (to t₂ ≈ 20 s): the same size, 1.5–2.5 m before the target along the net's normal,
//!   the net plane turned by ψ ∈ ±0.7 rad about z (Case 2 turns it by ≈ 0.5 rad);
//! - close (to 30 s): a square of half-width 0.3–0.8 m around the target, which sits at x ∈ [3, 7],
//!   y ∈ [−1, 6], z ∈ [−1, 1] m, arriving with a common velocity (Case 2 arrives at
//!   [0.25, 0.43, 0] m/s).
//!
//! Phase ends t₁, t₂ are jittered by ±1.5 s. Each MU follows quintic segments (zero acceleration
//! at the ends) through its corner of those squares, tracked at Δt = 0.1 s by
//! u = m(a_d + k_p(p_d − p) + k_d(v_d − v)) − f·T_measured + dither, each axis saturated at the
//! 5 N bound, with ω = √k_p ∈ [0.6, 1.5] rad/s, ζ ∈ [0.7, 1.0], f ∈ {0, 1} (tension feedforward
//! in half of the trajectories) and a Gaussian dither of σ ∈ [0, 0.5] N per axis and step, all
//! drawn per trajectory. The dither and the two tracker variants keep the thrust history from
//! being a fixed function of the state, so the network sees how thrust moves the tension.

use cohort_host::campaign::Campaign;

use crate::net::{N_MU, Net, NetParams, adjacent_mus};
use crate::predictor::{FEATURES_PER_STEP, Sample};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Control step Δt of the data (and of the predictor), s.
pub const DT_S: f64 = 0.1;
/// Steps per trajectory (30 s).
pub const STEPS: usize = 300;
/// Thrust bound per axis, N (papers/tsnr/README.md).
pub const THRUST_BOUND_N: f64 = 5.0;

/// One simulated trajectory, sampled every Δt: states and tensions at t_0 … t_STEPS, thrusts
/// over each step.
pub struct Trajectory {
    /// [k][mu] = [x, y, z, vx, vy, vz], m and m/s.
    pub state: Vec<[[f64; 6]; N_MU]>,
    /// [k][mu] held over [t_k, t_{k+1}), N.
    pub thrust_n: Vec<[[f64; 3]; N_MU]>,
    /// [k][mu], N.
    pub tension_n: Vec<[[f64; 3]; N_MU]>,
    /// Steps with at least one thrust axis at the bound.
    pub saturated_steps: usize,
}

/// A quintic from (p0, v0, 0) at t0 to (p1, v1, 0) at t1.
#[derive(Debug, Clone, Copy)]
struct Quintic {
    t0: f64,
    c: [f64; 6],
}

impl Quintic {
    fn new(t0: f64, t1: f64, p0: f64, v0: f64, p1: f64, v1: f64) -> Self {
        let t = t1 - t0;
        let d = p1 - p0;
        let c3 = (20.0 * d - (8.0 * v1 + 12.0 * v0) * t) / (2.0 * t.powi(3));
        let c4 = (-30.0 * d + (14.0 * v1 + 16.0 * v0) * t) / (2.0 * t.powi(4));
        let c5 = (12.0 * d - 6.0 * (v1 + v0) * t) / (2.0 * t.powi(5));
        Self { t0, c: [p0, v0, 0.0, c3, c4, c5] }
    }
    /// (position, velocity, acceleration) at `t`.
    fn eval(&self, t: f64) -> [f64; 3] {
        let s = t - self.t0;
        let c = &self.c;
        let p = c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))));
        let v = c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])));
        let a = 2.0 * c[2] + s * (6.0 * c[3] + s * (12.0 * c[4] + s * 20.0 * c[5]));
        [p, v, a]
    }
}

/// The four corners of a square of half-width `h` centred at `c` in a plane turned by `psi`
/// about z from the y–z plane, in MU order (MU1 (+y', +z), MU2 (−y', +z), MU3 (+y', −z), MU4).
fn square(c: [f64; 3], h: f64, psi: f64) -> [[f64; 3]; N_MU] {
    let y = [-psi.sin(), psi.cos(), 0.0];
    let signs = [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)];
    signs.map(|(sy, sz)| [c[0] + sy * h * y[0], c[1] + sy * h * y[1], c[2] + sz * h])
}

/// Each MU's desired path: per MU, per axis, three quintic segments.
struct Path {
    ends_s: [f64; 3],
    segments: [[[Quintic; 3]; 3]; N_MU],
}

impl Path {
    fn random(rng: &mut ChaCha8Rng, start: &[[f64; 3]; N_MU]) -> Self {
        let mut u = |lo: f64, hi: f64| rng.random_range(lo..hi);
        let t1 = 10.0 + u(-1.5, 1.5);
        let t2 = 20.0 + u(-1.5, 1.5);
        let deploy = square([u(-6.0, -4.0), u(-0.5, 0.5), u(-0.5, 0.5)], u(2.2, 2.7), u(-0.15, 0.15));
        let target = [u(3.0, 7.0), u(-1.0, 6.0), u(-1.0, 1.0)];
        let psi = u(-0.7, 0.7);
        let gap = u(1.5, 2.5);
        let normal = [psi.cos(), psi.sin(), 0.0];
        let approach_c = std::array::from_fn(|a| target[a] - gap * normal[a]);
        let approach = square(approach_c, u(2.2, 2.7), psi);
        let close = square(target, u(0.3, 0.8), psi);
        let v_end = [u(-0.2, 0.4), u(-0.5, 0.6), u(-0.2, 0.2)];
        let segments = std::array::from_fn(|i| {
            std::array::from_fn(|ax| {
                [
                    Quintic::new(0.0, t1, start[i][ax], 0.0, deploy[i][ax], 0.0),
                    Quintic::new(t1, t2, deploy[i][ax], 0.0, approach[i][ax], 0.0),
                    Quintic::new(t2, 30.0, approach[i][ax], 0.0, close[i][ax], v_end[ax]),
                ]
            })
        });
        Self { ends_s: [t1, t2, 30.0], segments }
    }

    /// (position, velocity, acceleration) of MU `i` on axis `ax` at `t`.
    fn desired(&self, i: usize, ax: usize, t: f64) -> [f64; 3] {
        let seg = self.ends_s.iter().position(|&end| t < end).unwrap_or(2);
        self.segments[i][ax][seg].eval(t.min(self.ends_s[2]))
    }
}

/// Simulate trajectory number `index` of the data set drawn from `seed`.
pub fn simulate(seed: u64, index: u64, net: &mut Net) -> Trajectory {
    // One independent stream per trajectory: the data set does not depend on how the
    // trajectories are shared among threads.
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    let mut start = [[-10.0, 0.75, 0.75], [-10.0, -0.75, 0.75], [-10.0, 0.75, -0.75], [-10.0, -0.75, -0.75]];
    for r in start.iter_mut().flatten() {
        *r += rng.random_range(-0.05..0.05);
    }
    let path = Path::random(&mut rng, &start);
    let omega = rng.random_range(0.6..1.5);
    let zeta = rng.random_range(0.7..1.0);
    let (kp, kd) = (omega * omega, 2.0 * zeta * omega);
    let feedforward = if rng.random_bool(0.5) { 1.0 } else { 0.0 };
    let dither_n = rng.random_range(0.0..0.5);
    let mass = net.params().mu_mass_kg;

    let mut state = net.folded_state(&start, &[[0.0; 3]; N_MU]);
    let corners = net.corner_nodes();
    let mut out = Trajectory {
        state: Vec::with_capacity(STEPS + 1),
        thrust_n: Vec::with_capacity(STEPS),
        tension_n: Vec::with_capacity(STEPS + 1),
        saturated_steps: 0,
    };
    let record = |out: &mut Trajectory, net: &Net, s: &crate::net::NetState| {
        out.state.push(std::array::from_fn(|i| {
            let (r, v) = (s.r_lvlh_m[corners[i]], s.v_lvlh_mps[corners[i]]);
            [r[0], r[1], r[2], v[0], v[1], v[2]]
        }));
        out.tension_n.push(net.corner_tension_n(s));
    };
    for k in 0..STEPS {
        record(&mut out, net, &state);
        let t = k as f64 * DT_S;
        let (x, tension) = (out.state[k], out.tension_n[k]);
        let mut saturated = false;
        let u: [[f64; 3]; N_MU] = std::array::from_fn(|i| {
            std::array::from_fn(|ax| {
                let [p, v, a] = path.desired(i, ax, t);
                let noise: f64 = rng.sample(StandardNormal);
                let raw = mass * (a + kp * (p - x[i][ax]) + kd * (v - x[i][3 + ax])) - feedforward * tension[i][ax]
                    + dither_n * noise;
                saturated |= raw.abs() >= THRUST_BOUND_N;
                raw.clamp(-THRUST_BOUND_N, THRUST_BOUND_N)
            })
        });
        out.saturated_steps += usize::from(saturated);
        out.thrust_n.push(u);
        net.advance(&mut state, DT_S, &u);
    }
    record(&mut out, net, &state);
    out
}

/// Simulate trajectories `indices` on up to `threads` threads; the result is in index order
/// and the same for any number of threads.
pub fn simulate_all(seed: u64, indices: std::ops::Range<u64>, threads: usize) -> Vec<Trajectory> {
    let all: Vec<u64> = indices.collect();
    Campaign::new(all.len())
        .workers(threads)
        .map_with(|| Net::new(NetParams::default()).expect("our net is valid"), |net, k| simulate(seed, all[k], net))
}

/// Windows of eq. (7): inputs (27·N_t each, f64) and targets T(t_{e+1..e+N_t}) (3·N_t each, N).
pub struct Windows {
    pub n_t: usize,
    pub inputs: Vec<f64>,
    pub targets: Vec<f64>,
    pub count: usize,
}

impl Windows {
    pub fn input(&self, w: usize) -> &[f64] {
        let n = FEATURES_PER_STEP * self.n_t;
        &self.inputs[w * n..(w + 1) * n]
    }
    pub fn target(&self, w: usize) -> &[f64] {
        let n = 3 * self.n_t;
        &self.targets[w * n..(w + 1) * n]
    }
}

/// Every window of every MU of every trajectory: the newest sample e runs over
/// N_t − 1 … STEPS − N_t, so the history and the targets both lie inside the trajectory.
pub fn windows(trajectories: &[Trajectory], n_t: usize) -> Windows {
    let mut w = Windows { n_t, inputs: Vec::new(), targets: Vec::new(), count: 0 };
    for tr in trajectories {
        for mu in 1..=N_MU as u32 {
            let i = (mu - 1) as usize;
            let [j1, j2] = adjacent_mus(mu).map(|j| (j - 1) as usize);
            for e in n_t - 1..=STEPS - n_t {
                for m in e + 1 - n_t..=e {
                    Sample {
                        own_state: tr.state[m][i],
                        neighbour_states: [tr.state[m][j1], tr.state[m][j2]],
                        own_thrust_n: tr.thrust_n[m][i],
                        neighbour_thrust_n: [tr.thrust_n[m][j1], tr.thrust_n[m][j2]],
                    }
                    .extend_features(&mut w.inputs);
                }
                for n in 1..=n_t {
                    w.targets.extend_from_slice(&tr.tension_n[e + n][i]);
                }
                w.count += 1;
            }
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quintic_meets_its_boundary_conditions() {
        let q = Quintic::new(2.0, 7.0, 1.0, 0.5, -3.0, 0.25);
        let [p0, v0, a0] = q.eval(2.0);
        let [p1, v1, a1] = q.eval(7.0);
        for (got, want) in [(p0, 1.0), (v0, 0.5), (a0, 0.0), (p1, -3.0), (v1, 0.25), (a1, 0.0)] {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
    }

    #[test]
    fn data_do_not_depend_on_the_thread_count_and_windows_line_up() {
        let one = simulate_all(5, 0..3, 1);
        let two = simulate_all(5, 0..3, 2);
        for (a, b) in one.iter().zip(&two) {
            assert_eq!(a.state, b.state);
            assert_eq!(a.tension_n, b.tension_n);
        }
        assert_ne!(one[0].state[STEPS], one[1].state[STEPS], "each trajectory has its own draw");
        let tr = &one[0];
        // Deployed and tracked: the net is taut at some point and the MUs end near the close square.
        assert!(tr.tension_n.iter().flatten().flatten().any(|t| t.abs() > 1.0));
        let w = windows(&one[..1], 10);
        assert_eq!(w.count, 4 * (STEPS - 2 * 10 + 2));
        // MU 1's first window: samples 0..=9, targets T(t_10..=t_19).
        assert_eq!(w.input(0)[0..6], tr.state[0][0]);
        assert_eq!(w.input(0)[6..12], tr.state[0][1], "MU 2 is MU 1's first neighbour");
        assert_eq!(w.input(0)[12..18], tr.state[0][2]);
        assert_eq!(w.input(0)[18..21], tr.thrust_n[0][0]);
        assert_eq!(w.input(0)[9 * 27..9 * 27 + 6], tr.state[9][0]);
        assert_eq!(w.target(0)[0..3], tr.tension_n[10][0]);
        assert_eq!(w.target(0)[27..30], tr.tension_n[19][0]);
    }
}
