//! Seed 001 (Ma et al.): AEMC, the active-energy-management formation controller of Sec. 3 — a
//! cooperative-game distributed MPC (14)–(26) over the total force ûᵢ = uᵢ + T̂ᵢ (13), with the
//! net tension T̂ᵢ forecast over the horizon, as a pure `Algorithm`.
//!
//! **Game state.** The consensus error (14), eᵢ = Σⱼ aᵢⱼ(x̃ᵢ − x̃ⱼ) + bᵢx̃ᵢ = cᵢx̃ᵢ − Σⱼ aᵢⱼx̃ⱼ with
//! x̃ = x − x^d and cᵢ = dᵢ + bᵢ (dᵢ = Σⱼ aᵢⱼ). The graph is the scenario's neighbour lists: for the
//! square net each MU's neighbours are the two corners it shares a net edge with (not the
//! diagonal), aᵢⱼ = `adjacency_weight` for each, bᵢ = `pinning_weight` for every MU (each knows its
//! own desired trajectory).
//!
//! **Prediction.** Stacked over the horizon (21), Eᵢ = cᵢ(Φxᵢ + ΓUᵢ − Xᵢ^d) − Σⱼ aᵢⱼ(Xⱼ − Xⱼ^d),
//! where Xⱼ is neighbour j's own predicted state sequence from its latest share. The printed
//! Hᵢ = [Âᵢ; …; Âᵢ^{N_p}] with Âᵢ = LᵢA would raise the scalar cᵢ to the p-th power; (20) and (21)
//! say Lᵢ multiplies the predicted state, so we use cᵢΦ (and cᵢΓ for Wᵢ).
//!
//! **Cost.** The Pareto solution minimises J = Σᵢ λᵢJᵢ (18), Jᵢ of (23). MU i can only choose Uᵢ, so
//! it minimises the terms of J that depend on Uᵢ, the others' sequences held at their latest
//! shares: its own λᵢJᵢ and, for every neighbour j that reads i, λⱼ's share of Jⱼ — j's consensus
//! error (which contains −aⱼᵢx̃ᵢ) and j's weight Rⱼᵢ on i's force. Divided by λᵢ:
//!
//! ```text
//! J̃ᵢ(U) = |cᵢΓU + sᵢ|²_Q̄ + r|U|² + Σⱼ (λⱼ/λᵢ)(|−aⱼᵢΓU + sⱼᵢ|²_Q̄ + rᵢⱼ|U|²)
//! sᵢ  = cᵢ(Φxᵢ − Xᵢ^d) − Σⱼ aᵢⱼ X̃ⱼ            (everything in Eᵢ but Uᵢ)
//! sⱼᵢ = ρⱼ\ᵢ − aⱼᵢ(Φxᵢ − Xᵢ^d),  ρⱼ\ᵢ = cⱼX̃ⱼ − Σ_{m∈Nⱼ, m≠i} aⱼₘX̃ₘ   (j's, from its share)
//! ```
//!
//! so P = 2H with H = (cᵢ² + Σⱼ(λⱼ/λᵢ)aⱼᵢ²)ΓᵀQ̄Γ + (r + Σⱼ(λⱼ/λᵢ)rᵢⱼ)I — fixed for the run — and
//! q = 2ΓᵀQ̄(cᵢsᵢ − Σⱼ(λⱼ/λᵢ)aⱼᵢsⱼᵢ). With `neighbour_costs = false` the sum over j is dropped and
//! this is exactly (25)–(26) (the Σⱼ UⱼᵀRᵢⱼUⱼ of (24) is constant in Uᵢ there, so Rᵢⱼ only acts
//! through the neighbours' costs). Thrust bound: |û − T̂| ≤ ū per axis at every step of the horizon.
//! With `force_cost = "thrust"` (not the paper's: an ablation) every force weight is on the MU's
//! thrust u = û − T̂ instead, which keeps H and adds −2(r + Σⱼ(λⱼ/λᵢ)rᵢⱼ)T̂ to q.
//! The command is uᵢ = ûᵢ* − T̂ᵢ (first step of the plan).
//!
//! **Timing.** At t_k MU i has its neighbours' shares of step k−1 (k−1−delay with a link delay):
//! their sequences are shifted by the age, the state tail extrapolated with their last planned
//! force held (the model (19)), the ρ tail held. A neighbour never heard, silent for more than N_p
//! steps, or whose share has the wrong length is taken as on its desired trajectory (X̃ⱼ = 0,
//! ρⱼ\ᵢ = 0); the Hessian, built for the configured graph, does not change.
//!
//! **Share layout** (N_p = horizon, D = this MU's neighbour count), all f64:
//!
//! | offset                  | length | content |
//! |-------------------------|--------|---------|
//! | 0                       | 6      | own state [r; v] at t_k, LVLH, m and m/s |
//! | 6                       | 3      | thrust uᵢ commanded at t_k, N |
//! | 9                       | 3N_p   | Uᵢ: planned total forces û(t_k … t_{k+N_p−1}), N |
//! | 9 + 3N_p + (7 + 3N_p)·s | 1      | age in steps of the s-th neighbour m's share as this MU used it at t_k (0: none) |
//! | … + 1                   | 6      | m's state in that share |
//! | … + 7                   | 3N_p   | m's Uₘ in that share |
//!
//! 9 + 3N_p + D(7 + 3N_p) values: with D = 2, N_p ≤ 54 fits the wire's 512 (validation checks it).
//! Every MU knows the scenario (the model, every MU's desired trajectory, the graph, the weights),
//! so a receiver rebuilds from this exactly what the sender computed, bit for bit, by the same
//! functions on the same numbers: the predicted states Xⱼ = Φxⱼ + ΓUⱼ (19), and ρⱼ\ᵢ from the
//! copies of j's other neighbours' shares that j forwards. Sending Xⱼ and every ρⱼ\ₘ themselves,
//! as this crate first did, takes 9 + (9 + 6D)N_p values and caps N_p at 23.
//!
//! **Solver failure.** Any status but Solved is counted (report) and recorded (telemetry); the MU
//! then applies the previous solve's plan for this step less the current T̂ᵢ, saturated, and
//! shares that shifted plan.

use crate::config::formation::{ForceCost, SHARE_HEADER, TsnrFormation, TsnrModel};
use crate::cw::Cw;
use crate::forecast::{ForecastInput, NeighbourSample, TensionForecast};
use crate::trajectory::{Desired, Trajectory};
use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use cohort_runtime::solver_stats::SolverStats;
use nalgebra::DVector;

use super::common::{Sensed, V3, base_columns, base_row, push_header, saturate, trajectory_of};
use super::mpc::{BoxQp, Horizon, Plan, QpStatus};

/// Values in an AEMC share of an MU with `degree` neighbours.
pub fn share_len(np: usize, degree: usize) -> usize {
    SHARE_HEADER + 3 * np + degree * forwarded_len(np)
}

/// Values of one forwarded neighbour share: its age, state and plan.
fn forwarded_len(np: usize) -> usize {
    7 + 3 * np
}

/// What a share says of a plan: the state at the share's step and U from then on.
struct PlanView<'a> {
    state: [f64; 6],
    u: &'a [f64],
}

impl<'a> PlanView<'a> {
    /// The sender's own plan in its share `v`.
    fn own(v: &'a [f64], np: usize) -> Self {
        Self { state: std::array::from_fn(|i| v[i]), u: &v[SHARE_HEADER..SHARE_HEADER + 3 * np] }
    }
    /// The plan of the `slot`-th neighbour the sender forwarded in its share `v`, with its age
    /// (None when the sender had none).
    fn forwarded(v: &'a [f64], np: usize, slot: usize) -> Option<(u64, Self)> {
        let off = SHARE_HEADER + 3 * np + slot * forwarded_len(np);
        let age = v[off];
        (age >= 1.0).then(|| {
            (age as u64, Self { state: std::array::from_fn(|i| v[off + 1 + i]), u: &v[off + 7..off + 7 + 3 * np] })
        })
    }
}

/// A plan made `age` steps before step k, brought to step k (at `t_s`): X̃ over t_{k+1} …
/// t_{k+N_p} against the desired trajectory `traj`, the states past the plan's end extrapolated
/// with its last force held. None when `age` is 0 or beyond the horizon.
fn aligned_error(hz: &Horizon, traj: &Trajectory, plan: &PlanView<'_>, age: u64, t_s: f64) -> Option<DVector<f64>> {
    let np = hz.np;
    let age = age as usize;
    if age == 0 || age > np {
        return None;
    }
    let xs = hz.pred.states(&plan.state, plan.u);
    let u_last = [plan.u[3 * np - 3], plan.u[3 * np - 2], plan.u[3 * np - 1]];
    let mut err = DVector::zeros(6 * np);
    // X[q] = x(t_{k_data + 1 + q}); step k needs x(t_{k+p}) = X[p + age − 1], p = 1..N_p.
    let mut x: [f64; 6] = std::array::from_fn(|i| xs[6 * (np - 1) + i]);
    for p in 1..=np {
        let q = p + age - 1;
        if q < np {
            x = std::array::from_fn(|i| xs[6 * q + i]);
        } else {
            x = hz.disc.step(&x, &u_last);
        }
        let d = traj.at(t_s + p as f64 * hz.dt_s).state();
        for i in 0..6 {
            err[6 * (p - 1) + i] = x[i] - d[i];
        }
    }
    Some(err)
}

/// One neighbour j as MU i sees it.
struct Nbr {
    id: u32,
    /// aᵢⱼ: its weight in eᵢ.
    a_ij: f64,
    traj: Trajectory,
    /// j's own neighbour list (its share length depends on its length) and c_j = d_j + b_j.
    their_list: Vec<u32>,
    c_j: f64,
    /// When j reads i and neighbours' costs are on: (slot of i in j's list, aⱼᵢ, λⱼ/λᵢ).
    pareto: Option<(usize, f64, f64)>,
    /// j's latest share and the step it was made at.
    latest: Vec<f64>,
    k_data: Option<u64>,
}

/// Neighbour j's share brought to step k: X̃ⱼ and ρⱼ\ᵢ over t_{k+1} … t_{k+N_p}.
struct Aligned {
    err: DVector<f64>,
    rho: Option<DVector<f64>>,
}

pub struct TsnrAemc {
    np: usize,
    traj: Trajectory,
    hz: Horizon,
    qp: BoxQp,
    bound_n: f64,
    /// cᵢ = dᵢ + bᵢ.
    c_i: f64,
    neighbours: Vec<Nbr>,
    /// With `force_cost = "thrust"`: the total weight on this MU's force (r + Σⱼ(λⱼ/λᵢ)rᵢⱼ).
    thrust_cost: Option<f64>,
    /// Every MU's desired trajectory (index id − 1): a neighbour's ρ needs its neighbours'.
    trajs: Vec<Trajectory>,
    /// aᵢⱼ, the same for every edge.
    adjacency: f64,
    link_delay_steps: u64,
    forecast: Box<dyn TensionForecast>,
    plan: Plan,
    k: u64,
    // This step, for telemetry and the share.
    sensed: Sensed,
    desired: Desired,
    u_n: V3,
    t_hat: Vec<V3>,
    status: QpStatus,
    iterations: u32,
    heard: usize,
    /// Neighbour shares ignored because of their length (counted, in telemetry).
    bad_shares: u64,
}

impl TsnrAemc {
    /// Agent `id` of a (validated) scenario with `method = "aemc"`: `graph[j − 1]` is agent j's
    /// neighbour list, `dt_s` the control step, `forecast` the tension forecast T̂ᵢ.
    pub fn new(
        cfg: &TsnrFormation,
        model: &TsnrModel,
        dt_s: f64,
        link_delay_steps: u32,
        id: u32,
        graph: &[Vec<u32>],
        forecast: Box<dyn TensionForecast>,
    ) -> Self {
        let m = cfg.mpc.as_ref().expect("validated: aemc needs [algorithm.mpc]");
        let np = m.horizon_steps as usize;
        let n = graph.len() as u32;
        let lam_i = m.pareto_weight(id, n);
        let a = m.adjacency_weight;
        let mine = &graph[id as usize - 1];
        let c_i = a * mine.len() as f64 + m.pinning_weight;
        let neighbours: Vec<Nbr> = mine
            .iter()
            .map(|&j| {
                let theirs = &graph[j as usize - 1];
                let pareto = if m.neighbour_costs {
                    theirs.iter().position(|&x| x == id).map(|slot| (slot, a, m.pareto_weight(j, n) / lam_i))
                } else {
                    None
                };
                Nbr {
                    id: j,
                    a_ij: a,
                    traj: trajectory_of(cfg, j),
                    their_list: theirs.clone(),
                    c_j: a * theirs.len() as f64 + m.pinning_weight,
                    pareto,
                    latest: Vec::new(),
                    k_data: None,
                }
            })
            .collect();
        let (mut w_error, mut w_force) = (c_i * c_i, m.r_force);
        for nb in &neighbours {
            if let Some((_, a_ji, rel)) = nb.pareto {
                w_error += rel * a_ji * a_ji;
                w_force += rel * m.r_neighbour_force;
            }
        }
        let hz = Horizon::new(Cw::new(model.orbit_radius_m, model.mass_kg), dt_s, np, m.q_position, m.q_velocity);
        let qp = BoxQp::new(&hz.hessian(w_error, w_force), model.thrust_max_n, m.max_iter, m.qp_solver);
        Self {
            np,
            traj: trajectory_of(cfg, id),
            hz,
            qp,
            bound_n: model.thrust_max_n,
            c_i,
            neighbours,
            thrust_cost: (m.force_cost == ForceCost::Thrust).then_some(w_force),
            trajs: (1..=n).map(|j| trajectory_of(cfg, j)).collect(),
            adjacency: a,
            link_delay_steps: u64::from(link_delay_steps),
            forecast,
            plan: Plan::default(),
            k: 0,
            sensed: Sensed::default(),
            desired: Desired::default(),
            u_n: [0.0; 3],
            t_hat: vec![[0.0; 3]; np],
            status: QpStatus::Solved,
            iterations: 0,
            heard: 0,
            bad_shares: 0,
        }
    }

    /// The QP this agent solves (its last problem, its statistics).
    pub fn qp(&self) -> &BoxQp {
        &self.qp
    }

    /// Neighbour `nb`'s latest share brought to step `k` (None: treat it as on track).
    fn aligned(&self, nb: &Nbr, k: u64, t_s: f64) -> Option<Aligned> {
        let np = self.np;
        let age = k - nb.k_data?;
        let err = aligned_error(&self.hz, &nb.traj, &PlanView::own(&nb.latest, np), age, t_s)?;
        let rho = nb.pareto.map(|(slot, _, _)| {
            let rho = self.rho_of(nb, slot);
            // Row r is horizon step p = r/6 + 1, at index p + age − 1 of j's sequence.
            let age = age as usize;
            DVector::from_fn(6 * np, |r, _| rho[6 * (r / 6 + age).min(np - 1) + r % 6])
        });
        Some(Aligned { err, rho })
    }

    /// ρⱼ\ᵢ = cⱼX̃ⱼ − Σ_{m∈Nⱼ, m≠i} aⱼₘX̃ₘ over j's horizon, rebuilt as j computed it at the step of
    /// its latest share (`slot`: this MU's place in j's list): X̃ⱼ from j's own plan, X̃ₘ from the
    /// copies of its neighbours' shares that j forwarded.
    fn rho_of(&self, nb: &Nbr, slot: usize) -> DVector<f64> {
        let np = self.np;
        let v = &nb.latest;
        let k_j = nb.k_data.expect("called for a neighbour heard from");
        let t_j = k_j as f64 * self.hz.dt_s;
        let own = PlanView::own(v, np);
        let x_pred = self.hz.pred.states(&own.state, own.u);
        let xd = self.hz.desired(&nb.traj, t_j);
        let mut rho = (x_pred - xd) * nb.c_j;
        for (s, &m) in nb.their_list.iter().enumerate() {
            if s == slot {
                continue;
            }
            let Some((age, plan)) = PlanView::forwarded(v, np, s) else { continue };
            if let Some(err) = aligned_error(&self.hz, &self.trajs[m as usize - 1], &plan, age, t_j) {
                rho -= &err * self.adjacency;
            }
        }
        rho
    }

    /// The linear term q of the QP at step k, and the neighbours' aligned errors (for ρ).
    fn linear_term(&self, k: u64, t_s: f64, free: &DVector<f64>) -> (DVector<f64>, Vec<Option<Aligned>>) {
        let aligned: Vec<Option<Aligned>> = self.neighbours.iter().map(|nb| self.aligned(nb, k, t_s)).collect();
        let mut s_i = free * self.c_i;
        for (nb, al) in self.neighbours.iter().zip(&aligned) {
            if let Some(al) = al {
                s_i -= &al.err * nb.a_ij;
            }
        }
        let mut g = &s_i * self.c_i;
        for (nb, al) in self.neighbours.iter().zip(&aligned) {
            if let Some((_, a_ji, rel)) = nb.pareto {
                let mut s_ji = free * (-a_ji);
                if let Some(rho) = al.as_ref().and_then(|a| a.rho.as_ref()) {
                    s_ji += rho;
                }
                g -= s_ji * (rel * a_ji);
            }
        }
        ((&self.hz.gt_q * g) * 2.0, aligned)
    }

    /// Forecast T̂ᵢ over the horizon from what this MU knows at t_k.
    fn forecast(&mut self, k: u64, t_s: f64) {
        let samples: Vec<NeighbourSample> = self
            .neighbours
            .iter()
            .filter_map(|nb| {
                let kd = nb.k_data?;
                let v = &nb.latest;
                Some(NeighbourSample {
                    id: nb.id,
                    state: std::array::from_fn(|i| v[i]),
                    thrust_n: [v[6], v[7], v[8]],
                    age_steps: k - kd,
                })
            })
            .collect();
        let input = ForecastInput {
            k,
            t_s,
            state: self.sensed.state,
            thrust_prev_n: self.u_n,
            tension_measured_n: self.sensed.tension_n,
            neighbours: &samples,
        };
        self.forecast.forecast(&input, &mut self.t_hat);
    }
}

/// What an AEMC agent carries from one step to the next: its last plan, the step, each
/// neighbour's latest share and its step, the tension forecast's memory, this step's readings,
/// command and forecast, and the counters. The QP is rebuilt from the scenario.
type AemcState = (Option<u64>, Vec<f64>, u64, Vec<(Vec<f64>, Option<u64>)>, Vec<u8>, [f64; 6], V3, V3, Vec<V3>, u64);

impl Algorithm for TsnrAemc {
    fn save_state(&self) -> Vec<u8> {
        let st: AemcState = (
            self.plan.k,
            self.plan.u.clone(),
            self.k,
            self.neighbours.iter().map(|n| (n.latest.clone(), n.k_data)).collect(),
            self.forecast.save(),
            self.sensed.state,
            self.sensed.tension_n,
            self.u_n,
            self.t_hat.clone(),
            self.bad_shares,
        );
        cohort_runtime::checkpoint::encode_state(&st)
    }
    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        let (pk, pu, k, nbrs, forecast, state, tension, u_n, t_hat, bad): AemcState =
            cohort_runtime::checkpoint::decode_state(bytes)?;
        if nbrs.len() != self.neighbours.len() {
            return Err(RestoreStateError::Refused(format!(
                "{} neighbours saved, this agent has {}",
                nbrs.len(),
                self.neighbours.len()
            )));
        }
        self.forecast.restore(&forecast).map_err(RestoreStateError::Refused)?;
        self.plan = Plan { k: pk, u: pu };
        self.k = k;
        for (n, (latest, k_data)) in self.neighbours.iter_mut().zip(nbrs) {
            (n.latest, n.k_data) = (latest, k_data);
        }
        (self.sensed.state, self.sensed.tension_n, self.u_n, self.t_hat, self.bad_shares) =
            (state, tension, u_n, t_hat, bad);
        Ok(())
    }

    fn columns(&self) -> Vec<String> {
        let mut c = base_columns();
        for ax in ["x", "y", "z"] {
            c.push(format!("tension_used_{ax}_n"));
        }
        c.extend(["qp_status", "qp_iterations", "neighbours_heard", "bad_shares"].map(String::from));
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        let (k, t_s, np) = (input.k, input.t_s, self.np);
        self.k = k;
        self.sensed = Sensed::from_readings(input.readings);
        self.desired = self.traj.at(t_s);
        self.forecast(k, t_s);
        let x0 = self.sensed.state;
        let xd = self.hz.desired(&self.traj, t_s);
        let free = self.hz.free_error(&x0, &xd);
        let (q, aligned) = self.linear_term(k, t_s, &free);
        self.heard = aligned.iter().filter(|a| a.is_some()).count();
        let offset: Vec<f64> = self.t_hat.iter().flatten().copied().collect();
        let mut q = q;
        if let Some(w_force) = self.thrust_cost {
            // R on u = û − T̂: w|U − T̂|² adds −2w T̂ᵀU (the constant dropped).
            for (qi, t) in q.iter_mut().zip(&offset) {
                *qi -= 2.0 * w_force * t;
            }
        }
        let (status, iterations, x) = self.qp.solve(q.as_slice(), &offset);
        (self.status, self.iterations) = (status, iterations);
        if let Some(u) = x {
            self.plan = Plan { k: Some(k), u: u.to_vec() };
        }
        let u_plan = self.plan.shifted(k, np);
        let t0 = self.t_hat[0];
        self.u_n = saturate([u_plan[0] - t0[0], u_plan[1] - t0[1], u_plan[2] - t0[2]], self.bound_n);

        out.command.extend_from_slice(&self.u_n);
        push_header(&mut out.values, &self.sensed, &self.u_n);
        out.values.extend_from_slice(&u_plan);
        // Each neighbour's share as used here, for the neighbours' ρ (see the share layout).
        for nb in &self.neighbours {
            match nb.k_data {
                Some(kd) => {
                    out.values.push((k - kd) as f64);
                    let plan = PlanView::own(&nb.latest, np);
                    out.values.extend_from_slice(&plan.state);
                    out.values.extend_from_slice(plan.u);
                }
                None => out.values.extend(std::iter::repeat_n(0.0, forwarded_len(np))),
            }
        }
        debug_assert_eq!(out.values.len(), share_len(np, self.neighbours.len()));
    }

    fn step(&mut self, _dt_s: f64, neighbours: &[Neighbour<'_>]) {
        // The driver hands over the shares of step k − link delay.
        let Some(k_data) = self.k.checked_sub(self.link_delay_steps) else { return };
        for n in neighbours {
            let Some(nb) = self.neighbours.iter_mut().find(|nb| nb.id == n.id) else { continue };
            if n.values.len() != share_len(self.np, nb.their_list.len()) {
                self.bad_shares += 1;
                continue;
            }
            nb.latest.clear();
            nb.latest.extend_from_slice(n.values);
            nb.k_data = Some(k_data);
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        base_row(out, &self.u_n, &self.sensed, &self.desired);
        out.extend_from_slice(&self.t_hat[0]);
        out.extend([self.status.code(), f64::from(self.iterations), self.heard as f64, self.bad_shares as f64]);
    }

    fn solver_stats(&self) -> Option<SolverStats> {
        Some(self.qp.stats())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agents::common::test_support::{DT_S, MODEL, case1, closed_loop, readings, square};
    use crate::agents::dmpc::TsnrDmpc;
    use crate::forecast::HoldMeasured;
    use nalgebra::DMatrix;

    const NP: usize = 20;

    fn aemc(cfg: &TsnrFormation, id: u32) -> TsnrAemc {
        aemc_with(cfg, &MODEL, id)
    }

    fn aemc_with(cfg: &TsnrFormation, model: &TsnrModel, id: u32) -> TsnrAemc {
        TsnrAemc::new(cfg, model, DT_S, 0, id, &square(), Box::new(HoldMeasured))
    }

    fn share_at(a: &mut dyn Algorithm, k: u64, state: &[f64; 6], tension: &[f64; 3]) -> ShareOut {
        let mut out = ShareOut::default();
        a.share(&AgentInput { k, t_s: k as f64 * DT_S, readings: &readings(state, tension) }, &mut out);
        out
    }

    /// A deterministic, irregular share of neighbour `j` made at step 0: its predicted states
    /// wander about its desired trajectory, its forces and residuals are arbitrary.
    fn neighbour_share(cfg: &TsnrFormation, j: u32) -> Vec<f64> {
        let traj = trajectory_of(cfg, j);
        let wobble = |i: usize| ((i * 7919 + j as usize * 104_729) % 1000) as f64 / 1000.0 - 0.5;
        let mut v = Vec::new();
        let x = traj.at(0.0).state();
        v.extend((0..6).map(|i| x[i] + 0.2 * wobble(2000 + i)));
        v.extend([0.5, -0.25, 0.125]);
        v.extend((0..3 * NP).map(|i| 3.0 * wobble(i)));
        // Its neighbours' shares of the step before, as it forwards them: agents 1 and 4.
        for m in square()[j as usize - 1].clone() {
            v.push(1.0);
            let xm = trajectory_of(cfg, m).at(0.0).state();
            v.extend((0..6).map(|i| xm[i] + 0.3 * wobble(3000 + 10 * m as usize + i)));
            v.extend((0..3 * NP).map(|i| 2.0 * wobble(5000 + 100 * m as usize + i)));
        }
        assert_eq!(v.len(), share_len(NP, 2));
        v
    }

    /// The state and plan in a share (`slot` None: the sender's own, else the forwarded one).
    fn plan_in(share: &[f64], slot: Option<usize>) -> ([f64; 6], Vec<f64>) {
        let off = slot.map_or(0, |s| 9 + 3 * NP + s * (7 + 3 * NP) + 1);
        let u_off = slot.map_or(9, |_| off + 6);
        (std::array::from_fn(|i| share[off + i]), share[u_off..u_off + 3 * NP].to_vec())
    }

    /// MU `id`'s plan (state `x`, forces `u`) made `age` steps before the step at `t_s`, seen
    /// from that step: x(t_s + pΔt) − x_d(t_s + pΔt), p = 1..N_p, by stepping the ZOH model
    /// (written out here independently of the module's condensed form).
    fn plan_error(cfg: &TsnrFormation, id: u32, x: [f64; 6], u: &[f64], age: usize, t_s: f64) -> DVector<f64> {
        let disc = Cw::new(MODEL.orbit_radius_m, MODEL.mass_kg).discretise(DT_S);
        let traj = trajectory_of(cfg, id);
        let mut xs = Vec::new();
        let mut state = x;
        for p in 0..NP + age {
            let f = [u[3 * p.min(NP - 1)], u[3 * p.min(NP - 1) + 1], u[3 * p.min(NP - 1) + 2]];
            state = disc.step(&state, &f);
            xs.push(state);
        }
        let mut e = DVector::zeros(6 * NP);
        for p in 1..=NP {
            let d = traj.at(t_s + p as f64 * DT_S).state();
            for i in 0..6 {
                e[6 * (p - 1) + i] = xs[p + age - 1][i] - d[i];
            }
        }
        e
    }

    /// Step k = 1 of agent 1 after hearing `shares` (of agents 2 and 3) at step 0. Returns the
    /// share of step 1 and the inputs the test recomputes from.
    fn run_agent_1(cfg: &TsnrFormation, model: &TsnrModel, x1: [f64; 6], t1: [f64; 3]) -> (ShareOut, Vec<Vec<f64>>) {
        let mut a = aemc_with(cfg, model, 1);
        share_at(&mut a, 0, &trajectory_of(cfg, 1).at(0.0).state(), &[0.0; 3]);
        let shares = vec![neighbour_share(cfg, 2), neighbour_share(cfg, 3)];
        a.step(
            DT_S,
            &[
                Neighbour { id: 2, values: &shares[0], age_steps: 0 },
                Neighbour { id: 3, values: &shares[1], age_steps: 0 },
            ],
        );
        (share_at(&mut a, 1, &x1, &t1), shares)
    }

    /// Neighbour j's states X_j(t_2 … t_{N_p+1}) from its step-0 share, the tail extrapolated
    /// with its last planned force (as the module documents), minus its desired states.
    /// Neighbour j's error X̃ⱼ(t_2 … t_{N_p+1}) from its step-0 share, as agent 1 sees it at step 1.
    fn neighbour_error(cfg: &TsnrFormation, j: u32, share: &[f64]) -> DVector<f64> {
        let (x, u) = plan_in(share, None);
        plan_error(cfg, j, x, &u, 1, DT_S)
    }

    fn qbar(cfg: &TsnrFormation) -> DMatrix<f64> {
        let m = cfg.mpc.as_ref().unwrap();
        DMatrix::from_fn(6 * NP, 6 * NP, |r, c| {
            if r != c {
                0.0
            } else if r % 6 < 3 {
                m.q_position
            } else {
                m.q_velocity
            }
        })
    }

    fn offset_state(cfg: &TsnrFormation, t_s: f64, dr: [f64; 3]) -> [f64; 6] {
        let mut x = trajectory_of(cfg, 1).at(t_s).state();
        for a in 0..3 {
            x[a] += dr[a];
        }
        x
    }

    #[test]
    fn unconstrained_solution_is_the_closed_form_of_25_26() {
        let mut cfg = case1("aemc");
        let model = TsnrModel { thrust_max_n: 1e4, ..MODEL }; // no bound active: the QP is (25) alone
        cfg.mpc.as_mut().unwrap().neighbour_costs = false;
        let x1 = offset_state(&cfg, DT_S, [0.3, -0.2, 0.1]);
        let (out, shares) = run_agent_1(&cfg, &model, x1, [1.0, -2.0, 0.5]);
        let m = cfg.mpc.as_ref().unwrap();
        // Paper (21)–(22), (26) with Lᵢ = (dᵢ + bᵢ)I, L_ij = −aᵢⱼI.
        let c = m.adjacency_weight * 2.0 + m.pinning_weight;
        let pred = Cw::new(MODEL.orbit_radius_m, MODEL.mass_kg).discretise(DT_S).prediction(NP);
        let (h, w) = (&pred.phi * c, &pred.gamma * c);
        let traj = trajectory_of(&cfg, 1);
        let xd = DVector::from_fn(6 * NP, |r, _| traj.at((1 + r / 6 + 1) as f64 * DT_S).state()[r % 6]);
        let mut s = &xd * (-c);
        for (j, sh) in [(2, &shares[0]), (3, &shares[1])] {
            s -= neighbour_error(&cfg, j, sh) * m.adjacency_weight;
        }
        let q_bar = qbar(&cfg);
        let q = (DMatrix::identity(3 * NP, 3 * NP) * m.r_force + w.transpose() * &q_bar * &w) * 2.0;
        let p = w.transpose() * &q_bar * (h * DVector::from_column_slice(&x1) + s) * 2.0;
        let u = -q.clone().lu().solve(&p).unwrap();
        let got = &out.values[9..9 + 3 * NP];
        for i in 0..3 * NP {
            assert!((got[i] - u[i]).abs() < 1e-8, "U[{i}] = {} vs closed form {}", got[i], u[i]);
        }
        // And the command is the first total force less the forecast tension.
        assert!((out.command[0] - (u[0] - 1.0)).abs() < 1e-8);
    }

    #[test]
    fn a_cost_on_the_thrust_shifts_the_plan_by_h_inverse_r_t_hat() {
        // Unbounded, own cost only: H U = −q/2 (total) and H U' = −q/2 + r T̂ (thrust), so
        // H (U' − U) = r T̂ stacked, with H = c²ΓᵀQ̄Γ + r I.
        let mut cfg = case1("aemc");
        let model = TsnrModel { thrust_max_n: 1e4, ..MODEL };
        cfg.mpc.as_mut().unwrap().neighbour_costs = false;
        let x1 = offset_state(&cfg, DT_S, [0.3, -0.2, 0.1]);
        let t_hat = [1.0, -2.0, 0.5];
        let (total, _) = run_agent_1(&cfg, &model, x1, t_hat);
        cfg.mpc.as_mut().unwrap().force_cost = ForceCost::Thrust;
        let (thrust, _) = run_agent_1(&cfg, &model, x1, t_hat);
        let m = cfg.mpc.as_ref().unwrap();
        let c = m.adjacency_weight * 2.0 + m.pinning_weight;
        let pred = Cw::new(MODEL.orbit_radius_m, MODEL.mass_kg).discretise(DT_S).prediction(NP);
        let h =
            pred.gamma.transpose() * qbar(&cfg) * &pred.gamma * (c * c) + DMatrix::identity(3 * NP, 3 * NP) * m.r_force;
        let du = DVector::from_fn(3 * NP, |i, _| thrust.values[9 + i] - total.values[9 + i]);
        let lhs = h * du;
        for i in 0..3 * NP {
            let want = m.r_force * t_hat[i % 3];
            assert!((lhs[i] - want).abs() < 1e-9, "row {i}: {} vs {want}", lhs[i]);
        }
        assert!(lhs.iter().any(|x| x.abs() > 1e-4), "the two plans must differ");
    }

    #[test]
    fn with_neighbour_costs_the_solution_is_stationary_for_the_pareto_sum() {
        let cfg = case1("aemc");
        let model = TsnrModel { thrust_max_n: 1e4, ..MODEL };
        let x1 = offset_state(&cfg, DT_S, [0.3, -0.2, 0.1]);
        let (out, shares) = run_agent_1(&cfg, &model, x1, [1.0, -2.0, 0.5]);
        let m = cfg.mpc.clone().unwrap();
        let a = m.adjacency_weight;
        let c = a * 2.0 + m.pinning_weight;
        let pred = Cw::new(MODEL.orbit_radius_m, MODEL.mass_kg).discretise(DT_S).prediction(NP);
        let traj = trajectory_of(&cfg, 1);
        let xd = DVector::from_fn(6 * NP, |r, _| traj.at((1 + r / 6 + 1) as f64 * DT_S).state()[r % 6]);
        let errs: Vec<DVector<f64>> =
            [(2, &shares[0]), (3, &shares[1])].iter().map(|(j, sh)| neighbour_error(&cfg, *j, sh)).collect();
        // ρⱼ\₁ = cⱼX̃ⱼ − aⱼ₄X̃₄ over j's horizon at step 0: agent 1 is slot 0 in both 2's list [1, 4]
        // and 3's list [1, 4], agent 4 slot 1, forwarded with age 1. Seen at step 1, tail held.
        let rhos: Vec<DVector<f64>> = [(2, &shares[0]), (3, &shares[1])]
            .iter()
            .map(|(j, sh)| {
                let (xj, uj) = plan_in(sh, None);
                let (x4, u4) = plan_in(sh, Some(1));
                let rho = plan_error(&cfg, *j, xj, &uj, 0, 0.0) * c - plan_error(&cfg, 4, x4, &u4, 1, 0.0) * a;
                DVector::from_fn(6 * NP, |r, _| rho[6 * (r / 6 + 1).min(NP - 1) + r % 6])
            })
            .collect();
        let q_bar = qbar(&cfg);
        let norm2 = |e: &DVector<f64>| (e.transpose() * &q_bar * e)[0];
        // J₁ + Σⱼ (λⱼ/λ₁) Jⱼ, every term that depends on U₁, written out from (14), (16), (18).
        let cost = |u: &DVector<f64>| -> f64 {
            let x_err = &pred.phi * DVector::from_column_slice(&x1) + &pred.gamma * u - &xd;
            let e1 = &x_err * c - &errs[0] * a - &errs[1] * a;
            let mut j = norm2(&e1) + m.r_force * u.norm_squared();
            for rho in &rhos {
                j += norm2(&(rho - &x_err * a)) + m.r_neighbour_force * u.norm_squared();
            }
            j
        };
        let u_star = DVector::from_column_slice(&out.values[9..9 + 3 * NP]);
        let grad = |u: &DVector<f64>| -> DVector<f64> {
            let h = 1e-3;
            DVector::from_fn(3 * NP, |i, _| {
                let (mut up, mut dn) = (u.clone(), u.clone());
                up[i] += h;
                dn[i] -= h;
                (cost(&up) - cost(&dn)) / (2.0 * h)
            })
        };
        let g0 = grad(&DVector::zeros(3 * NP)).norm();
        let g = grad(&u_star).norm();
        assert!(g < 1e-7 * g0, "gradient at the solution {g} (at zero {g0})");
        // The neighbours' costs change the answer (else this test could not tell them apart).
        let mut own = cfg.clone();
        own.mpc.as_mut().unwrap().neighbour_costs = false;
        let (out_own, _) = run_agent_1(&own, &model, x1, [1.0, -2.0, 0.5]);
        let diff = (0..3 * NP).map(|i| (out_own.values[9 + i] - u_star[i]).abs()).fold(0.0, f64::max);
        assert!(diff > 1e-3, "neighbour costs changed U by only {diff} N");
    }

    #[test]
    fn thrust_bound_holds_over_the_whole_horizon_under_a_large_error() {
        let cfg = case1("aemc");
        let tension = [3.0, -4.0, 6.0];
        let x1 = offset_state(&cfg, DT_S, [30.0, -20.0, 15.0]);
        let (out, _) = run_agent_1(&cfg, &MODEL, x1, tension);
        let mut row = Vec::new();
        let mut a = aemc(&cfg, 1);
        let out0 = share_at(&mut a, 0, &x1, &tension);
        a.row(&mut row);
        assert_eq!(row[18], 0.0, "qp_status {}", row[18]);
        for o in [&out, &out0] {
            assert!(o.command.iter().all(|u| u.abs() <= 5.0), "{:?}", o.command);
            assert!(o.command.iter().any(|u| (u.abs() - 5.0).abs() < 1e-6), "not at the bound: {:?}", o.command);
            for p in 0..NP {
                for ax in 0..3 {
                    let u = o.values[9 + 3 * p + ax] - tension[ax];
                    assert!(u.abs() <= 5.0 + 1e-7, "step {p} axis {ax}: thrust {u}");
                }
            }
        }
    }

    #[test]
    fn without_the_game_it_is_dmpc() {
        // dᵢ + bᵢ = 1, no neighbour heard, own cost only: AEMC's QP is DMPC's.
        let mut cfg = case1("aemc");
        let m = cfg.mpc.as_mut().unwrap();
        m.neighbour_costs = false;
        (m.adjacency_weight, m.pinning_weight) = (0.25, 0.5);
        let mut a = aemc(&cfg, 4);
        let mut d = TsnrDmpc::new(&cfg, &MODEL, DT_S, 4);
        let x = [-9.0, -1.0, -0.2, 0.1, 0.0, -0.1];
        let t = [0.5, 1.5, -2.5];
        let (oa, od) = (share_at(&mut a, 0, &x, &t), share_at(&mut d, 0, &x, &t));
        for ax in 0..3 {
            assert!((oa.command[ax] - od.command[ax]).abs() < 1e-9, "{:?} vs {:?}", oa.command, od.command);
        }
    }

    #[test]
    fn a_failed_solve_falls_back_and_is_counted() {
        let mut cfg = case1("aemc");
        cfg.mpc.as_mut().unwrap().max_iter = 1;
        let mut a = aemc(&cfg, 1);
        let out = share_at(&mut a, 0, &[-9.0, 1.0, 1.0, 0.0, 0.0, 0.0], &[1.0, -7.0, 0.5]);
        // No plan yet: zero total force, i.e. thrust = −T̂, saturated.
        assert_eq!(out.command, vec![-1.0, 5.0, -0.5]);
        let mut row = Vec::new();
        a.row(&mut row);
        assert_eq!(row[18], QpStatus::MaxIterations.code());
        let st = a.solver_stats().unwrap();
        assert_eq!((st.solves, st.solved, st.not_converged), (1, 0, 1));
    }

    #[test]
    fn a_share_of_the_wrong_length_is_ignored_and_counted() {
        let cfg = case1("aemc");
        let mut a = aemc(&cfg, 1);
        share_at(&mut a, 0, &trajectory_of(&cfg, 1).at(0.0).state(), &[0.0; 3]);
        let short = vec![0.0; 9];
        let good = neighbour_share(&cfg, 3);
        a.step(
            DT_S,
            &[Neighbour { id: 2, values: &short, age_steps: 0 }, Neighbour { id: 3, values: &good, age_steps: 0 }],
        );
        share_at(&mut a, 1, &trajectory_of(&cfg, 1).at(DT_S).state(), &[0.0; 3]);
        let mut row = Vec::new();
        a.row(&mut row);
        let n = row.len();
        assert_eq!((row[n - 2], row[n - 1]), (1.0, 1.0), "heard, bad shares");
    }

    #[test]
    fn closed_loop_on_cw_tracks_case_1_within_the_bound() {
        for method in ["aemc", "dmpc"] {
            let cfg = case1(method);
            let mut algos: Vec<Box<dyn Algorithm>> = (1..=4)
                .map(|id| -> Box<dyn Algorithm> {
                    if method == "aemc" {
                        Box::new(aemc(&cfg, id))
                    } else {
                        Box::new(TsnrDmpc::new(&cfg, &MODEL, DT_S, id))
                    }
                })
                .collect();
            // Start 0.3 m off in x and at rest; a constant, exactly measured pull of the net.
            let x0: Vec<[f64; 6]> = (1..=4)
                .map(|id| {
                    let mut x = trajectory_of(&cfg, id).at(0.0).state();
                    x[0] += 0.3;
                    x
                })
                .collect();
            let pull = |_: u64, i: usize, _: &[f64; 6]| [0.0, if i.is_multiple_of(2) { 1.0 } else { -1.0 }, 0.5];
            // 5 s past the last knot: the weight on the total force makes an MPC lag a moving
            // reference by centimetres, so "reaches its target" is judged once it has stopped.
            let run = closed_loop(&mut algos, &square(), x0, 350, pull);
            assert!(run.max_thrust_n <= 5.0, "{method}: thrust {}", run.max_thrust_n);
            for (i, x) in run.states.iter().enumerate() {
                let d = trajectory_of(&cfg, i as u32 + 1).at(35.0);
                let e = (0..3).map(|a| (x[a] - d.r_m[a]).powi(2)).sum::<f64>().sqrt();
                assert!(e < 1e-3, "{method}: MU {} ends {e} m from its target", i + 1);
            }
            let st = algos[0].solver_stats().unwrap();
            assert_eq!((st.solves, st.solved), (350, 350), "{method}: {st:?}");
        }
    }
}
