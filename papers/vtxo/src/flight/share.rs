//! What the two agents exchange every step, as flat f64 layouts. New fields (a supervisor's
//! state) are appended after the last one, so the offsets below stay.
//!
//! Leader → follower, [`LEADER_SHARE_LEN`] = 20 values:
//!
//! | offset | value | unit |
//! |---|---|---|
//! | 0..3 | û_L, the leader's commanded acceleration (for (65)–(66)) | m/s², ECI |
//! | 3..6 | r̂_L | m, ECI |
//! | 6..9 | v̂_L | m/s, ECI |
//! | 9..13 | q̂_L (scalar last) | — |
//! | 13..16 | ω̂_L | rad/s, body |
//! | 16..19 | ã_L, the leader's accelerometer reading (for the follower's v̂_rel) | m/s², ECI |
//! | 19 | 1 when r̂_L, v̂_L are known (the hand-over arrived), else 0 | — |
//!
//! Follower → leader, [`FOLLOWER_SHARE_LEN`] = 10 values:
//!
//! | offset | value | unit |
//! |---|---|---|
//! | 0..3 | û_F, the follower's commanded acceleration (for (70)) | m/s², ECI |
//! | 3..6 | r̂_rel = r̂_F − r̂_L | m, ECI |
//! | 6..9 | v̂_rel | m/s, ECI |
//! | 9 | 1 when v̂_rel is known, else 0 | — |

use serde::{Deserialize, Serialize};

use crate::model::quaternion::{Quat, V3};

pub const LEADER_SHARE_LEN: usize = 20;
pub const FOLLOWER_SHARE_LEN: usize = 10;
// The wire's bound on share values.
const _: () = assert!(LEADER_SHARE_LEN <= 512 && FOLLOWER_SHARE_LEN <= 512);

fn v3(x: &[f64], at: usize) -> V3 {
    V3::new(x[at], x[at + 1], x[at + 2])
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LeaderShare {
    pub u_mps2: V3,
    pub r_eci_m: V3,
    pub v_eci_mps: V3,
    pub q_body_eci: Quat,
    pub omega_body_rad_s: V3,
    pub accel_meas_mps2: V3,
    pub orbit_known: bool,
}

impl LeaderShare {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend(self.u_mps2.iter());
        out.extend(self.r_eci_m.iter());
        out.extend(self.v_eci_mps.iter());
        out.extend(self.q_body_eci.iter());
        out.extend(self.omega_body_rad_s.iter());
        out.extend(self.accel_meas_mps2.iter());
        out.push(if self.orbit_known { 1.0 } else { 0.0 });
    }

    /// `None` when the values are too short to be a leader share.
    pub fn read(x: &[f64]) -> Option<Self> {
        if x.len() < LEADER_SHARE_LEN {
            return None;
        }
        Some(Self {
            u_mps2: v3(x, 0),
            r_eci_m: v3(x, 3),
            v_eci_mps: v3(x, 6),
            q_body_eci: Quat::new(x[9], x[10], x[11], x[12]),
            omega_body_rad_s: v3(x, 13),
            accel_meas_mps2: v3(x, 16),
            orbit_known: x[19] > 0.5,
        })
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FollowerShare {
    pub u_mps2: V3,
    pub r_rel_eci_m: V3,
    pub v_rel_eci_mps: V3,
    pub valid: bool,
}

impl FollowerShare {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend(self.u_mps2.iter());
        out.extend(self.r_rel_eci_m.iter());
        out.extend(self.v_rel_eci_mps.iter());
        out.push(if self.valid { 1.0 } else { 0.0 });
    }

    pub fn read(x: &[f64]) -> Option<Self> {
        if x.len() < FOLLOWER_SHARE_LEN {
            return None;
        }
        Some(Self { u_mps2: v3(x, 0), r_rel_eci_m: v3(x, 3), v_rel_eci_mps: v3(x, 6), valid: x[9] > 0.5 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_round_trip() {
        let l = LeaderShare {
            u_mps2: V3::new(1.0, 2.0, 3.0),
            r_eci_m: V3::new(4.0, 5.0, 6.0),
            v_eci_mps: V3::new(7.0, 8.0, 9.0),
            q_body_eci: Quat::new(0.1, 0.2, 0.3, 0.9),
            omega_body_rad_s: V3::new(-1.0, -2.0, -3.0),
            accel_meas_mps2: V3::new(1e-9, 2e-9, 3e-9),
            orbit_known: true,
        };
        let mut v = Vec::new();
        l.write(&mut v);
        assert_eq!(v.len(), LEADER_SHARE_LEN);
        assert_eq!(LeaderShare::read(&v), Some(l));
        let f = FollowerShare {
            u_mps2: V3::new(1.0, 0.0, -1.0),
            r_rel_eci_m: V3::new(0.0, 0.0, 1e3),
            v_rel_eci_mps: V3::zeros(),
            valid: true,
        };
        let mut v = Vec::new();
        f.write(&mut v);
        assert_eq!(v.len(), FOLLOWER_SHARE_LEN);
        assert_eq!(FollowerShare::read(&v), Some(f));
        assert_eq!(FollowerShare::read(&v[..9]), None);
    }
}
