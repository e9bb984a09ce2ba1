//! The goal-seeking baseline policy of the swarm: a critically damped PD law toward the goal,
//! saturated per axis, a = clip(ω²(g − p) − 2ωv, ±a_max). It ignores the neighbours entirely (no
//! collision avoidance, on purpose): an honest baseline that flies straight through conflicts,
//! and a [`SwarmPolicy`] that lets the swarm run before a learned policy exists. Not from the
//! paper ("Neural-Rendezvous", arXiv:2208.04883, Sec. 7.2 flies a learned deep-set policy).

use crate::swarm::control::obs::{SwarmObservation, SwarmPolicy};

/// a = clip(ω²(g − p) − 2ωv, ±a_max) per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PdPolicy {
    pub omega_per_s: f64,
    pub a_max_mps2: f64,
}

impl SwarmPolicy for PdPolicy {
    fn accel_mps2(&self, obs: &SwarmObservation) -> [f64; 3] {
        let (w, a_max) = (self.omega_per_s, self.a_max_mps2);
        [0, 1, 2].map(|a| (w * w * obs.goal_offset_m[a] - 2.0 * w * obs.v_mps[a]).clamp(-a_max, a_max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_saturates_far_away_damps_near_the_goal_and_ignores_neighbours() {
        let pd = PdPolicy { omega_per_s: 1.0, a_max_mps2: 2.0 };
        let mut obs =
            SwarmObservation { goal_offset_m: [3.0, -0.5, 0.1], v_mps: [0.0, 0.0, 0.2], ..Default::default() };
        let a = pd.accel_mps2(&obs);
        assert_eq!(a, [2.0, -0.5, 0.1 - 0.4]);
        obs.n_neighbours = 1;
        obs.neighbours[0].dp_m = [0.1, 0.0, 0.0];
        assert_eq!(pd.accel_mps2(&obs), a);
        // Closed loop from rest 4 m away: within 0.1 m of the goal and nearly at rest by 8 s.
        let (mut p, mut v) = (-4.0, 0.0);
        for _ in 0..80 {
            let o = SwarmObservation { goal_offset_m: [-p, 0.0, 0.0], v_mps: [v, 0.0, 0.0], ..Default::default() };
            let u = pd.accel_mps2(&o)[0];
            p += v * 0.1 + 0.5 * u * 0.01;
            v += u * 0.1;
        }
        assert!(p.abs() < 0.1 && v.abs() < 0.1, "p = {p}, v = {v}");
    }
}
