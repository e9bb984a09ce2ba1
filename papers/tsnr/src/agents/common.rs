//! What the three seed-001 formation controllers (AEMC, DMPC, SMC) have in common: reading an
//! MU's sensors, its desired trajectory from the scenario, the thrust bound, and the telemetry
//! columns they all write.

use crate::config::formation::{READINGS_USED, SHARE_HEADER, TsnrFormation};
use crate::trajectory::{Desired, Trajectory, Waypoint};

pub type V3 = [f64; 3];

/// An MU's readings at t_k: its own state and the net tension on it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sensed {
    /// [r; v] in the target's LVLH frame, m and m/s.
    pub state: [f64; 6],
    /// Measured net tension on the MU, N.
    pub tension_n: V3,
}

impl Sensed {
    /// From the `tsnr-net` plant's readings: [r (3), v (3), T (3)].
    pub fn from_readings(readings: &[f64]) -> Self {
        assert!(
            readings.len() >= READINGS_USED,
            "tsnr-formation needs {READINGS_USED} readings ([r; v; T]), got {} (validation requires the tsnr-net plant)",
            readings.len()
        );
        let mut s = Self::default();
        s.state.copy_from_slice(&readings[..6]);
        s.tension_n.copy_from_slice(&readings[6..9]);
        s
    }
    pub fn r_m(&self) -> V3 {
        [self.state[0], self.state[1], self.state[2]]
    }
    pub fn v_mps(&self) -> V3 {
        [self.state[3], self.state[4], self.state[5]]
    }
}

/// Agent `id`'s desired trajectory, as the (validated) scenario gives it.
pub fn trajectory_of(cfg: &TsnrFormation, id: u32) -> Trajectory {
    let w = cfg.trajectory.agents.iter().find(|w| w.id == id).expect("validated: every agent has waypoints");
    let waypoints: Vec<Waypoint> =
        w.r_m.iter().zip(w.velocities()).map(|(r, v)| Waypoint { r_m: *r, v_mps: v }).collect();
    Trajectory::new(&cfg.trajectory.knots_s, &waypoints).expect("validated: knots increase, one waypoint per knot")
}

/// Clip each axis to ±bound (the plant counts any excess as a violation).
pub fn saturate(u: V3, bound_n: f64) -> V3 {
    u.map(|x| x.clamp(-bound_n, bound_n))
}

/// The header every tsnr-formation share starts with: own state at t_k and the thrust
/// commanded at t_k (what a neighbour's tension predictor reads).
pub fn push_header(out: &mut Vec<f64>, sensed: &Sensed, u_n: &V3) {
    out.extend_from_slice(&sensed.state);
    out.extend_from_slice(u_n);
    debug_assert_eq!(SHARE_HEADER, 9);
}

/// Telemetry every method writes first, and the values to go with it.
pub fn base_columns() -> Vec<String> {
    let mut c = Vec::new();
    for (q, unit) in [("u", "n"), ("err", "m"), ("err_v", "mps"), ("r_des", "m"), ("tension_meas", "n")] {
        for ax in ["x", "y", "z"] {
            c.push(format!("{q}_{ax}_{unit}"));
        }
    }
    c
}

pub fn base_row(out: &mut Vec<f64>, u_n: &V3, sensed: &Sensed, d: &Desired) {
    out.extend_from_slice(u_n);
    for ax in 0..3 {
        out.push(sensed.state[ax] - d.r_m[ax]);
    }
    for ax in 0..3 {
        out.push(sensed.state[3 + ax] - d.v_mps[ax]);
    }
    out.extend_from_slice(&d.r_m);
    out.extend_from_slice(&sensed.tension_n);
}

#[cfg(test)]
pub mod test_support {
    //! Case 1 of papers/tsnr/README.md as a configuration, and a closed loop of four MUs under pure CW
    //! dynamics (no net) exchanging shares as the lockstep driver does.

    use crate::config::formation::{TsnrFormation, TsnrModel, TsnrMpc, TsnrSmc, TsnrTrajectory, TsnrWaypoints};
    use crate::cw::Cw;
    use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};

    pub const DT_S: f64 = 0.1;
    /// our choices: r₀ = 42 164 km, MU mass 10 kg, 5 N per axis.
    pub const MODEL: TsnrModel = TsnrModel { orbit_radius_m: 42_164e3, mass_kg: 10.0, thrust_max_n: 5.0 };

    /// The square net's graph: each MU reads the two corners it shares an edge with.
    pub fn square() -> Vec<Vec<u32>> {
        vec![vec![2, 3], vec![1, 4], vec![1, 4], vec![2, 3]]
    }

    /// The paper's Case 1: start, deployed (x = −5, ±2.55), approach (x = 3), closed (x = 5, ±0.5).
    pub fn case1(method: &str) -> TsnrFormation {
        let signs = [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)];
        let agents = signs
            .iter()
            .enumerate()
            .map(|(i, (sy, sz))| TsnrWaypoints {
                id: i as u32 + 1,
                r_m: [(-10.0, 0.75), (-5.0, 2.55), (3.0, 2.55), (5.0, 0.5)]
                    .iter()
                    .map(|(x, h)| [*x, sy * h, sz * h])
                    .collect(),
                v_mps: None,
            })
            .collect();
        TsnrFormation {
            method: method.parse().expect("a method name"),
            trajectory: TsnrTrajectory { knots_s: vec![0.0, 10.0, 20.0, 30.0], agents },
            mpc: Some(TsnrMpc {
                horizon_steps: 20,
                q_position: 1.0,
                q_velocity: 0.1,
                r_force: 0.002,
                r_neighbour_force: 0.002 / 16.0,
                adjacency_weight: 0.25,
                pinning_weight: 1.0,
                pareto_weights: None,
                neighbour_costs: true,
                tension_forecast: crate::config::formation::Forecast::HoldMeasured,
                tension_weights: None,
                max_iter: 100,
                qp_solver: Default::default(),
                tension_oracle: None,
                oracle_series: None,
                force_cost: Default::default(),
            }),
            smc: Some(TsnrSmc { lambda_per_s: 1.5, switching_gain_mps2: 0.3, boundary_layer_mps: 0.2 }),
        }
    }

    pub fn readings(state: &[f64; 6], tension_n: &[f64; 3]) -> Vec<f64> {
        state.iter().chain(tension_n).copied().collect()
    }

    /// What a closed loop did.
    pub struct Run {
        pub states: Vec<[f64; 6]>,
        /// Largest |u| on any axis of any MU, N.
        pub max_thrust_n: f64,
        /// ∫‖uᵢ‖dt per MU, N·s.
        pub fuel_n_s: Vec<f64>,
    }

    /// `algos[i]` is MU i+1 on `graph`; exact ZOH CW dynamics, the tension `tension(k, i, x)`
    /// (N) added to the thrust.
    pub fn closed_loop(
        algos: &mut [Box<dyn Algorithm>],
        graph: &[Vec<u32>],
        mut states: Vec<[f64; 6]>,
        steps: u64,
        tension: impl Fn(u64, usize, &[f64; 6]) -> [f64; 3],
    ) -> Run {
        let disc = Cw::new(MODEL.orbit_radius_m, MODEL.mass_kg).discretise(DT_S);
        let n = algos.len();
        let mut outs = vec![ShareOut::default(); n];
        let mut run = Run { states: Vec::new(), max_thrust_n: 0.0, fuel_n_s: vec![0.0; n] };
        for k in 0..steps {
            let t_s = k as f64 * DT_S;
            let tensions: Vec<[f64; 3]> = (0..n).map(|i| tension(k, i, &states[i])).collect();
            for i in 0..n {
                outs[i] = ShareOut::default();
                let r = readings(&states[i], &tensions[i]);
                algos[i].share(&AgentInput { k, t_s, readings: &r }, &mut outs[i]);
                let mut row = Vec::new();
                algos[i].row(&mut row);
                assert_eq!(row.len(), algos[i].columns().len());
            }
            for i in 0..n {
                let nb: Vec<Neighbour<'_>> = graph[i]
                    .iter()
                    .map(|&j| Neighbour { id: j, values: &outs[j as usize - 1].values, age_steps: 0 })
                    .collect();
                algos[i].step(DT_S, &nb);
                let u: [f64; 3] = std::array::from_fn(|a| outs[i].command[a]);
                run.max_thrust_n = u.iter().fold(run.max_thrust_n, |m, x| m.max(x.abs()));
                run.fuel_n_s[i] += (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt() * DT_S;
                let f = [u[0] + tensions[i][0], u[1] + tensions[i][1], u[2] + tensions[i][2]];
                states[i] = disc.step(&states[i], &f);
            }
        }
        run.states = states;
        run
    }
}
