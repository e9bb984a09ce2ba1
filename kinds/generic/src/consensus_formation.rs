//! Consensus formation keeping (the smoke scenario's method). Each agent estimates its own
//! position and velocity from noisy position readings with a Luenberger observer, publishes the
//! estimate, and steers toward its slot relative to the positions its neighbours publish:
//!
//!   uᵢ = −k_p Σⱼ [(r̂ᵢ − r̂ⱼ) − (pᵢ − pⱼ)] − k_d v̂ᵢ
//!   dr̂ᵢ/dt = v̂ᵢ + l₁ (yᵢ − r̂ᵢ),   dv̂ᵢ/dt = uᵢ + l₂ (yᵢ − r̂ᵢ)
//!
//! The command of step k uses the neighbours' estimates of step k−1 (the latest they have
//! published when the measurement of step k arrives). A neighbour that has published nothing yet
//! contributes no term.

use crate::config::ConsensusFormation as Gains;
use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};

#[derive(serde::Serialize, serde::Deserialize)]
pub struct ConsensusFormation {
    #[serde(with = "cohort_runtime::checkpoint::as_json")]
    gains: Gains,
    slot_m: [f64; 3],
    /// Neighbour id → (its slot, its latest published position estimate).
    neighbours: Vec<(u32, [f64; 3], Option<[f64; 3]>)>,
    r_hat_m: [f64; 3],
    v_hat_mps: [f64; 3],
    y_m: [f64; 3],
    u_mps2: [f64; 3],
    initialised: bool,
}

impl ConsensusFormation {
    pub fn new(gains: Gains, id: u32, n_agents: u32, neighbours: &[u32]) -> Self {
        let slot_m = gains.slot_m(id, n_agents);
        let neighbours = neighbours.iter().map(|&j| (j, gains.slot_m(j, n_agents), None)).collect();
        Self {
            gains,
            slot_m,
            neighbours,
            r_hat_m: [0.0; 3],
            v_hat_mps: [0.0; 3],
            y_m: [0.0; 3],
            u_mps2: [0.0; 3],
            initialised: false,
        }
    }

    fn command(&self) -> [f64; 3] {
        let g = &self.gains;
        let mut u = [0.0; 3];
        for (_, slot_j, r_j) in &self.neighbours {
            if let Some(r_j) = r_j {
                for a in 0..3 {
                    u[a] -= g.kp_per_s2 * ((self.r_hat_m[a] - r_j[a]) - (self.slot_m[a] - slot_j[a]));
                }
            }
        }
        for a in 0..3 {
            u[a] -= g.kd_per_s * self.v_hat_mps[a];
        }
        u
    }

    /// Observer derivative at state (r̂, v̂) with y and u held.
    fn deriv(&self, r: &[f64; 3], v: &[f64; 3]) -> ([f64; 3], [f64; 3]) {
        let (l1, l2) = (self.gains.observer_l1_per_s, self.gains.observer_l2_per_s2);
        let mut dr = [0.0; 3];
        let mut dv = [0.0; 3];
        for a in 0..3 {
            let res = self.y_m[a] - r[a];
            dr[a] = v[a] + l1 * res;
            dv[a] = self.u_mps2[a] + l2 * res;
        }
        (dr, dv)
    }
}

fn axpy(x: &[f64; 3], a: f64, d: &[f64; 3]) -> [f64; 3] {
    [x[0] + a * d[0], x[1] + a * d[1], x[2] + a * d[2]]
}

impl Algorithm for ConsensusFormation {
    cohort_runtime::serde_checkpoint!();

    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for (q, unit) in [("r_hat", "m"), ("v_hat", "mps"), ("u", "mps2")] {
            for ax in ["x", "y", "z"] {
                c.push(format!("{q}_{ax}_{unit}"));
            }
        }
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        for a in 0..3 {
            self.y_m[a] = input.readings.get(a).copied().unwrap_or(0.0);
        }
        if !self.initialised {
            // Start the observer on the first reading rather than at the origin.
            self.r_hat_m = self.y_m;
            self.initialised = true;
        }
        self.u_mps2 = self.command();
        out.command.extend_from_slice(&self.u_mps2);
        out.values.extend_from_slice(&self.r_hat_m);
        out.values.extend_from_slice(&self.v_hat_mps);
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        // RK4 of the observer, y and u held over the step.
        let (r, v) = (self.r_hat_m, self.v_hat_mps);
        let (k1r, k1v) = self.deriv(&r, &v);
        let (k2r, k2v) = self.deriv(&axpy(&r, dt_s / 2.0, &k1r), &axpy(&v, dt_s / 2.0, &k1v));
        let (k3r, k3v) = self.deriv(&axpy(&r, dt_s / 2.0, &k2r), &axpy(&v, dt_s / 2.0, &k2v));
        let (k4r, k4v) = self.deriv(&axpy(&r, dt_s, &k3r), &axpy(&v, dt_s, &k3v));
        for a in 0..3 {
            self.r_hat_m[a] = r[a] + dt_s / 6.0 * (k1r[a] + 2.0 * k2r[a] + 2.0 * k3r[a] + k4r[a]);
            self.v_hat_mps[a] = v[a] + dt_s / 6.0 * (k1v[a] + 2.0 * k2v[a] + 2.0 * k3v[a] + k4v[a]);
        }
        for nb in neighbours {
            if let Some(entry) = self.neighbours.iter_mut().find(|(j, _, _)| *j == nb.id)
                && let [x, y, z, ..] = nb.values
            {
                entry.2 = Some([*x, *y, *z]);
            }
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&self.r_hat_m);
        out.extend_from_slice(&self.v_hat_mps);
        out.extend_from_slice(&self.u_mps2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gains() -> Gains {
        Gains {
            formation_radius_m: 10.0,
            kp_per_s2: 0.5,
            kd_per_s: 1.5,
            observer_l1_per_s: 6.0,
            observer_l2_per_s2: 9.0,
        }
    }

    #[test]
    fn the_command_depends_on_the_neighbours_shares() {
        let mut a = ConsensusFormation::new(gains(), 1, 6, &[2, 6]);
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &[0.0, 0.0, 0.0] }, &mut out);
        assert_eq!(out.command, vec![0.0, 0.0, 0.0], "no neighbour heard yet, at rest");
        a.step(0.01, &[Neighbour { id: 2, values: &[50.0, 0.0, 0.0, 0.0, 0.0, 0.0], age_steps: 0 }]);
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 1, t_s: 0.01, readings: &[0.0, 0.0, 0.0] }, &mut out);
        assert!(out.command[0] > 1.0, "pulled toward the far neighbour: {:?}", out.command);
    }

    #[test]
    fn shares_carry_the_estimate() {
        let mut a = ConsensusFormation::new(gains(), 3, 6, &[2, 4]);
        let mut out = ShareOut::default();
        a.share(&AgentInput { k: 0, t_s: 0.0, readings: &[1.0, 2.0, 3.0] }, &mut out);
        assert_eq!(out.values, vec![1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
    }
}
