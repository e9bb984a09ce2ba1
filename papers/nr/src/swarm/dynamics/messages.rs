//! What the `swarm` plant tells each vehicle every step, and what each vehicle shares with the
//! others (our message list for Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883; the paper's
//! are not printed).
//!
//! Readings (9 values, SI units): own position estimate p̂ (m, world frame: x, y horizontal, z up),
//! own velocity estimate v̂ (m/s), both the truth plus white Gaussian noise, and the goal g (m).
//!
//! Command (3 values): the acceleration a (m/s², world frame); the plant clips it to a_max per
//! axis.
//!
//! Share values (10): [p̂ (3), v̂ (3), u (3), mode]: the sender's estimates and command of the step.
//! A receiver propagates them over the one control interval they are late by (the share of step k
//! arrives after the command of step k is due, see `swarm_agent`) with the shared u, which is why
//! u is in the share.

/// Readings per vehicle.
pub const READINGS_LEN: usize = 9;
/// Command components.
pub const COMMAND_LEN: usize = 3;
/// Values per share.
pub const SHARE_LEN: usize = 10;

type V3 = [f64; 3];

fn v3(s: &[f64]) -> V3 {
    [s[0], s[1], s[2]]
}

/// One step's readings, parsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SwarmReading {
    pub p_m: V3,
    pub v_mps: V3,
    pub goal_m: V3,
}

impl SwarmReading {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend(self.p_m);
        out.extend(self.v_mps);
        out.extend(self.goal_m);
    }

    /// Check length and finiteness; the reason names what is wrong.
    pub fn parse(r: &[f64]) -> Result<Self, String> {
        if r.len() != READINGS_LEN {
            return Err(format!("{} readings, expected {READINGS_LEN} (swarm plant)", r.len()));
        }
        if let Some(i) = r.iter().position(|x| !x.is_finite()) {
            return Err(format!("reading {i} is not finite"));
        }
        Ok(Self { p_m: v3(&r[0..3]), v_mps: v3(&r[3..6]), goal_m: v3(&r[6..9]) })
    }
}

/// One vehicle's share, parsed.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct SwarmShare {
    pub p_m: V3,
    pub v_mps: V3,
    pub u_mps2: V3,
    pub mode: f64,
}

impl SwarmShare {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend(self.p_m);
        out.extend(self.v_mps);
        out.extend(self.u_mps2);
        out.push(self.mode);
    }

    /// None unless it has [`SHARE_LEN`] finite values (a vehicle with bad readings shares NaN
    /// states, and is then not observed).
    pub fn parse(values: &[f64]) -> Option<Self> {
        (values.len() == SHARE_LEN && values.iter().all(|x| x.is_finite())).then(|| Self {
            p_m: v3(&values[0..3]),
            v_mps: v3(&values[3..6]),
            u_mps2: v3(&values[6..9]),
            mode: values[9],
        })
    }

    /// The sender's state `dt_s` later under its shared command (exact for a double integrator
    /// without disturbance).
    pub fn propagated(&self, dt_s: f64) -> (V3, V3) {
        let (p, v, u) = (self.p_m, self.v_mps, self.u_mps2);
        ([0, 1, 2].map(|a| p[a] + v[a] * dt_s + 0.5 * u[a] * dt_s * dt_s), [0, 1, 2].map(|a| v[a] + u[a] * dt_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_and_shares_round_trip_and_bad_ones_are_refused() {
        let r = SwarmReading { p_m: [1.0, 2.0, 3.0], v_mps: [0.1, 0.2, 0.3], goal_m: [-1.0, 0.0, 1.5] };
        let mut out = Vec::new();
        r.write(&mut out);
        assert_eq!(SwarmReading::parse(&out), Ok(r));
        out[4] = f64::NAN;
        assert!(SwarmReading::parse(&out).unwrap_err().contains("reading 4"));
        assert!(SwarmReading::parse(&out[..8]).is_err());
        let s = SwarmShare { p_m: [1.0, 0.0, 1.0], v_mps: [1.0, 0.0, 0.0], u_mps2: [2.0, 0.0, -2.0], mode: 1.0 };
        let mut v = Vec::new();
        s.write(&mut v);
        assert_eq!(SwarmShare::parse(&v), Some(s));
        assert_eq!(SwarmShare::parse(&v[..9]), None);
        let (p, w) = s.propagated(0.5);
        assert_eq!((p, w), ([1.75, 0.0, 0.75], [2.0, 0.0, -1.0]));
    }
}
