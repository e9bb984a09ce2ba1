//! Rigid-body attitude truth (seed 004): Euler's equations J ω̇ = τ − ω × Jω with the true
//! inertia J, and the attitude quaternion q̇ = ½ q ⊗ (0, ω) (scalar first, rotating body-frame
//! vectors into the inertial frame). Each agent senses its body rates and commands a body torque,
//! held over the control period (zero-order hold) while the truth is integrated with fixed RK4
//! sub-steps, so the result depends only on the scenario (deterministic in every run mode).
//!
//! [`euler_rate`] and [`quaternion_rate`] are the dynamics; the coupled continuous integration
//! of the orchestrator (`coupling = "continuous"`) calls the same functions.

use cohort_runtime::model::PlantModel;
use nalgebra::{Matrix3, Vector3, Vector4};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// ω̇ = J⁻¹(τ − ω × Jω), rad/s².
pub fn euler_rate(j: &Matrix3<f64>, j_inv: &Matrix3<f64>, omega: &Vector3<f64>, torque: &Vector3<f64>) -> Vector3<f64> {
    j_inv * (torque - omega.cross(&(j * omega)))
}

/// q̇ = ½ q ⊗ (0, ω) for q = (w, x, y, z) rotating body vectors into the inertial frame.
pub fn quaternion_rate(q: &Vector4<f64>, w: &Vector3<f64>) -> Vector4<f64> {
    let (qw, qx, qy, qz) = (q[0], q[1], q[2], q[3]);
    0.5 * Vector4::new(
        -qx * w[0] - qy * w[1] - qz * w[2],
        qw * w[0] + qy * w[2] - qz * w[1],
        qw * w[1] + qz * w[0] - qx * w[2],
        qw * w[2] + qx * w[1] - qy * w[0],
    )
}

/// Rotation matrix of q (body → inertial).
pub fn rotation(q: &Vector4<f64>) -> Matrix3<f64> {
    let n2 = q.norm_squared();
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    let s = 2.0 / n2;
    Matrix3::new(
        1.0 - s * (y * y + z * z),
        s * (x * y - z * w),
        s * (x * z + y * w),
        s * (x * y + z * w),
        1.0 - s * (x * x + z * z),
        s * (y * z - x * w),
        s * (x * z - y * w),
        s * (y * z + x * w),
        1.0 - s * (x * x + y * y),
    )
}

/// One spacecraft's truth.
#[derive(Debug, Clone)]
pub struct Body {
    pub q: Vector4<f64>,
    pub omega_rad_s: Vector3<f64>,
    pub torque_n_m: Vector3<f64>,
}

impl Body {
    /// Angular momentum in the inertial frame, N·m·s.
    pub fn h_inertial(&self, j: &Matrix3<f64>) -> Vector3<f64> {
        rotation(&self.q) * (j * self.omega_rad_s)
    }

    /// One RK4 step of (q, ω) over `h` seconds with the torque held.
    pub fn rk4(&mut self, j: &Matrix3<f64>, j_inv: &Matrix3<f64>, h: f64) {
        let tau = self.torque_n_m;
        let f = |q: &Vector4<f64>, w: &Vector3<f64>| (quaternion_rate(q, w), euler_rate(j, j_inv, w, &tau));
        let (q0, w0) = (self.q, self.omega_rad_s);
        let (k1q, k1w) = f(&q0, &w0);
        let (k2q, k2w) = f(&(q0 + 0.5 * h * k1q), &(w0 + 0.5 * h * k1w));
        let (k3q, k3w) = f(&(q0 + 0.5 * h * k2q), &(w0 + 0.5 * h * k2w));
        let (k4q, k4w) = f(&(q0 + h * k3q), &(w0 + h * k3w));
        self.q = q0 + h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
        self.omega_rad_s = w0 + h / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w);
    }
}

pub struct RigidBodyPlant {
    j: Matrix3<f64>,
    j_inv: Matrix3<f64>,
    bodies: Vec<Body>,
    substeps: u32,
    gyro_noise_std_rad_s: f64,
    torque_peak_n_m: f64,
}

impl RigidBodyPlant {
    /// `n` identical spacecraft; `substeps` RK4 sub-steps per control period.
    pub fn new(
        inertia_kg_m2: &[[f64; 3]; 3],
        omega0_rad_s: [f64; 3],
        q0: [f64; 4],
        n: usize,
        substeps: u32,
        gyro_noise_std_rad_s: f64,
    ) -> Self {
        let j = Matrix3::from_fn(|r, c| inertia_kg_m2[r][c]);
        let j_inv = j.try_inverse().expect("validated: the inertia is positive definite");
        let body = Body {
            q: Vector4::from_row_slice(&q0),
            omega_rad_s: Vector3::from_row_slice(&omega0_rad_s),
            torque_n_m: Vector3::zeros(),
        };
        Self { j, j_inv, bodies: vec![body; n], substeps: substeps.max(1), gyro_noise_std_rad_s, torque_peak_n_m: 0.0 }
    }

    pub fn body(&self, agent: u32) -> &Body {
        &self.bodies[(agent - 1) as usize]
    }

    /// For the coupled continuous integration, which owns the truth and sets it here to write
    /// the same telemetry row.
    pub fn body_mut(&mut self, agent: u32) -> &mut Body {
        &mut self.bodies[(agent - 1) as usize]
    }

    pub fn inverse_inertia(&self) -> &Matrix3<f64> {
        &self.j_inv
    }

    pub fn inertia(&self) -> &Matrix3<f64> {
        &self.j
    }
}

impl PlantModel for RigidBodyPlant {
    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for i in 1..=self.bodies.len() {
            for ax in ["w", "x", "y", "z"] {
                c.push(format!("a{i}_q_{ax}"));
            }
            for ax in ["x", "y", "z"] {
                c.push(format!("a{i}_omega_{ax}_rad_s"));
            }
            for ax in ["x", "y", "z"] {
                c.push(format!("a{i}_torque_{ax}_n_m"));
            }
            for ax in ["x", "y", "z"] {
                c.push(format!("a{i}_h_inertial_{ax}_n_m_s"));
            }
        }
        c
    }

    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let w = self.bodies[(agent - 1) as usize].omega_rad_s;
        for x in w.iter() {
            if self.gyro_noise_std_rad_s > 0.0 {
                let n: f64 = rng.sample(StandardNormal);
                out.push(x + self.gyro_noise_std_rad_s * n);
            } else {
                out.push(*x);
            }
        }
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let b = &mut self.bodies[(agent - 1) as usize];
        for a in 0..3 {
            b.torque_n_m[a] = command.get(a).copied().unwrap_or(0.0);
        }
        self.torque_peak_n_m = self.torque_peak_n_m.max(b.torque_n_m.norm());
    }

    fn advance(&mut self, dt_s: f64) {
        let h = dt_s / f64::from(self.substeps);
        for b in &mut self.bodies {
            for _ in 0..self.substeps {
                b.rk4(&self.j, &self.j_inv, h);
            }
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        for b in &self.bodies {
            out.extend(b.q.iter());
            out.extend(b.omega_rad_s.iter());
            out.extend(b.torque_n_m.iter());
            out.extend(b.h_inertial(&self.j).iter());
        }
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        let mut m = vec![("torque_peak_n_m".to_string(), self.torque_peak_n_m)];
        for (i, b) in self.bodies.iter().enumerate() {
            m.push((format!("a{}_omega_final_norm_rad_s", i + 1), b.omega_rad_s.norm()));
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const J: [[f64; 3]; 3] = [[1.0, 0.2, 0.3], [0.2, 2.0, 0.4], [0.3, 0.4, 1.0]];

    #[test]
    fn torque_free_motion_conserves_inertial_angular_momentum_and_energy() {
        // 100 s of torque-free tumbling about no principal axis, RK4 at 1 ms.
        let mut p = RigidBodyPlant::new(&J, [0.3, -0.5, 0.8], [1.0, 0.0, 0.0, 0.0], 1, 10, 0.0);
        let j = *p.inertia();
        let h0 = p.body(1).h_inertial(&j);
        let energy = |b: &Body| 0.5 * b.omega_rad_s.dot(&(j * b.omega_rad_s));
        let e0 = energy(p.body(1));
        p.apply_command(1, &[0.0; 3]);
        for _ in 0..10_000 {
            p.advance(0.01);
        }
        let b = p.body(1);
        let dh = (b.h_inertial(&j) - h0).norm() / h0.norm();
        let de = (energy(b) - e0).abs() / e0;
        assert!(dh <= 1e-9, "relative change of the inertial angular momentum over 100 s: {dh:e}");
        assert!(de <= 1e-9, "relative change of the kinetic energy over 100 s: {de:e}");
        // The body-frame rates did change (the motion is not a trivial spin).
        assert!((b.omega_rad_s - Vector3::new(0.3, -0.5, 0.8)).norm() > 0.1);
        // And the quaternion stayed a unit quaternion without renormalisation.
        assert!((b.q.norm() - 1.0).abs() < 1e-9, "{}", b.q.norm());
    }

    #[test]
    fn constant_torque_about_a_principal_axis_spins_up_linearly() {
        // Diagonal inertia, torque and rate along z: ω × Jω = 0, so ω_z(t) = ω_z(0) + τ t / Izz.
        let jd = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]];
        let mut p = RigidBodyPlant::new(&jd, [0.0, 0.0, 0.1], [1.0, 0.0, 0.0, 0.0], 1, 4, 0.0);
        p.apply_command(1, &[0.0, 0.0, 1.5]);
        for _ in 0..100 {
            p.advance(0.01);
        }
        let w = p.body(1).omega_rad_s;
        assert!((w[2] - (0.1 + 1.5 / 3.0)).abs() < 1e-12, "{w}");
        assert!(w[0].abs() < 1e-15 && w[1].abs() < 1e-15);
        // The attitude is a rotation about z by ∫ω dt = 0.1 · 1 + ½ · 0.5 · 1² = 0.35 rad.
        let angle: f64 = 0.1 * 1.0 + 0.5 * 0.5 * 1.0;
        let q = p.body(1).q;
        assert!((q[0] - (angle / 2.0).cos()).abs() < 1e-10 && (q[3] - (angle / 2.0).sin()).abs() < 1e-10, "{q}");
    }

    #[test]
    fn readings_are_the_rates_and_commands_are_held() {
        let mut p = RigidBodyPlant::new(&J, [0.02, 0.03, 0.01], [1.0, 0.0, 0.0, 0.0], 2, 1, 0.0);
        let mut rng = cohort_runtime::rng::setup_rng(1, "test");
        let mut out = Vec::new();
        p.readings(2, &mut rng, &mut out);
        assert_eq!(out, vec![0.02, 0.03, 0.01]);
        p.apply_command(1, &[1.0, 2.0]);
        assert_eq!(p.body(1).torque_n_m, Vector3::new(1.0, 2.0, 0.0));
        assert_eq!(p.body(2).torque_n_m, Vector3::zeros());
    }
}
