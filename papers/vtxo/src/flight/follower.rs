//! The follower (agent 2, the Inner Satellite with NISTEx-II and the radio ranging): its attitude
//! control system ([`crate::flight::acs`]), its relative navigation ([`crate::flight::relative_nav`]), and the
//! relative-position law — SMC (64)–(67) (sign or sat) or PD (56) — on r̂_rel, v̂_rel with the
//! leader's shared r̂_L and previous-step û_L.
//!
//! Until v̂_rel is known (step 0: the leader's first share has not arrived) it commands no thrust.
//! Shares (see [`crate::flight::share`]): û_F, r̂_rel, v̂_rel. Command: τ̂_in (body, N·m) and
//! F̂_in = m û_F (ECI, N).

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};
use serde::{Deserialize, Serialize};

use crate::flight::acs::Acs;
use crate::flight::attitude_control::AttitudeLaw;
use crate::flight::layout::Readings;
use crate::flight::relative_control::{RelativeLaw, RelativeState, follower_accel, sliding_vector};
use crate::flight::relative_filter::RelativeFilterConfig;
use crate::flight::relative_nav::RelativeNav;
use crate::flight::share::{FollowerShare, LeaderShare};
use crate::model::quaternion::V3;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Follower {
    pub acs: Acs,
    pub law: RelativeLaw,
    pub nav: RelativeNav,
    pub mass_kg: f64,
    pub r_target_eci_m: V3,
    pub v_target_eci_mps: V3,
    pub u_cmd_mps2: V3,
    /// The length of the last step (for the velocity integration at the next readings).
    pub last_dt_s: f64,
}

impl Follower {
    pub fn new(
        acs: Acs,
        law: RelativeLaw,
        mass_kg: f64,
        mu_m3ps2: f64,
        r_target_eci_m: V3,
        v_target_eci_mps: V3,
        filter: Option<RelativeFilterConfig>,
    ) -> Self {
        Self {
            acs,
            law,
            nav: RelativeNav::new(mu_m3ps2, filter),
            mass_kg,
            r_target_eci_m,
            v_target_eci_mps,
            u_cmd_mps2: V3::zeros(),
            last_dt_s: 0.0,
        }
    }

    pub fn set_attitude_law(&mut self, law: AttitudeLaw) {
        self.acs.set_law(law);
    }

    fn relative_state(&self) -> Option<RelativeState> {
        let v = self.nav.v_rel_mps?;
        let (rl, _) = self.nav.leader_rv?;
        Some(RelativeState {
            r_rel_m: self.nav.r_rel_m,
            v_rel_mps: v,
            r_leader_m: rl,
            r_target_m: self.r_target_eci_m,
            v_target_mps: self.v_target_eci_mps,
            mu_m3ps2: self.nav.mu_m3ps2,
        })
    }

    fn sliding(&self) -> V3 {
        match (&self.law, self.relative_state()) {
            (RelativeLaw::Smc { k, .. }, Some(st)) => sliding_vector(*k, &st),
            _ => V3::zeros(),
        }
    }
}

impl Algorithm for Follower {
    cohort_runtime::serde_checkpoint!();

    fn columns(&self) -> Vec<String> {
        let mut c = Acs::columns();
        for (name, unit) in [("f_cmd", "n"), ("r_rel_hat_eci", "m"), ("v_rel_hat_eci", "mps"), ("s_eci", "mps")] {
            for ax in ["x", "y", "z"] {
                c.push(format!("{name}_{ax}_{unit}"));
            }
        }
        if self.nav.filter_cfg.is_some() {
            for (name, unit) in [("accel_bias_hat_eci", "mps2"), ("v_rel_sigma_eci", "mps")] {
                c.extend(["x", "y", "z"].map(|ax| format!("{name}_{ax}_{unit}")));
            }
        }
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.clear();
        out.values.clear();
        let Some(r) = Readings::parse(input.readings) else {
            out.command.extend([0.0; 6]);
            return;
        };
        if let Some((_, v)) = r.handover {
            self.nav.own_handover_v_mps = Some(v);
        }
        self.nav.measure(self.last_dt_s, &r.r_rel_eci_m(), &r.accel_mps2);
        let torque = self.acs.on_readings(&r);
        self.u_cmd_mps2 = match self.relative_state() {
            Some(st) => follower_accel(&self.law, &st, &self.nav.u_leader_mps2),
            None => V3::zeros(),
        };
        out.command.extend(torque.iter());
        out.command.extend((self.mass_kg * self.u_cmd_mps2).iter());
        FollowerShare {
            u_mps2: self.u_cmd_mps2,
            r_rel_eci_m: self.nav.r_rel_m,
            v_rel_eci_mps: self.nav.v_rel_mps.unwrap_or_default(),
            valid: self.nav.v_rel_mps.is_some(),
        }
        .write(&mut out.values);
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        if let Some(l) = neighbours.iter().find(|n| n.id == 1).and_then(|n| LeaderShare::read(n.values)) {
            self.nav.on_leader_share(&l);
        }
        self.nav.propagate_leader(dt_s);
        self.acs.propagate(dt_s);
        self.last_dt_s = dt_s;
    }

    fn row(&self, out: &mut Vec<f64>) {
        self.acs.row(out);
        out.extend((self.mass_kg * self.u_cmd_mps2).iter());
        out.extend(self.nav.r_rel_m.iter());
        // NaN until v̂_rel is known (step 0): a zero would read as an estimate.
        out.extend(self.nav.v_rel_mps.unwrap_or(V3::repeat(f64::NAN)).iter());
        out.extend(self.sliding().iter());
        if self.nav.filter_cfg.is_some() {
            // NaN until the filter starts with v̂_rel (step 0).
            let f = self.nav.filter.as_ref();
            out.extend(f.map_or(V3::repeat(f64::NAN), |f| f.bias_mps2()).iter());
            out.extend(f.map_or(V3::repeat(f64::NAN), |f| f.v_sigma_mps()).iter());
        }
    }
}
