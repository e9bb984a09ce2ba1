//! Seed 000's plant: N servicers and one defunct spacecraft in Earth orbit. Truth is integrated in
//! ECI (two-body + J2 + drag, RK4 with sub-steps, commands held). The agents' coordinates qᵢ are
//! Cartesian positions in the LVLH frame of a reference point on the defunct's initial
//! osculating Keplerian orbit (papers/fig1/README.md), so q₀ — the defunct's own drift under J2 and drag —
//! is the "unknown f₀" the servicers learn. Commands are thrust accelerations in that frame
//! (g = I₃), rotated to ECI at every RK4 stage.
//!
//! Sensors (noise seeded per process, drawn in agent order): yᵢ = Cᵢ(q₀ − qᵢ) (10) then
//! dᵢⱼ = qⱼ − qᵢ (9) for each neighbour in the scenario's order.

use cohort_runtime::model::PlantModel;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use cohort_astro::orbit::{BodyProps, DensityHold, EarthForces, KeplerOrbit, Lvlh, V3, rk4_step};

/// Start of the tracking-error window of the summary metrics (Fig. 4: "≈ 5 m after ≈ 200 s").
pub const E_WINDOW_START_S: f64 = 200.0;

#[derive(Debug, Clone)]
pub struct Body {
    pub props: BodyProps,
    pub r_eci_m: V3,
    pub v_eci_mps: V3,
}

/// One servicer's sensing set-up.
#[derive(Debug, Clone)]
pub struct Sensing {
    pub output_matrix: Vec<[f64; 3]>,
    pub b: bool,
    pub neighbours: Vec<u32>,
}

pub struct ServicingPlant {
    forces: EarthForces,
    hold: DensityHold,
    substeps: u32,
    reference: KeplerOrbit,
    /// Index 0 is the defunct, i the servicer of agent i.
    bodies: Vec<Body>,
    sensing: Vec<Sensing>,
    noise_std_m: f64,
    u_lvlh_mps2: Vec<V3>,
    t_s: f64,
    frame: Lvlh,
    /// Per servicer: Σ‖e‖², max ‖e‖, samples in the window; peak ‖u‖; ∫‖u‖dt.
    e_sq_sum: Vec<f64>,
    e_max: Vec<f64>,
    e_samples: u64,
    u_peak: Vec<f64>,
    dv: Vec<f64>,
    end_s: f64,
}

impl ServicingPlant {
    /// `bodies[0]` is the defunct; its initial state defines the reference orbit.
    pub fn new(
        forces: EarthForces,
        hold: DensityHold,
        substeps: u32,
        bodies: Vec<Body>,
        sensing: Vec<Sensing>,
        noise_std_m: f64,
        end_s: f64,
    ) -> Self {
        let d = &bodies[0];
        let reference =
            KeplerOrbit::new(d.r_eci_m, d.v_eci_mps, forces.mu_m3ps2).expect("validated: an elliptic orbit");
        let n = sensing.len();
        let frame = Lvlh::of(&d.r_eci_m, &d.v_eci_mps);
        Self {
            forces,
            hold,
            substeps,
            reference,
            bodies,
            sensing,
            noise_std_m,
            u_lvlh_mps2: vec![V3::zeros(); n],
            t_s: 0.0,
            frame,
            e_sq_sum: vec![0.0; n],
            e_max: vec![0.0; n],
            e_samples: 0,
            u_peak: vec![0.0; n],
            dv: vec![0.0; n],
            end_s,
        }
    }

    fn frame_at(&self, t_s: f64) -> Lvlh {
        let (r, v) = self.reference.state(t_s);
        Lvlh::of(&r, &v)
    }

    /// qᵢ of body `b` now.
    pub fn q(&self, b: usize) -> V3 {
        self.frame.position(&self.bodies[b].r_eci_m)
    }
    /// q̇ of body `b` now.
    pub fn q_dot(&self, b: usize) -> V3 {
        self.frame.velocity(&self.bodies[b].r_eci_m, &self.bodies[b].v_eci_mps)
    }
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Truth ζᵢ = η̇ᵢ = Σⱼ (q̇ⱼ − q̇ᵢ) + bᵢ CᵢᵀCᵢ (q̇₀ − q̇ᵢ) (from (12) with noise-free sensors).
    fn zeta(&self, i: usize, qd: &[V3]) -> V3 {
        let s = &self.sensing[i - 1];
        let mut z = V3::zeros();
        for &j in &s.neighbours {
            z += qd[j as usize] - qd[i];
        }
        if s.b {
            let e_dot = qd[0] - qd[i];
            for row in &s.output_matrix {
                let c = V3::from_row_slice(row);
                z += c * c.dot(&e_dot);
            }
        }
        z
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

impl PlantModel for ServicingPlant {
    /// The servicers' ECI positions: the Earth's centre is the origin, as `[links]` expects.
    fn positions_m(&self, out: &mut Vec<[f64; 3]>) -> bool {
        out.extend(self.bodies[1..].iter().map(|b| [b.r_eci_m[0], b.r_eci_m[1], b.r_eci_m[2]]));
        true
    }
    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for b in 0..self.bodies.len() {
            for (q, unit) in [("r_eci", "m"), ("v_eci", "mps"), ("q_lvlh", "m")] {
                for ax in AXES {
                    c.push(format!("b{b}_{q}_{ax}_{unit}"));
                }
            }
        }
        for i in 1..=self.sensing.len() {
            c.push(format!("a{i}_e_norm_m"));
            for ax in AXES {
                c.push(format!("a{i}_zeta_{ax}_mps"));
            }
            for ax in AXES {
                c.push(format!("a{i}_u_{ax}_mps2"));
            }
        }
        c
    }

    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let i = agent as usize;
        let qi = self.q(i);
        let e = self.q(0) - qi;
        let s = &self.sensing[i - 1];
        for row in &s.output_matrix {
            let n: f64 = rng.sample(StandardNormal);
            out.push(V3::from_row_slice(row).dot(&e) + self.noise_std_m * n);
        }
        for &j in &s.neighbours {
            let d = self.frame.position(&self.bodies[j as usize].r_eci_m) - qi;
            for a in 0..3 {
                let n: f64 = rng.sample(StandardNormal);
                out.push(d[a] + self.noise_std_m * n);
            }
        }
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let u = &mut self.u_lvlh_mps2[agent as usize - 1];
        for a in 0..3 {
            u[a] = command.get(a).copied().unwrap_or(0.0);
        }
    }

    fn advance(&mut self, dt_s: f64) {
        // The state is at tₖ here, once per step: accumulate the e-window metrics over the same
        // samples the telemetry holds.
        if self.t_s + 1e-9 >= E_WINDOW_START_S {
            self.e_samples += 1;
            for i in 1..self.bodies.len() {
                let e = (self.q(0) - self.q(i)).norm();
                self.e_sq_sum[i - 1] += e * e;
                self.e_max[i - 1] = self.e_max[i - 1].max(e);
            }
        }
        let h = dt_s / f64::from(self.substeps);
        for sub in 0..self.substeps {
            let t0 = self.t_s + f64::from(sub) * h;
            // The frame at the RK4 stage times: commands are held in LVLH, rotated at each stage.
            let rots = [self.frame_at(t0).rot, self.frame_at(t0 + 0.5 * h).rot, self.frame_at(t0 + h).rot];
            for (b, body) in self.bodies.iter_mut().enumerate() {
                let u = if b == 0 { V3::zeros() } else { self.u_lvlh_mps2[b - 1] };
                let thrust = |tau: f64| {
                    if b == 0 {
                        return V3::zeros();
                    }
                    let k = if tau == 0.0 {
                        0
                    } else if tau < h {
                        1
                    } else {
                        2
                    };
                    rots[k] * u
                };
                rk4_step(&self.forces, &body.props, self.hold, &mut body.r_eci_m, &mut body.v_eci_mps, h, &thrust);
            }
        }
        for (i, u) in self.u_lvlh_mps2.iter().enumerate() {
            let un = u.norm();
            self.u_peak[i] = self.u_peak[i].max(un);
            self.dv[i] += un * dt_s;
        }
        self.t_s += dt_s;
        self.frame = self.frame_at(self.t_s);
    }

    fn row(&self, out: &mut Vec<f64>) {
        let nb = self.bodies.len();
        let q: Vec<V3> = (0..nb).map(|b| self.q(b)).collect();
        let qd: Vec<V3> = (0..nb).map(|b| self.q_dot(b)).collect();
        for (b, body) in self.bodies.iter().enumerate() {
            out.extend(body.r_eci_m.iter());
            out.extend(body.v_eci_mps.iter());
            out.extend(q[b].iter());
        }
        for i in 1..nb {
            out.push((q[0] - q[i]).norm());
            out.extend(self.zeta(i, &qd).iter());
            out.extend(self.u_lvlh_mps2[i - 1].iter());
        }
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        let end = self.end_s.round();
        let mut m = Vec::new();
        for i in 0..self.sensing.len() {
            let id = i + 1;
            if self.e_samples > 0 {
                let rms = (self.e_sq_sum[i] / self.e_samples as f64).sqrt();
                m.push((format!("servicer_{id}.e_rms_{E_WINDOW_START_S:.0}_{end:.0}_m"), rms));
                m.push((format!("servicer_{id}.e_max_{E_WINDOW_START_S:.0}_{end:.0}_m"), self.e_max[i]));
            }
            m.push((format!("servicer_{id}.u_peak_mps2"), self.u_peak[i]));
            m.push((format!("servicer_{id}.dv_total_mps"), self.dv[i]));
        }
        m
    }
}
