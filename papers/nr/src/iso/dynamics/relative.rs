//! The spacecraft's motion relative to the ISO in the ISO's LVLH frame, eqs. (1)–(2) of
//! "Neural-Rendezvous" (arXiv:2208.04883): m p̈ + C(œ) ṗ + G(p, œ) = u with (reference [23])
//!
//! C = 2mḟ [[0, −1, 0], [1, 0, 0], [0, 0, 0]] (skew),
//! G = m [−ḟ²x − f̈y + μ(r+x)/r_d³ − μ/r²;  f̈x − ḟ²y + μy/r_d³;  μz/r_d³],  r_d = ‖(r+x, y, z)‖,
//!
//! integrated together with the ISO's own two-body flow (Definition 1) by RK4. Every controller
//! of the crate predicts with this model.
//!
//! The command: u is given in the LVLH axes of the step's start and held constant in inertial
//! axes over the step (the plant applies it in inertial axes, zero-order hold), so inside a step
//! the model sees u_lvlh(t) = R(t)ᵀ R(t_k) u; the mass falls at ṁ = −‖u‖/(I_sp g₀) through the
//! step, as in the plant. Departures: the exact Jacobian of the RK4 step ([`step_jac`]) leaves
//! out ∂m/∂u (the mass changes by < 0.1 % over a step, a second-order effect on the prediction).

use nalgebra::{Matrix3, Matrix3x6, Matrix6, Matrix6x3};

use crate::iso::dynamics::constants::{G0_MPS2, MU_SUN_M3PS2};
use crate::iso::dynamics::lvlh::{IsoFrame, OrbitRates, X6, join, pos, vel};
use crate::iso::dynamics::two_body::{Inertial, V3};

/// C(œ)/m: the Coriolis matrix of (2) per unit mass.
pub fn c_over_m(rates: &OrbitRates) -> Matrix3<f64> {
    let w = 2.0 * rates.fdot_radps;
    Matrix3::new(0.0, -w, 0.0, w, 0.0, 0.0, 0.0, 0.0, 0.0)
}

/// G(p, œ)/m of (2), m/s².
pub fn g_over_m(p: &V3, rates: &OrbitRates) -> V3 {
    let (r, fd, fdd) = (rates.r_m, rates.fdot_radps, rates.fddot_radps2);
    let rd = V3::new(r + p.x, p.y, p.z);
    let k = MU_SUN_M3PS2 / rd.norm().powi(3);
    V3::new(
        -fd * fd * p.x - fdd * p.y + k * (r + p.x) - MU_SUN_M3PS2 / (r * r),
        fdd * p.x - fd * fd * p.y + k * p.y,
        k * p.z,
    )
}

/// p̈ of (2) for the force per unit mass `u_over_m` (LVLH axes), m/s².
pub fn accel(x: &X6, rates: &OrbitRates, u_over_m: &V3) -> V3 {
    u_over_m - c_over_m(rates) * vel(x) - g_over_m(&pos(x), rates)
}

/// ∂p̈/∂p and ∂p̈/∂ṗ.
pub fn accel_jacobian(x: &X6, rates: &OrbitRates) -> (Matrix3<f64>, Matrix3<f64>) {
    let (r, fd, fdd) = (rates.r_m, rates.fdot_radps, rates.fddot_radps2);
    let d = V3::new(r + x[0], x[1], x[2]);
    let dn2 = d.norm_squared();
    let k = MU_SUN_M3PS2 / (dn2 * dn2.sqrt());
    // −∂(μ d/‖d‖³)/∂p = −k (I − 3 d dᵀ/‖d‖²).
    let gravity = -k * (Matrix3::identity() - 3.0 / dn2 * d * d.transpose());
    let frame = Matrix3::new(fd * fd, fdd, 0.0, -fdd, fd * fd, 0.0, 0.0, 0.0, 0.0);
    (gravity + frame, -c_over_m(rates))
}

/// State after one step: relative state, ISO, mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepped {
    pub x: X6,
    pub iso: Inertial,
    pub m_kg: f64,
}

/// ∂x_{k+1}/∂x_k and ∂x_{k+1}/∂u_k (u in the LVLH axes of the step's start, N).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepJac {
    pub a: Matrix6<f64>,
    pub b: Matrix6x3<f64>,
}

/// The command held over a step: inertial force and mass flow.
#[derive(Debug, Clone, Copy)]
struct Held {
    u_inertial_n: V3,
    m0_kg: f64,
    mdot_kgps: f64,
}

impl Held {
    fn new(iso: &Inertial, m_kg: f64, u_lvlh_n: &V3, isp_s: f64) -> Self {
        let u_inertial_n = IsoFrame::of(iso).to_inertial(u_lvlh_n);
        Self { u_inertial_n, m0_kg: m_kg, mdot_kgps: u_lvlh_n.norm() / (isp_s * G0_MPS2) }
    }
    fn mass(&self, tau_s: f64) -> f64 {
        self.m0_kg - self.mdot_kgps * tau_s
    }
}

/// One stage: ISO acceleration, ẋ, and (if wanted) ∂ẋ/∂x and ∂ẋ/∂u_k.
struct Stage {
    iso_acc: V3,
    xdot: X6,
    jac: Option<(Matrix6<f64>, Matrix6x3<f64>)>,
}

fn stage(iso: &Inertial, x: &X6, held: &Held, tau_s: f64, rot_k: &Matrix3<f64>, want_jac: bool) -> Stage {
    let r2 = iso.r_m.norm_squared();
    let iso_acc = -MU_SUN_M3PS2 / (r2 * r2.sqrt()) * iso.r_m;
    let frame = IsoFrame::of(iso);
    let m = held.mass(tau_s);
    let u_over_m = frame.to_lvlh(&held.u_inertial_n) / m;
    let rates = frame.rates;
    let xdot = join(&vel(x), &accel(x, &rates, &u_over_m));
    let jac = want_jac.then(|| {
        let (dp, dq) = accel_jacobian(x, &rates);
        let mut j = Matrix6::zeros();
        j.fixed_view_mut::<3, 3>(0, 3).copy_from(&Matrix3::identity());
        j.fixed_view_mut::<3, 3>(3, 0).copy_from(&dp);
        j.fixed_view_mut::<3, 3>(3, 3).copy_from(&dq);
        let mut jb = Matrix6x3::zeros();
        jb.fixed_view_mut::<3, 3>(3, 0).copy_from(&(frame.rot().transpose() * rot_k / m));
        (j, jb)
    });
    Stage { iso_acc, xdot, jac }
}

fn advance(iso: &Inertial, k: &Stage, c: f64) -> Inertial {
    Inertial::new(iso.r_m + c * iso.v_mps, iso.v_mps + c * k.iso_acc)
}

fn rk4(x: &X6, iso: &Inertial, m_kg: f64, u_lvlh_n: &V3, isp_s: f64, h: f64, jac: bool) -> (Stepped, Option<StepJac>) {
    let held = Held::new(iso, m_kg, u_lvlh_n, isp_s);
    let rot_k = *IsoFrame::of(iso).rot();
    let s1 = stage(iso, x, &held, 0.0, &rot_k, jac);
    let (i2, x2) = (advance(iso, &s1, 0.5 * h), x + 0.5 * h * s1.xdot);
    let s2 = stage(&i2, &x2, &held, 0.5 * h, &rot_k, jac);
    let (i3, x3) =
        (Inertial::new(iso.r_m + 0.5 * h * i2.v_mps, iso.v_mps + 0.5 * h * s2.iso_acc), x + 0.5 * h * s2.xdot);
    let s3 = stage(&i3, &x3, &held, 0.5 * h, &rot_k, jac);
    let (i4, x4) = (Inertial::new(iso.r_m + h * i3.v_mps, iso.v_mps + h * s3.iso_acc), x + h * s3.xdot);
    let s4 = stage(&i4, &x4, &held, h, &rot_k, jac);
    let iso1 = Inertial::new(
        iso.r_m + h / 6.0 * (iso.v_mps + 2.0 * i2.v_mps + 2.0 * i3.v_mps + i4.v_mps),
        iso.v_mps + h / 6.0 * (s1.iso_acc + 2.0 * s2.iso_acc + 2.0 * s3.iso_acc + s4.iso_acc),
    );
    let x1 = x + h / 6.0 * (s1.xdot + 2.0 * s2.xdot + 2.0 * s3.xdot + s4.xdot);
    let out = Stepped { x: x1, iso: iso1, m_kg: held.mass(h) };
    let sj = jac.then(|| {
        let j = |s: &Stage| s.jac.expect("asked for");
        let ((j1, b1), (j2, b2), (j3, b3), (j4, b4)) = (j(&s1), j(&s2), j(&s3), j(&s4));
        let i6 = Matrix6::<f64>::identity();
        // The chain rule through the four stages: k₂ = f(x + h/2 k₁) etc.
        let d1 = j1;
        let d2 = j2 * (i6 + 0.5 * h * d1);
        let d3 = j3 * (i6 + 0.5 * h * d2);
        let d4 = j4 * (i6 + h * d3);
        let e1 = b1;
        let e2 = j2 * (0.5 * h * e1) + b2;
        let e3 = j3 * (0.5 * h * e2) + b3;
        let e4 = j4 * (h * e3) + b4;
        StepJac { a: i6 + h / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4), b: h / 6.0 * (e1 + 2.0 * e2 + 2.0 * e3 + e4) }
    });
    (out, sj)
}

/// One RK4 step of `h` seconds (negative: backwards) with `u_lvlh_n` held as described above.
pub fn step(x: &X6, iso: &Inertial, m_kg: f64, u_lvlh_n: &V3, isp_s: f64, h: f64) -> Stepped {
    rk4(x, iso, m_kg, u_lvlh_n, isp_s, h, false).0
}

/// [`step`] and its exact Jacobian (up to ∂m/∂u, see the module notes).
pub fn step_jac(x: &X6, iso: &Inertial, m_kg: f64, u_lvlh_n: &V3, isp_s: f64, h: f64) -> (Stepped, StepJac) {
    let (s, j) = rk4(x, iso, m_kg, u_lvlh_n, isp_s, h, true);
    (s, j.expect("asked for"))
}

/// Where the spacecraft would be at t + τ without thrust, in the LVLH frame of the ISO then: in
/// ⌈τ / h_max⌉ equal RK4 steps (the relative motion changes on time scales of months, so a few
/// steps suffice: see the tests).
pub fn coast_position(x: &X6, iso: &Inertial, tau_s: f64, h_max_s: f64) -> V3 {
    let n = (tau_s.abs() / h_max_s).ceil().max(1.0) as usize;
    let h = tau_s / n as f64;
    let (mut x, mut iso) = (*x, *iso);
    for _ in 0..n {
        let s = step(&x, &iso, 1.0, &V3::zeros(), 1.0, h);
        (x, iso) = (s.x, s.iso);
    }
    pos(&x)
}

/// [`coast_position`] and its Jacobian ∂p(t+τ)/∂x(t).
pub fn coast_position_jac(x: &X6, iso: &Inertial, tau_s: f64, h_max_s: f64) -> (V3, Matrix3x6<f64>) {
    let n = (tau_s.abs() / h_max_s).ceil().max(1.0) as usize;
    let h = tau_s / n as f64;
    let (mut x, mut iso, mut phi) = (*x, *iso, Matrix6::<f64>::identity());
    for _ in 0..n {
        let (s, j) = step_jac(&x, &iso, 1.0, &V3::zeros(), 1.0, h);
        (x, iso, phi) = (s.x, s.iso, j.a * phi);
    }
    (pos(&x), phi.fixed_view::<3, 6>(0, 0).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::AU_M;

    fn iso() -> Inertial {
        Inertial::new(V3::new(1.1 * AU_M, -0.4 * AU_M, 0.2 * AU_M), V3::new(25e3, 30e3, -18e3))
    }
    fn sc() -> Inertial {
        // ≈ 4·10⁹ m away, ≈ 45 km/s relative: a typical start of the terminal phase.
        Inertial::new(iso().r_m + V3::new(-2e9, 3e9, 1.5e9), iso().v_mps + V3::new(20e3, -35e3, -17e3))
    }

    #[test]
    fn coasting_relative_model_matches_the_inertial_truth_over_a_day() {
        let (mut i, mut s) = (iso(), sc());
        let mut x = IsoFrame::of(&i).relative(&s);
        let mut im = i;
        let dt = 600.0;
        for _ in 0..144 {
            i.step(dt, &|_| V3::zeros());
            s.step(dt, &|_| V3::zeros());
            let st = step(&x, &im, 500.0, &V3::zeros(), 220.0, dt);
            (x, im) = (st.x, st.iso);
        }
        let truth = IsoFrame::of(&i).relative(&s);
        let dp = (pos(&x) - pos(&truth)).norm();
        let dv = (vel(&x) - vel(&truth)).norm();
        eprintln!("relative model vs inertial truth after one day: {dp:.3e} m, {dv:.3e} m/s");
        assert!(dp <= 10.0, "relative model vs inertial truth after one day: {dp} m");
        assert!(dv <= 1e-3, "{dv} m/s");
        // The ISO flow inside the model is the inertial one.
        assert!((im.r_m - i.r_m).norm() < 1e-3);
    }

    #[test]
    fn thrust_held_in_inertial_axes_matches_the_inertial_truth() {
        let (i0, s0) = (iso(), sc());
        let u_lvlh = V3::new(0.7, -1.0, 0.4);
        let frame = IsoFrame::of(&i0);
        let u_in = frame.to_inertial(&u_lvlh);
        let (m0, isp, dt) = (500.0, 220.0, 600.0);
        let mdot = u_lvlh.norm() / (isp * G0_MPS2);
        let (mut i, mut s) = (i0, s0);
        i.step(dt, &|_| V3::zeros());
        s.step(dt, &|tau| u_in / (m0 - mdot * tau));
        let st = step(&frame.relative(&s0), &i0, m0, &u_lvlh, isp, dt);
        let truth = IsoFrame::of(&i).relative(&s);
        assert!((pos(&st.x) - pos(&truth)).norm() < 1e-3, "{}", (pos(&st.x) - pos(&truth)).norm());
        assert!((st.m_kg - (m0 - mdot * dt)).abs() < 1e-12);
    }

    #[test]
    fn model_is_m_pddot_plus_c_pdot_plus_g_equals_u_with_skew_c() {
        let frame = IsoFrame::of(&iso());
        let x = frame.relative(&sc());
        let (m, u) = (480.0, V3::new(0.3, -0.2, 0.9));
        let a = accel(&x, &frame.rates, &(u / m));
        let c = m * c_over_m(&frame.rates);
        let g = m * g_over_m(&pos(&x), &frame.rates);
        assert!((m * a + c * vel(&x) + g - u).norm() < 1e-12);
        assert!((c + c.transpose()).norm() == 0.0);
        // G vanishes at the ISO.
        assert!(g_over_m(&V3::zeros(), &frame.rates).norm() < 1e-18);
    }

    #[test]
    fn step_jacobian_matches_central_differences() {
        let (i0, frame) = (iso(), IsoFrame::of(&iso()));
        let x0 = frame.relative(&sc());
        let u0 = V3::new(0.2, -0.5, 0.1);
        let (m, isp, h) = (500.0, 220.0, 600.0);
        let (_, j) = step_jac(&x0, &i0, m, &u0, isp, h);
        for c in 0..6 {
            let d = if c < 3 { 1e3 } else { 1.0 };
            let (mut xp, mut xm) = (x0, x0);
            xp[c] += d;
            xm[c] -= d;
            let fd = (step(&xp, &i0, m, &u0, isp, h).x - step(&xm, &i0, m, &u0, isp, h).x) / (2.0 * d);
            let err = (fd - j.a.column(c)).norm() / j.a.column(c).norm();
            assert!(err < 1e-6, "column {c} of A: relative error {err:e}");
        }
        for c in 0..3 {
            let d = 1e-2;
            let (mut up, mut um) = (u0, u0);
            up[c] += d;
            um[c] -= d;
            let fd = (step(&x0, &i0, m, &up, isp, h).x - step(&x0, &i0, m, &um, isp, h).x) / (2.0 * d);
            // ∂m/∂u is left out of B: a relative error of the order of the mass change per step.
            let err = (fd - j.b.column(c)).norm() / j.b.column(c).norm();
            assert!(err < 2e-3, "column {c} of B: relative error {err:e}");
        }
    }

    #[test]
    fn four_coarse_steps_predict_the_terminal_position_to_a_metre() {
        let frame = IsoFrame::of(&iso());
        let x = frame.relative(&sc());
        let fine = coast_position(&x, &iso(), 86_400.0, 60.0);
        let coarse = coast_position(&x, &iso(), 86_400.0, 21_600.0);
        // ≈ 0.16 m for this geometry: far below the navigation noise at the end (≥ 10 m).
        assert!((fine - coarse).norm() < 1.0, "{} m", (fine - coarse).norm());
        let (p, j) = coast_position_jac(&x, &iso(), 86_400.0, 21_600.0);
        assert_eq!(p, coarse);
        // Straight-line flight dominates: ∂p(t_f)/∂ṗ ≈ τ I.
        assert!((j[(1, 4)] / 86_400.0 - 1.0).abs() < 0.1, "{}", j[(1, 4)]);
    }
}
