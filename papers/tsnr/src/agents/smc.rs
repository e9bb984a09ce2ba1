//! Seed 001 baseline "SMC" (Sec. 4, the paper's ref. [23], which is not in the text): a
//! force-compensation sliding-mode tracking controller per MU, no communication used.
//!
//! With e = r − r_d and ė = v − v_d (per axis), the sliding surface s = ė + λe and
//!
//! ```text
//! u = −T_meas + m (r̈_d − f_CW(r, v) − λė − k·sat(s/φ)),      then |u| ≤ ū per axis,
//! ```
//!
//! f_CW the Clohessy–Wiltshire acceleration (gravity gradient and Coriolis) and T_meas the measured
//! net tension, compensated as a disturbance. Unsaturated, and with the tension and model exact,
//! this gives ṡ = −k·sat(s/φ): s reaches the boundary layer |s| ≤ φ in finite time and inside it
//! decays as ṡ = −(k/φ)s, so e obeys ë + (λ + k/φ)ė + (λk/φ)e = 0.
//!
//! **Boundary layer.** sat(s/φ) replaces sign(s) by a linear ramp of half-width φ (m/s). A pure
//! sign would switch ±k every control step (chattering at the 10 Hz sample rate, which a sampled
//! controller cannot slide on); the price is that under a disturbance d the compensation misses
//! (tension changing within a step, model error) s settles to |s| ≈ φ·d/k instead of zero.
//!
//! The thrust saturation is applied after the law, per axis; while it is active the reaching
//! condition does not hold and the error grows until the demand falls back inside the bound.

use crate::config::formation::{TsnrFormation, TsnrModel, TsnrSmc as Gains};
use crate::cw::{free_accel_mps2, mean_motion_rad_s};
use crate::trajectory::{Desired, Trajectory};
use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};

use super::common::{Sensed, V3, base_columns, base_row, push_header, saturate, trajectory_of};

pub struct TsnrSmc {
    g: Gains,
    traj: Trajectory,
    n_rad_s: f64,
    mass_kg: f64,
    bound_n: f64,
    // This step, for telemetry.
    sensed: Sensed,
    desired: Desired,
    s: V3,
    u_n: V3,
}

/// sat(x) = x clipped to [−1, 1].
fn sat(x: f64) -> f64 {
    x.clamp(-1.0, 1.0)
}

impl TsnrSmc {
    /// Agent `id` of a (validated) scenario with `method = "smc"`.
    pub fn new(cfg: &TsnrFormation, model: &TsnrModel, id: u32) -> Self {
        Self {
            g: cfg.smc.clone().expect("validated: smc needs [algorithm.smc]"),
            traj: trajectory_of(cfg, id),
            n_rad_s: mean_motion_rad_s(model.orbit_radius_m),
            mass_kg: model.mass_kg,
            bound_n: model.thrust_max_n,
            sensed: Sensed::default(),
            desired: Desired::default(),
            s: [0.0; 3],
            u_n: [0.0; 3],
        }
    }

    /// The law above, before saturation; also sets the sliding variable s.
    fn law(&mut self) -> V3 {
        let (lam, k, phi) = (self.g.lambda_per_s, self.g.switching_gain_mps2, self.g.boundary_layer_mps);
        let (r, v) = (self.sensed.r_m(), self.sensed.v_mps());
        let f_cw = free_accel_mps2(self.n_rad_s, &r, &v);
        let d = &self.desired;
        std::array::from_fn(|ax| {
            let e = r[ax] - d.r_m[ax];
            let e_dot = v[ax] - d.v_mps[ax];
            self.s[ax] = e_dot + lam * e;
            -self.sensed.tension_n[ax]
                + self.mass_kg * (d.a_mps2[ax] - f_cw[ax] - lam * e_dot - k * sat(self.s[ax] / phi))
        })
    }
}

/// What an SMC agent carries from one step to the next (the law itself is memoryless).
type SmcState = ([f64; 6], V3, V3, V3);

impl Algorithm for TsnrSmc {
    fn save_state(&self) -> Vec<u8> {
        let st: SmcState = (self.sensed.state, self.sensed.tension_n, self.s, self.u_n);
        cohort_runtime::checkpoint::encode_state(&st)
    }
    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        let st: SmcState = cohort_runtime::checkpoint::decode_state(bytes)?;
        (self.sensed.state, self.sensed.tension_n, self.s, self.u_n) = st;
        Ok(())
    }

    fn columns(&self) -> Vec<String> {
        let mut c = base_columns();
        for ax in ["x", "y", "z"] {
            c.push(format!("s_{ax}_mps"));
        }
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        self.sensed = Sensed::from_readings(input.readings);
        self.desired = self.traj.at(input.t_s);
        let u = self.law();
        self.u_n = saturate(u, self.bound_n);
        out.command.extend_from_slice(&self.u_n);
        push_header(&mut out.values, &self.sensed, &self.u_n);
    }

    fn step(&mut self, _dt_s: f64, _neighbours: &[Neighbour<'_>]) {}

    fn row(&self, out: &mut Vec<f64>) {
        base_row(out, &self.u_n, &self.sensed, &self.desired);
        out.extend_from_slice(&self.s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agents::common::test_support::{MODEL, case1, closed_loop, readings};

    fn err_at_end(run_state: &[f64; 6], traj: &Trajectory, t_s: f64) -> f64 {
        let d = traj.at(t_s);
        (0..3).map(|a| (run_state[a] - d.r_m[a]).powi(2)).sum::<f64>().sqrt()
    }

    #[test]
    fn drives_a_cw_only_mu_from_an_offset_start_to_its_target() {
        let cfg = case1("smc");
        let traj = trajectory_of(&cfg, 1);
        // Half a metre off the start in every axis, moving the wrong way.
        let x0 = [-9.5, 1.25, 0.25, 0.1, -0.1, 0.05];
        for tension in [[0.0; 3], [2.0, -3.0, 1.0]] {
            let mut algos: Vec<Box<dyn Algorithm>> = vec![Box::new(TsnrSmc::new(&cfg, &MODEL, 1))];
            let run = closed_loop(&mut algos, &[vec![]], vec![x0], 300, |_, _, _| tension);
            assert!(run.max_thrust_n <= 5.0, "thrust {}", run.max_thrust_n);
            let e = err_at_end(&run.states[0], &traj, 30.0);
            assert!(e < 0.01, "terminal position error {e} m with tension {tension:?}");
            let v_err: f64 = (0..3).map(|a| run.states[0][3 + a].powi(2)).sum::<f64>().sqrt();
            assert!(v_err < 0.01, "terminal speed {v_err} m/s (target at rest)");
        }
    }

    #[test]
    fn saturates_at_the_bound_under_a_large_error() {
        let cfg = case1("smc");
        let mut smc = TsnrSmc::new(&cfg, &MODEL, 1);
        let mut out = ShareOut::default();
        // Far off and moving away: m(λė + k) = 10·(1.5·2 + 0.3) = 33 N per axis before the clip.
        let r = readings(&[40.0, -30.0, 25.0, 2.0, -2.0, 2.0], &[0.0; 3]);
        smc.share(&AgentInput { k: 0, t_s: 0.0, readings: &r }, &mut out);
        assert_eq!(out.command, vec![-5.0, 5.0, -5.0]);
        assert_eq!(out.values.len(), 9);
    }

    #[test]
    fn inside_the_boundary_layer_the_law_is_exact_compensation_plus_linear_feedback() {
        let cfg = case1("smc");
        let mut smc = TsnrSmc::new(&cfg, &MODEL, 2);
        let t_s = 12.0;
        let d = smc.traj.at(t_s);
        let (e, e_dot) = (0.01, -0.02);
        let state = [d.r_m[0] + e, d.r_m[1], d.r_m[2], d.v_mps[0] + e_dot, d.v_mps[1], d.v_mps[2]];
        let tension = [0.7, -1.1, 0.4];
        let mut out = ShareOut::default();
        smc.share(&AgentInput { k: 120, t_s, readings: &readings(&state, &tension) }, &mut out);
        let g = cfg.smc.unwrap();
        let s = e_dot + g.lambda_per_s * e;
        let n = mean_motion_rad_s(MODEL.orbit_radius_m);
        let f = free_accel_mps2(n, &[state[0], state[1], state[2]], &[state[3], state[4], state[5]]);
        let want_x = -tension[0]
            + MODEL.mass_kg
                * (d.a_mps2[0] - f[0] - g.lambda_per_s * e_dot - g.switching_gain_mps2 * s / g.boundary_layer_mps);
        assert!((out.command[0] - want_x).abs() < 1e-12, "{} vs {want_x}", out.command[0]);
    }
}
