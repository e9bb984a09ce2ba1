//! Training data of the swarm policy (Sec. 7.2.1 of "Neural-Rendezvous", arXiv:2208.04883: "we
//! solve nonlinear motion planning problems to sample target guidance and control inputs … the
//! training is performed in a distributed manner as in [42], so we can use local observations to
//! account for centralised global solutions").
//!
//! For each case c (N = 6, 7, 8 in turn; starts and targets from [`SwarmCase::draw`] with the
//! label `train<c>`) the global solution x*, u* ([`crate::swarm::train::scp`]); cases whose SCP fails or
//! is not collision-free on the fine grid are left out (counted). Then, at every node k of
//! 0…K + hold (after T: x* = (target, 0), u* = 0, so the policy learns to stay), one perturbed
//! swarm state x = x* + s·(σ_p ξ_p, σ_v ξ_v), ξ ~ N(0, I) per vehicle and axis, s ~ U(0, 1) per
//! node (so small and large deviations both appear), and for each vehicle i:
//!
//! - the observation [`SwarmObservation::local`] of the *perturbed* swarm (nearest ≤ 6 within
//!   R_comm) at the node's time to go max(T − t_k, 0), and
//! - the target u*ᵢ(k) + K_p (p*ᵢ(k) − pᵢ) + K_d (v*ᵢ(k) − vᵢ), clipped to ±a_max.
//!
//! Ours (the paper's are lost): σ_p = 0.1 m, σ_v = 0.1 m/s; K_p = 4 s⁻², K_d = 4 s⁻¹ (a critically
//! damped PD, ω = 2 rad/s: it brings a deviation back in ≈ 2 s, the NR layer's roll-out horizon).
//! The perturbation is what makes imitation work in closed loop (the learner sees how to return
//! to the plan, in the spirit of the robust learning of the paper's [44]).
//!
//! Deterministic: a case is a function of (seed, c) alone (its own RNG stream), generated on any
//! number of threads and gathered in case order, so the set is the same bytes on every run.

use cohort_host::campaign::Campaign;

use rand::Rng;
use rand_distr::StandardNormal;
use serde::Serialize;

use crate::swarm::control::obs::SwarmObservation;
use crate::swarm::train::problem::{A_MAX_MPS2, R_COMM_M, STEPS, SwarmCase, t_to_go_s};
use crate::swarm::train::scp::{self as swarm_scp, SwarmPlan, SwarmScpSettings};

/// How the data set is drawn.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SwarmDataOptions {
    pub seed: u64,
    /// Cases 0…cases−1 (labels `train<c>`).
    pub cases: usize,
    /// Vehicles per case: n_min, n_min + 1, …, n_max in turn.
    pub n_min: usize,
    pub n_max: usize,
    /// Nodes after T at which the vehicles hold their targets.
    pub hold_steps: usize,
    pub sigma_p_m: f64,
    pub sigma_v_mps: f64,
    pub k_p_per_s2: f64,
    pub k_d_per_s: f64,
    pub scp: SwarmScpSettings,
}

impl SwarmDataOptions {
    /// The reference set: 150 cases of N = 6–8, 2 s of hold.
    pub fn reference(seed: u64) -> Self {
        Self {
            seed,
            cases: 150,
            n_min: 6,
            n_max: 8,
            hold_steps: 20,
            sigma_p_m: 0.1,
            sigma_v_mps: 0.1,
            k_p_per_s2: 4.0,
            k_d_per_s: 4.0,
            scp: SwarmScpSettings::default(),
        }
    }

    /// Vehicles of case `c`.
    pub fn n_of(&self, c: usize) -> usize {
        self.n_min + c % (self.n_max - self.n_min + 1)
    }
}

/// One sample: what the vehicle observed and the command it should give.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwarmSample {
    pub case: usize,
    pub obs: SwarmObservation,
    pub target_mps2: [f64; 3],
}

/// What the global solutions of one case gave.
#[derive(Debug, Clone, PartialEq)]
pub struct CaseOutcome {
    pub case: usize,
    pub n: usize,
    /// The SCP's result (None: the SCP failed; Some(false): not safe on the fine grid).
    pub safe: Option<bool>,
    pub iterations: u32,
    pub solve_s: f64,
    pub effort_l1: f64,
    pub min_distance_fine: f64,
}

/// A case's global solution as the expert that labels states: the target for vehicle i at node
/// k from (p, v) (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Expert {
    pub case: usize,
    pub problem: SwarmCase,
    pub plan: SwarmPlan,
}

impl Expert {
    /// (p*, v*, u*) of vehicle `i` at node `k` (after T: at rest at the target).
    pub fn nominal(&self, i: usize, k: usize) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let kk = k.min(STEPS);
        let u = if k < STEPS { self.plan.a_mps2[i][k] } else { [0.0; 3] };
        (self.plan.p_m[i][kk], self.plan.v_mps[i][kk], u)
    }

    /// u*ᵢ(k) + K_p (p*ᵢ(k) − p) + K_d (v*ᵢ(k) − v), clipped to ±a_max.
    pub fn target(&self, o: &SwarmDataOptions, i: usize, k: usize, p: [f64; 3], v: [f64; 3]) -> [f64; 3] {
        let (p_star, v_star, u_star) = self.nominal(i, k);
        std::array::from_fn(|a| {
            (u_star[a] + o.k_p_per_s2 * (p_star[a] - p[a]) + o.k_d_per_s * (v_star[a] - v[a]))
                .clamp(-A_MAX_MPS2, A_MAX_MPS2)
        })
    }
}

/// The samples of one case (none if its global solution is unusable).
#[cfg(test)] // used by the unit tests only
pub fn case_samples(o: &SwarmDataOptions, c: usize) -> (CaseOutcome, Vec<SwarmSample>) {
    let (out, samples, _) = case_data(o, c);
    (out, samples)
}

/// One case's outcome, samples and expert.
pub type CaseData = (CaseOutcome, Vec<SwarmSample>, Option<Expert>);

/// The samples of one case and its expert (none if its global solution is unusable).
pub fn case_data(o: &SwarmDataOptions, c: usize) -> CaseData {
    let n = o.n_of(c);
    let mut out =
        CaseOutcome { case: c, n, safe: None, iterations: 0, solve_s: 0.0, effort_l1: 0.0, min_distance_fine: 0.0 };
    let Ok(case) = SwarmCase::draw(o.seed, &format!("train{c}"), n) else { return (out, Vec::new(), None) };
    let Ok(plan) = swarm_scp::solve(&case, &o.scp) else { return (out, Vec::new(), None) };
    out.safe = Some(plan.is_safe());
    (out.iterations, out.solve_s, out.effort_l1, out.min_distance_fine) =
        (plan.iterations, plan.solve_s, plan.effort_l1, plan.min_distance_fine);
    if !plan.is_safe() {
        return (out, Vec::new(), None);
    }
    let expert = Expert { case: c, problem: case, plan };
    let case = &expert.problem;
    let mut rng = cohort_runtime::rng::setup_rng(o.seed, &format!("nr.swarm.data[{c}]"));
    let mut samples = Vec::with_capacity((STEPS + o.hold_steps) * n);
    for k in 0..STEPS + o.hold_steps {
        let nominal = |i: usize| expert.nominal(i, k);
        let s: f64 = rng.random_range(0.0..1.0);
        let mut draw =
            |sigma: f64| -> [f64; 3] { std::array::from_fn(|_| s * sigma * rng.sample::<f64, _>(StandardNormal)) };
        let state: Vec<([f64; 3], [f64; 3])> = (0..n)
            .map(|i| {
                let (p, v, _) = nominal(i);
                let (dp, dv) = (draw(o.sigma_p_m), draw(o.sigma_v_mps));
                (std::array::from_fn(|a| p[a] + dp[a]), std::array::from_fn(|a| v[a] + dv[a]))
            })
            .collect();
        for i in 0..n {
            let (p, v) = state[i];
            let others: Vec<_> = (0..n).filter(|&j| j != i).map(|j| state[j]).collect();
            let obs = SwarmObservation::local(p, v, case.goals_m[i], &others, R_COMM_M).at(t_to_go_s(k));
            samples.push(SwarmSample { case: c, obs, target_mps2: expert.target(o, i, k, p, v) });
        }
    }
    (out, samples, Some(expert))
}

/// Every case's outcome and samples, in case order, computed on `threads` threads.
#[cfg(test)] // used by the unit tests only
pub fn generate(o: &SwarmDataOptions, threads: usize) -> (Vec<CaseOutcome>, Vec<SwarmSample>) {
    let (outcomes, samples, _) = generate_with_experts(o, threads);
    (outcomes, samples)
}

/// [`generate`], and the experts of the usable cases (case order).
pub fn generate_with_experts(
    o: &SwarmDataOptions,
    threads: usize,
) -> (Vec<CaseOutcome>, Vec<SwarmSample>, Vec<Expert>) {
    let all: Vec<CaseData> = Campaign::new(o.cases).workers(threads).map(|c| case_data(o, c));
    let outcomes = all.iter().map(|(oc, _, _)| oc.clone()).collect();
    let mut samples = Vec::new();
    let mut experts = Vec::new();
    for (_, s, e) in all {
        samples.extend(s);
        experts.extend(e);
    }
    (outcomes, samples, experts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_set_is_the_same_on_one_or_two_threads_and_targets_follow_the_plan() {
        let mut o = SwarmDataOptions::reference(2);
        o.cases = 3;
        o.n_min = 2;
        o.n_max = 3;
        let (oc1, s1) = generate(&o, 1);
        let (oc2, s2) = generate(&o, 2);
        assert_eq!(s1, s2);
        assert_eq!(
            oc1.iter().map(|c| (c.n, c.safe)).collect::<Vec<_>>(),
            [(2, Some(true)), (3, Some(true)), (2, Some(true))]
        );
        assert_eq!(oc1.len(), oc2.len());
        assert_eq!(s1.len(), (2 + 3 + 2) * (STEPS + o.hold_steps));
        assert!(s1.iter().all(|s| s.target_mps2.iter().all(|a| a.abs() <= A_MAX_MPS2)));
        // With no perturbation the target is the plan's own command.
        o.sigma_p_m = 0.0;
        o.sigma_v_mps = 0.0;
        o.cases = 1;
        let (_, s0) = case_samples(&o, 0);
        let case = SwarmCase::draw(o.seed, "train0", 2).unwrap();
        let plan = swarm_scp::solve(&case, &o.scp).unwrap();
        assert_eq!(s0[2].target_mps2, plan.a_mps2[0][1]);
        assert_eq!(s0[2].obs.goal_offset_m, std::array::from_fn(|a| case.goals_m[0][a] - plan.p_m[0][1][a]));
        assert_eq!(s0.last().unwrap().target_mps2, [0.0; 3]);
    }
}
