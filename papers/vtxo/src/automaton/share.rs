//! What the supervisor adds to the two spacecraft's messages (Sec. 8 of "Explainable
//! AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"; the paper says
//! nothing about who runs the automaton: the follower — the Inner Satellite, which has the
//! relative sensors and so sees the formation event — is the master, the leader follows and
//! acknowledges). Clocks travel in ticks (whole numbers, exact in f64 below 2⁵³).
//!
//! Follower → leader, [`MASTER_SHARE_LEN`] = 12 values:
//!
//! | offset | value | unit |
//! |---|---|---|
//! | 0 | location s (0..6) | — |
//! | 1 | Id (Table 6) | — |
//! | 2..9 | clocks t0..t5, tw | ticks |
//! | 9 | u2 = max(T̂_L, T̂_F) in force | ticks |
//! | 10 | formation reached (u4) | 0/1 |
//! | 11 | the follower's T̂_F | s |
//!
//! Leader → follower, [`LEADER_SHARE_LEN`] = 5 values: acknowledged s and Id, and the leader's
//! transient prediction T̂_L (s), k1, k2 (0 outside s2).

use crate::automaton::exec::Supervisor;

pub const N_CLOCKS: usize = 7;
pub const MASTER_SHARE_LEN: usize = 12;
pub const LEADER_SHARE_LEN: usize = 5;

#[derive(Debug, Clone, PartialEq)]
pub struct MasterShare {
    pub sup: Supervisor,
    pub u2_ticks: u64,
    pub formation: bool,
    pub t_hat_follower_s: f64,
}

impl MasterShare {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.push(self.sup.state as f64);
        out.push(f64::from(self.sup.id));
        out.extend((0..N_CLOCKS).map(|i| self.sup.clocks.get(i).copied().unwrap_or(0) as f64));
        out.push(self.u2_ticks as f64);
        out.push(if self.formation { 1.0 } else { 0.0 });
        out.push(self.t_hat_follower_s);
    }

    /// None when too short or not a supervisor's values (negative, fractional, out of range).
    pub fn read(x: &[f64]) -> Option<Self> {
        if x.len() < MASTER_SHARE_LEN {
            return None;
        }
        let whole = |v: f64| (v >= 0.0 && v.fract() == 0.0 && v < 9.0e15).then_some(v as u64);
        let state = whole(x[0]).filter(|s| *s <= 6)? as usize;
        let id = u32::try_from(whole(x[1])?).ok()?;
        let clocks = x[2..2 + N_CLOCKS].iter().map(|v| whole(*v)).collect::<Option<Vec<u64>>>()?;
        Some(Self {
            sup: Supervisor { state, id, clocks },
            u2_ticks: whole(x[9])?,
            formation: x[10] > 0.5,
            t_hat_follower_s: x[11],
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderShare {
    pub ack_state: usize,
    pub ack_id: u32,
    pub t_hat_s: f64,
    pub k1: f64,
    pub k2: f64,
}

impl LeaderShare {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend([self.ack_state as f64, f64::from(self.ack_id), self.t_hat_s, self.k1, self.k2]);
    }

    pub fn read(x: &[f64]) -> Option<Self> {
        if x.len() < LEADER_SHARE_LEN || !(x[0] >= 0.0 && x[0] <= 6.0 && x[1] >= 0.0 && x[1] < 4.0e9) {
            return None;
        }
        Some(Self { ack_state: x[0] as usize, ack_id: x[1] as u32, t_hat_s: x[2], k1: x[3], k2: x[4] })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_round_trip_and_refuse_garbage() {
        let m = MasterShare {
            sup: Supervisor { state: 3, id: 8, clocks: vec![1, 2, 3, 162_720_000, 5, 6, 7] },
            u2_ticks: 4800,
            formation: true,
            t_hat_follower_s: 47.5,
        };
        let mut v = Vec::new();
        m.write(&mut v);
        assert_eq!(v.len(), MASTER_SHARE_LEN);
        assert_eq!(MasterShare::read(&v), Some(m));
        v[0] = 7.0;
        assert_eq!(MasterShare::read(&v), None);
        v[0] = 3.0;
        v[4] = 2.5;
        assert_eq!(MasterShare::read(&v), None);
        let l = LeaderShare { ack_state: 2, ack_id: 4, t_hat_s: 48.0, k1: 0.085, k2: 0.25 };
        let mut v = Vec::new();
        l.write(&mut v);
        assert_eq!(v.len(), LEADER_SHARE_LEN);
        assert_eq!(LeaderShare::read(&v), Some(l));
        assert_eq!(LeaderShare::read(&v[..4]), None);
    }
}
