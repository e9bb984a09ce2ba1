//! What one vehicle of the swarm (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883) knows when
//! it chooses its acceleration, and the one interface every swarm policy implements.
//!
//! The paper's distributed policy acts on *local* observations (GLAS, its ref. [42]): its own
//! goal offset and velocity, and the relative states of the vehicles within the communication
//! radius R_comm; ours adds the vehicle's clock, the time to go to the reconfiguration time T
//! (see [`crate::swarm::control::policy`] for why). Ours (the paper's radius, counts and scalings are
//! lost): at most [`MAX_NEIGHBOURS`] = 6 neighbours, the nearest first, strictly within R_comm; a
//! vehicle at or beyond R_comm is not observed at all, whatever it shares.
//!
//! The learned deep-set policy, the goal-seeking baselines and the Neural-Rendezvous layer (which
//! rolls a policy ahead and tracks it) all consume a [`SwarmObservation`] through
//! [`SwarmPolicy`], so the agent, the in-process simulation and the training data see one
//! definition of "what a vehicle knows".

/// Most neighbours a vehicle observes (the nearest within R_comm).
pub const MAX_NEIGHBOURS: usize = 6;

/// One observed neighbour, relative to the observing vehicle (world frame).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Neighbour {
    /// p_j − p_i.
    pub dp_m: [f64; 3],
    /// v_j − v_i.
    pub dv_mps: [f64; 3],
}

/// A vehicle's local observation.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SwarmObservation {
    /// g_i − p_i: the goal relative to the vehicle's (estimated) position.
    pub goal_offset_m: [f64; 3],
    /// The vehicle's (estimated) velocity.
    pub v_mps: [f64; 3],
    /// Observed neighbours, nearest first; only the first `n_neighbours` are meaningful.
    pub neighbours: [Neighbour; MAX_NEIGHBOURS],
    pub n_neighbours: usize,
    /// Time to go to the reconfiguration time T, s: max(T − t, 0) (0 when the caller has no
    /// clock; see [`SwarmObservation::at`]).
    pub t_to_go_s: f64,
}

impl SwarmObservation {
    /// The observation of a vehicle at (`p_m`, `v_mps`) with goal `goal_m`, among `others`
    /// (positions and velocities of every other vehicle, in any order): the nearest
    /// [`MAX_NEIGHBOURS`] with ‖p_j − p_i‖ < `r_comm_m`. Ties in distance keep the order of
    /// `others`, so the result does not depend on sort stability.
    pub fn local(
        p_m: [f64; 3],
        v_mps: [f64; 3],
        goal_m: [f64; 3],
        others: &[([f64; 3], [f64; 3])],
        r_comm_m: f64,
    ) -> Self {
        let mut near: Vec<(f64, usize)> = others
            .iter()
            .enumerate()
            .filter_map(|(k, (p, _))| {
                let d = dist(*p, p_m);
                (d < r_comm_m).then_some((d, k))
            })
            .collect();
        // Total order (distance, then index): deterministic whatever the sort.
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut obs = SwarmObservation { goal_offset_m: sub(goal_m, p_m), v_mps, ..Default::default() };
        for (slot, &(_, k)) in near.iter().take(MAX_NEIGHBOURS).enumerate() {
            let (p, v) = others[k];
            obs.neighbours[slot] = Neighbour { dp_m: sub(p, p_m), dv_mps: sub(v, v_mps) };
        }
        obs.n_neighbours = near.len().min(MAX_NEIGHBOURS);
        obs
    }

    /// The same observation at time to go `t_to_go_s` (clamped at 0).
    pub fn at(mut self, t_to_go_s: f64) -> Self {
        self.t_to_go_s = t_to_go_s.max(0.0);
        self
    }

    /// The meaningful neighbours.
    pub fn observed(&self) -> &[Neighbour] {
        &self.neighbours[..self.n_neighbours]
    }
}

/// A swarm policy: acceleration command (m/s², world frame) from a local observation. Pure: the
/// same observation always gives the same command (determinism across processes relies on it).
/// Implementations clip to their own bound; the plant clips again to |a_i| ≤ a_max per axis.
pub trait SwarmPolicy: Send + Sync {
    fn accel_mps2(&self, obs: &SwarmObservation) -> [f64; 3];
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_nearest_six_within_the_radius_are_observed() {
        // Eight others on the x axis at 0.1, 0.2, …, 0.8 m plus one at exactly R_comm and one beyond.
        let mut others: Vec<([f64; 3], [f64; 3])> =
            (1..=8).rev().map(|k| ([0.1 * k as f64, 0.0, 1.0], [0.0; 3])).collect();
        others.push(([1.0, 0.0, 1.0], [0.0; 3]));
        others.push(([0.0, 1.5, 1.0], [0.0; 3]));
        let obs = SwarmObservation::local([0.0, 0.0, 1.0], [0.1, 0.0, 0.0], [1.0, 1.0, 1.0], &others, 1.0);
        assert_eq!(obs.n_neighbours, MAX_NEIGHBOURS);
        let dx: Vec<f64> = obs.observed().iter().map(|n| n.dp_m[0]).collect();
        for (k, x) in dx.iter().enumerate() {
            assert!((x - 0.1 * (k + 1) as f64).abs() < 1e-12, "neighbour {k} at {x}");
        }
        assert_eq!(obs.neighbours[0].dv_mps, [-0.1, 0.0, 0.0]);
        assert_eq!(obs.goal_offset_m, [1.0, 1.0, 0.0]);
    }

    #[test]
    fn a_vehicle_at_or_beyond_the_radius_is_not_observed() {
        let others = [([1.0, 0.0, 0.0], [0.0; 3]), ([0.0, 0.0, 2.0], [1.0; 3])];
        let obs = SwarmObservation::local([0.0; 3], [0.0; 3], [0.0; 3], &others, 1.0);
        assert_eq!(obs.n_neighbours, 0);
        assert_eq!(obs.observed(), &[]);
    }
}
