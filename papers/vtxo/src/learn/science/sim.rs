//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! One science-phase attitude flight for the Pareto data of Sec. 3.1/3.2.2: the rigid body
//! (13)–(14) with J = J̄ + δJ(t) (the plant's own integrator, [`crate::model::attitude`]) under the PD law
//! (54) as corrected, k̂ = [k_P, k_D], or the SMC (58)–(60), k̂ = [z, k_SMC, ε] (63) (the agents'
//! own [`crate::flight::attitude_control::torque`]), held over each 10 ms step as in flight, from the
//! science start (84) to the end of the phase, and the two objectives of the vector loss (72):
//!
//! - E = Σᵢ ∫ |τᵢ ωᵢ| dt of the applied wheel torque, J ((74) with the absolute value per axis, as
//!   the plant's `_energy_j`);
//! - e = the mean of the principal angle 2 acos|δq₄| over the whole phase, deg ((73) with D = T:
//!   "the scalar value of e is minimized for the whole duration of the science phase");
//! - and ω_f, the body rate at the end of the phase (the rate the next phase inherits).
//!
//! Start (84), as the plant's `draw = "science"`: θ₀ ~ N(0, 0.0289°) per axis, q₀ = δq(θ₀) ⊗ q_f,
//! ω₀ ~ N(0, [0.052, 0.048, 0.058] deg/s) (√ of Table 3's variances; reference choice 9).
//!
//! What acts on the body (one realisation per draw, [`Environment`], shared by every candidate gain
//! of that draw so that E and e are deterministic functions of the gains — common random numbers):
//! the wheels of Table E.10 ((28)–(30): scale factor, misalignment, white noise w_τ, bias b_τ as an
//! ECRV started at 0 as in the plant) and the white disturbance torque w_ω (E.11), both per 10 ms
//! step as the plant draws them. Without them the steady state would be exact and the Pareto
//! front would only be the initial transient's; with them, a stiffer law rejects the wheel bias
//! (smaller e) and, towards the stiff end, pays in work against the noise (larger E): the
//! trade-off of (72). (E is not monotone: a soft law lets the bias swing the body, which costs too.)
//!
//! Departures from the print, and why:
//! - the law acts on the truth, not on the MEKF's estimate (as the transient data do, and as the
//!   print's optimisation (76)–(77) states the dynamics): one flight is ≈ 72 000 steps and the search
//!   flies hundreds per draw; the follower's MEKF error (≈ 0.06 µrad) is far below the errors here;
//! - no gravity-gradient torque: near apogee (7.7e7 m) it is below 1e-9 N·m, a millionth of w_ω;
//! - q_f = identity: the DNN has no x_f input (as for the transient DNN), so q₀ is the attitude
//!   relative to the target;
//! - the phase is 0.2 h (720 s), the length the Table 5 analogue uses (the print gives none).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::flight::attitude_control::{self, AttitudeLaw};
use crate::learn::transient::sim::INERTIA;
use crate::model::actuators::{Actuator, ErrorModel};
use crate::model::attitude::{AttitudeState, TorqueInputs};
use crate::model::ecrv::white;
use crate::model::quaternion::{self, Quat, V3};

/// The flight step, s: the scenarios' 10 ms, over which the command is held.
pub const DT_S: f64 = 0.01;
/// Length of the science phase, s (0.2 h).
pub const PHASE_S: f64 = 720.0;
/// Bounds of every science gain, (79): 0.01 < k < 3.
pub const K_MIN: f64 = 0.01;
pub const K_MAX: f64 = 3.0;
/// σ of θ₀ per axis (Table 2's DNN P99(e) 0.0867° taken as 3σ), deg.
pub const THETA0_SIGMA_DEG: f64 = 0.0289;
/// σ of ω₀ per axis (√ of Table 3's variances), deg/s.
pub const OMEGA0_SIGMA_DEG_S: [f64; 3] = [0.052, 0.048, 0.058];
/// The white disturbance torque w_ω, 3σ per step, N·m (E.11).
pub const TORQUE_NOISE_3SIGMA_N_M: f64 = 1e-3;

/// The two science laws.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ScienceLaw {
    /// (54) as corrected, k̂ = [k_P (N·m), k_D (N·m·s)].
    Pd,
    /// (58)–(60), k̂ = [z (1/s²), k_SMC (1/s), ε (rad/s)].
    Smc,
}

impl ScienceLaw {
    pub const ALL: [ScienceLaw; 2] = [ScienceLaw::Pd, ScienceLaw::Smc];

    pub fn name(self) -> &'static str {
        match self {
            ScienceLaw::Pd => "pd",
            ScienceLaw::Smc => "smc",
        }
    }

    /// Gain column names with units, in k̂'s order.
    pub fn gain_columns(self) -> &'static [&'static str] {
        match self {
            ScienceLaw::Pd => &["k_p_N_m", "k_d_N_m_s"],
            ScienceLaw::Smc => &["z_1_s2", "k_smc_1_s", "eps_rad_s"],
        }
    }

    pub fn n_gains(self) -> usize {
        self.gain_columns().len()
    }

    /// The law with gains `k` (k̂'s order).
    pub fn law(self, k: &[f64]) -> AttitudeLaw {
        match self {
            ScienceLaw::Pd => AttitudeLaw::Pd { k_p: k[0], k_d: k[1] },
            ScienceLaw::Smc => AttitudeLaw::Smc { z: k[0], k: k[1], epsilon: k[2] },
        }
    }

    /// Table 4's gains (the paper's DNN output for w = 6.28 (PD) and 26.14 (SMC)).
    pub fn table4(self) -> &'static [f64] {
        match self {
            ScienceLaw::Pd => &[0.1208, 0.3786],
            ScienceLaw::Smc => &[2.9947, 0.0193, 0.2601],
        }
    }
}

/// A science start relative to the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    /// q₀ = δq(θ₀) (target identity), scalar last.
    pub q: Quat,
    pub omega_rad_s: V3,
}

/// One draw's disturbances, step by step (shared by every gain flown from that draw).
#[derive(Debug, Clone)]
pub struct Environment {
    /// The wheel triad's constant errors (scale factor, misalignment); its bias is in `wheel_error_n_m`.
    pub wheels: Actuator,
    /// Wheel bias + white noise over step k, N·m.
    pub wheel_error_n_m: Vec<V3>,
    /// The disturbance torque w_ω over step k, N·m.
    pub disturbance_n_m: Vec<V3>,
}

/// How Table E.10's wheel-bias entry (w_bτ = 1 mN·m 3σ, τ_τ = 1 h, no initial value) is read.
/// The plant and the Pareto data use [`WheelBias::EcrvFromZero`]; the others are the readings
/// the Table 5 study compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WheelBias {
    /// No bias.
    Off,
    /// w_bτ the stationary 3σ of the ECRV b_τ, started at 0 (ours).
    EcrvFromZero,
    /// The same ECRV started at a draw from its stationary spread.
    EcrvStationary,
    /// w_bτ the 3σ of the driving noise of each sample: b⁺ = e^{−Δt/τ} b + w n (depends on Δt).
    DrivenPerSample,
    /// w_bτ a driving density, N·m/√s: b⁺ = e^{−Δt/τ} b + w √Δt n.
    DrivenPerRootSecond,
}

impl WheelBias {
    pub const ALL: [WheelBias; 5] = [
        WheelBias::Off,
        WheelBias::EcrvFromZero,
        WheelBias::EcrvStationary,
        WheelBias::DrivenPerSample,
        WheelBias::DrivenPerRootSecond,
    ];

    pub fn name(self) -> &'static str {
        match self {
            WheelBias::Off => "off",
            WheelBias::EcrvFromZero => "ECRV from 0 (ours)",
            WheelBias::EcrvStationary => "ECRV drawn",
            WheelBias::DrivenPerSample => "driven per sample",
            WheelBias::DrivenPerRootSecond => "driven per √s",
        }
    }

    /// (initial 3σ, stationary 3σ) of the ECRV that realises this reading at step `dt_s` for the
    /// entry `w` (a driving noise q per step is an ECRV of stationary σ = q/√(1 − φ²)).
    fn ecrv_3sigma(self, w: f64, tau_s: f64, dt_s: f64) -> (f64, f64) {
        let per_step = (1.0 - (-2.0 * dt_s / tau_s).exp()).sqrt();
        match self {
            WheelBias::Off => (0.0, 0.0),
            WheelBias::EcrvFromZero => (0.0, w),
            WheelBias::EcrvStationary => (w, w),
            WheelBias::DrivenPerSample => (0.0, w / per_step),
            WheelBias::DrivenPerRootSecond => (0.0, w * dt_s.sqrt() / per_step),
        }
    }
}

/// The start of draw `index` of `seed` and its environment over `steps` steps of `dt_s`, from
/// the ChaCha8 stream (seed, index) (returned for whatever the caller draws next), with the
/// plant's reading of the wheel bias.
pub fn draw(seed: u64, index: u64, steps: usize, dt_s: f64) -> (Start, Environment, ChaCha8Rng) {
    draw_with(seed, index, steps, dt_s, WheelBias::EcrvFromZero)
}

/// [`draw`] with another reading of the wheel bias. Every reading consumes the stream alike, so
/// one (seed, index) gives the same start, noise and disturbance under each (common random
/// numbers: the readings differ by the bias alone).
pub fn draw_with(seed: u64, index: u64, steps: usize, dt_s: f64, bias: WheelBias) -> (Start, Environment, ChaCha8Rng) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    let theta = white::<3, _>(THETA0_SIGMA_DEG.to_radians(), &mut rng);
    let omega =
        V3::from_fn(|i, _| Normal::new(0.0, OMEGA0_SIGMA_DEG_S[i].to_radians()).expect("σ > 0").sample(&mut rng));
    let start = Start { q: quaternion::from_rotation_vector(&theta), omega_rad_s: omega };
    // Table E.10's wheels as the plant builds them (plant.rs `make_craft`, WheelConfig defaults).
    let (bias0_3sigma, bias_3sigma) = bias.ecrv_3sigma(1e-3, 3600.0, dt_s);
    let model = ErrorModel {
        scale_3sigma: 0.01,
        misalignment_3sigma_rad: 1e-3,
        noise_3sigma: 1e-3,
        bias_3sigma,
        bias0_3sigma,
        bias_tau_s: 3600.0,
    };
    let mut wheels = Actuator::new(&model, &mut rng);
    let mut wheel_error_n_m = Vec::with_capacity(steps);
    let mut disturbance_n_m = Vec::with_capacity(steps);
    for _ in 0..steps {
        wheel_error_n_m.push(wheels.bias.value + wheels.draw_noise(&mut rng));
        disturbance_n_m.push(white::<3, _>(TORQUE_NOISE_3SIGMA_N_M / 3.0, &mut rng));
        wheels.bias.advance(dt_s, &mut rng);
    }
    wheels.bias.value = V3::zeros();
    (start, Environment { wheels, wheel_error_n_m, disturbance_n_m }, rng)
}

/// What one flight gave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    pub energy_j: f64,
    pub error_deg: f64,
    /// ω at the end of the phase, body, rad/s.
    pub omega_end_rad_s: V3,
}

/// Fly `law` from `start` through `env` (its length sets the phase), step `dt_s`. (Table 4's
/// gains on a 720 s draw give e and E of the size the full plant gives them in the Table 5
/// analogue: PD 0.21°, 7.2e-5 J; SMC 0.63°, 4.2e-5 J.)
pub fn fly(start: &Start, env: &Environment, law: &AttitudeLaw, dt_s: f64) -> Outcome {
    let target = quaternion::identity();
    let j_nominal = INERTIA.nominal();
    let mut s = AttitudeState { q_body_eci: start.q, omega_body_rad_s: start.omega_rad_s };
    let n = env.wheel_error_n_m.len();
    let (mut energy_j, mut angle_sum) = (0.0, 0.5 * quaternion::principal_angle(&s.q_body_eci));
    for k in 0..n {
        let cmd = attitude_control::torque(law, &s.q_body_eci, &s.omega_body_rad_s, &target, &j_nominal);
        let applied = env.wheels.applied(&cmd, &env.wheel_error_n_m[k]);
        let inp = TorqueInputs {
            inertia: &INERTIA,
            held_torque_n_m: applied + env.disturbance_n_m[k],
            gravity_gradient_r_eci_m: None,
            mu_m3ps2: 0.0,
        };
        let w0 = s.omega_body_rad_s;
        s.rk4_step(k as f64 * dt_s, dt_s, &inp);
        // The work of the held wheel torque over the step (trapezoid in ω).
        let w_mid = 0.5 * (w0 + s.omega_body_rad_s);
        energy_j += applied.component_mul(&w_mid).abs().sum() * dt_s;
        let a = quaternion::principal_angle(&s.q_body_eci);
        angle_sum += if k + 1 == n { 0.5 * a } else { a };
    }
    let error_deg = if n == 0 { 0.0 } else { (angle_sum / n as f64).to_degrees() };
    Outcome { energy_j, error_deg, omega_end_rad_s: s.omega_body_rad_s }
}

/// Steps of a phase of `phase_s` at `dt_s`.
pub fn steps(phase_s: f64, dt_s: f64) -> usize {
    (phase_s / dt_s).round() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_follow_84_and_the_environment_is_the_plants() {
        let n = 4000;
        let (mut th2, mut om2) = (V3::zeros(), V3::zeros());
        for i in 0..n {
            let (s, _, _) = draw(7, i, 0, DT_S);
            let th = quaternion::rotation_vector(&s.q);
            th2 += th.component_mul(&th) / n as f64;
            om2 += s.omega_rad_s.component_mul(&s.omega_rad_s) / n as f64;
        }
        for i in 0..3 {
            let (a, b) = (th2[i].sqrt().to_degrees(), om2[i].sqrt().to_degrees());
            assert!((a / THETA0_SIGMA_DEG - 1.0).abs() < 0.05, "σθ axis {i}: {a}");
            assert!((b / OMEGA0_SIGMA_DEG_S[i] - 1.0).abs() < 0.05, "σω axis {i}: {b}");
        }
        // Same (seed, index): the same draw and environment; another index: another draw.
        let (a, ea, _) = draw(7, 3, 100, DT_S);
        let (b, eb, _) = draw(7, 3, 100, DT_S);
        assert_eq!((a, &ea.disturbance_n_m, &ea.wheel_error_n_m), (b, &eb.disturbance_n_m, &eb.wheel_error_n_m));
        assert_ne!(draw(7, 4, 0, DT_S).0, a);
        // w_ω per step at its σ (1 mN·m 3σ).
        let (_, e, _) = draw(7, 0, 20_000, DT_S);
        let sd = (e.disturbance_n_m.iter().map(|d| d.x * d.x).sum::<f64>() / 20_000.0).sqrt();
        assert!((sd / (TORQUE_NOISE_3SIGMA_N_M / 3.0) - 1.0).abs() < 0.05, "σ w_ω {sd}");
    }

    #[test]
    fn wheel_bias_readings_differ_by_the_bias_alone() {
        let (dt, n) = (0.1, 7200);
        let (s0, off, _) = draw_with(5, 2, n, dt, WheelBias::Off);
        let bias_at = |b: WheelBias| {
            let (s, e, _) = draw_with(5, 2, n, dt, b);
            assert_eq!((s, &e.disturbance_n_m), (s0, &off.disturbance_n_m), "{b:?}");
            // The wheel error less the (shared) white noise is the bias.
            (0..n).map(|k| e.wheel_error_n_m[k] - off.wheel_error_n_m[k]).collect::<Vec<V3>>()
        };
        assert_eq!(
            draw(5, 2, n, dt).1.wheel_error_n_m,
            draw_with(5, 2, n, dt, WheelBias::EcrvFromZero).1.wheel_error_n_m
        );
        let from_zero = bias_at(WheelBias::EcrvFromZero);
        let drawn = bias_at(WheelBias::EcrvStationary);
        let per_sample = bias_at(WheelBias::DrivenPerSample);
        let per_root_s = bias_at(WheelBias::DrivenPerRootSecond);
        assert_eq!((from_zero[0], per_sample[0], per_root_s[0]), (V3::zeros(), V3::zeros(), V3::zeros()));
        assert_ne!(drawn[0], V3::zeros());
        // After 720 s, over the three axes: a driven walk of q per step has σ ≈ q√n (n ≪ τ/Δt);
        // per √s, q√Δt per step; from 0 the ECRV has σ√(1 − e^{−2t/τ}) ≈ 0.57σ. Loose bounds (3 samples).
        let rms = |v: &[V3]| (v[n - 1].norm_squared() / 3.0).sqrt();
        let q = 1e-3 / 3.0;
        for (name, got, want) in [
            ("per sample", rms(&per_sample), q * (n as f64).sqrt()),
            ("per √s", rms(&per_root_s), q * (n as f64 * dt).sqrt()),
            ("from zero", rms(&from_zero), q * (1.0 - (-2.0 * 720.0 / 3600.0f64).exp()).sqrt()),
        ] {
            assert!(got > 0.2 * want && got < 3.0 * want, "{name}: {got:e} vs {want:e}");
        }
    }

    #[test]
    fn a_stiffer_law_holds_closer_and_the_chattering_corner_spends_most() {
        // The trade-off the Pareto search explores: on one draw (same disturbances), stiffer PD
        // gains give a smaller e and a larger E; both laws end near rest.
        let (s, env, _) = draw(1, 0, steps(120.0, DT_S), DT_S);
        let soft = fly(&s, &env, &ScienceLaw::Pd.law(&[0.05, 0.1]), DT_S);
        let stiff = fly(&s, &env, &ScienceLaw::Pd.law(&[2.0, 1.0]), DT_S);
        assert!(stiff.error_deg < 0.5 * soft.error_deg, "{soft:?} {stiff:?}");
        // The energy is not monotone in the gains (a soft law lets the bias swing the body, which
        // costs work too), but the stiffest corner, chattering at the step, spends far more.
        let smc = fly(&s, &env, &ScienceLaw::Smc.law(ScienceLaw::Smc.table4()), DT_S);
        let corner = fly(&s, &env, &ScienceLaw::Smc.law(&[K_MAX, K_MAX, K_MIN]), DT_S);
        assert!(corner.energy_j > 10.0 * smc.energy_j.max(stiff.energy_j), "{smc:?} {corner:?}");
        for o in [soft, stiff, smc] {
            assert!(o.error_deg.is_finite() && o.error_deg < 5.0 && o.energy_j > 0.0, "{o:?}");
            assert!(o.omega_end_rad_s.norm().to_degrees() < 0.5, "{o:?}");
        }
        // Undisturbed from rest on the target: nothing moves, E = e = 0.
        let rest = Start { q: quaternion::identity(), omega_rad_s: V3::zeros() };
        let quiet = Environment {
            wheels: env.wheels.clone(),
            wheel_error_n_m: vec![V3::zeros(); 100],
            disturbance_n_m: vec![V3::zeros(); 100],
        };
        let o = fly(&rest, &quiet, &ScienceLaw::Pd.law(&[1.0, 1.0]), DT_S);
        assert_eq!((o.energy_j, o.error_deg), (0.0, 0.0));
    }
}
