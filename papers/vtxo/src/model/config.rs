//! The plant section (`[plant]`, kind "vtxo") of a seed-002 scenario. Every key has a default:
//! the values of Tables D.9 and E.10–E.13 and the reference's choices where the paper is silent
//! (see the module docs of [`crate::model::orbit_setup`], [`crate::model::actuators`], [`crate::model::sensors`]).
//! All noise and bias values are 3σ (white: per sample; ECRV: stationary).

use cohort_scenario::Problem;
use serde::{Deserialize, Serialize};

use crate::config::Checker;
use crate::model::orbit::{Gravity, R_EARTH_M};
use crate::model::orbit_setup::{FollowerStart, kepler_period_s};

fn yes() -> bool {
    true
}
fn hour_s() -> f64 {
    3600.0
}
fn mas_rad(x: f64) -> f64 {
    (x * 1e-3 / 3600.0).to_radians()
}
fn arcmin_rad(x: f64) -> f64 {
    (x / 60.0).to_radians()
}
const G0_MPS2: f64 = 9.80665;

/// Why a vtxo scenario has exactly two agents.
pub const AGENTS_REASON: &str = "the vtxo plant flies exactly 2 agents: 1 = leader, 2 = follower";

/// `[plant]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VtxoPlantConfig {
    /// Earth's J2 in the orbit truth (drag is always off: perigee altitude ≈ 5 690 km).
    #[serde(default = "yes")]
    pub j2: bool,
    #[serde(default)]
    pub orbit: OrbitConfig,
    #[serde(default)]
    pub spacecraft: SpacecraftConfig,
    #[serde(default)]
    pub attitude: InitialAttitudeConfig,
    #[serde(default)]
    pub disturbances: DisturbanceConfig,
    #[serde(default)]
    pub wheels: WheelConfig,
    #[serde(default)]
    pub thrusters: ThrusterConfig,
    #[serde(default)]
    pub sensors: SensorsConfig,
    #[serde(default)]
    pub metrics: MetricsConfig,
}

impl Default for VtxoPlantConfig {
    fn default() -> Self {
        Self {
            j2: true,
            orbit: OrbitConfig::default(),
            spacecraft: SpacecraftConfig::default(),
            attitude: InitialAttitudeConfig::default(),
            disturbances: DisturbanceConfig::default(),
            wheels: WheelConfig::default(),
            thrusters: ThrusterConfig::default(),
            sensors: SensorsConfig::default(),
            metrics: MetricsConfig::default(),
        }
    }
}

/// `[plant.orbit]`: Table D.9 and the Sec. 7 initial relative state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrbitConfig {
    pub a_m: f64,
    pub e_leader: f64,
    /// Used when `follower_start = "elements"`.
    pub e_follower: f64,
    pub inclination_deg: f64,
    pub raan_deg: f64,
    pub arg_periapsis_deg: f64,
    /// The leader's true anomaly at t = 0 (Table D.9 has none; 180° = apogee).
    pub true_anomaly_deg: f64,
    /// "relative" (r_F = r_L + r_rel0, Sec. 7) or "elements" (the follower's own orbit).
    pub follower_start: FollowerStart,
    /// r_rel(0) = r_F − r_L, ECI, m (91).
    pub r_rel0_eci_m: [f64; 3],
    /// v_rel(0), ECI, m/s (90).
    pub v_rel0_eci_mps: [f64; 3],
}

impl Default for OrbitConfig {
    fn default() -> Self {
        Self {
            a_m: 45_300e3,
            e_leader: 0.7125,
            e_follower: 0.7336,
            inclination_deg: 0.34,
            raan_deg: 0.0,
            arg_periapsis_deg: 4.6743,
            true_anomaly_deg: 180.0,
            follower_start: FollowerStart::Relative,
            r_rel0_eci_m: [1e3, 2e3, 10e3],
            v_rel0_eci_mps: [1.0, 1.0, 1.0],
        }
    }
}

/// `[plant.spacecraft]`: App. E, both spacecraft alike.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SpacecraftConfig {
    pub mass_kg: f64,
    /// J̄ (E.1), principal moments, kg·m².
    pub inertia_kg_m2: [f64; 3],
    /// Amplitudes of δJ(t) = diag(a₁ sin t, a₂ cos t, a₃) (E.2), kg·m²; zeros switch it off.
    pub inertia_error_kg_m2: [f64; 3],
}

impl Default for SpacecraftConfig {
    fn default() -> Self {
        Self { mass_kg: 10.2, inertia_kg_m2: [0.1383, 0.1577, 0.1039], inertia_error_kg_m2: [0.0038, 0.005, 0.0011] }
    }
}

/// How the initial attitudes are set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AttitudeDraw {
    /// Both spacecraft at `q0_body_eci`, `omega0_body_rad_s`.
    Fixed,
    /// (84): q₀ = δq(θ₀) ⊗ q_f, θ₀ ~ N(0, σ_θ) and ω₀ ~ N(0, σ_ω) per axis, per spacecraft.
    Science,
    /// (85), (87): q₀ components U(−1, 1), q₄ ≥ 0, normalised; ω₀ ~ N(0, σ) per axis.
    Transient,
}

/// `[plant.attitude]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitialAttitudeConfig {
    pub draw: AttitudeDraw,
    /// Scalar last, ECI → body.
    pub q0_body_eci: [f64; 4],
    pub omega0_body_rad_s: [f64; 3],
    /// q_f: the attitude error e = 2 acos|δq₄| is measured from it (and `science` draws around it).
    pub q_target_body_eci: [f64; 4],
    /// σ of θ₀ per axis for `science` (Table 2's DNN P99(e) 0.0867° taken as 3σ), deg.
    pub science_theta_sigma_deg: f64,
    /// σ of ω₀ per axis for `science` (√ of Table 3's variances), deg/s.
    pub science_omega_sigma_deg_s: [f64; 3],
    /// σ of ω₀ per axis for `transient` (87), rad/s.
    pub transient_omega_sigma_rad_s: f64,
}

impl Default for InitialAttitudeConfig {
    fn default() -> Self {
        Self {
            draw: AttitudeDraw::Fixed,
            q0_body_eci: [0.0, 0.0, 0.0, 1.0],
            omega0_body_rad_s: [0.0; 3],
            q_target_body_eci: [0.0, 0.0, 0.0, 1.0],
            science_theta_sigma_deg: 0.0289,
            science_omega_sigma_deg_s: [0.052, 0.048, 0.058],
            transient_omega_sigma_rad_s: 0.6,
        }
    }
}

/// `[plant.disturbances]`: Table E.11.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DisturbanceConfig {
    /// w_ω, white disturbance torque per axis, N·m.
    pub torque_noise_3sigma_n_m: f64,
    /// u_g (25): ECRV perturbation force per axis, N (÷ mass), and its correlation time.
    pub force_3sigma_n: f64,
    pub force_tau_s: f64,
    /// τ_g (23).
    pub gravity_gradient: bool,
}

impl Default for DisturbanceConfig {
    fn default() -> Self {
        Self { torque_noise_3sigma_n_m: 1e-3, force_3sigma_n: 22.5e-6, force_tau_s: 3600.0, gravity_gradient: true }
    }
}

/// `[plant.wheels]`: Table E.10.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WheelConfig {
    pub scale_3sigma: f64,
    pub misalignment_3sigma_rad: f64,
    pub noise_3sigma_n_m: f64,
    pub bias_3sigma_n_m: f64,
    /// Spread of b_τ(0) (Table E.10 has no b_τ: 0).
    pub bias0_3sigma_n_m: f64,
    pub bias_tau_s: f64,
}

impl Default for WheelConfig {
    fn default() -> Self {
        Self {
            scale_3sigma: 0.01,
            misalignment_3sigma_rad: 1e-3,
            noise_3sigma_n_m: 1e-3,
            bias_3sigma_n_m: 1e-3,
            bias0_3sigma_n_m: 0.0,
            bias_tau_s: 3600.0,
        }
    }
}

/// `[plant.thrusters]`: Table E.10.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ThrusterConfig {
    pub scale_3sigma: f64,
    pub noise_3sigma_n: f64,
    pub bias_3sigma_n: f64,
    /// Spread of b_u(0): Table E.10's "b_u 0.1 mN".
    pub bias0_3sigma_n: f64,
    pub bias_tau_s: f64,
}

impl Default for ThrusterConfig {
    fn default() -> Self {
        Self { scale_3sigma: 0.01, noise_3sigma_n: 1e-3, bias_3sigma_n: 1e-3, bias0_3sigma_n: 1e-4, bias_tau_s: 3600.0 }
    }
}

/// `[plant.sensors]`: Tables E.12–E.13.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorsConfig {
    #[serde(default)]
    pub gyro: GyroConfig,
    #[serde(default = "star_tracker_leader")]
    pub star_tracker_leader: StarTrackerConfig,
    #[serde(default = "star_tracker_follower")]
    pub star_tracker_follower: StarTrackerConfig,
    #[serde(default)]
    pub accelerometer: AccelerometerConfig,
    #[serde(default = "ranging")]
    pub ranging: RelativeSensorConfig,
    #[serde(default = "interferometer")]
    pub interferometer: RelativeSensorConfig,
    #[serde(default)]
    pub handover: HandoverConfig,
}

impl Default for SensorsConfig {
    fn default() -> Self {
        Self {
            gyro: GyroConfig::default(),
            star_tracker_leader: star_tracker_leader(),
            star_tracker_follower: star_tracker_follower(),
            accelerometer: AccelerometerConfig::default(),
            ranging: ranging(),
            interferometer: interferometer(),
            handover: HandoverConfig::default(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GyroConfig {
    pub scale_3sigma: f64,
    pub misalignment_3sigma_rad: f64,
    pub noise_3sigma_rad_s: f64,
    pub bias_3sigma_rad_s: f64,
    /// Not in Table E.12: 1 h like every other bias.
    pub bias_tau_s: f64,
}

impl Default for GyroConfig {
    fn default() -> Self {
        Self {
            scale_3sigma: 3e-4,
            misalignment_3sigma_rad: 3e-3,
            noise_3sigma_rad_s: 22.5e-6,
            bias_3sigma_rad_s: 3f64.to_radians() / 3600.0,
            bias_tau_s: 3600.0,
        }
    }
}

/// A star tracker (every key required when the table is given: the two have different defaults).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StarTrackerConfig {
    pub noise_3sigma_rad: f64,
    pub bias_3sigma_rad: f64,
    #[serde(default = "hour_s")]
    pub bias_tau_s: f64,
}

fn star_tracker_leader() -> StarTrackerConfig {
    StarTrackerConfig { noise_3sigma_rad: arcmin_rad(3.0), bias_3sigma_rad: arcmin_rad(3.0), bias_tau_s: 3600.0 }
}
fn star_tracker_follower() -> StarTrackerConfig {
    StarTrackerConfig { noise_3sigma_rad: mas_rad(41.0), bias_3sigma_rad: mas_rad(0.1), bias_tau_s: 3600.0 }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccelerometerConfig {
    pub noise_3sigma_mps2: f64,
    pub bias_3sigma_mps2: f64,
    pub bias_tau_s: f64,
}

impl Default for AccelerometerConfig {
    fn default() -> Self {
        Self { noise_3sigma_mps2: 1e-9 * G0_MPS2, bias_3sigma_mps2: 1e-6 * G0_MPS2, bias_tau_s: 3600.0 }
    }
}

/// Ranging (z) or interferometer (x, y) on the follower (every key required when given).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelativeSensorConfig {
    pub noise_3sigma_m: f64,
    pub bias_3sigma_m: f64,
    #[serde(default = "hour_s")]
    pub bias_tau_s: f64,
}

fn ranging() -> RelativeSensorConfig {
    RelativeSensorConfig { noise_3sigma_m: 1.0, bias_3sigma_m: 1.0, bias_tau_s: 3600.0 }
}
fn interferometer() -> RelativeSensorConfig {
    RelativeSensorConfig { noise_3sigma_m: 2e-4, bias_3sigma_m: 1e-5, bias_tau_s: 3600.0 }
}

/// `[plant.sensors.handover]`: each agent's own ECI position and velocity at t = 0, handed over
/// by the tracking phase's orbit determination (GPS and ranging near perigee, Sec. 2.2). The
/// paper is silent; the default is an exact hand-over.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct HandoverConfig {
    pub position_3sigma_m: f64,
    pub velocity_3sigma_mps: f64,
}

/// `[plant.metrics]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MetricsConfig {
    /// r_rel^f (89), ECI, m: the formation error is r_rel − r_f.
    pub r_target_eci_m: [f64; 3],
    /// The window at the end of the run for the transverse statistics (Figs. 7–8: 15 s), s.
    pub transverse_window_s: f64,
    /// "Formation reached" when |r_rel − r_f| < this, m.
    pub formation_tolerance_m: f64,
}

impl Default for MetricsConfig {
    fn default() -> Self {
        Self { r_target_eci_m: [0.0, 0.0, 1e3], transverse_window_s: 15.0, formation_tolerance_m: 1.0 }
    }
}

impl VtxoPlantConfig {
    /// Every problem, with key paths under `prefix` (normally "plant"), and the agent count and
    /// step a standalone loop ([`crate::formation::sim`]) is given (a scenario's are checked by the runtime
    /// and [`crate::formation::kinds`]).
    pub fn validate(&self, prefix: &str, n_agents: u32, dt_s: f64) -> Vec<Problem> {
        let mut c = Checker::new();
        if n_agents != 2 {
            c.fail("agents", Some(n_agents.to_string()), AGENTS_REASON);
        }
        c.positive("scenario.dt_s", dt_s);
        c.problems.extend(self.validate_section(prefix));
        c.problems
    }

    /// The gravity field the plant integrates (μ of the Earth, J2 per `j2`).
    pub fn gravity(&self) -> Gravity {
        Gravity::earth(self.j2)
    }

    /// The Keplerian period 2π√(a³/μ) of the plant's orbit, s, from `plant.orbit.a_m` and the μ
    /// the plant integrates with ([`Self::gravity`]); None when `a_m` is no semi-major axis (not
    /// finite and positive: a problem at `plant.orbit.a_m`). Both spacecraft share a; J2 is left
    /// out (it shortens the perigee-to-perigee time by 131 s, 1.37e-3, see the README).
    pub fn orbit_period_s(&self) -> Option<f64> {
        let a_m = self.orbit.a_m;
        (a_m.is_finite() && a_m > 0.0).then(|| kepler_period_s(a_m, self.gravity().mu_m3ps2))
    }

    /// Every problem of the section itself, with key paths under `prefix`.
    pub fn validate_section(&self, prefix: &str) -> Vec<Problem> {
        let mut c = Checker::new();
        self.orbit.check(&mut c, &format!("{prefix}.orbit"));
        self.spacecraft.check(&mut c, &format!("{prefix}.spacecraft"));
        self.attitude.check(&mut c, &format!("{prefix}.attitude"));
        self.check_noise(&mut c, prefix);
        let m = &self.metrics;
        let p = format!("{prefix}.metrics");
        c.finite_all(&format!("{p}.r_target_eci_m"), &m.r_target_eci_m);
        c.positive(&format!("{p}.transverse_window_s"), m.transverse_window_s);
        c.positive(&format!("{p}.formation_tolerance_m"), m.formation_tolerance_m);
        c.problems
    }

    fn check_noise(&self, c: &mut Checker, prefix: &str) {
        let d = &self.disturbances;
        let p = format!("{prefix}.disturbances");
        c.non_negative(&format!("{p}.torque_noise_3sigma_n_m"), d.torque_noise_3sigma_n_m);
        c.non_negative(&format!("{p}.force_3sigma_n"), d.force_3sigma_n);
        c.positive(&format!("{p}.force_tau_s"), d.force_tau_s);
        let w = &self.wheels;
        let p = format!("{prefix}.wheels");
        for (k, v) in [
            ("scale_3sigma", w.scale_3sigma),
            ("misalignment_3sigma_rad", w.misalignment_3sigma_rad),
            ("noise_3sigma_n_m", w.noise_3sigma_n_m),
            ("bias_3sigma_n_m", w.bias_3sigma_n_m),
            ("bias0_3sigma_n_m", w.bias0_3sigma_n_m),
        ] {
            c.non_negative(&format!("{p}.{k}"), v);
        }
        c.positive(&format!("{p}.bias_tau_s"), w.bias_tau_s);
        let t = &self.thrusters;
        let p = format!("{prefix}.thrusters");
        for (k, v) in [
            ("scale_3sigma", t.scale_3sigma),
            ("noise_3sigma_n", t.noise_3sigma_n),
            ("bias_3sigma_n", t.bias_3sigma_n),
            ("bias0_3sigma_n", t.bias0_3sigma_n),
        ] {
            c.non_negative(&format!("{p}.{k}"), v);
        }
        c.positive(&format!("{p}.bias_tau_s"), t.bias_tau_s);
        self.sensors.check(c, &format!("{prefix}.sensors"));
    }
}

impl OrbitConfig {
    fn check(&self, c: &mut Checker, p: &str) {
        c.positive(&format!("{p}.a_m"), self.a_m);
        for (k, e) in [("e_leader", self.e_leader), ("e_follower", self.e_follower)] {
            c.range(&format!("{p}.{k}"), e, 0.0, 0.99, "an ellipse");
            let perigee = self.a_m * (1.0 - e);
            if self.a_m.is_finite() && e.is_finite() && perigee <= R_EARTH_M {
                c.fail(
                    &format!("{p}.{k}"),
                    Some(format!("{e:?}")),
                    &format!("perigee radius {perigee:.0} m is inside the Earth"),
                );
            }
        }
        for (k, v) in [
            ("inclination_deg", self.inclination_deg),
            ("raan_deg", self.raan_deg),
            ("arg_periapsis_deg", self.arg_periapsis_deg),
            ("true_anomaly_deg", self.true_anomaly_deg),
        ] {
            c.range(&format!("{p}.{k}"), v, -360.0, 360.0, "an angle in degrees");
        }
        c.finite_all(&format!("{p}.r_rel0_eci_m"), &self.r_rel0_eci_m);
        c.finite_all(&format!("{p}.v_rel0_eci_mps"), &self.v_rel0_eci_mps);
    }
}

impl SpacecraftConfig {
    fn check(&self, c: &mut Checker, p: &str) {
        c.positive(&format!("{p}.mass_kg"), self.mass_kg);
        c.positive_all(&format!("{p}.inertia_kg_m2"), &self.inertia_kg_m2);
        c.finite_all(&format!("{p}.inertia_error_kg_m2"), &self.inertia_error_kg_m2);
        for i in 0..3 {
            let (j, d) = (self.inertia_kg_m2[i], self.inertia_error_kg_m2[i]);
            if j.is_finite() && d.is_finite() && j > 0.0 && d.abs() >= j {
                c.fail(
                    &format!("{p}.inertia_error_kg_m2[{i}]"),
                    Some(format!("{d:?}")),
                    "|δJ| must stay below J̄ (J must stay positive)",
                );
            }
        }
    }
}

impl InitialAttitudeConfig {
    fn check(&self, c: &mut Checker, p: &str) {
        c.unit_quaternion(&format!("{p}.q0_body_eci"), &self.q0_body_eci);
        c.unit_quaternion(&format!("{p}.q_target_body_eci"), &self.q_target_body_eci);
        c.finite_all(&format!("{p}.omega0_body_rad_s"), &self.omega0_body_rad_s);
        c.non_negative(&format!("{p}.science_theta_sigma_deg"), self.science_theta_sigma_deg);
        c.non_negative_all(&format!("{p}.science_omega_sigma_deg_s"), &self.science_omega_sigma_deg_s);
        c.non_negative(&format!("{p}.transient_omega_sigma_rad_s"), self.transient_omega_sigma_rad_s);
    }
}

impl SensorsConfig {
    fn check(&self, c: &mut Checker, p: &str) {
        let g = &self.gyro;
        for (k, v) in [
            ("scale_3sigma", g.scale_3sigma),
            ("misalignment_3sigma_rad", g.misalignment_3sigma_rad),
            ("noise_3sigma_rad_s", g.noise_3sigma_rad_s),
            ("bias_3sigma_rad_s", g.bias_3sigma_rad_s),
        ] {
            c.non_negative(&format!("{p}.gyro.{k}"), v);
        }
        c.positive(&format!("{p}.gyro.bias_tau_s"), g.bias_tau_s);
        for (name, s) in
            [("star_tracker_leader", &self.star_tracker_leader), ("star_tracker_follower", &self.star_tracker_follower)]
        {
            c.non_negative(&format!("{p}.{name}.noise_3sigma_rad"), s.noise_3sigma_rad);
            c.non_negative(&format!("{p}.{name}.bias_3sigma_rad"), s.bias_3sigma_rad);
            c.positive(&format!("{p}.{name}.bias_tau_s"), s.bias_tau_s);
        }
        let a = &self.accelerometer;
        c.non_negative(&format!("{p}.accelerometer.noise_3sigma_mps2"), a.noise_3sigma_mps2);
        c.non_negative(&format!("{p}.accelerometer.bias_3sigma_mps2"), a.bias_3sigma_mps2);
        c.positive(&format!("{p}.accelerometer.bias_tau_s"), a.bias_tau_s);
        for (name, s) in [("ranging", &self.ranging), ("interferometer", &self.interferometer)] {
            c.non_negative(&format!("{p}.{name}.noise_3sigma_m"), s.noise_3sigma_m);
            c.non_negative(&format!("{p}.{name}.bias_3sigma_m"), s.bias_3sigma_m);
            c.positive(&format!("{p}.{name}.bias_tau_s"), s.bias_tau_s);
        }
        c.non_negative(&format!("{p}.handover.position_3sigma_m"), self.handover.position_3sigma_m);
        c.non_negative(&format!("{p}.handover.velocity_3sigma_mps"), self.handover.velocity_3sigma_mps);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_parse_from_an_empty_table() {
        let c: VtxoPlantConfig = toml::from_str("").unwrap();
        assert_eq!(c, VtxoPlantConfig::default());
        assert!(c.validate("plant", 2, 0.01).is_empty());
    }

    #[test]
    fn unknown_keys_are_refused() {
        assert!(toml::from_str::<VtxoPlantConfig>("[orbit]\na_km = 45300\n").is_err());
        assert!(toml::from_str::<VtxoPlantConfig>("[sensors.gyro]\nbias = 1.0\n").is_err());
    }

    #[test]
    fn every_bad_value_is_named_by_its_key_path() {
        let text = r#"
            [orbit]
            a_m = -1.0
            e_leader = 1.5
            [spacecraft]
            mass_kg = 0.0
            inertia_error_kg_m2 = [0.2, 0.0, 0.0]
            [attitude]
            q0_body_eci = [0.0, 0.0, 0.0, 2.0]
            [disturbances]
            force_tau_s = 0.0
            [wheels]
            noise_3sigma_n_m = -1.0
            [thrusters]
            bias_tau_s = -5.0
            [sensors.gyro]
            bias_3sigma_rad_s = -1.0
            [sensors.star_tracker_follower]
            noise_3sigma_rad = -1.0
            bias_3sigma_rad = 0.0
            [sensors.interferometer]
            noise_3sigma_m = 2e-4
            bias_3sigma_m = 1e-5
            bias_tau_s = 0.0
            [sensors.handover]
            velocity_3sigma_mps = -0.1
            [metrics]
            transverse_window_s = 0.0
        "#;
        let c: VtxoPlantConfig = toml::from_str(text).unwrap();
        let paths: Vec<String> = c.validate("plant", 3, 0.0).into_iter().map(|p| p.path).collect();
        for want in [
            "agents",
            "scenario.dt_s",
            "plant.orbit.a_m",
            "plant.orbit.e_leader",
            "plant.spacecraft.mass_kg",
            "plant.spacecraft.inertia_error_kg_m2[0]",
            "plant.attitude.q0_body_eci",
            "plant.disturbances.force_tau_s",
            "plant.wheels.noise_3sigma_n_m",
            "plant.thrusters.bias_tau_s",
            "plant.sensors.gyro.bias_3sigma_rad_s",
            "plant.sensors.star_tracker_follower.noise_3sigma_rad",
            "plant.sensors.interferometer.bias_tau_s",
            "plant.sensors.handover.velocity_3sigma_mps",
            "plant.metrics.transverse_window_s",
        ] {
            assert!(paths.iter().any(|p| p == want), "no problem at {want}: {paths:?}");
        }
    }
}
