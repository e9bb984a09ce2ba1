//! One spacecraft's attitude control system, as both agents run it: the MEKF on the gyro and the
//! star tracker (Sec. 2.10.2) and the attitude law of the current phase (Sec. 2.11) on its
//! estimates. The law is replaceable at run time ([`Acs::set_law`]) for a supervisor.
//!
//! Step protocol: at step k the readings update (or, the first time, start) the filter, and the
//! law computes the torque held over [t_k, t_{k+1}]; `propagate` then carries the filter to t_{k+1}.

use serde::{Deserialize, Serialize};

use crate::flight::attitude_control::{self, AttitudeLaw};
use crate::flight::layout::Readings;
use crate::flight::mekf::{FilterModel, Mekf, MekfVariant};
use crate::model::quaternion::{Quat, V3};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Acs {
    pub variant: MekfVariant,
    pub model: FilterModel,
    pub law: AttitudeLaw,
    pub q_target_body_eci: Quat,
    pub mekf: Option<Mekf>,
    pub torque_cmd_n_m: V3,
}

impl Acs {
    pub fn new(variant: MekfVariant, model: FilterModel, law: AttitudeLaw, q_target_body_eci: Quat) -> Self {
        Self { variant, model, law, q_target_body_eci, mekf: None, torque_cmd_n_m: V3::zeros() }
    }

    /// Switch the law (and its gains) from the next command on.
    pub fn set_law(&mut self, law: AttitudeLaw) {
        self.law = law;
    }

    /// Filter the readings of step k and compute the commanded torque.
    pub fn on_readings(&mut self, r: &Readings) -> V3 {
        let q_meas = r.star_q_body_eci.normalize();
        match &mut self.mekf {
            None => self.mekf = Some(Mekf::new(self.variant, self.model.clone(), &q_meas, &r.gyro_rad_s)),
            Some(f) => f.update(&q_meas, &r.gyro_rad_s),
        }
        self.command()
    }

    /// The current law's torque on the current estimate (after [`Acs::on_readings`]), held from
    /// now on: a supervisor that switches the law after the filter update calls it again.
    pub fn command(&mut self) -> V3 {
        let j = nalgebra::Matrix3::from_diagonal(&V3::from(self.model.inertia_kg_m2));
        self.torque_cmd_n_m = match &self.mekf {
            Some(f) => {
                attitude_control::torque(&self.law, &f.q_hat(), &f.omega_hat_rad_s(), &self.q_target_body_eci, &j)
            }
            None => V3::zeros(),
        };
        self.torque_cmd_n_m
    }

    pub fn propagate(&mut self, dt_s: f64) {
        if let Some(f) = &mut self.mekf {
            f.propagate(dt_s, &self.torque_cmd_n_m);
        }
    }

    pub fn q_hat(&self) -> Quat {
        self.mekf.as_ref().map_or(self.q_target_body_eci, Mekf::q_hat)
    }

    pub fn omega_hat_rad_s(&self) -> V3 {
        self.mekf.as_ref().map_or(V3::zeros(), Mekf::omega_hat_rad_s)
    }

    /// Telemetry column names (after a role prefix is added by the agent).
    pub fn columns() -> Vec<String> {
        let mut c = Vec::new();
        for n in ["q1", "q2", "q3", "q4"] {
            c.push(format!("q_hat_{n}"));
        }
        for (name, unit) in [
            ("omega_hat", "rad_s"),
            ("b_gyro_hat", "rad_s"),
            ("b_star_hat", "rad"),
            ("sigma_theta", "rad"),
            ("tau_cmd", "n_m"),
        ] {
            for ax in ["x", "y", "z"] {
                c.push(format!("{name}_{ax}_{unit}"));
            }
        }
        c
    }

    pub fn row(&self, out: &mut Vec<f64>) {
        out.extend(self.q_hat().iter());
        out.extend(self.omega_hat_rad_s().iter());
        match &self.mekf {
            Some(f) => {
                out.extend(f.gyro_bias_rad_s().iter());
                out.extend(f.star_bias_rad().iter());
                out.extend(f.sigma_theta_rad().iter());
            }
            None => out.extend([0.0; 9]),
        }
        out.extend(self.torque_cmd_n_m.iter());
    }
}
