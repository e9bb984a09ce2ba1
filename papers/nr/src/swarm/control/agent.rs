//! One vehicle of the swarm (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883): the algorithm of
//! the `nr-swarm` kind, one process per vehicle. `algorithm.method` chooses
//!
//! - `policy`: the [`SwarmPolicy`] alone, u = u_ℓ(o), o the local observation (with the time to
//!   go T − t, T the plant's `t_reconfig_s`);
//! - `nr`: the Neural-Rendezvous layer over that policy. Every `rebuild_every_s` (0.5 s) the
//!   vehicle rolls its own policy `horizon_s` (2 s) ahead from its estimate, the neighbours it
//!   hears moving at constant velocity, the time to go running down ([`roll_out`]): the desired trajectory (p_d, v_d, a_d). Each
//!   step it tracks it with the min-norm control (27) of [`crate::iso::control::min_norm`] for m = 1, C = G = 0:
//!   s = v̂ − v_d + Λ(p̂ − p_d), ς = a_d − Λ(v̂ − v_d), u* = argmin ‖u − u_ℓ‖² s.t.
//!   sᵀ(u − ς) + α‖s‖² ≤ 0, about the policy's command u_ℓ at the current observation.
//!
//! The command is clipped to a_max per axis (counted; the plant clips too). Two additions of ours,
//! each on only when its scenario table is there (the shipped swarm scenarios have both):
//! `[algorithm.estimator]`, the vehicle flies and shares the Kalman estimate of
//! [`crate::swarm::control::nav`] (updated with each reading, predicted with the command flown) in place of
//! its raw readings; `[algorithm.safety]`, the clipped command passes last through the barrier
//! filter of [`crate::swarm::control::safety`] against the neighbours heard within R_comm (the roll-out is
//! the policy's own, unfiltered).
//!
//! What a vehicle knows of the others: the shares ([`crate::swarm::dynamics::messages`]) every vehicle
//! publishes each step, to every vehicle that lists it (all-to-all in the shipped scenarios; the
//! vehicles it could meet within R_comm in generated ones, [`crate::swarm::dynamics::neighbours`]). The runtime hands an agent its neighbours' shares of step k
//! only after its own command of step k is out, so the command of step k uses the shares of step
//! k − 1, propagated over the interval with their shared command (a one-interval link latency,
//! ours; the paper's radio latency is not given). A share whose propagated position is at or
//! beyond R_comm from the vehicle's own estimate is dropped before anything reads it: neither the
//! observation nor the roll-out sees that vehicle. Of those within, the observation keeps the
//! nearest six ([`SwarmObservation::local`]). A share with non-finite values (a vehicle with bad
//! readings) is dropped too.
//!
//! Departures (the paper's are lost): Λ = λI and α as scenario keys (ours: 2 s⁻¹ each, a tracking
//! time constant of 0.5 s, the rebuild period); the roll-out uses the control interval as its step.

use std::sync::Arc;

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use serde::{Deserialize, Serialize};

use crate::iso::control::min_norm::min_norm;
use crate::swarm::config::SwarmMethod;
use crate::swarm::control::nav::{EstimatorConfig, OwnState};
use crate::swarm::control::obs::{SwarmObservation, SwarmPolicy};
use crate::swarm::control::safety::{self as swarm_safety, SafetyConfig};
use crate::swarm::dynamics::messages::{SHARE_LEN, SwarmReading, SwarmShare};
use crate::swarm::dynamics::setup::distance_m;

type V3 = [f64; 3];

/// Mode codes (telemetry and the share's last value).
pub const MODE_BAD_READINGS: f64 = -1.0;
pub const MODE_POLICY: f64 = 0.0;
pub const MODE_TRACKING: f64 = 1.0;
pub const MODE_REBUILT: f64 = 2.0;

/// What a vehicle flies with (from the scenario's sections, see `swarm_kinds`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwarmAgentParams {
    pub method: SwarmMethod,
    pub r_comm_m: f64,
    pub a_max_mps2: f64,
    pub lambda_per_s: f64,
    pub alpha_per_s: f64,
    /// Control intervals per roll-out and per rebuild (rebuild ≤ horizon).
    pub horizon_steps: usize,
    pub rebuild_steps: usize,
    /// The reconfiguration time T, s (the policy sees the time to go, T − t).
    pub t_reconfig_s: f64,
    /// The barrier filter on the final command, if any.
    pub safety: Option<SafetyConfig>,
    /// The own-state Kalman filter, if any (else the raw readings are flown).
    pub estimator: Option<EstimatorConfig>,
}

/// A desired trajectory: nodes j = 0..=n at t₀ + jΔt, the acceleration held over each interval.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Rollout {
    pub k0: u64,
    pub p_m: Vec<V3>,
    pub v_mps: Vec<V3>,
    pub a_mps2: Vec<V3>,
}

fn clip(u: V3, a_max: f64) -> V3 {
    u.map(|x| x.clamp(-a_max, a_max))
}

/// Roll `policy` `steps` intervals of `dt_s` ahead from (p0, v0), `others` = (p, v) of the heard
/// neighbours moving at constant velocity, the policy's time to go `t_to_go_s` at the start and
/// running down, each node's command clipped to a_max; exact double-integrator steps.
#[allow(clippy::too_many_arguments)]
pub fn roll_out(
    policy: &dyn SwarmPolicy,
    p0: V3,
    v0: V3,
    goal: V3,
    others: &[(V3, V3)],
    r_comm_m: f64,
    a_max_mps2: f64,
    dt_s: f64,
    steps: usize,
    t_to_go_s: f64,
) -> Rollout {
    let mut r = Rollout { k0: 0, p_m: vec![p0], v_mps: vec![v0], a_mps2: Vec::with_capacity(steps) };
    let mut moved = others.to_vec();
    for j in 0..steps {
        let tau = j as f64 * dt_s;
        for (m, (p, v)) in moved.iter_mut().zip(others) {
            m.0 = [0, 1, 2].map(|a| p[a] + v[a] * tau);
        }
        let (p, v) = (r.p_m[j], r.v_mps[j]);
        let obs = SwarmObservation::local(p, v, goal, &moved, r_comm_m).at(t_to_go_s - tau);
        let a = clip(policy.accel_mps2(&obs), a_max_mps2);
        r.p_m.push([0, 1, 2].map(|i| p[i] + v[i] * dt_s + 0.5 * a[i] * dt_s * dt_s));
        r.v_mps.push([0, 1, 2].map(|i| v[i] + a[i] * dt_s));
        r.a_mps2.push(a);
    }
    r
}

/// What the last `share` decided (the telemetry row).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
struct Outputs {
    mode: f64,
    u: V3,
    u_l: V3,
    du: f64,
    n_observed: f64,
    p_d: V3,
    /// Rows of the safety filter the nominal command broke; the slack it needed; the least
    /// barrier value h (NaN without a filter or with nobody heard).
    safety_active: f64,
    safety_slack: f64,
    safety_min_h: f64,
}

/// Everything that changes during a run (the checkpoint).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
struct State {
    /// The shares of the last step, by sender id.
    heard: Vec<(u32, SwarmShare)>,
    plan: Option<Rollout>,
    out: Outputs,
    clipped_steps: u64,
    bad_readings: u64,
    /// Steps the filter changed the command; steps its solver failed (the nominal was flown).
    filtered_steps: u64,
    filter_failures: u64,
    /// The own-state estimate (with an estimator).
    nav: OwnState,
}

pub struct SwarmAgent {
    prm: SwarmAgentParams,
    dt_s: f64,
    policy: Arc<dyn SwarmPolicy>,
    st: State,
}

impl SwarmAgent {
    pub fn new(prm: SwarmAgentParams, dt_s: f64, policy: Arc<dyn SwarmPolicy>) -> Self {
        Self { prm, dt_s, policy, st: State::default() }
    }

    /// The heard vehicles within R_comm of `p`, as (p, v) at t_k (the shares of k − 1 propagated).
    fn near(&self, p: V3) -> Vec<(V3, V3)> {
        self.st
            .heard
            .iter()
            .map(|(_, s)| s.propagated(self.dt_s))
            .filter(|(q, _)| distance_m(*q, p) < self.prm.r_comm_m)
            .collect()
    }

    /// The Neural-Rendezvous command about `u_l`: rebuild the roll-out when due, then the
    /// min-norm tracking of its node for step `k`.
    fn track(&mut self, k: u64, t_s: f64, r: &SwarmReading, others: &[(V3, V3)], u_l: V3) -> (V3, f64) {
        let prm = self.prm;
        let due = self.st.plan.as_ref().is_none_or(|p| k >= p.k0 + prm.rebuild_steps as u64);
        if due {
            let mut plan = roll_out(
                self.policy.as_ref(),
                r.p_m,
                r.v_mps,
                r.goal_m,
                others,
                prm.r_comm_m,
                prm.a_max_mps2,
                self.dt_s,
                prm.horizon_steps,
                prm.t_reconfig_s - t_s,
            );
            plan.k0 = k;
            self.st.plan = Some(plan);
        }
        let plan = self.st.plan.as_ref().expect("built above");
        let j = ((k - plan.k0) as usize).min(plan.a_mps2.len() - 1);
        let (pd, vd, ad) = (plan.p_m[j], plan.v_mps[j], plan.a_mps2[j]);
        let lam = prm.lambda_per_s;
        let s: V3 = [0, 1, 2].map(|a| r.v_mps[a] - vd[a] + lam * (r.p_m[a] - pd[a]));
        let sigma: V3 = [0, 1, 2].map(|a| ad[a] - lam * (r.v_mps[a] - vd[a]));
        let mut u = [0.0; 3];
        min_norm(&u_l, &s, &sigma, prm.alpha_per_s, &mut u);
        self.st.out.p_d = pd;
        (u, if due { MODE_REBUILT } else { MODE_TRACKING })
    }
}

impl Algorithm for SwarmAgent {
    fn columns(&self) -> Vec<String> {
        [
            "mode",
            "u_x_mps2",
            "u_y_mps2",
            "u_z_mps2",
            "u_l_x_mps2",
            "u_l_y_mps2",
            "u_l_z_mps2",
            "du_mps2",
            "n_observed",
            "p_d_x_m",
            "p_d_y_m",
            "p_d_z_m",
            "clipped_steps",
            "safety_active",
            "safety_slack_mps2",
            "safety_min_h",
            "filtered_steps",
            "filter_failures",
        ]
        .map(String::from)
        .to_vec()
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.clear();
        out.values.clear();
        let Ok(mut r) = SwarmReading::parse(input.readings) else {
            self.st.bad_readings += 1;
            // The estimate moves on with the zero command flown.
            if let Some(cfg) = &self.prm.estimator {
                self.st.nav.predict(cfg, [0.0; 3], self.dt_s);
            }
            self.st.out =
                Outputs { mode: MODE_BAD_READINGS, p_d: [f64::NAN; 3], safety_min_h: f64::NAN, ..Outputs::default() };
            out.command.extend([0.0; 3]);
            out.values.extend([f64::NAN; SHARE_LEN - 1]);
            out.values.push(MODE_BAD_READINGS);
            return;
        };
        if let Some(cfg) = &self.prm.estimator {
            self.st.nav.update(cfg, r.p_m, r.v_mps);
            (r.p_m, r.v_mps) = (self.st.nav.p_m, self.st.nav.v_mps);
        }
        let others = self.near(r.p_m);
        let obs = SwarmObservation::local(r.p_m, r.v_mps, r.goal_m, &others, self.prm.r_comm_m)
            .at(self.prm.t_reconfig_s - input.t_s);
        let u_l = clip(self.policy.accel_mps2(&obs), self.prm.a_max_mps2);
        self.st.out = Outputs { u_l, n_observed: obs.n_neighbours as f64, p_d: [f64::NAN; 3], ..Outputs::default() };
        let (u_star, mode) = match self.prm.method {
            SwarmMethod::Policy => (u_l, MODE_POLICY),
            SwarmMethod::Nr => self.track(input.k, input.t_s, &r, &others, u_l),
        };
        let du = distance_m(u_star, u_l);
        let mut u = clip(u_star, self.prm.a_max_mps2);
        if u != u_star {
            self.st.clipped_steps += 1;
        }
        if !u.iter().all(|x| x.is_finite()) {
            u = [0.0; 3];
        }
        self.st.out.safety_min_h = f64::NAN;
        if let Some(cfg) = &self.prm.safety {
            let f = swarm_safety::filter(cfg, self.prm.a_max_mps2, r.p_m, r.v_mps, u, &others);
            self.st.filtered_steps += u64::from(f.active > 0 && !f.failed);
            self.st.filter_failures += u64::from(f.failed);
            // No neighbour heard: no barrier value (NaN, as without a filter).
            let min_h = if f.min_h.is_finite() { f.min_h } else { f64::NAN };
            (self.st.out.safety_active, self.st.out.safety_slack, self.st.out.safety_min_h) =
                (f.active as f64, f.slack_mps2, min_h);
            u = f.u_mps2;
        }
        if let Some(cfg) = &self.prm.estimator {
            self.st.nav.predict(cfg, u, self.dt_s);
        }
        (self.st.out.mode, self.st.out.u, self.st.out.du) = (mode, u, du);
        out.command.extend(u);
        SwarmShare { p_m: r.p_m, v_mps: r.v_mps, u_mps2: u, mode }.write(&mut out.values);
    }

    fn step(&mut self, _dt_s: f64, neighbours: &[Neighbour<'_>]) {
        let mut heard: Vec<(u32, SwarmShare)> =
            neighbours.iter().filter_map(|n| SwarmShare::parse(n.values).map(|s| (n.id, s))).collect();
        // The observation breaks distance ties by this order: make it the ids', whatever the
        // arrival order.
        heard.sort_by_key(|(id, _)| *id);
        self.st.heard = heard;
    }

    fn row(&self, out: &mut Vec<f64>) {
        let o = &self.st.out;
        out.push(o.mode);
        out.extend(o.u);
        out.extend(o.u_l);
        out.extend([o.du, o.n_observed]);
        out.extend(o.p_d);
        out.push(self.st.clipped_steps as f64);
        out.extend([o.safety_active, o.safety_slack, o.safety_min_h]);
        out.extend([self.st.filtered_steps as f64, self.st.filter_failures as f64]);
    }

    fn save_state(&self) -> Vec<u8> {
        cohort_runtime::checkpoint::encode_state(&self.st)
    }

    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        self.st = cohort_runtime::checkpoint::decode_state(bytes)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::swarm::control::pd::PdPolicy;

    /// A policy that reacts to its neighbours (pushes away from each observed one), so a test
    /// can see whether a share reached the command.
    struct Repel;
    impl SwarmPolicy for Repel {
        fn accel_mps2(&self, obs: &SwarmObservation) -> [f64; 3] {
            let mut a = obs.goal_offset_m;
            for n in obs.observed() {
                for i in 0..3 {
                    a[i] -= n.dp_m[i];
                }
            }
            a
        }
    }

    fn params(method: SwarmMethod) -> SwarmAgentParams {
        SwarmAgentParams {
            method,
            r_comm_m: 1.0,
            a_max_mps2: 2.0,
            lambda_per_s: 2.0,
            alpha_per_s: 2.0,
            horizon_steps: 20,
            rebuild_steps: 5,
            t_reconfig_s: 8.0,
            safety: None,
            estimator: None,
        }
    }

    fn readings(p: V3, v: V3, g: V3) -> Vec<f64> {
        let mut out = Vec::new();
        SwarmReading { p_m: p, v_mps: v, goal_m: g }.write(&mut out);
        out
    }

    fn share_of(p: V3, v: V3) -> Vec<f64> {
        let mut out = Vec::new();
        SwarmShare { p_m: p, v_mps: v, u_mps2: [0.0; 3], mode: 0.0 }.write(&mut out);
        out
    }

    /// The command at step 1 after hearing `heard` at step 0.
    fn command_after(method: SwarmMethod, heard: &[(u32, Vec<f64>)]) -> Vec<f64> {
        let mut a = SwarmAgent::new(params(method), 0.1, Arc::new(Repel));
        let mut out = ShareOut::default();
        let r0 = readings([0.0, 0.0, 1.0], [0.1, 0.0, 0.0], [1.0, 0.5, 1.0]);
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &r0 }, &mut out);
        let nbrs: Vec<Neighbour<'_>> =
            heard.iter().map(|(id, v)| Neighbour { id: *id, values: v, age_steps: 0 }).collect();
        a.step(0.1, &nbrs);
        let r1 = readings([0.01, 0.0, 1.0], [0.1, 0.0, 0.0], [1.0, 0.5, 1.0]);
        a.share(&AgentInput { k: 1, t_s: 0.1, readings: &r1 }, &mut out);
        out.command
    }

    #[test]
    fn a_vehicle_outside_r_comm_does_not_change_the_command_and_one_inside_does() {
        for method in [SwarmMethod::Nr, SwarmMethod::Policy] {
            let alone = command_after(method, &[]);
            // 1.2 m away, and still 1.1 m away after the interval (moving toward us at 1 m/s).
            let far = command_after(method, &[(3, share_of([1.2, 0.0, 1.0], [-1.0, 0.0, 0.0]))]);
            let bits = |c: &[f64]| c.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&alone), bits(&far), "{method:?}: a share from beyond R_comm changed the command");
            // 1.0 m from the own estimate at step 1 (x = 0.01): at R_comm, not observed either.
            let edge = command_after(method, &[(4, share_of([1.01, 0.0, 1.0], [0.0; 3]))]);
            assert_eq!(bits(&alone), bits(&edge), "{method:?}: a share at R_comm changed the command");
            let near = command_after(method, &[(3, share_of([0.5, 0.0, 1.0], [0.0; 3]))]);
            assert_ne!(bits(&alone), bits(&near), "{method:?}: a share within R_comm must count");
            // The far one next to the near one changes nothing either.
            let both = command_after(
                method,
                &[(3, share_of([0.5, 0.0, 1.0], [0.0; 3])), (7, share_of([0.0, 1.5, 1.0], [0.0; 3]))],
            );
            assert_eq!(bits(&near), bits(&both), "{method:?}");
        }
    }

    /// A policy that flies its time to go along x (to see which time it is given).
    struct Clock;
    impl SwarmPolicy for Clock {
        fn accel_mps2(&self, obs: &SwarmObservation) -> [f64; 3] {
            [obs.t_to_go_s, 0.0, 0.0]
        }
    }

    #[test]
    fn the_policy_sees_the_time_to_go_now_and_along_the_roll_out() {
        let mut a = SwarmAgent::new(params(SwarmMethod::Policy), 0.1, Arc::new(Clock));
        let mut out = ShareOut::default();
        let r = readings([0.0, 0.0, 1.0], [0.0; 3], [1.0, 0.0, 1.0]);
        for (t_s, want) in [(6.5, 1.5), (7.9, 8.0 - 7.9), (9.0, 0.0)] {
            a.share(&AgentInput { k: 0, t_s, readings: &r }, &mut out);
            assert!((out.command[0] - want).abs() < 1e-12, "t = {t_s}: {:?}", out.command);
        }
        // T − t = 1 s at the roll-out's start: 1.0, 0.9, …, 0.1, then 0 from T on.
        let plan = roll_out(&Clock, [0.0; 3], [0.0; 3], [1.0; 3], &[], 1.0, 2.0, 0.1, 15, 1.0);
        for (j, a) in plan.a_mps2.iter().enumerate() {
            let want = (1.0 - 0.1 * j as f64).max(0.0);
            assert!((a[0] - want).abs() < 1e-12, "node {j}: {a:?}");
        }
    }

    #[test]
    fn nr_tracks_its_roll_out_exactly_without_noise_and_rebuilds_on_schedule() {
        // A PD policy with no neighbours and perfect readings: the vehicle is on its own roll-out
        // (s = 0), so u* = u_ℓ and the desired position is where it is.
        let pd = PdPolicy { omega_per_s: 1.0, a_max_mps2: 2.0 };
        let mut a = SwarmAgent::new(params(SwarmMethod::Nr), 0.1, Arc::new(pd));
        let (mut p, mut v, g) = ([0.0, 0.0, 1.0], [0.0; 3], [2.0, -1.0, 1.5]);
        let mut out = ShareOut::default();
        let mut modes = Vec::new();
        for k in 0..12 {
            a.share(&AgentInput { k, t_s: k as f64 * 0.1, readings: &readings(p, v, g) }, &mut out);
            let mut row = Vec::new();
            a.row(&mut row);
            modes.push(row[0]);
            assert!(row[7] < 1e-12, "‖u* − u_ℓ‖ = {} at k = {k}", row[7]);
            assert!(distance_m([row[9], row[10], row[11]], p) < 1e-12);
            a.step(0.1, &[]);
            let u = [out.command[0], out.command[1], out.command[2]];
            p = [0, 1, 2].map(|i| p[i] + v[i] * 0.1 + 0.5 * u[i] * 0.01);
            v = [0, 1, 2].map(|i| v[i] + u[i] * 0.1);
        }
        let want: Vec<f64> = (0..12).map(|k| if k % 5 == 0 { MODE_REBUILT } else { MODE_TRACKING }).collect();
        assert_eq!(modes, want);
    }

    #[test]
    fn off_its_roll_out_nr_pulls_back_and_satisfies_the_stability_condition() {
        // A disturbance pushed the vehicle 5 cm off since the rebuild: the constraint is active and
        // the command differs from the policy's.
        let pd = PdPolicy { omega_per_s: 1.0, a_max_mps2: 2.0 };
        let mut a = SwarmAgent::new(params(SwarmMethod::Nr), 0.1, Arc::new(pd));
        let g = [2.0, 0.0, 1.0];
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &readings([0.0, 0.0, 1.0], [0.0; 3], g) }, &mut out);
        a.step(0.1, &[]);
        let plan = a.st.plan.clone().unwrap();
        let (p1, v1) = (plan.p_m[1], plan.v_mps[1]);
        let off = [p1[0], p1[1] + 0.05, p1[2]];
        a.share(&AgentInput { k: 1, t_s: 0.1, readings: &readings(off, v1, g) }, &mut out);
        let mut row = Vec::new();
        a.row(&mut row);
        assert_eq!(row[0], MODE_TRACKING);
        assert!(row[7] > 0.0, "the min-norm constraint must act");
        // The pull is toward the roll-out (−y).
        assert!(out.command[1] < row[5], "u_y {} vs u_ℓ,y {}", out.command[1], row[5]);
    }

    #[test]
    fn checkpoints_restore_exactly_and_bad_readings_give_zero() {
        let pd = PdPolicy { omega_per_s: 1.0, a_max_mps2: 2.0 };
        let mut a = SwarmAgent::new(params(SwarmMethod::Nr), 0.1, Arc::new(pd));
        let mut out = ShareOut::default();
        let r = readings([0.0, 0.0, 1.0], [0.0; 3], [1.0, 1.0, 1.0]);
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &r }, &mut out);
        let s = share_of([0.3, 0.0, 1.0], [0.0; 3]);
        a.step(0.1, &[Neighbour { id: 2, values: &s, age_steps: 0 }]);
        let bytes = a.save_state();
        let mut b = SwarmAgent::new(params(SwarmMethod::Nr), 0.1, Arc::new(pd));
        b.restore_state(&bytes).unwrap();
        // Bytes, not ==: the state holds NaN (no barrier value without a filter).
        assert_eq!(b.save_state(), bytes);
        assert!(b.restore_state(&bytes[..bytes.len() / 2]).is_err());
        assert_eq!(b.save_state(), bytes);
        a.share(&AgentInput { k: 1, t_s: 0.1, readings: &[1.0; 4] }, &mut out);
        assert_eq!(out.command, vec![0.0; 3]);
        assert_eq!(out.values.len(), SHARE_LEN);
        assert_eq!(SwarmShare::parse(&out.values), None, "a bad vehicle's share is not observed");
    }
}
