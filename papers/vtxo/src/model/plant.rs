//! The seed-002 truth (`PlantModel`): leader (agent 1) and follower (agent 2) orbits
//! ([`crate::model::orbit`]), each spacecraft's attitude ([`crate::model::attitude`]), its reaction wheels and
//! thrusters ([`crate::model::actuators`]), the perturbation force u_g (25) and torque w_ω (15), and the
//! sensors ([`crate::model::sensors`]); RK4 at the scenario's step with the commands held.
//!
//! Random numbers: constant errors, initial biases and initial attitude draws come from the
//! set-up stream of the seed; the process noise (w_ω, w_τ, w_u, and every ECRV: u_g, b_τ, b_u
//! and the sensor biases) from the plant's own process stream, drawn in `advance` for the next
//! step (and at construction for step 0), so the applied torque and thrust of step k are known
//! when its telemetry row is written; the sensors' white noise only from the rng `readings` is
//! given, in agent order. Readings and command layouts: [`crate::flight::layout`].

use cohort_runtime::model::PlantModel;
use cohort_runtime::rng::setup_rng;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::flight::layout::{Readings, parse_command};
use crate::model::actuators::{Actuator, ErrorModel};
use crate::model::attitude::{AttitudeState, Inertia, TorqueInputs};
use crate::model::config::{AttitudeDraw, VtxoPlantConfig};
use crate::model::ecrv::{Ecrv, white};
use crate::model::metrics::{CraftMetrics, FormationMetrics, RunMetrics, attitude_error_deg};
use crate::model::orbit::{Gravity, OrbitPair};
use crate::model::orbit_setup::{Elements, initial_pair};
use crate::model::quaternion::{self, Quat, V3};
use crate::model::sensors::{self, Axes, SensorModel, SensorSuite};

/// One spacecraft's hardware and held inputs.
#[derive(Debug, Clone)]
pub struct Craft {
    pub attitude: AttitudeState,
    pub wheels: Actuator,
    pub thrusters: Actuator,
    /// u_g as a force, N, ECI.
    pub force_disturbance: Ecrv<3>,
    pub sensors: SensorSuite,
    pub torque_cmd_n_m: V3,
    pub force_cmd_n: V3,
    /// This step's white samples: wheel noise, thruster noise, disturbance torque.
    pub wheel_noise_n_m: V3,
    pub thrust_noise_n: V3,
    pub torque_disturbance_n_m: V3,
    /// Non-gravitational acceleration over the last step (what the accelerometer senses).
    pub last_nongrav_mps2: V3,
}

impl Craft {
    pub fn applied_torque_n_m(&self) -> V3 {
        self.wheels.applied(&self.torque_cmd_n_m, &self.wheel_noise_n_m)
    }
    pub fn applied_force_n(&self) -> V3 {
        self.thrusters.applied(&self.force_cmd_n, &self.thrust_noise_n)
    }
}

#[derive(Clone)]
pub struct VtxoPlant {
    pub cfg: VtxoPlantConfig,
    pub gravity: Gravity,
    pub inertia: Inertia,
    pub q_target: Quat,
    pub r_target_eci_m: V3,
    pub dt_s: f64,
    pub t_s: f64,
    pub k: u64,
    pub orbit: OrbitPair,
    pub craft: [Craft; 2],
    process: ChaCha8Rng,
    pub metrics: RunMetrics,
}

fn initial_attitude(cfg: &VtxoPlantConfig, rng: &mut ChaCha8Rng) -> AttitudeState {
    let a = &cfg.attitude;
    let q_f = Quat::from(a.q_target_body_eci);
    match a.draw {
        AttitudeDraw::Fixed => {
            AttitudeState { q_body_eci: Quat::from(a.q0_body_eci), omega_body_rad_s: V3::from(a.omega0_body_rad_s) }
        }
        AttitudeDraw::Science => {
            let theta = white::<3, _>(a.science_theta_sigma_deg.to_radians(), rng);
            let s = V3::from(a.science_omega_sigma_deg_s).map(f64::to_radians);
            let w = white::<3, _>(1.0, rng).component_mul(&s);
            AttitudeState {
                q_body_eci: quaternion::compose(&quaternion::from_rotation_vector(&theta), &q_f),
                omega_body_rad_s: w,
            }
        }
        AttitudeDraw::Transient => {
            let mut q = Quat::from_fn(|_, _| rng.random_range(-1.0..1.0));
            q[3] = q[3].abs();
            let w = white::<3, _>(a.transient_omega_sigma_rad_s, rng);
            AttitudeState { q_body_eci: q.normalize(), omega_body_rad_s: w }
        }
    }
}

fn make_sensors(cfg: &VtxoPlantConfig, follower: bool, rng: &mut ChaCha8Rng) -> SensorSuite {
    let s = &cfg.sensors;
    let g = &s.gyro;
    let gyro = SensorModel {
        scale_3sigma: g.scale_3sigma,
        misalignment_3sigma_rad: g.misalignment_3sigma_rad,
        noise_3sigma: g.noise_3sigma_rad_s,
        bias_3sigma: g.bias_3sigma_rad_s,
        bias_tau_s: g.bias_tau_s,
    };
    let st = if follower { &s.star_tracker_follower } else { &s.star_tracker_leader };
    let plain = |noise: f64, bias: f64, tau: f64| SensorModel {
        scale_3sigma: 0.0,
        misalignment_3sigma_rad: 0.0,
        noise_3sigma: noise,
        bias_3sigma: bias,
        bias_tau_s: tau,
    };
    let a = &s.accelerometer;
    let gyro = Axes::new(&gyro, rng);
    let star_tracker = Axes::new(&plain(st.noise_3sigma_rad, st.bias_3sigma_rad, st.bias_tau_s), rng);
    let accelerometer = Axes::new(&plain(a.noise_3sigma_mps2, a.bias_3sigma_mps2, a.bias_tau_s), rng);
    let (ranging, interferometer) = if follower {
        let (r, i) = (&s.ranging, &s.interferometer);
        (
            Some(Axes::new(&plain(r.noise_3sigma_m, r.bias_3sigma_m, r.bias_tau_s), rng)),
            Some(Axes::new(&plain(i.noise_3sigma_m, i.bias_3sigma_m, i.bias_tau_s), rng)),
        )
    } else {
        (None, None)
    };
    SensorSuite { gyro, star_tracker, accelerometer, ranging, interferometer }
}

fn make_craft(cfg: &VtxoPlantConfig, follower: bool, rng: &mut ChaCha8Rng) -> Craft {
    let w = &cfg.wheels;
    let wheels = Actuator::new(
        &ErrorModel {
            scale_3sigma: w.scale_3sigma,
            misalignment_3sigma_rad: w.misalignment_3sigma_rad,
            noise_3sigma: w.noise_3sigma_n_m,
            bias_3sigma: w.bias_3sigma_n_m,
            bias0_3sigma: w.bias0_3sigma_n_m,
            bias_tau_s: w.bias_tau_s,
        },
        rng,
    );
    let t = &cfg.thrusters;
    let thrusters = Actuator::new(
        &ErrorModel {
            scale_3sigma: t.scale_3sigma,
            misalignment_3sigma_rad: 0.0,
            noise_3sigma: t.noise_3sigma_n,
            bias_3sigma: t.bias_3sigma_n,
            bias0_3sigma: t.bias0_3sigma_n,
            bias_tau_s: t.bias_tau_s,
        },
        rng,
    );
    let d = &cfg.disturbances;
    let force_disturbance = Ecrv::drawn(d.force_3sigma_n / 3.0, d.force_3sigma_n / 3.0, d.force_tau_s, rng);
    let sensors = make_sensors(cfg, follower, rng);
    let attitude = initial_attitude(cfg, rng);
    let last_nongrav_mps2 = force_disturbance.value / cfg.spacecraft.mass_kg;
    Craft {
        attitude,
        wheels,
        thrusters,
        force_disturbance,
        sensors,
        torque_cmd_n_m: V3::zeros(),
        force_cmd_n: V3::zeros(),
        wheel_noise_n_m: V3::zeros(),
        thrust_noise_n: V3::zeros(),
        torque_disturbance_n_m: V3::zeros(),
        last_nongrav_mps2,
    }
}

impl VtxoPlant {
    /// The plant of a validated configuration.
    pub fn new(cfg: &VtxoPlantConfig, dt_s: f64, seed: u64) -> Self {
        let mut setup = setup_rng(seed, "vtxo.plant.setup");
        let o = &cfg.orbit;
        let leader = Elements {
            a_m: o.a_m,
            e: o.e_leader,
            inc_rad: o.inclination_deg.to_radians(),
            raan_rad: o.raan_deg.to_radians(),
            argp_rad: o.arg_periapsis_deg.to_radians(),
            true_anomaly_rad: o.true_anomaly_deg.to_radians(),
        };
        let gravity = cfg.gravity();
        let orbit = initial_pair(
            &leader,
            o.e_follower,
            o.follower_start,
            &V3::from(o.r_rel0_eci_m),
            &V3::from(o.v_rel0_eci_mps),
            gravity.mu_m3ps2,
        );
        let craft = [make_craft(cfg, false, &mut setup), make_craft(cfg, true, &mut setup)];
        let m = &cfg.metrics;
        let metrics = RunMetrics {
            leader: CraftMetrics::default(),
            follower: CraftMetrics::default(),
            formation: FormationMetrics::new(m.formation_tolerance_m, m.transverse_window_s, dt_s),
        };
        let mut plant = Self {
            cfg: cfg.clone(),
            gravity,
            inertia: Inertia {
                nominal_kg_m2: cfg.spacecraft.inertia_kg_m2,
                error_amplitude_kg_m2: cfg.spacecraft.inertia_error_kg_m2,
            },
            q_target: Quat::from(cfg.attitude.q_target_body_eci),
            r_target_eci_m: V3::from(m.r_target_eci_m),
            dt_s,
            t_s: 0.0,
            k: 0,
            orbit,
            craft,
            process: setup_rng(seed, "vtxo.plant.process"),
            metrics,
        };
        plant.draw_step_noise();
        plant
    }

    /// Each spacecraft's ECI position and velocity (0 leader, 1 follower).
    pub fn rv_eci(&self, i: usize) -> (V3, V3) {
        if i == 0 {
            (self.orbit.r_leader_eci_m, self.orbit.v_leader_eci_mps)
        } else {
            (self.orbit.r_follower_eci_m(), self.orbit.v_follower_eci_mps())
        }
    }

    fn draw_step_noise(&mut self) {
        let sigma = self.cfg.disturbances.torque_noise_3sigma_n_m / 3.0;
        for c in &mut self.craft {
            c.wheel_noise_n_m = c.wheels.draw_noise(&mut self.process);
            c.thrust_noise_n = c.thrusters.draw_noise(&mut self.process);
            c.torque_disturbance_n_m = white::<3, _>(sigma, &mut self.process);
        }
    }

    fn advance_processes(&mut self, dt_s: f64) {
        for c in &mut self.craft {
            c.wheels.bias.advance(dt_s, &mut self.process);
            c.thrusters.bias.advance(dt_s, &mut self.process);
            c.force_disturbance.advance(dt_s, &mut self.process);
            c.sensors.advance(dt_s, &mut self.process);
        }
        self.draw_step_noise();
    }

    fn record_metrics(&mut self, dt_s: f64) {
        let mass = self.cfg.spacecraft.mass_kg;
        for (i, c) in self.craft.iter().enumerate() {
            let e = attitude_error_deg(&c.attitude.q_body_eci, &self.q_target);
            let m = if i == 0 { &mut self.metrics.leader } else { &mut self.metrics.follower };
            m.record(dt_s, mass, &c.applied_force_n(), &c.applied_torque_n_m(), &c.attitude.omega_body_rad_s, e);
        }
        self.metrics.formation.record(self.t_s, dt_s, &self.orbit.r_rel_eci_m, &self.r_target_eci_m);
    }
}

impl PlantModel for VtxoPlant {
    fn columns(&self) -> Vec<String> {
        crate::model::plant_row::columns()
    }

    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let i = match agent {
            1 => 0,
            2 => 1,
            _ => return,
        };
        let c = &self.craft[i];
        let s = &c.sensors;
        let gyro_rad_s = sensors::read_gyro(&s.gyro, &c.attitude.omega_body_rad_s, rng);
        let star_q_body_eci = sensors::read_star_tracker(&s.star_tracker, &c.attitude.q_body_eci, rng);
        let accel_mps2 = s.accelerometer.read(&c.last_nongrav_mps2, rng);
        let r_rel = self.orbit.r_rel_eci_m;
        let ranging_z_m = s.ranging.as_ref().map_or(0.0, |r| r.read(&nalgebra::Vector1::new(r_rel.z), rng)[0]);
        let interferometer_xy_m = s.interferometer.as_ref().map_or([0.0; 2], |f| {
            let m = f.read(&nalgebra::Vector2::new(r_rel.x, r_rel.y), rng);
            [m[0], m[1]]
        });
        let handover = (self.k == 0).then(|| {
            let h = &self.cfg.sensors.handover;
            let (r, v) = self.rv_eci(i);
            (r + white::<3, _>(h.position_3sigma_m / 3.0, rng), v + white::<3, _>(h.velocity_3sigma_mps / 3.0, rng))
        });
        Readings { gyro_rad_s, star_q_body_eci, accel_mps2, ranging_z_m, interferometer_xy_m, handover }.write(out);
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let i = match agent {
            1 => 0,
            2 => 1,
            _ => return,
        };
        let (torque, force) = parse_command(command);
        self.craft[i].torque_cmd_n_m = torque;
        self.craft[i].force_cmd_n = force;
    }

    fn advance(&mut self, dt_s: f64) {
        self.record_metrics(dt_s);
        let mass = self.cfg.spacecraft.mass_kg;
        let a: [V3; 2] =
            std::array::from_fn(|i| (self.craft[i].applied_force_n() + self.craft[i].force_disturbance.value) / mass);
        // τ_g uses the positions at the start of the step.
        let r0 = [self.orbit.r_leader_eci_m, self.orbit.r_follower_eci_m()];
        self.orbit.rk4_step(&self.gravity, &a[0], &a[1], dt_s);
        let gg = self.cfg.disturbances.gravity_gradient;
        for (i, r) in r0.into_iter().enumerate() {
            let c = &mut self.craft[i];
            let inp = TorqueInputs {
                inertia: &self.inertia,
                held_torque_n_m: c.applied_torque_n_m() + c.torque_disturbance_n_m,
                gravity_gradient_r_eci_m: gg.then_some(r),
                mu_m3ps2: self.gravity.mu_m3ps2,
            };
            c.attitude.rk4_step(self.t_s, dt_s, &inp);
            c.last_nongrav_mps2 = a[i];
        }
        self.k += 1;
        self.t_s = self.k as f64 * dt_s;
        self.advance_processes(dt_s);
    }

    fn row(&self, out: &mut Vec<f64>) {
        crate::model::plant_row::row(self, out);
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        self.metrics.summary()
    }
}
