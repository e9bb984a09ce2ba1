//! Seed 001 baseline "DMPC" (Sec. 4): each MU runs the same receding-horizon controller as AEMC
//! on its own, with no game — no neighbours' Uⱼ/Xⱼ, no consensus error, no neighbours' costs —
//! and no tension prediction: the net tension is a disturbance compensated once measured.
//!
//! At t_k the MU predicts with the latest measured tension T_k held over the horizon, solves
//!
//! ```text
//! min_U (ΓU + Φx_k − X^d)ᵀ Q̄ (ΓU + Φx_k − X^d) + Uᵀ R̄ U   s.t.  |û_{k+p} − T_k| ≤ ū per axis,
//! ```
//!
//! (U the total-force sequence, as in AEMC), and applies u_k = û_k − T_k. With `force_cost =
//! "thrust"` (an ablation) R weighs the thrust U − T instead of U. This is AEMC's QP with
//! every neighbour term removed and the consensus error reduced to the tracking error x̃ᵢ. AEMC
//! weighs a common error of the whole formation (every MU off by the same x̃) with bᵢ²Q, so with
//! bᵢ = 1 (the scenario files) Q and R mean the same thing in both; AEMC adds weight on the
//! formation's shape through aᵢⱼ.
//!
//! A failed solve (any status but Solved) is counted, and the MU applies the previous solve's
//! plan for this step, less the measured tension, saturated (zero thrust before any plan).

use crate::config::formation::{ForceCost, TsnrFormation, TsnrModel};
use crate::cw::Cw;
use crate::trajectory::{Desired, Trajectory};
use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use cohort_runtime::solver_stats::SolverStats;
use nalgebra::DVector;

use super::common::{Sensed, V3, base_columns, base_row, push_header, saturate, trajectory_of};
use super::mpc::{BoxQp, Horizon, Plan, QpStatus};

pub struct TsnrDmpc {
    traj: Trajectory,
    hz: Horizon,
    qp: BoxQp,
    bound_n: f64,
    /// With `force_cost = "thrust"`: R, then on the thrust instead of the total force.
    thrust_cost: Option<f64>,
    plan: Plan,
    // This step, for telemetry.
    sensed: Sensed,
    desired: Desired,
    u_n: V3,
    status: QpStatus,
    iterations: u32,
}

impl TsnrDmpc {
    /// Agent `id` of a (validated) scenario with `method = "dmpc"` and control step `dt_s`.
    pub fn new(cfg: &TsnrFormation, model: &TsnrModel, dt_s: f64, id: u32) -> Self {
        let m = cfg.mpc.as_ref().expect("validated: dmpc needs [algorithm.mpc]");
        let np = m.horizon_steps as usize;
        let hz = Horizon::new(Cw::new(model.orbit_radius_m, model.mass_kg), dt_s, np, m.q_position, m.q_velocity);
        let qp = BoxQp::new(&hz.hessian(1.0, m.r_force), model.thrust_max_n, m.max_iter, m.qp_solver);
        Self {
            traj: trajectory_of(cfg, id),
            hz,
            qp,
            bound_n: model.thrust_max_n,
            thrust_cost: (m.force_cost == ForceCost::Thrust).then_some(m.r_force),
            plan: Plan::default(),
            sensed: Sensed::default(),
            desired: Desired::default(),
            u_n: [0.0; 3],
            status: QpStatus::Solved,
            iterations: 0,
        }
    }

    /// The QP this agent solves (its last problem, its statistics).
    pub fn qp(&self) -> &BoxQp {
        &self.qp
    }

    /// The command at t_k from the state and the measured tension.
    fn command(&mut self, k: u64, t_s: f64) -> V3 {
        let np = self.hz.np;
        let x0 = self.sensed.state;
        let t = self.sensed.tension_n;
        let s = self.hz.free_error(&x0, &self.hz.desired(&self.traj, t_s));
        let mut q: DVector<f64> = (&self.hz.gt_q * s) * 2.0;
        let offset: Vec<f64> = (0..np).flat_map(|_| t).collect();
        if let Some(r) = self.thrust_cost {
            // R on u = û − T: r|U − T|² adds −2r Tᵀ U.
            for (qi, t) in q.iter_mut().zip(&offset) {
                *qi -= 2.0 * r * t;
            }
        }
        let (status, iterations, x) = self.qp.solve(q.as_slice(), &offset);
        (self.status, self.iterations) = (status, iterations);
        if let Some(u) = x {
            self.plan = Plan { k: Some(k), u: u.to_vec() };
        }
        let u = self.plan.shifted(k, np);
        saturate([u[0] - t[0], u[1] - t[1], u[2] - t[2]], self.bound_n)
    }
}

/// What a DMPC agent carries from one step to the next: its last plan (a failed solve falls back
/// on it), and this step's readings and command. The QP is rebuilt from the scenario.
type DmpcState = (Option<u64>, Vec<f64>, [f64; 6], V3, V3);

impl Algorithm for TsnrDmpc {
    fn save_state(&self) -> Vec<u8> {
        let st: DmpcState = (self.plan.k, self.plan.u.clone(), self.sensed.state, self.sensed.tension_n, self.u_n);
        cohort_runtime::checkpoint::encode_state(&st)
    }
    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        let (k, u, state, tension, u_n): DmpcState = cohort_runtime::checkpoint::decode_state(bytes)?;
        self.plan = Plan { k, u };
        (self.sensed.state, self.sensed.tension_n, self.u_n) = (state, tension, u_n);
        Ok(())
    }

    fn columns(&self) -> Vec<String> {
        // The same columns as AEMC where they mean the same (the tension used is the measured one).
        let mut c = base_columns();
        for ax in ["x", "y", "z"] {
            c.push(format!("tension_used_{ax}_n"));
        }
        c.extend(["qp_status".into(), "qp_iterations".into()]);
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        self.sensed = Sensed::from_readings(input.readings);
        self.desired = self.traj.at(input.t_s);
        self.u_n = self.command(input.k, input.t_s);
        out.command.extend_from_slice(&self.u_n);
        push_header(&mut out.values, &self.sensed, &self.u_n);
    }

    fn step(&mut self, _dt_s: f64, _neighbours: &[Neighbour<'_>]) {}

    fn row(&self, out: &mut Vec<f64>) {
        base_row(out, &self.u_n, &self.sensed, &self.desired);
        out.extend_from_slice(&self.sensed.tension_n);
        out.extend([self.status.code(), f64::from(self.iterations)]);
    }

    fn solver_stats(&self) -> Option<SolverStats> {
        Some(self.qp.stats())
    }
}
