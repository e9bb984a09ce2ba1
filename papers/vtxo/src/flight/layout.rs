//! The plant ↔ agent message layouts.
//!
//! Readings, [`READINGS_LEN`] = 20 values per agent per step, the same layout for both (the
//! leader's relative-sensor slots are 0):
//!
//! | offset | reading | unit, frame |
//! |---|---|---|
//! | 0..3 | gyro ω̃ (C.1) | rad/s, body |
//! | 3..7 | star tracker q̃ (C.4), scalar last | —, ECI → body |
//! | 7..10 | accelerometer ã (C.7): non-gravitational acceleration over the step that just ended | m/s², ECI |
//! | 10 | radio ranging r̃_rel,z (C.10), follower only | m, ECI z |
//! | 11..13 | interferometer r̃_rel,x, r̃_rel,y, follower only | m, ECI x, y |
//! | 13 | hand-over flag: 1 at step 0 (the next six values are valid), else 0 | — |
//! | 14..17 | hand-over r̃, own position | m, ECI |
//! | 17..20 | hand-over ṽ, own velocity | m/s, ECI |
//!
//! Command, [`COMMAND_LEN`] = 6 values (≤ 8), held over the step:
//!
//! | offset | command | unit, frame |
//! |---|---|---|
//! | 0..3 | τ̂_in, reaction-wheel torque | N·m, body |
//! | 3..6 | F̂_in = m û_in, thrust | N, ECI |

use crate::model::quaternion::{Quat, V3};

pub const READINGS_LEN: usize = 20;
pub const COMMAND_LEN: usize = 6;
// The wire's bounds: ≤ 64 readings per measurement, ≤ 8 command values.
const _: () = assert!(READINGS_LEN <= 64 && COMMAND_LEN <= 8);

/// One agent's readings, parsed.
#[derive(Debug, Clone, PartialEq)]
pub struct Readings {
    pub gyro_rad_s: V3,
    pub star_q_body_eci: Quat,
    pub accel_mps2: V3,
    pub ranging_z_m: f64,
    pub interferometer_xy_m: [f64; 2],
    /// Own (r, v) in ECI when the hand-over is in this step.
    pub handover: Option<(V3, V3)>,
}

fn v3(x: &[f64], at: usize) -> V3 {
    V3::new(x[at], x[at + 1], x[at + 2])
}

impl Readings {
    /// `None` when there are too few values (an agent never trusts a short message).
    pub fn parse(x: &[f64]) -> Option<Self> {
        if x.len() < READINGS_LEN {
            return None;
        }
        Some(Self {
            gyro_rad_s: v3(x, 0),
            star_q_body_eci: Quat::new(x[3], x[4], x[5], x[6]),
            accel_mps2: v3(x, 7),
            ranging_z_m: x[10],
            interferometer_xy_m: [x[11], x[12]],
            handover: (x[13] > 0.5).then(|| (v3(x, 14), v3(x, 17))),
        })
    }

    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend(self.gyro_rad_s.iter());
        out.extend(self.star_q_body_eci.iter());
        out.extend(self.accel_mps2.iter());
        out.push(self.ranging_z_m);
        out.extend(self.interferometer_xy_m);
        match &self.handover {
            Some((r, v)) => {
                out.push(1.0);
                out.extend(r.iter());
                out.extend(v.iter());
            }
            None => out.extend([0.0; 7]),
        }
    }

    /// The relative position r̂_rel from the ranging (z) and the interferometer (x, y).
    pub fn r_rel_eci_m(&self) -> V3 {
        V3::new(self.interferometer_xy_m[0], self.interferometer_xy_m[1], self.ranging_z_m)
    }
}

/// The command's two vectors; missing values are zero (an agent that never sent one).
pub fn parse_command(c: &[f64]) -> (V3, V3) {
    let at = |i: usize| c.get(i).copied().unwrap_or(0.0);
    (V3::new(at(0), at(1), at(2)), V3::new(at(3), at(4), at(5)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_round_trip() {
        let r = Readings {
            gyro_rad_s: V3::new(1.0, 2.0, 3.0),
            star_q_body_eci: Quat::new(0.0, 0.6, 0.0, 0.8),
            accel_mps2: V3::new(1e-6, 0.0, -1e-6),
            ranging_z_m: 1000.5,
            interferometer_xy_m: [1e-4, -2e-4],
            handover: Some((V3::new(1.0, 2.0, 3.0), V3::new(4.0, 5.0, 6.0))),
        };
        let mut v = Vec::new();
        r.write(&mut v);
        assert_eq!(v.len(), READINGS_LEN);
        assert_eq!(Readings::parse(&v), Some(r.clone()));
        let r2 = Readings { handover: None, ..r };
        v.clear();
        r2.write(&mut v);
        assert_eq!(Readings::parse(&v), Some(r2));
        assert_eq!(Readings::parse(&v[..19]), None);
        assert_eq!(parse_command(&[]), (V3::zeros(), V3::zeros()));
    }
}
