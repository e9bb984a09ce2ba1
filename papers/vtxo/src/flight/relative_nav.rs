//! The follower's relative navigation (Sec. 7): "each sensor measures the
//! states of the dynamics individually".
//!
//! - r̂_rel is measured every step: ECI x, y by the laser interferometer, z by radio ranging.
//! - v̂_rel is dead-reckoned from the accelerometers with the agents' model (40):
//!   v̂_rel(t_k) = v̂_rel(t_{k−1}) + Δt [μ(r̂_L/|r̂_L|³ − r̂_F/|r̂_F|³) + ã_F − ã_L],
//!   with r̂_F = r̂_L + r̂_rel, ã_F the follower's reading of step k (which covers [t_{k−1}, t_k])
//!   and ã_L the leader's latest shared reading (one step older: the leader's reading of step k
//!   arrives with its share of step k, after the follower has committed its command). So the
//!   error of v̂_rel is ∫(accelerometer errors F − L) dt plus that one-step lag, and it is never
//!   corrected: the accelerometer biases (1 µg 3σ) make it drift.
//! - v̂_rel(t₀) = ṽ_F − v̂_L from the follower's own hand-over fix and the leader's first share, so
//!   the follower has no v̂_rel (and commands no thrust) at step 0.
//! - r̂_L, v̂_L are the leader's shared estimates, propagated by the follower over each step with
//!   the point-mass model (36)–(37) and the leader's shared command.
//!
//! With `algorithm.relative.navigation = "filter"` (ours, not the paper's) the same readings go
//! through [`crate::flight::relative_filter`] instead: r̂_rel and v̂_rel are the filter's, and the
//! differential accelerometer bias is estimated, so v̂_rel no longer drifts.

use serde::{Deserialize, Serialize};

use crate::flight::relative_filter::{RelativeFilter, RelativeFilterConfig};
use crate::flight::share::LeaderShare;
use crate::model::orbit::{point_mass_accel, rk4_point_mass};
use crate::model::quaternion::V3;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RelativeNav {
    pub mu_m3ps2: f64,
    pub r_rel_m: V3,
    pub v_rel_mps: Option<V3>,
    /// r̂_L, v̂_L at the current step's time, once the leader has shared them.
    pub leader_rv: Option<(V3, V3)>,
    pub u_leader_mps2: V3,
    pub a_leader_meas_mps2: V3,
    /// The follower's own hand-over velocity, kept until the leader's state arrives.
    pub own_handover_v_mps: Option<V3>,
    /// The fusing filter's statistics when it flies, and the filter once v̂_rel(t₀) is known
    /// (boxed: 3 × 12 values the dead-reckoning follower need not carry).
    pub filter_cfg: Option<RelativeFilterConfig>,
    pub filter: Option<Box<RelativeFilter>>,
}

impl RelativeNav {
    pub fn new(mu_m3ps2: f64, filter_cfg: Option<RelativeFilterConfig>) -> Self {
        Self {
            mu_m3ps2,
            r_rel_m: V3::zeros(),
            v_rel_mps: None,
            leader_rv: None,
            u_leader_mps2: V3::zeros(),
            a_leader_meas_mps2: V3::zeros(),
            own_handover_v_mps: None,
            filter_cfg,
            filter: None,
        }
    }

    /// At step k: integrate v̂_rel over the step that just ended (with the r̂_rel of its start and
    /// the follower's accelerometer reading of step k), then take the new position measurement.
    /// With the filter: its prediction over the step with the same input, then its update with the
    /// reading.
    pub fn measure(&mut self, dt_s: f64, r_rel_meas_m: &V3, accel_meas_mps2: &V3) {
        if let (Some(v), Some((rl, _))) = (&mut self.v_rel_mps, &self.leader_rv) {
            let dg = point_mass_accel(self.mu_m3ps2, &(rl + self.r_rel_m)) - point_mass_accel(self.mu_m3ps2, rl);
            let u = dg + accel_meas_mps2 - self.a_leader_meas_mps2;
            if let Some(f) = &mut self.filter {
                f.step(dt_s, &u, r_rel_meas_m);
                (self.r_rel_m, *v) = (f.r_m(), f.v_mps());
                return;
            }
            *v += dt_s * u;
        }
        self.r_rel_m = *r_rel_meas_m;
    }

    /// The leader's share of step k (state at t_k).
    pub fn on_leader_share(&mut self, s: &LeaderShare) {
        if !s.orbit_known {
            return;
        }
        self.leader_rv = Some((s.r_eci_m, s.v_eci_mps));
        self.u_leader_mps2 = s.u_mps2;
        self.a_leader_meas_mps2 = s.accel_meas_mps2;
        if self.v_rel_mps.is_none()
            && let Some(vf) = self.own_handover_v_mps.take()
        {
            let v = vf - s.v_eci_mps;
            self.v_rel_mps = Some(v);
            self.filter = self.filter_cfg.as_ref().map(|c| Box::new(RelativeFilter::new(c, &self.r_rel_m, &v)));
        }
    }

    /// Carry r̂_L, v̂_L from t_k to t_{k+1}.
    pub fn propagate_leader(&mut self, dt_s: f64) {
        if let Some((r, v)) = &mut self.leader_rv {
            rk4_point_mass(self.mu_m3ps2, r, v, &self.u_leader_mps2, dt_s);
        }
    }
}
