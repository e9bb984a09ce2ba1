//! Seed 001's plant: the tethered space net robot. The net is `crate::net` (spring–damper
//! mesh of eq. (4), CW relative motion, RK4 sub-steps); its four corners are the MUs, agent i
//! flying MU i.
//!
//! Readings of agent i (9 values, exact truth, no noise):
//!   `[0..3]` MU i's position [x, y, z] in the target's LVLH frame, m,
//!   `[3..6]` its velocity [vx, vy, vz], m/s,
//!   `[6..9]` the net tension on it [Tx, Ty, Tz], N (the sum of its two edges' forces, eq. (5)).
//! Command of agent i: MU i's thrust [ux, uy, uz] in the LVLH frame, N, held over the step. It is
//! applied as sent: a component beyond the thrust bound is not clipped but counted
//! (`thrust_bound_violations`, one per MU-step with any axis over the bound), so a controller
//! that overdrives its thrusters is visible rather than silently corrected.
//!
//! Besides the per-step row, the position of every node at the scenario's snapshot times goes to
//! `snapshots/net_nodes.csv` of the run directory (long format: one line per node and time),
//! enough to draw the net in 3-D at 0, 10, 20 and 30 s without a 363-column row at every step.

use crate::net::{N_MU, Net, NetParams, NetState};
use cohort_runtime::model::PlantModel;
use rand_chacha::ChaCha8Rng;

const AXES: [&str; 3] = ["x", "y", "z"];

/// Name of the snapshot file in the run's `snapshots/`.
pub const SNAPSHOT_FILE: &str = "net_nodes.csv";

pub struct TsnrNetPlant {
    net: Net,
    state: NetState,
    thrust_n: [[f64; 3]; N_MU],
    thrust_bound_n: f64,
    dt_s: f64,
    /// Steps taken so far (the state is at t = k·dt).
    k: u64,
    snapshot_steps: Vec<u64>,
    /// (t_s, node positions) at each snapshot step reached.
    snapshots: Vec<(f64, Vec<[f64; 3]>)>,
    fuel_ns: [f64; N_MU],
    thrust_max_abs_n: [[f64; 3]; N_MU],
    thrust_bound_violations: u64,
    malformed_commands: u64,
    tension_max_n: [f64; N_MU],
    edge_tension_max_n: f64,
}

impl TsnrNetPlant {
    /// The net folded between the MUs at their initial states (`mu_r0_lvlh_m[i]` is MU i+1).
    pub fn new(
        params: NetParams,
        mu_r0_lvlh_m: [[f64; 3]; N_MU],
        mu_v0_lvlh_mps: [[f64; 3]; N_MU],
        thrust_bound_n: f64,
        dt_s: f64,
        snapshot_steps: Vec<u64>,
    ) -> Result<Self, crate::net::NetError> {
        let net = Net::new(params)?;
        let state = net.folded_state(&mu_r0_lvlh_m, &mu_v0_lvlh_mps);
        let mut plant = Self {
            net,
            state,
            thrust_n: [[0.0; 3]; N_MU],
            thrust_bound_n,
            dt_s,
            k: 0,
            snapshot_steps,
            snapshots: Vec::new(),
            fuel_ns: [0.0; N_MU],
            thrust_max_abs_n: [[0.0; 3]; N_MU],
            thrust_bound_violations: 0,
            malformed_commands: 0,
            tension_max_n: [0.0; N_MU],
            edge_tension_max_n: 0.0,
        };
        plant.snapshot_if_due();
        Ok(plant)
    }

    pub fn net(&self) -> &Net {
        &self.net
    }
    pub fn state(&self) -> &NetState {
        &self.state
    }

    fn snapshot_if_due(&mut self) {
        if self.snapshot_steps.contains(&self.k) {
            self.snapshots.push((self.k as f64 * self.dt_s, self.state.r_lvlh_m.clone()));
        }
    }

    /// MU `mu` (1..=4)'s node index.
    fn corner(&self, mu: u32) -> usize {
        self.net.corner_nodes()[(mu - 1) as usize]
    }
}

impl PlantModel for TsnrNetPlant {
    /// The MUs' positions in the target's LVLH frame (no body at its origin).
    fn positions_m(&self, out: &mut Vec<[f64; 3]>) -> bool {
        out.extend((1..=N_MU as u32).map(|mu| self.state.r_lvlh_m[self.corner(mu)]));
        true
    }
    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for i in 1..=N_MU {
            for (q, unit) in [("r_lvlh", "m"), ("v_lvlh", "mps"), ("thrust", "n"), ("tension", "n")] {
                for ax in AXES {
                    c.push(format!("mu{i}_{q}_{ax}_{unit}"));
                }
            }
        }
        c.push("net_max_edge_tension_n".into());
        c.push("net_energy_j".into());
        c
    }

    fn readings(&mut self, agent: u32, _rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let c = self.corner(agent);
        out.extend_from_slice(&self.state.r_lvlh_m[c]);
        out.extend_from_slice(&self.state.v_lvlh_mps[c]);
        out.extend_from_slice(&self.net.corner_tension_n(&self.state)[(agent - 1) as usize]);
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let i = (agent - 1) as usize;
        if command.len() != 3 {
            // Only a broken algorithm sends another length; the missing axes coast.
            self.malformed_commands += 1;
        }
        let u: [f64; 3] = std::array::from_fn(|ax| command.get(ax).copied().unwrap_or(0.0));
        if u.iter().any(|x| x.abs() > self.thrust_bound_n) {
            self.thrust_bound_violations += 1;
        }
        for ax in 0..3 {
            self.thrust_max_abs_n[i][ax] = self.thrust_max_abs_n[i][ax].max(u[ax].abs());
        }
        self.thrust_n[i] = u;
    }

    fn advance(&mut self, dt_s: f64) {
        // The state is still at tₖ: sample the peak tensions on the same grid as the telemetry.
        let t = self.net.corner_tension_n(&self.state);
        for i in 0..N_MU {
            self.tension_max_n[i] = self.tension_max_n[i].max(norm(&t[i]));
            self.fuel_ns[i] += norm(&self.thrust_n[i]) * dt_s;
        }
        self.edge_tension_max_n = self.edge_tension_max_n.max(self.net.max_edge_tension_n(&self.state));
        self.net.advance(&mut self.state, dt_s, &self.thrust_n);
        self.k += 1;
        self.snapshot_if_due();
    }

    fn row(&self, out: &mut Vec<f64>) {
        let t = self.net.corner_tension_n(&self.state);
        for (i, &c) in self.net.corner_nodes().iter().enumerate() {
            out.extend_from_slice(&self.state.r_lvlh_m[c]);
            out.extend_from_slice(&self.state.v_lvlh_mps[c]);
            out.extend_from_slice(&self.thrust_n[i]);
            out.extend_from_slice(&t[i]);
        }
        out.push(self.net.max_edge_tension_n(&self.state));
        out.push(self.net.energy(&self.state).total_j());
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        let mut m = Vec::new();
        for i in 0..N_MU {
            let id = i + 1;
            m.push((format!("mu_{id}.fuel_ns"), self.fuel_ns[i]));
            for (ax, name) in AXES.iter().enumerate() {
                m.push((format!("mu_{id}.thrust_max_abs_{name}_n"), self.thrust_max_abs_n[i][ax]));
            }
            m.push((format!("mu_{id}.tension_max_n"), self.tension_max_n[i]));
        }
        m.push(("fuel_total_ns".into(), self.fuel_ns.iter().sum()));
        for (ax, name) in AXES.iter().enumerate() {
            let max = self.thrust_max_abs_n.iter().map(|u| u[ax]).fold(0.0, f64::max);
            m.push((format!("thrust_max_abs_{name}_n"), max));
        }
        m.push(("thrust_bound_n".into(), self.thrust_bound_n));
        m.push(("thrust_bound_violations".into(), self.thrust_bound_violations as f64));
        m.push(("malformed_commands".into(), self.malformed_commands as f64));
        m.push(("net.max_edge_tension_n".into(), self.edge_tension_max_n));
        m
    }

    fn extra_telemetry(&self) -> Vec<(String, String)> {
        use std::fmt::Write as _;
        let n = self.net.params().nodes_per_side;
        let mut text = String::from("t_s,node,grid_row,grid_col,r_lvlh_x_m,r_lvlh_y_m,r_lvlh_z_m\n");
        for (t_s, nodes) in &self.snapshots {
            for (node, r) in nodes.iter().enumerate() {
                // `{:?}` prints the shortest text that parses back to the same f64.
                let _ = writeln!(text, "{t_s:?},{node},{},{},{:?},{:?},{:?}", node / n, node % n, r[0], r[1], r[2]);
            }
        }
        vec![(SNAPSHOT_FILE.to_string(), text)]
    }
}

fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn start() -> ([[f64; 3]; 4], [[f64; 3]; 4]) {
        let r = [[-10.0, 0.75, 0.75], [-10.0, -0.75, 0.75], [-10.0, 0.75, -0.75], [-10.0, -0.75, -0.75]];
        (r, [[0.0; 3]; 4])
    }

    fn plant(snapshots: Vec<u64>) -> TsnrNetPlant {
        let (r, v) = start();
        TsnrNetPlant::new(NetParams::default(), r, v, 5.0, 0.1, snapshots).unwrap()
    }

    #[test]
    fn readings_are_the_mu_state_then_the_tension() {
        let mut p = plant(vec![]);
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut out = Vec::new();
        p.readings(2, &mut rng, &mut out);
        assert_eq!(out, vec![-10.0, -0.75, 0.75, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        // Pull MU 1 out along +y and +z until its edges are taut: its tension points back in.
        for _ in 0..40 {
            p.apply_command(1, &[0.0, 5.0, 5.0]);
            for mu in 2..=4 {
                p.apply_command(mu, &[0.0; 3]);
            }
            p.advance(0.1);
        }
        out.clear();
        p.readings(1, &mut rng, &mut out);
        let c = p.net().corner_nodes()[0];
        assert_eq!(out[0..3], p.state().r_lvlh_m[c]);
        assert_eq!(out[3..6], p.state().v_lvlh_mps[c]);
        assert_eq!(out[6..9], p.net().corner_tension_n(p.state())[0]);
        assert!(out[7] < -0.1 && out[8] < -0.1, "the net holds MU 1 back: {out:?}");
    }

    #[test]
    fn fuel_and_bound_violations_are_counted_not_clipped() {
        let mut p = plant(vec![]);
        p.apply_command(1, &[3.0, 4.0, 0.0]);
        p.apply_command(2, &[0.0, 0.0, -5.0]);
        p.apply_command(3, &[5.5, 0.0, 0.0]);
        p.apply_command(4, &[0.0, 0.0]);
        let v0 = p.state().v_lvlh_mps[p.net().corner_nodes()[2]];
        p.advance(0.1);
        let m: std::collections::BTreeMap<String, f64> = p.metrics().into_iter().collect();
        assert!((m["mu_1.fuel_ns"] - 0.5).abs() < 1e-12);
        assert!((m["mu_2.fuel_ns"] - 0.5).abs() < 1e-12);
        assert!((m["fuel_total_ns"] - 1.55).abs() < 1e-12);
        assert_eq!(m["thrust_bound_violations"], 1.0, "only MU 3 is over 5 N; exactly 5 N is allowed");
        assert_eq!(m["malformed_commands"], 1.0);
        assert_eq!(m["thrust_max_abs_x_n"], 5.5);
        assert_eq!(m["mu_2.thrust_max_abs_z_n"], 5.0);
        // MU 3 got the full 5.5 N (the folded net is slack): Δv = 5.5 / 10 · 0.1 up to the CW terms.
        let v1 = p.state().v_lvlh_mps[p.net().corner_nodes()[2]];
        assert!((v1[0] - v0[0] - 0.055).abs() < 1e-6, "{v1:?}");
    }

    #[test]
    fn snapshots_hold_every_node_at_the_requested_steps() {
        let mut p = plant(vec![0, 3]);
        for _ in 0..5 {
            for mu in 1..=4 {
                p.apply_command(mu, &[1.0, 0.0, 0.0]);
            }
            p.advance(0.1);
        }
        let files = p.extra_telemetry();
        assert_eq!(files.len(), 1);
        let (name, text) = &files[0];
        assert_eq!(name, SNAPSHOT_FILE);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 1 + 2 * 121);
        assert_eq!(lines[1], "0.0,0,0,0,-10.0,0.75,0.75");
        assert!(lines[122].starts_with("0.30000000000000004,0,0,0,"), "{}", lines[122]);
        let x: f64 = lines[122].split(',').nth(4).unwrap().parse().unwrap();
        assert!(x > -10.0, "the net moved by 0.3 s: {x}");
        assert_eq!(p.columns().len(), 4 * 12 + 2);
        let mut row = Vec::new();
        p.row(&mut row);
        assert_eq!(row.len(), p.columns().len());
    }

    #[test]
    fn thirty_seconds_of_deployment_are_quick() {
        // The closed loop's cost: 30 s at 1 ms sub-steps, all edges live after deployment.
        let mut p = plant(vec![]);
        let t0 = std::time::Instant::now();
        for k in 0..300 {
            let out = if k < 100 { 3.0 } else { 0.0 };
            let u = [[0.0, out, out], [0.0, -out, out], [0.0, out, -out], [0.0, -out, -out]];
            for (i, u) in u.iter().enumerate() {
                p.apply_command(i as u32 + 1, u);
            }
            p.advance(0.1);
        }
        let wall = t0.elapsed().as_secs_f64();
        let m: std::collections::BTreeMap<String, f64> = p.metrics().into_iter().collect();
        assert!(m["net.max_edge_tension_n"] > 1.0, "the net was deployed taut: {m:?}");
        assert!(p.state().r_lvlh_m.iter().flatten().all(|x| x.is_finite()));
        // Generous bound (debug builds, loaded machines); a release build takes ≈ 0.2 s.
        assert!(wall < 60.0, "{wall} s");
    }
}
