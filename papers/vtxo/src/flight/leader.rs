//! The leader (agent 1, the Outer Satellite with the laser beacons): its attitude control system
//! ([`crate::flight::acs`]), its own orbit estimate r̂_L, v̂_L (started from the hand-over fix and
//! propagated with the point-mass model (36)–(37) and its own command — no GPS at apogee), and
//! either a natural drift (û_L = 0, Sec. 7, the default) or the SMC (70) with the follower's
//! previous-step command and relative estimates (the leader has no relative sensor).
//!
//! Shares (see [`crate::flight::share`]): û_L, r̂_L, v̂_L, q̂_L, ω̂_L, ã_L. Command: τ̂_in (body, N·m) and
//! F̂_in = m û_L (ECI, N).

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};
use serde::{Deserialize, Serialize};

use crate::flight::acs::Acs;
use crate::flight::attitude_control::AttitudeLaw;
use crate::flight::layout::Readings;
use crate::flight::relative_control::{RelativeLaw, RelativeState, leader_accel};
use crate::flight::share::{FollowerShare, LeaderShare};
use crate::model::orbit::rk4_point_mass;
use crate::model::quaternion::V3;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Leader {
    pub acs: Acs,
    pub law: RelativeLaw,
    pub mass_kg: f64,
    pub mu_m3ps2: f64,
    pub r_target_eci_m: V3,
    pub v_target_eci_mps: V3,
    /// r̂_L, v̂_L once the hand-over has arrived.
    pub rv_hat: Option<(V3, V3)>,
    pub u_cmd_mps2: V3,
    pub accel_meas_mps2: V3,
    pub follower: Option<FollowerShare>,
}

impl Leader {
    pub fn new(
        acs: Acs,
        law: RelativeLaw,
        mass_kg: f64,
        mu_m3ps2: f64,
        r_target_eci_m: V3,
        v_target_eci_mps: V3,
    ) -> Self {
        Self {
            acs,
            law,
            mass_kg,
            mu_m3ps2,
            r_target_eci_m,
            v_target_eci_mps,
            rv_hat: None,
            u_cmd_mps2: V3::zeros(),
            accel_meas_mps2: V3::zeros(),
            follower: None,
        }
    }

    pub fn set_attitude_law(&mut self, law: AttitudeLaw) {
        self.acs.set_law(law);
    }

    fn relative_command(&self) -> V3 {
        let (Some((r, _)), Some(f)) = (&self.rv_hat, &self.follower) else { return V3::zeros() };
        if !f.valid {
            return V3::zeros();
        }
        let st = RelativeState {
            r_rel_m: f.r_rel_eci_m,
            v_rel_mps: f.v_rel_eci_mps,
            r_leader_m: *r,
            r_target_m: self.r_target_eci_m,
            v_target_mps: self.v_target_eci_mps,
            mu_m3ps2: self.mu_m3ps2,
        };
        leader_accel(&self.law, &st, &f.u_mps2)
    }
}

impl Algorithm for Leader {
    cohort_runtime::serde_checkpoint!();

    fn columns(&self) -> Vec<String> {
        let mut c = Acs::columns();
        for (name, unit) in [("f_cmd", "n"), ("r_hat_eci", "m"), ("v_hat_eci", "mps")] {
            for ax in ["x", "y", "z"] {
                c.push(format!("{name}_{ax}_{unit}"));
            }
        }
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.clear();
        out.values.clear();
        let Some(r) = Readings::parse(input.readings) else {
            // A short message is never trusted: hold nothing, command nothing.
            out.command.extend([0.0; 6]);
            return;
        };
        if self.rv_hat.is_none() {
            self.rv_hat = r.handover;
        }
        self.accel_meas_mps2 = r.accel_mps2;
        let torque = self.acs.on_readings(&r);
        self.u_cmd_mps2 = self.relative_command();
        out.command.extend(torque.iter());
        out.command.extend((self.mass_kg * self.u_cmd_mps2).iter());
        let (rl, vl) = self.rv_hat.unwrap_or((V3::zeros(), V3::zeros()));
        LeaderShare {
            u_mps2: self.u_cmd_mps2,
            r_eci_m: rl,
            v_eci_mps: vl,
            q_body_eci: self.acs.q_hat(),
            omega_body_rad_s: self.acs.omega_hat_rad_s(),
            accel_meas_mps2: self.accel_meas_mps2,
            orbit_known: self.rv_hat.is_some(),
        }
        .write(&mut out.values);
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        if let Some(f) = neighbours.iter().find(|n| n.id == 2).and_then(|n| FollowerShare::read(n.values)) {
            self.follower = Some(f);
        }
        self.acs.propagate(dt_s);
        if let Some((r, v)) = &mut self.rv_hat {
            rk4_point_mass(self.mu_m3ps2, r, v, &self.u_cmd_mps2, dt_s);
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        self.acs.row(out);
        out.extend((self.mass_kg * self.u_cmd_mps2).iter());
        let (r, v) = self.rv_hat.unwrap_or((V3::zeros(), V3::zeros()));
        out.extend(r.iter());
        out.extend(v.iter());
    }
}
