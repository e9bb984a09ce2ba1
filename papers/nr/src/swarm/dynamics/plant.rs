//! The `swarm` plant (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883): N vehicles as 3-D
//! double integrators p̈ᵢ = uᵢ + dᵢ, uᵢ the command clipped to a_max per axis and held over the
//! control interval, dᵢ a bounded disturbance; readings p̂ᵢ, v̂ᵢ (truth + white Gaussian noise) and
//! the goal ([`crate::swarm::dynamics::messages`]); starts and goals from [`crate::swarm::dynamics::setup::draw`].
//!
//! Where the paper is silent (its vehicles are Crazyflies with their own attitude loops; we keep
//! the point-mass model the reference chooses):
//!
//! - the disturbance (the paper's d̄ is that of its ref. [44], value lost; ours 0 or 0.2 m/s²):
//!   each vehicle, each control interval, a constant acceleration of norm exactly d̄ in a direction
//!   uniform on the sphere, drawn from the plant's own set-up stream of the seed (so the
//!   multi-process and reference runs draw the same); the worst magnitude every interval;
//! - collisions: a pair collides while ‖diag(0.12, 0.12, 0.30)⁻¹(pᵢ − pⱼ)‖ < 1; the plant checks
//!   every pair at `substeps` (10) points per control interval, integrating exactly between them,
//!   and counts a collision each time a pair *enters* that set (a pair that stays inside counts
//!   once); also the distinct pairs that ever collided and the least distance seen;
//! - the cuboid bounds only the sampling: nothing keeps a vehicle inside it (sub-steps spent
//!   outside are counted);
//! - the control effort is ∫‖uᵢ‖dt of the applied (clipped) command, disturbance excluded.
//!
//! Rows (state at t_k, before its command): per vehicle p, v, ‖p − g‖; then the least pairwise
//! ellipsoid distance at t_k, the least over the sub-steps of the interval that ended at t_k
//! (t_0's own at k = 0) and the collisions so far. The end-of-run file `snapshots/swarm.csv`
//! holds what the rows never do (the state after the last interval, per-vehicle effort, the
//! distance to the goal at T).

use cohort_runtime::model::PlantModel;
use cohort_runtime::rng::setup_rng;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::swarm::dynamics::messages::SwarmReading;
use crate::swarm::dynamics::setup::{Cuboid, DrawError, distance_m, draw_in, ellipsoid_distance};

type V3 = [f64; 3];

/// What the plant needs besides the vehicles (checked by `swarm_config`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwarmParams {
    pub a_max_mps2: f64,
    pub disturbance_mps2: f64,
    pub pos_noise_m: f64,
    pub vel_noise_mps: f64,
    pub substeps: u32,
    pub t_reconfig_s: f64,
    /// Where starts and goals are drawn (and outside of which sub-steps are counted), m.
    pub cuboid_m: Cuboid,
}

/// Collision bookkeeping over every pair i < j.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Collisions {
    /// Entries into the collision set, over all pairs.
    pub events: u64,
    inside: Vec<bool>,
    ever: Vec<bool>,
    /// Least pairwise ellipsoid distance over every check so far.
    pub min_distance: f64,
}

impl Collisions {
    pub fn new(n: usize) -> Self {
        let pairs = n * n.saturating_sub(1) / 2;
        Self { events: 0, inside: vec![false; pairs], ever: vec![false; pairs], min_distance: f64::INFINITY }
    }

    /// Check every pair at positions `p`; returns the least pairwise distance of this check.
    pub fn check(&mut self, p: &[V3]) -> f64 {
        let mut least = f64::INFINITY;
        let mut k = 0;
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                let e = ellipsoid_distance([p[j][0] - p[i][0], p[j][1] - p[i][1], p[j][2] - p[i][2]]);
                least = least.min(e);
                let now = e < 1.0;
                if now && !self.inside[k] {
                    self.events += 1;
                    self.ever[k] = true;
                }
                self.inside[k] = now;
                k += 1;
            }
        }
        self.min_distance = self.min_distance.min(least);
        least
    }

    /// Distinct pairs that ever collided.
    pub fn pairs(&self) -> usize {
        self.ever.iter().filter(|x| **x).count()
    }
}

/// Least pairwise ellipsoid distance of `p` (∞ for fewer than two vehicles).
pub fn min_pair_distance(p: &[V3]) -> f64 {
    Collisions::new(p.len()).check(p)
}

pub struct SwarmPlant {
    prm: SwarmParams,
    p: Vec<V3>,
    v: Vec<V3>,
    goal: Vec<V3>,
    u: Vec<V3>,
    d: Vec<V3>,
    effort: Vec<f64>,
    clipped: Vec<u64>,
    outside_substeps: u64,
    goal_dist_at_t: Option<Vec<f64>>,
    coll: Collisions,
    interval_min: f64,
    disturbance_rng: ChaCha8Rng,
    t_s: f64,
    steps: u64,
}

impl SwarmPlant {
    /// `n` vehicles on the problem of `problem_seed`; the disturbance stream of `seed`.
    pub fn new(prm: SwarmParams, n: usize, problem_seed: u64, seed: u64) -> Result<Self, DrawError> {
        let (starts, goals) = draw_in(n, problem_seed, &prm.cuboid_m)?;
        Ok(Self::with_problem(prm, starts, goals, seed))
    }

    /// Given starts and goals (hand cases, tests), at rest.
    pub fn with_problem(prm: SwarmParams, starts: Vec<V3>, goal: Vec<V3>, seed: u64) -> Self {
        let n = starts.len();
        let mut coll = Collisions::new(n);
        let interval_min = coll.check(&starts);
        Self {
            prm,
            v: vec![[0.0; 3]; n],
            p: starts,
            goal,
            u: vec![[0.0; 3]; n],
            d: vec![[0.0; 3]; n],
            effort: vec![0.0; n],
            clipped: vec![0; n],
            outside_substeps: 0,
            goal_dist_at_t: None,
            coll,
            interval_min,
            disturbance_rng: setup_rng(seed, "nr-swarm-disturbance"),
            t_s: 0.0,
            steps: 0,
        }
    }

    #[cfg(feature = "host")]
    pub fn positions(&self) -> &[V3] {
        &self.p
    }
    #[cfg(test)] // used by the unit tests only
    pub fn velocities(&self) -> &[V3] {
        &self.v
    }
    #[cfg(feature = "host")]
    pub fn goals(&self) -> &[V3] {
        &self.goal
    }
    #[cfg(feature = "host")]
    pub fn collisions(&self) -> &Collisions {
        &self.coll
    }
    /// ∫‖uᵢ‖dt of each vehicle so far, m/s.
    #[cfg(feature = "host")]
    pub fn effort_mps(&self) -> &[f64] {
        &self.effort
    }

    fn goal_distances(&self) -> Vec<f64> {
        self.p.iter().zip(&self.goal).map(|(p, g)| distance_m(*p, *g)).collect()
    }

    /// A direction uniform on the sphere (normalised Gaussian) times d̄.
    fn draw_disturbance(&mut self) -> V3 {
        let g: V3 = [(); 3].map(|_| self.disturbance_rng.sample::<f64, _>(StandardNormal));
        let n = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        if n == 0.0 { [0.0; 3] } else { g.map(|x| self.prm.disturbance_mps2 * x / n) }
    }

    fn outside(&self, p: &V3) -> bool {
        (0..3).any(|a| p[a] < self.prm.cuboid_m[a][0] || p[a] > self.prm.cuboid_m[a][1])
    }
}

impl PlantModel for SwarmPlant {
    /// The vehicles' positions in the swarm's frame (no body at its origin).
    fn positions_m(&self, out: &mut Vec<[f64; 3]>) -> bool {
        out.extend_from_slice(&self.p);
        true
    }
    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for j in 1..=self.p.len() {
            for name in ["p_x_m", "p_y_m", "p_z_m", "v_x_mps", "v_y_mps", "v_z_mps", "goal_dist_m"] {
                c.push(format!("a{j}_{name}"));
            }
        }
        c.extend(["min_pair_ellipsoid", "min_pair_ellipsoid_interval", "collisions"].map(String::from));
        c
    }

    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let i = (agent as usize).wrapping_sub(1);
        let (Some(p), Some(v)) = (self.p.get(i).copied(), self.v.get(i).copied()) else { return };
        let mut noise = |s: f64| s * rng.sample::<f64, _>(StandardNormal);
        let p_hat = p.map(|x| x + noise(self.prm.pos_noise_m));
        let v_hat = v.map(|x| x + noise(self.prm.vel_noise_mps));
        SwarmReading { p_m: p_hat, v_mps: v_hat, goal_m: self.goal[i] }.write(out);
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let Some(u) = self.u.get_mut((agent as usize).wrapping_sub(1)) else { return };
        let a_max = self.prm.a_max_mps2;
        let raw: V3 = [0, 1, 2].map(|a| command.get(a).copied().filter(|x| x.is_finite()).unwrap_or(0.0));
        *u = raw.map(|x| x.clamp(-a_max, a_max));
        if *u != raw {
            self.clipped[agent as usize - 1] += 1;
        }
    }

    fn advance(&mut self, dt_s: f64) {
        if self.prm.disturbance_mps2 > 0.0 {
            self.d = (0..self.p.len()).map(|_| self.draw_disturbance()).collect();
        }
        let n = self.prm.substeps.max(1);
        let h = dt_s / f64::from(n);
        self.interval_min = f64::INFINITY;
        for _ in 0..n {
            for i in 0..self.p.len() {
                let acc: V3 = [0, 1, 2].map(|a| self.u[i][a] + self.d[i][a]);
                for a in 0..3 {
                    self.p[i][a] += self.v[i][a] * h + 0.5 * acc[a] * h * h;
                    self.v[i][a] += acc[a] * h;
                }
                self.outside_substeps += u64::from(self.outside(&self.p[i]));
            }
            let least = self.coll.check(&self.p);
            self.interval_min = self.interval_min.min(least);
        }
        for (e, u) in self.effort.iter_mut().zip(&self.u) {
            *e += (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt() * dt_s;
        }
        self.t_s += dt_s;
        self.steps += 1;
        if self.goal_dist_at_t.is_none() && self.t_s >= self.prm.t_reconfig_s - 1e-9 * dt_s {
            self.goal_dist_at_t = Some(self.goal_distances());
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        for ((p, v), g) in self.p.iter().zip(&self.v).zip(&self.goal) {
            out.extend(p);
            out.extend(v);
            out.push(distance_m(*p, *g));
        }
        out.extend([min_pair_distance(&self.p), self.interval_min, self.coll.events as f64]);
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        let d = self.goal_distances();
        vec![
            ("collisions".to_string(), self.coll.events as f64),
            ("collision_pairs".to_string(), self.coll.pairs() as f64),
            ("min_pair_ellipsoid".to_string(), self.coll.min_distance),
            ("max_goal_dist_end_m".to_string(), d.iter().copied().fold(0.0, f64::max)),
            ("total_effort_mps".to_string(), self.effort.iter().sum()),
        ]
    }

    fn extra_telemetry(&self) -> Vec<(String, String)> {
        vec![(SWARM_FILE.to_string(), self.end_csv())]
    }
}

/// The plant's end-of-run file in the run's `snapshots/`.
pub const SWARM_FILE: &str = "swarm.csv";
/// Its columns per vehicle j (prefixed `a{j}_`).
pub const SWARM_VEHICLE_COLUMNS: [&str; 10] = [
    "p_x_m",
    "p_y_m",
    "p_z_m",
    "goal_x_m",
    "goal_y_m",
    "goal_z_m",
    "goal_dist_m",
    "goal_dist_at_t_m",
    "effort_mps",
    "clipped_steps",
];
/// Its columns for the whole swarm.
pub const SWARM_COLUMNS: [&str; 5] =
    ["collisions", "collision_pairs", "min_pair_ellipsoid", "outside_cuboid_substeps", "t_reconfig_s"];

impl SwarmPlant {
    /// One row (`k`, `t_s` at the end) with [`SWARM_VEHICLE_COLUMNS`] per vehicle (the distance at
    /// T is NaN when the run stopped before T) and [`SWARM_COLUMNS`].
    fn end_csv(&self) -> String {
        let mut header = vec!["k".to_string(), "t_s".to_string()];
        let mut row = vec![self.steps.to_string(), format!("{:?}", self.t_s)];
        let now = self.goal_distances();
        for i in 0..self.p.len() {
            header.extend(SWARM_VEHICLE_COLUMNS.iter().map(|c| format!("a{}_{c}", i + 1)));
            let at_t = self.goal_dist_at_t.as_ref().map_or(f64::NAN, |d| d[i]);
            let (p, g) = (self.p[i], self.goal[i]);
            let values = [p[0], p[1], p[2], g[0], g[1], g[2], now[i], at_t, self.effort[i], self.clipped[i] as f64];
            row.extend(values.iter().map(|v| format!("{v:?}")));
        }
        header.extend(SWARM_COLUMNS.map(String::from));
        let swarm = [
            self.coll.events as f64,
            self.coll.pairs() as f64,
            self.coll.min_distance,
            self.outside_substeps as f64,
            self.prm.t_reconfig_s,
        ];
        row.extend(swarm.iter().map(|v| format!("{v:?}")));
        format!("{}\n{}\n", header.join(","), row.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn params() -> SwarmParams {
        SwarmParams {
            a_max_mps2: 2.0,
            disturbance_mps2: 0.0,
            pos_noise_m: 0.0,
            vel_noise_mps: 0.0,
            substeps: 10,
            t_reconfig_s: 8.0,
            cuboid_m: [[-2.0, 2.0], [-2.0, 2.0], [0.5, 2.0]],
        }
    }

    #[test]
    fn a_hand_case_counts_each_entry_once_and_sees_a_crossing_between_control_steps() {
        // Vehicle 1 at x = −1 flies at 2 m/s along x through vehicle 2 at rest at the origin; a
        // third hangs 0.25 m straight above vehicle 2 (ellipsoid distance 0.25/0.30 < 1: in
        // collision from the start, but the plant counts entries, so the pair counts once, at its
        // first check after the start).
        let starts = vec![[-1.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.25]];
        let mut plant = SwarmPlant::with_problem(params(), starts, vec![[0.0, 0.0, 1.0]; 3], 1);
        assert_eq!(plant.collisions().events, 1, "2–3 inside at t = 0");
        plant.v[0] = [2.0, 0.0, 0.0];
        // Control steps of 1 s: vehicle 1 jumps from x = −1 to 1 in one, through both others;
        // only the sub-steps (0.1 s, 0.2 m) see it pass within 0.12 m of x = 0.
        plant.advance(1.0);
        let c = plant.collisions();
        // Vehicle 1 crosses 2 (|Δx| ≤ 0.12 at x = 0: one entry) and passes 0.25 m below 3
        // (0.25/0.30 and |Δx| = 0 at the same sub-step: another).
        assert_eq!((c.events, c.pairs()), (3, 3), "{c:?}");
        assert!(c.min_distance < 1e-9, "vehicle 1 passes exactly through vehicle 2");
        // Staying apart adds nothing; staying inside adds nothing either.
        plant.advance(1.0);
        assert_eq!(plant.collisions().events, 3);
        // With one sub-step the crossing is missed: what the 10× check is for.
        let mut coarse = SwarmPlant::with_problem(
            SwarmParams { substeps: 1, ..params() },
            vec![[-1.0, 0.0, 1.0], [0.0, 0.0, 1.0]],
            vec![[0.0; 3]; 2],
            1,
        );
        coarse.v[0] = [2.0, 0.0, 0.0];
        coarse.advance(1.0);
        assert_eq!(coarse.collisions().events, 0);
    }

    #[test]
    fn double_integrator_is_exact_commands_are_clipped_and_effort_is_integrated() {
        let mut plant = SwarmPlant::with_problem(params(), vec![[0.0, 0.0, 1.0]], vec![[1.0, 0.0, 1.0]], 1);
        plant.apply_command(1, &[1.0, 5.0, f64::NAN]);
        assert_eq!(plant.u[0], [1.0, 2.0, 0.0]);
        assert_eq!(plant.clipped[0], 1);
        plant.advance(0.5);
        let p = plant.positions()[0];
        assert!((p[0] - 0.125).abs() < 1e-15 && (p[1] - 0.25).abs() < 1e-15 && p[2] == 1.0, "{p:?}");
        assert!((plant.velocities()[0][1] - 1.0).abs() < 1e-15);
        assert!((plant.effort_mps()[0] - 5f64.sqrt() * 0.5).abs() < 1e-15);
    }

    #[test]
    fn the_disturbance_has_norm_d_bar_and_repeats_with_the_seed() {
        let prm = SwarmParams { disturbance_mps2: 0.2, ..params() };
        let run = |seed| {
            let mut p = SwarmPlant::new(prm, 8, 3, seed).unwrap();
            p.advance(0.1);
            p.d.clone()
        };
        let d = run(5);
        for di in &d {
            assert!(((di[0] * di[0] + di[1] * di[1] + di[2] * di[2]).sqrt() - 0.2).abs() < 1e-12);
        }
        assert_eq!(d, run(5));
        assert_ne!(d, run(6));
    }

    #[test]
    fn readings_carry_noise_of_the_configured_size_and_the_goal() {
        let prm = SwarmParams { pos_noise_m: 1e-3, vel_noise_mps: 1e-2, ..params() };
        let mut plant = SwarmPlant::new(prm, 2, 1, 1).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (mut dp, mut dv) = (0.0, 0.0);
        let m = 2000;
        for _ in 0..m {
            let mut out = Vec::new();
            plant.readings(2, &mut rng, &mut out);
            let r = SwarmReading::parse(&out).unwrap();
            assert_eq!(r.goal_m, plant.goals()[1]);
            dp += (r.p_m[0] - plant.positions()[1][0]).powi(2);
            dv += r.v_mps[2].powi(2);
        }
        let (sp, sv) = ((dp / m as f64).sqrt(), (dv / m as f64).sqrt());
        assert!((sp - 1e-3).abs() < 1e-4 && (sv - 1e-2).abs() < 1e-3, "{sp} {sv}");
    }
}
