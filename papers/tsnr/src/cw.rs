//! Clohessy–Wiltshire (linearised Hill) relative motion about a circular orbit, in the target's
//! LVLH frame: x radial (outward), y along-track, z cross-track. Eq. (2) of the paper has a
//! sign/factor slip in its y-equation (papers/tsnr/README.md), so we use the standard form
//!
//! ```text
//! ẍ = 3n²x + 2nẏ + fₓ/m,   ÿ = −2nẋ + f_y/m,   z̈ = −n²z + f_z/m,   n = √(μ/r₀³),
//! ```
//!
//! as the state-space model ẋ = A x + B f with x = [r; v] (m, m/s) and **B mapping a force f in
//! newtons** (thrust plus net tension) to the state derivative, B = [0; I₃/m]. Everything the
//! controllers optimise is therefore a force, in the same unit as the 5 N thrust bound.
//!
//! The discrete model x_{k+1} = A_k x_k + B_k f_k is the exact zero-order-hold discretisation
//! (force held over the step): [A_k B_k; 0 I] = exp([A B; 0 0]·Δt), one 9×9 matrix exponential.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

/// Earth's gravitational parameter μ, m³/s² (EGM96 / WGS-84 value).
pub const MU_EARTH_M3_S2: f64 = 3.986004418e14;

pub type Mat6 = SMatrix<f64, 6, 6>;
pub type Mat63 = SMatrix<f64, 6, 3>;
pub type Vec6 = SVector<f64, 6>;

/// Mean motion n = √(μ/r₀³) of a circular orbit of radius `r0_m`, rad/s.
pub fn mean_motion_rad_s(r0_m: f64) -> f64 {
    (MU_EARTH_M3_S2 / (r0_m * r0_m * r0_m)).sqrt()
}

/// The acceleration of CW relative motion with no applied force, m/s²: the gravity-gradient and
/// Coriolis terms that a controller must cancel or use.
pub fn free_accel_mps2(n_rad_s: f64, r_m: &[f64; 3], v_mps: &[f64; 3]) -> [f64; 3] {
    let n2 = n_rad_s * n_rad_s;
    [3.0 * n2 * r_m[0] + 2.0 * n_rad_s * v_mps[1], -2.0 * n_rad_s * v_mps[0], -n2 * r_m[2]]
}

/// One body under CW relative motion: mean motion and the mass the force acts on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cw {
    pub n_rad_s: f64,
    pub mass_kg: f64,
}

impl Cw {
    /// A body of `mass_kg` relative to a target on a circular orbit of radius `r0_m`.
    pub fn new(r0_m: f64, mass_kg: f64) -> Self {
        Self { n_rad_s: mean_motion_rad_s(r0_m), mass_kg }
    }

    /// Continuous A (6×6).
    pub fn a(&self) -> Mat6 {
        let n = self.n_rad_s;
        let mut a = Mat6::zeros();
        for i in 0..3 {
            a[(i, 3 + i)] = 1.0;
        }
        a[(3, 0)] = 3.0 * n * n;
        a[(3, 4)] = 2.0 * n;
        a[(4, 3)] = -2.0 * n;
        a[(5, 2)] = -n * n;
        a
    }

    /// Continuous B (6×3) for a force in newtons: [0; I₃/m].
    pub fn b_force(&self) -> Mat63 {
        let mut b = Mat63::zeros();
        for i in 0..3 {
            b[(3 + i, i)] = 1.0 / self.mass_kg;
        }
        b
    }

    /// ẋ = A x + B f, written out (no matrices: this is what an integrator calls).
    pub fn deriv(&self, x: &[f64; 6], force_n: &[f64; 3]) -> [f64; 6] {
        let a = free_accel_mps2(self.n_rad_s, &[x[0], x[1], x[2]], &[x[3], x[4], x[5]]);
        let m = self.mass_kg;
        [x[3], x[4], x[5], a[0] + force_n[0] / m, a[1] + force_n[1] / m, a[2] + force_n[2] / m]
    }

    /// Exact zero-order-hold discretisation for the step `dt_s`.
    pub fn discretise(&self, dt_s: f64) -> Discrete {
        let mut m = SMatrix::<f64, 9, 9>::zeros();
        m.fixed_view_mut::<6, 6>(0, 0).copy_from(&(self.a() * dt_s));
        m.fixed_view_mut::<6, 3>(0, 6).copy_from(&(self.b_force() * dt_s));
        let e = m.exp();
        Discrete { a: e.fixed_view::<6, 6>(0, 0).into_owned(), b: e.fixed_view::<6, 3>(0, 6).into_owned(), dt_s }
    }
}

/// x_{k+1} = A_k x_k + B_k f_k with f held over the step.
#[derive(Debug, Clone, PartialEq)]
pub struct Discrete {
    pub a: Mat6,
    pub b: Mat63,
    pub dt_s: f64,
}

impl Discrete {
    pub fn step(&self, x: &[f64; 6], force_n: &[f64; 3]) -> [f64; 6] {
        let x1 = self.a * Vec6::from_column_slice(x) + self.b * SVector::<f64, 3>::from_column_slice(force_n);
        let mut out = [0.0; 6];
        out.copy_from_slice(x1.as_slice());
        out
    }

    /// The condensed predictions over `np` steps: stacking x_{k+1..k+np} gives
    /// X = Φ x_k + Γ F with Φ = [A; A²; …; A^np] (6np×6) and Γ the block lower-triangular
    /// Toeplitz matrix of blocks A^{p−q} B (6np×3np), F = [f_k; …; f_{k+np−1}].
    pub fn prediction(&self, np: usize) -> Prediction {
        let mut phi = DMatrix::zeros(6 * np, 6);
        let mut gamma = DMatrix::zeros(6 * np, 3 * np);
        // powers[p] = A^p B, p = 0..np−1
        let mut ap = Mat6::identity();
        let mut apb = Vec::with_capacity(np);
        for p in 0..np {
            apb.push(ap * self.b);
            ap = self.a * ap;
            phi.view_mut((6 * p, 0), (6, 6)).copy_from(&ap);
        }
        for row in 0..np {
            for col in 0..=row {
                gamma.view_mut((6 * row, 3 * col), (6, 3)).copy_from(&apb[row - col]);
            }
        }
        Prediction { np, phi, gamma }
    }
}

/// X = Φ x_k + Γ F over a horizon of `np` steps (see [`Discrete::prediction`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    pub np: usize,
    pub phi: DMatrix<f64>,
    pub gamma: DMatrix<f64>,
}

impl Prediction {
    /// The stacked states x_{k+1..k+np} from x_k and the forces F (3np).
    pub fn states(&self, x0: &[f64; 6], forces: &[f64]) -> DVector<f64> {
        &self.phi * DVector::from_column_slice(x0) + &self.gamma * DVector::from_column_slice(forces)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Classic fixed-step RK4 of the CW ODE with the force held, `steps` sub-steps over `dt_s`.
    fn rk4(cw: &Cw, x: [f64; 6], f: [f64; 3], dt_s: f64, steps: usize) -> [f64; 6] {
        let h = dt_s / steps as f64;
        let mut x = x;
        let add = |x: &[f64; 6], k: &[f64; 6], s: f64| std::array::from_fn::<f64, 6, _>(|i| x[i] + s * k[i]);
        for _ in 0..steps {
            let k1 = cw.deriv(&x, &f);
            let k2 = cw.deriv(&add(&x, &k1, h / 2.0), &f);
            let k3 = cw.deriv(&add(&x, &k2, h / 2.0), &f);
            let k4 = cw.deriv(&add(&x, &k3, h), &f);
            x = std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        }
        x
    }

    #[test]
    fn geo_mean_motion() {
        // r₀ = 42 164 km: one sidereal day, 86 164 s.
        let n = mean_motion_rad_s(42_164e3);
        assert!((std::f64::consts::TAU / n - 86_164.0).abs() < 5.0, "period {}", std::f64::consts::TAU / n);
    }

    #[test]
    fn zoh_discretisation_equals_fine_rk4() {
        let x0 = [-10.0, 0.75, -0.75, 0.3, -0.2, 0.1];
        let f = [5.0, -3.0, 1.5];
        // The control step at GEO, and a low orbit over a long step where the CW coupling is
        // large (nΔt ≈ 0.5 rad), so a wrong sign or factor in A or B could not hide.
        for (r0, m, dt, steps) in [(42_164e3, 10.0, 0.1, 1000), (7_000e3, 10.0, 500.0, 200_000)] {
            let cw = Cw::new(r0, m);
            let d = cw.discretise(dt);
            let exact = d.step(&x0, &f);
            let num = rk4(&cw, x0, f, dt, steps);
            for i in 0..6 {
                let scale = num[i].abs().max(1.0);
                assert!(
                    (exact[i] - num[i]).abs() <= 1e-9 * scale,
                    "r0 {r0} dt {dt}: x[{i}] {} vs {}",
                    exact[i],
                    num[i]
                );
            }
        }
    }

    #[test]
    fn free_motion_matches_the_closed_form_cw_solution() {
        // The textbook CW solution (no force), an independent check of A.
        let cw = Cw::new(7_000e3, 10.0);
        let n = cw.n_rad_s;
        let t = 900.0;
        let [x0, y0, z0, vx, vy, vz] = [1.0, -2.0, 3.0, 0.01, 0.02, -0.03];
        let (s, c) = ((n * t).sin(), (n * t).cos());
        let x = (4.0 - 3.0 * c) * x0 + s / n * vx + 2.0 / n * (1.0 - c) * vy;
        let y = 6.0 * (s - n * t) * x0 + y0 - 2.0 / n * (1.0 - c) * vx + (4.0 * s - 3.0 * n * t) / n * vy;
        let z = c * z0 + s / n * vz;
        let xd = 3.0 * n * s * x0 + c * vx + 2.0 * s * vy;
        let yd = -6.0 * n * (1.0 - c) * x0 - 2.0 * s * vx + (4.0 * c - 3.0) * vy;
        let zd = -n * s * z0 + c * vz;
        let got = cw.discretise(t).step(&[x0, y0, z0, vx, vy, vz], &[0.0; 3]);
        for (i, want) in [x, y, z, xd, yd, zd].iter().enumerate() {
            assert!((got[i] - want).abs() < 1e-9 * want.abs().max(1.0), "x[{i}] {} vs {want}", got[i]);
        }
    }

    #[test]
    fn condensed_prediction_equals_stepping() {
        let cw = Cw::new(42_164e3, 10.0);
        let d = cw.discretise(0.1);
        let np = 7;
        let pred = d.prediction(np);
        let forces: Vec<f64> = (0..3 * np).map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.7).collect();
        let mut x = [1.0, -2.0, 0.5, 0.1, 0.0, -0.2];
        let stacked = pred.states(&x, &forces);
        for p in 0..np {
            x = d.step(&x, &[forces[3 * p], forces[3 * p + 1], forces[3 * p + 2]]);
            for i in 0..6 {
                assert!((stacked[6 * p + i] - x[i]).abs() < 1e-12, "step {p} x[{i}]");
            }
        }
    }
}
