//! The desired trajectory with zero delivery error, (21)–(24) and Fig. 6 of "Neural-Rendezvous"
//! (arXiv:2208.04883): from the estimates (x̂, œ̂) at t, roll the guidance policy's closed loop
//! forward to t_f along the ISO flow, replace the terminal position by ρ_f (keeping that
//! velocity, (23)), and integrate the same closed loop backward to t. Without estimation error
//! the result ends exactly at ρ_f. Also built from an MPC plan (the robust NMPC's and the fixed
//! plans of the PD and robust-tracking baselines).
//!
//! Discretisation (ours): nodes at the control interval; the policy's command is held over each
//! interval, as the plant holds it. Two readings of "integrate back with u_ℓ" ([`Backward`]):
//!
//! - [`Backward::Replay`] (default, a departure): step back from the terminal state with the
//!   forward roll-out's commands. x_d is then the policy's own trajectory shifted by its terminal
//!   miss (carried back through the dynamics), and the tracking only removes that miss.
//! - [`Backward::Policy`]: the command of [t_j, t_{j+1}] is the policy at the unknown node
//!   x_d(t_j), found by a predictor (the next node's command) and two corrector passes. Once the
//!   policy imitates the MPC well this is ill-conditioned near t_f: the MPC's last step is nearly
//!   deadbeat (it sends any x(t_{N−1}) to ρ_f), so the backward map is close to singular there
//!   (the fixed-point factor ≈ 3Δt/t_go is not small) and the residuals of the last nodes are
//!   amplified going back (measured: x_d(t_s) 227–334 m from x̂ where replay's is within 0.1 m).
//!   Kept for the comparison in the crate README.
//!
//! Either way the trajectory satisfies the dynamics under its stored commands exactly. Backward steps hold the force in the
//! inertial axes of t_{j+1} rather than t_j (a 10⁻⁴ rad difference per step).

use serde::{Deserialize, Serialize};

use crate::iso::dynamics::lvlh::{OrbitRates, X6, join, pos, vel};
use crate::iso::dynamics::relative::{accel, step};
use crate::iso::dynamics::two_body::{Inertial, V3};
use crate::iso::guidance::scp::{Plan, ScpInput, rollout};

/// Corrector passes per backward node of [`Backward::Policy`].
const CORRECTIONS: usize = 2;

/// How the backward pass chooses its commands (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Backward {
    #[default]
    Replay,
    Policy,
}

/// Nodes 0…N of a desired trajectory (x_d, œ_d, m) and the commands 0…N−1 held between them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Desired {
    pub t0_s: f64,
    pub dt_s: f64,
    pub x: Vec<X6>,
    pub u_n: Vec<V3>,
    pub iso: Vec<Inertial>,
    pub m_kg: Vec<f64>,
}

impl Desired {
    /// An MPC plan as a desired trajectory.
    pub fn from_plan(plan: &Plan) -> Self {
        let t = &plan.traj;
        Self {
            t0_s: plan.t0_s,
            dt_s: plan.dt_s,
            x: t.x.clone(),
            u_n: t.u_n.clone(),
            iso: t.iso.clone(),
            m_kg: t.m_kg.clone(),
        }
    }

    /// The node at time t (a control instant before t_f), if the trajectory has one.
    pub fn node(&self, t_s: f64) -> Option<usize> {
        let k = ((t_s - self.t0_s) / self.dt_s).round();
        let on_grid = (t_s - self.t0_s - k * self.dt_s).abs() <= 1e-6 * self.dt_s;
        (on_grid && k >= 0.0 && (k as usize) < self.u_n.len()).then_some(k as usize)
    }

    /// x_d and p̈_d at node k (p̈_d from (2) with the held command and the desired ISO flow).
    pub fn state_accel(&self, k: usize) -> (X6, V3) {
        let x = self.x[k];
        (x, accel(&x, &OrbitRates::of(&self.iso[k]), &(self.u_n[k] / self.m_kg[k])))
    }

    /// Terminal position, m.
    pub fn terminal_position(&self) -> V3 {
        pos(self.x.last().expect("a trajectory has nodes"))
    }
}

/// Build the desired trajectory of (21)–(23) from `inp` (start estimates, horizon, ρ_f) with
/// the guidance `policy(x, œ, t)` → u (LVLH, N).
pub fn build(inp: &ScpInput, backward: Backward, policy: &mut dyn FnMut(&X6, &Inertial, f64) -> V3) -> Desired {
    let n = inp.steps();
    let (dt, isp) = (inp.dt_s, inp.isp_s);
    // Forward closed loop.
    let mut u_fwd = Vec::with_capacity(n);
    let (mut x, mut iso, mut m) = (inp.x0, inp.iso0, inp.m0_kg);
    for j in 0..n {
        let u = policy(&x, &iso, inp.t0_s + j as f64 * dt);
        u_fwd.push(u);
        let s = step(&x, &iso, m, &u, isp, dt);
        (x, iso, m) = (s.x, s.iso, s.m_kg);
    }
    let fwd = rollout(inp, &u_fwd, false);
    debug_assert_eq!(fwd.x[n], x);
    // (23): the terminal state with the desired position and the roll-out's velocity.
    let mut xd = vec![X6::zeros(); n + 1];
    xd[n] = join(&inp.rho_f_m, &vel(&fwd.x[n]));
    let mut ud = vec![V3::zeros(); n];
    for j in (0..n).rev() {
        let back = |u: &V3| step(&xd[j + 1], &fwd.iso[j + 1], fwd.m_kg[j + 1], u, isp, -dt).x;
        let t_j = inp.t0_s + j as f64 * dt;
        let mut u = if j + 1 < n && backward == Backward::Policy { ud[j + 1] } else { u_fwd[j] };
        for _ in 0..if backward == Backward::Policy { CORRECTIONS } else { 0 } {
            let next = policy(&back(&u), &fwd.iso[j], t_j);
            let change = (next - u).norm();
            u = next;
            if change <= 1e-9 + 1e-6 * u.norm() {
                break;
            }
        }
        ud[j] = u;
        xd[j] = back(&u);
    }
    Desired { t0_s: inp.t0_s, dt_s: dt, x: xd, u_n: ud, iso: fwd.iso, m_kg: fwd.m_kg }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::{ISO_SET_SEED, T_F_S};
    use crate::iso::dynamics::iso_set;
    use crate::iso::dynamics::lvlh::IsoFrame;

    fn start() -> ScpInput {
        let ideal = iso_set::ideal(ISO_SET_SEED, 21, 0, T_F_S, 100e3);
        let (iso0, sc0) = ideal.at(64_800.0);
        ScpInput {
            x0: IsoFrame::of(&iso0).relative(&(sc0)),
            iso0,
            m0_kg: 495.0,
            t0_s: 64_800.0,
            t_f_s: T_F_S,
            dt_s: 600.0,
            rho_f_m: ideal.rho_f_m + V3::new(3e3, -2e3, 1e3),
            u_max_n: 1.0,
            isp_s: 220.0,
        }
    }

    #[test]
    fn the_desired_trajectory_ends_at_rho_f_and_re_flies_under_its_commands() {
        let inp = start();
        // A crude linear guidance: push against the coasting miss.
        let mut policy = |x: &X6, iso: &Inertial, t: f64| {
            let zem = crate::iso::dynamics::relative::coast_position(x, iso, T_F_S - t, 21_600.0) - inp.rho_f_m;
            (-1e-6 * zem).map(|c| c.clamp(-1.0, 1.0))
        };
        let d = build(&inp, Backward::Policy, &mut policy);
        assert_eq!(d.x.len(), 37);
        assert_eq!(d.terminal_position(), inp.rho_f_m);
        // Flying the stored commands forward from x_d(t_s) lands on ρ_f (up to the backward
        // steps' frame and integration differences).
        let again = rollout(&ScpInput { x0: d.x[0], ..inp }, &d.u_n, false);
        let miss = (again.terminal_position() - inp.rho_f_m).norm();
        assert!(miss < 1.0, "re-flown miss {miss} m");
        // The commands are the policy along x_d.
        for j in [0, 10, 35] {
            let du = (policy(&d.x[j], &d.iso[j], d.t0_s + j as f64 * 600.0) - d.u_n[j]).norm();
            assert!(du < 1e-2 * d.u_n[j].norm() + 1e-9, "node {j}: {du}");
        }
        // Replay: the forward commands, x_d the forward trajectory shifted by its miss.
        let r = build(&inp, Backward::Replay, &mut policy);
        let fwd = rollout(&inp, &r.u_n, false);
        let miss = fwd.terminal_position() - inp.rho_f_m;
        assert!(miss.norm() > 100.0, "the crude policy misses: {}", miss.norm());
        let shift = pos(&r.x[0]) - pos(&inp.x0);
        assert!((shift + miss).norm() < 0.05 * miss.norm(), "x_d(t_s) − x̂(t_s) = {shift:?}, miss {miss:?}");
        let again = rollout(&ScpInput { x0: r.x[0], ..inp }, &r.u_n, false);
        assert!((again.terminal_position() - inp.rho_f_m).norm() < 1.0);
        assert_eq!(d.node(64_800.0 + 1200.0), Some(2));
        assert_eq!(d.node(64_800.0 + 1000.0), None);
        assert_eq!(d.node(T_F_S), None);
    }
}
