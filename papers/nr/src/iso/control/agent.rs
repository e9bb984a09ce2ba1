//! The spacecraft's algorithm: Neural-Rendezvous (Algorithm 1 of "Neural-Rendezvous",
//! arXiv:2208.04883) and the baselines of Sec. 6.3, selected by `algorithm.method`
//! ([`crate::iso::config::Method`]).
//!
//! Neural-Rendezvous, each step t_k: the SN-DNN guidance u_ℓ(x̂, œ̂, t, ρ_f) until t_s; from t_s
//! the desired trajectory (21)–(23) is built by rolling the SN-DNN forward to t_f and back
//! ([`crate::iso::guidance::desired`]), rebuilt every `rebuild_every_s` from the newest estimates (Remark 7), and
//! tracked with the min-norm control (27) ([`crate::iso::control::min_norm`], [`crate::iso::control::tracking`]) about u_ℓ;
//! the bound b_e ([`crate::iso::control::bound`]) restarts at each rebuild from ‖p̂ − p_d‖ + ε_p and
//! ‖ŝ‖ + ε_s and is driven by L̄ε/m_min, L̄ the secant Lipschitz constant (46) of the control in
//! the estimate by central differences of one noise level (ε) each way.
//!
//! Departures: the whole desired trajectory is built in the step it is needed (Remark 10 allows
//! several; the measured build time is within the step budget); the command is clipped to u_max
//! per LVLH axis (Remark 8: the min-norm solution may exceed it; clips are counted); the robust
//! NMPC reports no bound (its L̄ would need an SCP per difference).

use std::path::Path;
use std::sync::Arc;

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use cohort_runtime::solver_stats::{SolveLog, SolverStats};
use serde::{Deserialize, Serialize};

use crate::iso::config::{LinearMpcMode, Method, NrAlgorithmConfig};
use crate::iso::control::baselines::{linear_mpc, linear_mpc_plan, pd, robust_tracking};
use crate::iso::control::bound::Bound;
use crate::iso::control::min_norm::min_norm;
use crate::iso::control::tracking::{Tracking, tracking};
use crate::iso::dynamics::constants::{DV_BUDGET_MPS, G0_MPS2};
use crate::iso::dynamics::lvlh::{IsoFrame, OrbitRates, X6, pos};
use crate::iso::dynamics::messages::{Reading, SHARE_LEN};
use crate::iso::dynamics::two_body::{Inertial, V3};
use crate::iso::guidance::desired::{self, Desired};
use crate::iso::guidance::features::{N_FEATURES, REFERENCE_INPUTS, features};
use crate::iso::guidance::scp::{self, Plan, ScpInput};
use crate::nn::sn_dnn::{SnDnn, WeightsError};

/// Mode codes (telemetry and share value 0).
pub const MODE_BAD_READINGS: f64 = -1.0;
pub const MODE_GUIDANCE: f64 = 0.0;
pub const MODE_TRACKING: f64 = 1.0;
pub const MODE_REBUILT: f64 = 2.0;
pub const MODE_COAST: f64 = 3.0;

/// A weights file or configuration the agent cannot run with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AgentError {
    #[error(transparent)]
    Weights(#[from] WeightsError),
    #[error("{0}")]
    Config(String),
}

/// What the last `share` decided (the telemetry row).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
struct Outputs {
    mode: f64,
    u_lvlh_n: V3,
    du_n: f64,
    v: f64,
    b_e_m: f64,
    b_s_mps: f64,
    drive_mps2: f64,
    scp_miss_m: f64,
    /// The desired position p_d(t_k) being tracked (LVLH of the estimated ISO), NaN when none.
    p_d_m: V3,
}

/// Everything that changes during a run (the checkpoint).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
struct State {
    out: Outputs,
    desired: Option<Desired>,
    built_at_s: f64,
    bound: Option<Bound>,
    drive_mps2: f64,
    warm_u: Vec<V3>,
    fixed: Option<Desired>,
    clipped_steps: u64,
    bad_readings: u64,
    /// Δv spent so far by the commands sent (rocket equation), m/s.
    dv_spent_mps: f64,
    /// The one-solve linear MPC's commands, from the step at `lin_from_s`.
    lin_plan: Option<Vec<V3>>,
    lin_from_s: f64,
}

pub struct NrAgent {
    cfg: NrAlgorithmConfig,
    dt_s: f64,
    net: Option<Arc<SnDnn>>,
    st: State,
    log: SolveLog,
}

/// Load and check the SN-DNN a configuration names (None for methods without one).
pub fn load_net(cfg: &NrAlgorithmConfig) -> Result<Option<Arc<SnDnn>>, AgentError> {
    if !cfg.method.needs_weights() {
        return Ok(None);
    }
    let path = cfg.weights.as_deref().ok_or_else(|| {
        AgentError::Config(format!("algorithm.weights: method {} needs an SN-DNN weights file", cfg.method.name()))
    })?;
    let net = SnDnn::load(path)?;
    check_net(&net, cfg, path)?;
    Ok(Some(Arc::new(net)))
}

fn check_net(net: &SnDnn, cfg: &NrAlgorithmConfig, path: &Path) -> Result<(), AgentError> {
    let bad = |reason: String| AgentError::Weights(WeightsError::invalid(crate::nn::sn_dnn::MODEL, path, reason));
    if !(net.n_in() == N_FEATURES || net.n_in() == REFERENCE_INPUTS) || net.n_out() != 3 {
        return Err(bad(format!(
            "a network {} → {}, the guidance needs {N_FEATURES} (or the reference's {REFERENCE_INPUTS}) → 3",
            net.n_in(),
            net.n_out()
        )));
    }
    if let Some(c) = cfg.c_sn.filter(|c| *c != net.c_sn()) {
        return Err(bad(format!("C_sn = {}, algorithm.c_sn asks for {c}", net.c_sn())));
    }
    Ok(())
}

/// The agent for a configuration and control interval (loads the weights it names).
pub fn build_agent(cfg: &NrAlgorithmConfig, dt_s: f64) -> Result<NrAgent, AgentError> {
    let net = load_net(cfg)?;
    NrAgent::new(cfg.clone(), dt_s, net)
}

impl NrAgent {
    /// With an already loaded network (shared by many agents of a campaign).
    pub fn new(cfg: NrAlgorithmConfig, dt_s: f64, net: Option<Arc<SnDnn>>) -> Result<Self, AgentError> {
        if let Some(p) = cfg.validate().first() {
            return Err(AgentError::Config(p.to_string()));
        }
        if cfg.method.needs_weights() && net.is_none() {
            return Err(AgentError::Config(format!("method {} needs an SN-DNN", cfg.method.name())));
        }
        if let Some(n) = &net {
            check_net(n, &cfg, cfg.weights.as_deref().unwrap_or(Path::new("(in memory)")))?;
        }
        let log = SolveLog::new("clarabel terminal QP (3N variables, 3 equality + 6N box rows)");
        Ok(Self { cfg, dt_s, net, st: State::default(), log })
    }

    /// The bound b_e at the agent's current time (None if it keeps none), m.
    pub fn bound_m(&self) -> Option<f64> {
        self.st.bound.map(|b| b.b_e)
    }

    /// Steps whose command was clipped to u_max.
    pub fn clipped_steps(&self) -> u64 {
        self.st.clipped_steps
    }

    fn policy(&self, x: &X6, iso: &Inertial, t_s: f64, r: &Reading) -> V3 {
        let net = self.net.as_ref().expect("checked at construction");
        let f = features(x, iso, t_s, r.t_f_s, &r.rho_f_m);
        let mut u = [0.0; 3];
        net.forward(&f[..net.n_in()], &mut u);
        V3::from(u)
    }

    fn needs_rebuild(&self, t_s: f64) -> bool {
        match &self.st.desired {
            None => true,
            Some(d) => t_s - self.st.built_at_s >= self.cfg.rebuild_every_s - 1e-6 * self.dt_s || d.node(t_s).is_none(),
        }
    }

    /// u* of the min-norm control at estimate `x` on `d`'s node `k`, about `u_nom`.
    fn min_norm_at(&self, x: &X6, d: &Desired, k: usize, u_nom: &V3, r: &Reading) -> (V3, Tracking) {
        let (xd, pdd) = d.state_accel(k);
        let tr = tracking(x, &xd, &pdd, self.cfg.lambda_per_s, r.m_kg, &OrbitRates::of(&r.iso_hat));
        let mut u = [0.0; 3];
        min_norm(u_nom.as_slice(), tr.s.as_slice(), tr.sigma_n.as_slice(), self.cfg.alpha_per_s * r.m_kg, &mut u);
        (V3::from(u), tr)
    }

    /// L̄ε/m_min: the secant Lipschitz constant of the NR control in the estimate over one noise
    /// level each way, times the noise level, over the smallest mass the Δv budget leaves.
    fn drive(&self, d: &Desired, k: usize, r: &Reading, t_s: f64) -> f64 {
        let (eps_p, eps_v) = relative_noise(r);
        let mut lbar_eps = 0.0;
        for (block, eps) in [(0, eps_p), (3, eps_v)] {
            if eps == 0.0 {
                continue;
            }
            let mut frob = 0.0;
            for i in block..block + 3 {
                let mut col = V3::zeros();
                for sign in [1.0, -1.0] {
                    let mut x = r.x_hat;
                    x[i] += sign * eps;
                    let u_l = self.policy(&x, &r.iso_hat, t_s, r);
                    col += sign * self.min_norm_at(&x, d, k, &u_l, r).0;
                }
                frob += (col / (2.0 * eps)).norm_squared();
            }
            lbar_eps += frob.sqrt() * eps;
        }
        let m_min = r.m_kg * (-DV_BUDGET_MPS / (r.isp_s * G0_MPS2)).exp();
        lbar_eps / m_min
    }

    /// Min-norm tracking about `u_nom` on the (re)built desired trajectory; `build` makes a new one.
    fn track(
        &mut self,
        r: &Reading,
        t_s: f64,
        u_nom: V3,
        build: &mut dyn FnMut(&Self) -> Desired,
        with_bound: bool,
    ) -> (V3, f64) {
        let rebuilt = self.needs_rebuild(t_s);
        if rebuilt {
            self.st.desired = Some(build(self));
            self.st.built_at_s = t_s;
        }
        let d = self.st.desired.take().expect("just ensured");
        let k = d.node(t_s).expect("a fresh trajectory starts at t");
        let (u, tr) = self.min_norm_at(&r.x_hat, &d, k, &u_nom, r);
        self.st.out.v = tr.v;
        self.st.out.p_d_m = pos(&d.x[k]);
        if with_bound {
            let (eps_p, eps_v) = relative_noise(r);
            if rebuilt || self.st.bound.is_none() {
                let e0 = (pos(&r.x_hat) - pos(&d.x[k])).norm() + eps_p;
                self.st.bound = Some(Bound::new(tr.s.norm() + eps_v + self.cfg.lambda_per_s * eps_p, e0));
            }
            self.st.drive_mps2 = self.drive(&d, k, r, t_s);
        }
        self.st.desired = Some(d);
        (u, if rebuilt { MODE_REBUILT } else { MODE_TRACKING })
    }

    fn scp_plan(&mut self, inp: &ScpInput) -> Plan {
        let warm = std::mem::take(&mut self.st.warm_u);
        let plan = scp::solve(inp, Some(&warm), &self.cfg.scp, &mut self.log);
        self.st.warm_u = plan.traj.u_n.iter().skip(1).copied().collect();
        self.st.out.scp_miss_m = plan.miss_m;
        plan
    }

    fn fixed_plan(&mut self, inp: &ScpInput) -> (Desired, usize) {
        if self.st.fixed.as_ref().and_then(|d| d.node(inp.t0_s)).is_none() {
            let plan = scp::solve(inp, None, &self.cfg.scp, &mut self.log);
            self.st.out.scp_miss_m = plan.miss_m;
            self.st.fixed = Some(Desired::from_plan(&plan));
        }
        let d = self.st.fixed.clone().expect("just ensured");
        let k = d.node(inp.t0_s).expect("the plan starts at or before t");
        (d, k)
    }

    /// `u` cut so that the Δv it spends over this step (the rocket equation, as the plant counts
    /// it) keeps the total within `budget`; the spent total updated.
    fn within_budget(&mut self, u: V3, budget: f64, r: &Reading) -> V3 {
        let ve = r.isp_s * G0_MPS2;
        let dv = |n: f64| ve * (r.m_kg / (r.m_kg - n * self.dt_s / ve)).ln();
        // A part in 10⁹ kept back: the plant sums the same rocket equation in its own order.
        let left = (budget * (1.0 - 1e-9) - self.st.dv_spent_mps).max(0.0);
        let n = u.norm();
        let scale = if n == 0.0 || dv(n) <= left {
            1.0
        } else {
            // The rocket equation inverted: the thrust that spends exactly what is left.
            let n_left = ve * r.m_kg * (1.0 - (-left / ve).exp()) / self.dt_s;
            n_left / n
        };
        let u = u * scale;
        self.st.dv_spent_mps += dv(u.norm());
        u
    }

    /// The method's command (LVLH, N) and its nominal part u_ℓ (or u_mpc), and the mode.
    fn decide(&mut self, r: &Reading, inp: &ScpInput) -> (V3, V3, f64) {
        let t = inp.t0_s;
        let after_ts = t >= self.cfg.t_s_fraction * r.t_f_s - 1e-6 * self.dt_s;
        match self.cfg.method {
            Method::SnDnn => {
                let u = self.policy(&r.x_hat, &r.iso_hat, t, r);
                (u, u, MODE_GUIDANCE)
            }
            Method::NeuralRendezvous => {
                let u_l = self.policy(&r.x_hat, &r.iso_hat, t, r);
                if !after_ts {
                    return (u_l, u_l, MODE_GUIDANCE);
                }
                let backward = self.cfg.backward;
                let mut build = |me: &Self| {
                    desired::build(inp, backward, &mut |x: &X6, iso: &Inertial, tj: f64| me.policy(x, iso, tj, r))
                };
                let (u, mode) = self.track(r, t, u_l, &mut build, true);
                (u, u_l, mode)
            }
            Method::Nmpc => {
                let u = self.scp_plan(inp).first_u();
                (u, u, MODE_GUIDANCE)
            }
            Method::RobustNmpc => {
                let plan = self.scp_plan(inp);
                let u_mpc = plan.first_u();
                if !after_ts {
                    return (u_mpc, u_mpc, MODE_GUIDANCE);
                }
                let (u, mode) = self.track(r, t, u_mpc, &mut |_| Desired::from_plan(&plan), false);
                (u, u_mpc, mode)
            }
            Method::LinearMpc if self.cfg.linear_mpc == LinearMpcMode::Once => {
                if self.st.lin_plan.is_none() {
                    self.st.lin_plan = Some(linear_mpc_plan(inp, &mut self.log).map(|(u, _)| u).unwrap_or_default());
                    self.st.lin_from_s = t;
                }
                let k = ((t - self.st.lin_from_s) / self.dt_s).round() as usize;
                let u = self.st.lin_plan.as_ref().and_then(|p| p.get(k)).copied().unwrap_or_else(V3::zeros);
                (u, u, MODE_GUIDANCE)
            }
            Method::LinearMpc => {
                let u = linear_mpc(inp, &mut self.log).map(|(u, _)| u).unwrap_or_else(V3::zeros);
                (u, u, MODE_GUIDANCE)
            }
            Method::Pd => {
                let (d, k) = self.fixed_plan(inp);
                self.st.out.p_d_m = pos(&d.x[k]);
                let u = pd(&r.x_hat, &d.x[k], &d.u_n[k], r.m_kg, self.cfg.pd_lambda_per_s);
                (u, d.u_n[k], MODE_TRACKING)
            }
            Method::RobustTracking => {
                let (d, k) = self.fixed_plan(inp);
                self.st.out.p_d_m = pos(&d.x[k]);
                let (xd, pdd) = d.state_accel(k);
                let tr = tracking(&r.x_hat, &xd, &pdd, self.cfg.lambda_per_s, r.m_kg, &OrbitRates::of(&r.iso_hat));
                self.st.out.v = tr.v;
                (robust_tracking(&tr, self.cfg.alpha_per_s, r.m_kg), d.u_n[k], MODE_TRACKING)
            }
        }
    }
}

/// RMS norms of the relative position and velocity estimation errors (two bodies' independent
/// errors), the ε of the bound, m and m/s.
fn relative_noise(r: &Reading) -> (f64, f64) {
    (std::f64::consts::SQRT_2 * r.sigma.pos_rms_m(), std::f64::consts::SQRT_2 * r.sigma.vel_rms_mps())
}

impl Algorithm for NrAgent {
    fn columns(&self) -> Vec<String> {
        [
            "mode",
            "u_x_n",
            "u_y_n",
            "u_z_n",
            "du_n",
            "v",
            "b_e_m",
            "b_s_mps",
            "drive_mps2",
            "scp_miss_m",
            "p_d_x_m",
            "p_d_y_m",
            "p_d_z_m",
            "clipped_steps",
        ]
        .map(String::from)
        .to_vec()
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.clear();
        out.values.clear();
        let r = match Reading::parse(input.readings) {
            Ok(r) => r,
            Err(_) => {
                self.st.bad_readings += 1;
                self.st.out = Outputs { mode: MODE_BAD_READINGS, p_d_m: V3::repeat(f64::NAN), ..Outputs::default() };
                out.command.extend([0.0; 3]);
                out.values.extend([MODE_BAD_READINGS, 0.0, 0.0, -1.0]);
                return;
            }
        };
        let inp = ScpInput {
            x0: r.x_hat,
            iso0: r.iso_hat,
            m0_kg: r.m_kg,
            t0_s: input.t_s,
            t_f_s: r.t_f_s,
            dt_s: self.dt_s,
            rho_f_m: r.rho_f_m,
            u_max_n: r.u_max_n,
            isp_s: r.isp_s,
        };
        self.st.out = Outputs { scp_miss_m: self.st.out.scp_miss_m, p_d_m: V3::repeat(f64::NAN), ..Outputs::default() };
        let (mut u, u_nom, mode) =
            if inp.steps() == 0 { (V3::zeros(), V3::zeros(), MODE_COAST) } else { self.decide(&r, &inp) };
        let du = (u - u_nom).norm();
        if self.cfg.clip_to_u_max && u.amax() > r.u_max_n {
            u = u.map(|c| c.clamp(-r.u_max_n, r.u_max_n));
            self.st.clipped_steps += 1;
        }
        if !u.iter().all(|c| c.is_finite()) {
            u = V3::zeros();
        }
        if let Some(budget) = self.cfg.dv_budget_mps {
            u = self.within_budget(u, budget, &r);
        }
        let b = self.st.bound.unwrap_or(Bound::new(-1.0, -1.0));
        let o = &mut self.st.out;
        (o.mode, o.u_lvlh_n, o.du_n, o.b_e_m, o.b_s_mps, o.drive_mps2) =
            (mode, u, du, b.b_e, b.b_s, self.st.drive_mps2);
        out.command.extend(IsoFrame::of(&r.iso_hat).to_inertial(&u).iter());
        out.values.extend([mode, du, o.v, b.b_e]);
        debug_assert_eq!(out.values.len(), SHARE_LEN);
    }

    fn step(&mut self, dt_s: f64, _neighbours: &[Neighbour<'_>]) {
        if let Some(b) = &mut self.st.bound {
            b.advance(dt_s, self.cfg.alpha_per_s, self.cfg.lambda_per_s, self.st.drive_mps2);
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        let o = &self.st.out;
        out.extend([
            o.mode,
            o.u_lvlh_n.x,
            o.u_lvlh_n.y,
            o.u_lvlh_n.z,
            o.du_n,
            o.v,
            o.b_e_m,
            o.b_s_mps,
            o.drive_mps2,
            o.scp_miss_m,
            o.p_d_m.x,
            o.p_d_m.y,
            o.p_d_m.z,
        ]);
        out.push(self.st.clipped_steps as f64);
    }

    fn save_state(&self) -> Vec<u8> {
        cohort_runtime::checkpoint::encode_state(&self.st)
    }

    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        self.st = cohort_runtime::checkpoint::decode_state(bytes)?;
        Ok(())
    }

    fn solver_stats(&self) -> Option<SolverStats> {
        matches!(
            self.cfg.method,
            Method::Nmpc | Method::RobustNmpc | Method::LinearMpc | Method::Pd | Method::RobustTracking
        )
        .then(|| self.log.stats())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::config::{IsoEncounterConfig, build_plant};
    use crate::nn::sn_dnn::tests::random_net_scaled;
    use cohort_runtime::model::PlantModel;
    use cohort_runtime::rng::process_rng;
    use cohort_wire::transport::Proc;

    /// A random SN-DNN with input scales of the features' sizes (the behaviour is arbitrary but
    /// exercises every part of the agent).
    fn net() -> Arc<SnDnn> {
        let mut scale = vec![1e10, 1e10, 1e10, 1e5, 1e5, 1e5, 1e6, 1e6, 1e6, 1e5, 2e11, 1e-6, 1e5, 1e5, 1e5];
        scale.extend([1e-4; 3]);
        Arc::new(random_net_scaled(&[18, 16, 16, 3], 2.0, 3, scale, vec![0.05; 3]))
    }

    fn agent(method: Method) -> NrAgent {
        let mut cfg = NrAlgorithmConfig::new(method);
        cfg.weights = Some("random.safetensors".into());
        NrAgent::new(cfg, 600.0, method.needs_weights().then(net)).unwrap()
    }

    /// Run `a` to step `split`, then copy its state into `b` and check both give the same bits
    /// to the end.
    fn checkpoint_round_trip(method: Method, split: u64) {
        let cfg = IsoEncounterConfig { iso_index: Some(230), ..IsoEncounterConfig::default() };
        let mut plant = build_plant(&cfg, 1, 600.0, 230).unwrap();
        let mut rng = process_rng(230, Proc::Plant);
        let (mut a, mut b) = (agent(method), agent(method));
        let (mut oa, mut ob, mut readings) = (ShareOut::default(), ShareOut::default(), Vec::new());
        for k in 0..144u64 {
            readings.clear();
            plant.readings(1, &mut rng, &mut readings);
            let input = AgentInput { k, t_s: k as f64 * 600.0, readings: &readings };
            if k == split {
                let bytes = a.save_state();
                b.restore_state(&bytes).unwrap();
                assert_eq!(b.save_state(), bytes, "{method:?}: restore then save gives other bytes");
            }
            a.share(&input, &mut oa);
            if k >= split {
                b.share(&input, &mut ob);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&oa.command), bits(&ob.command), "{method:?} step {k}");
                assert_eq!(bits(&oa.values), bits(&ob.values), "{method:?} step {k}");
                let (mut ra, mut rb) = (Vec::new(), Vec::new());
                a.row(&mut ra);
                b.row(&mut rb);
                assert_eq!(bits(&ra), bits(&rb));
                b.step(600.0, &[]);
            }
            a.step(600.0, &[]);
            plant.apply_command(1, &oa.command);
            plant.advance(600.0);
        }
    }

    #[test]
    fn checkpoints_restore_every_method_exactly() {
        // After t_s (step 108) with a desired trajectory and a bound in the state, and mid-rebuild.
        for m in Method::ALL {
            checkpoint_round_trip(m, 115);
        }
        checkpoint_round_trip(Method::NeuralRendezvous, 0);
        checkpoint_round_trip(Method::NeuralRendezvous, 114);
    }

    #[test]
    fn a_damaged_checkpoint_is_refused_and_bad_readings_give_a_zero_command() {
        let mut a = agent(Method::NeuralRendezvous);
        assert!(a.restore_state(&[1, 2, 3]).is_err());
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &[1.0; 5] }, &mut out);
        assert_eq!(out.command, vec![0.0; 3]);
        assert_eq!(out.values[0], MODE_BAD_READINGS);
    }

    #[test]
    fn missing_or_mismatched_weights_are_errors_naming_the_file() {
        let mut cfg = NrAlgorithmConfig::new(Method::NeuralRendezvous);
        cfg.weights = Some("/nonexistent/nr.safetensors".into());
        let e = build_agent(&cfg, 600.0).err().expect("no such file").to_string();
        assert!(e.contains("/nonexistent/nr.safetensors") && e.contains("cannot read"), "{e}");
        cfg.c_sn = Some(4.0);
        let e = NrAgent::new(cfg, 600.0, Some(net())).err().expect("C_sn differs").to_string();
        assert!(e.contains("C_sn = 2") && e.contains("asks for 4"), "{e}");
        let small = Arc::new(random_net_scaled(&[4, 8, 3], 2.0, 1, vec![1.0; 4], vec![1.0; 3]));
        let mut cfg = NrAlgorithmConfig::new(Method::SnDnn);
        cfg.weights = Some("small.safetensors".into());
        let e = NrAgent::new(cfg, 600.0, Some(small)).err().expect("wrong input size").to_string();
        assert!(e.contains("small.safetensors") && e.contains("4 → 3"), "{e}");
    }
}
