//! What the plant tells each spacecraft every step, and what a spacecraft publishes (the
//! message list of our reading of "Neural-Rendezvous", arXiv:2208.04883, Sec. 6).
//!
//! Readings (23 values, SI units):
//!
//! | index | values | what |
//! |-------|--------|------|
//! | 0–5   | 6 | x̂ = [p̂; ṗ̂]: own state relative to the ISO, in the LVLH frame of the *estimated* ISO, m and m/s |
//! | 6–8   | 3 | ISO position estimate r̂, heliocentric inertial, m |
//! | 9–11  | 3 | ISO velocity estimate v̂, m/s |
//! | 12    | 1 | own mass m, kg (propellant accounting: exact) |
//! | 13–16 | 4 | navigation σ(t): position along-/cross-track (m), velocity along-/cross-track (m/s), per body |
//! | 17    | 1 | t_f, s |
//! | 18–20 | 3 | ρ_f, desired terminal position relative to the ISO (LVLH), m |
//! | 21    | 1 | u_max, per-axis thrust limit, N |
//! | 22    | 1 | I_sp, s |
//!
//! Departure: the mission constants (t_f, ρ_f, u_max, I_sp) ride on the readings, so the plant's
//! section is their one source (an uplinked mission definition) and the agent's configuration
//! cannot disagree with it.
//!
//! Command: u in heliocentric inertial axes, N (3 values): the agent turns its LVLH command into
//! inertial axes with its own estimate of the frame, so the plant applies what it meant.
//!
//! Share values: [mode, ‖u* − u_ℓ‖ (N), V = m‖s‖² (kg m²/s²), b_e (m)] — no agent–agent traffic.

use crate::iso::dynamics::lvlh::X6;
use crate::iso::dynamics::navigation::Sigma;
use crate::iso::dynamics::two_body::{Inertial, V3};

pub const READINGS_LEN: usize = 23;
pub const COMMAND_LEN: usize = 3;
pub const SHARE_LEN: usize = 4;

/// One step's readings, parsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    pub x_hat: X6,
    pub iso_hat: Inertial,
    pub m_kg: f64,
    pub sigma: Sigma,
    pub t_f_s: f64,
    pub rho_f_m: V3,
    pub u_max_n: f64,
    pub isp_s: f64,
}

fn v3(s: &[f64]) -> V3 {
    V3::new(s[0], s[1], s[2])
}

impl Reading {
    pub fn write(&self, out: &mut Vec<f64>) {
        out.extend(self.x_hat.iter());
        out.extend(self.iso_hat.r_m.iter());
        out.extend(self.iso_hat.v_mps.iter());
        out.push(self.m_kg);
        let s = &self.sigma;
        out.extend([s.pos_along_m, s.pos_cross_m, s.vel_along_mps, s.vel_cross_mps]);
        out.push(self.t_f_s);
        out.extend(self.rho_f_m.iter());
        out.extend([self.u_max_n, self.isp_s]);
    }

    /// Check length, finiteness and signs; the reason names what is wrong.
    pub fn parse(r: &[f64]) -> Result<Self, String> {
        if r.len() != READINGS_LEN {
            return Err(format!("{} readings, expected {READINGS_LEN} (iso-encounter plant)", r.len()));
        }
        if let Some(i) = r.iter().position(|x| !x.is_finite()) {
            return Err(format!("reading {i} is not finite"));
        }
        let out = Self {
            x_hat: X6::from_column_slice(&r[0..6]),
            iso_hat: Inertial::new(v3(&r[6..9]), v3(&r[9..12])),
            m_kg: r[12],
            sigma: Sigma { pos_along_m: r[13], pos_cross_m: r[14], vel_along_mps: r[15], vel_cross_mps: r[16] },
            t_f_s: r[17],
            rho_f_m: v3(&r[18..21]),
            u_max_n: r[21],
            isp_s: r[22],
        };
        if out.m_kg <= 0.0 || out.t_f_s <= 0.0 || out.u_max_n <= 0.0 || out.isp_s <= 0.0 {
            return Err("mass, t_f, u_max and I_sp must be positive".into());
        }
        if r[13..17].iter().any(|s| *s < 0.0) {
            return Err("a navigation σ is negative".into());
        }
        Ok(out)
    }
}
