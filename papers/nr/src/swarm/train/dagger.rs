//! DAgger-style aggregation for the swarm policy (Sec. 7.2 of "Neural-Rendezvous",
//! arXiv:2208.04883; the paper trains on global solutions only, this round is ours): imitation
//! from states near the global solution leaves the learner unprepared for the states its *own*
//! closed loop reaches (near-misses where its errors compound). So, after a first fit, fly the
//! learned policy on every training case and label each visited state by the expert of that
//! case — the global SCP solution tracked from where the vehicle actually is (the target of
//! [`crate::swarm::train::data`]: u*ᵢ(k) + K_p(p*ᵢ(k) − pᵢ) + K_d(v*ᵢ(k) − vᵢ), clipped) — and train on
//! the union (Ross, Gordon and Bagnell's DAgger with β = 0: the learner alone flies).
//!
//! The closed loop is the one of [`crate::swarm::train::eval`] without its bookkeeping: from rest at the
//! starts, exact local observations (nearest ≤ 6 within R_comm), the policy's command clipped and
//! held over Δt, exact double-integrator steps, T + hold nodes (the data's horizon). One sample
//! per vehicle per node, as in the perturbed set, so a round doubles nothing but the states.
//! Deterministic: no random draw at all.

use cohort_host::campaign::Campaign;

use crate::swarm::control::obs::{SwarmObservation, SwarmPolicy};
use crate::swarm::train::data::{Expert, SwarmDataOptions, SwarmSample};
use crate::swarm::train::problem::{A_MAX_MPS2, DT_S, R_COMM_M, STEPS, t_to_go_s};

/// The states `policy` visits on `e`'s case, each vehicle's observation labelled by `e`.
pub fn visited(o: &SwarmDataOptions, e: &Expert, policy: &dyn SwarmPolicy) -> Vec<SwarmSample> {
    let n = e.problem.n();
    let (mut p, mut v) = (e.problem.starts_m.clone(), vec![[0.0; 3]; n]);
    let mut out = Vec::with_capacity((STEPS + o.hold_steps) * n);
    for k in 0..STEPS + o.hold_steps {
        let mut a = Vec::with_capacity(n);
        for i in 0..n {
            let others: Vec<_> = (0..n).filter(|&j| j != i).map(|j| (p[j], v[j])).collect();
            let obs = SwarmObservation::local(p[i], v[i], e.problem.goals_m[i], &others, R_COMM_M).at(t_to_go_s(k));
            out.push(SwarmSample { case: e.case, obs, target_mps2: e.target(o, i, k, p[i], v[i]) });
            a.push(policy.accel_mps2(&obs).map(|x| x.clamp(-A_MAX_MPS2, A_MAX_MPS2)));
        }
        for i in 0..n {
            for c in 0..3 {
                p[i][c] += v[i][c] * DT_S + 0.5 * a[i][c] * DT_S * DT_S;
                v[i][c] += a[i][c] * DT_S;
            }
        }
    }
    out
}

/// [`visited`] for every expert, in their order, on `threads` threads.
pub fn visited_all(
    o: &SwarmDataOptions,
    experts: &[Expert],
    policy: &dyn SwarmPolicy,
    threads: usize,
) -> Vec<SwarmSample> {
    let per_expert = Campaign::new(experts.len()).workers(threads).map(|k| visited(o, &experts[k], policy));
    per_expert.into_iter().flatten().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::swarm::train::data::case_data;

    /// A policy that never moves.
    struct Stay;
    impl SwarmPolicy for Stay {
        fn accel_mps2(&self, _obs: &SwarmObservation) -> [f64; 3] {
            [0.0; 3]
        }
    }

    #[test]
    fn a_policy_that_stays_put_is_labelled_back_toward_the_plan_and_threads_do_not_matter() {
        let mut o = SwarmDataOptions::reference(4);
        (o.n_min, o.n_max, o.hold_steps) = (2, 3, 5);
        let (_, _, e0) = case_data(&o, 0);
        let (_, _, e1) = case_data(&o, 1);
        let experts = vec![e0.unwrap(), e1.unwrap()];
        let s = visited(&o, &experts[0], &Stay);
        assert_eq!(s.len(), 2 * (STEPS + 5));
        // Never moving: at node k the label is the tracking target from the start at rest.
        let k = 40;
        let (i, smp) = (1, s[2 * k + 1]);
        assert_eq!(smp.target_mps2, experts[0].target(&o, i, k, experts[0].problem.starts_m[i], [0.0; 3]));
        assert_eq!(smp.obs.v_mps, [0.0; 3]);
        // After T the label pulls toward the target (which the vehicle never left for).
        let g = experts[0].problem.goals_m[0];
        let p0 = experts[0].problem.starts_m[0];
        let last = s[2 * (STEPS + 4)].target_mps2;
        assert!((0..3).all(|c| (g[c] - p0[c]).abs() < 1e-9 || last[c].signum() == (g[c] - p0[c]).signum()), "{last:?}");
        assert_eq!(visited_all(&o, &experts, &Stay, 1), visited_all(&o, &experts, &Stay, 2));
    }
}
