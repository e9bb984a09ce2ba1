//! Initial orbits from the Keplerian elements of Table D.9 (a = 45 300 km, i = 0.34°, Ω = 0,
//! ω = 4.6743°, eccentricity 0.7125 for the leader and 0.7336 for the follower).
//!
//! Where the paper is silent or inconsistent:
//! - Table D.9 gives no anomaly: the leader starts at a configured true anomaly (default 180°,
//!   apogee, where the science phase and the Sec. 7 case take place).
//! - The Sec. 7 case starts the follower at r_rel(0) = [1, 2, 10] km, v_rel(0) = [1, 1, 1] m/s from
//!   the leader (91)–(90), which is not on the follower orbit of Table D.9 (at the same anomaly the
//!   two orbits are ≈ 950 km apart at apogee): `FollowerStart::Relative` (default) places it so;
//!   `FollowerStart::Elements` puts it on its own Table D.9 orbit at the leader's true anomaly.
//! - a = 45 300 km gives a period of 2π√(a³/μ) = 95 953 s = 26.65 h, not the 32.5 h the paper
//!   quotes (that needs a ≈ 51 700 km). The plant flies Table D.9; see the crate README.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::model::orbit::{OrbitPair, V3};

/// Classical elements of an ellipse, SI and radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Elements {
    pub a_m: f64,
    pub e: f64,
    pub inc_rad: f64,
    pub raan_rad: f64,
    pub argp_rad: f64,
    pub true_anomaly_rad: f64,
}

/// Perifocal → ECI: R3(−Ω) R1(−i) R3(−ω).
fn perifocal_to_eci(inc: f64, raan: f64, argp: f64) -> Matrix3<f64> {
    let r3 = |x: f64| Matrix3::new(x.cos(), -x.sin(), 0.0, x.sin(), x.cos(), 0.0, 0.0, 0.0, 1.0);
    let r1 = Matrix3::new(1.0, 0.0, 0.0, 0.0, inc.cos(), -inc.sin(), 0.0, inc.sin(), inc.cos());
    r3(raan) * r1 * r3(argp)
}

/// ECI position and velocity of the elements.
pub fn state_from_elements(el: &Elements, mu_m3ps2: f64) -> (V3, V3) {
    let p = el.a_m * (1.0 - el.e * el.e);
    let (s, c) = el.true_anomaly_rad.sin_cos();
    let r = p / (1.0 + el.e * c);
    let r_pf = V3::new(r * c, r * s, 0.0);
    let v_pf = (mu_m3ps2 / p).sqrt() * V3::new(-s, el.e + c, 0.0);
    let m = perifocal_to_eci(el.inc_rad, el.raan_rad, el.argp_rad);
    (m * r_pf, m * v_pf)
}

/// The Keplerian period 2π√(a³/μ), s.
pub fn kepler_period_s(a_m: f64, mu_m3ps2: f64) -> f64 {
    std::f64::consts::TAU * (a_m.powi(3) / mu_m3ps2).sqrt()
}

/// Where the follower starts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FollowerStart {
    /// r_F = r_L + r_rel(0), v_F = v_L + v_rel(0) (Sec. 7).
    Relative,
    /// On its own Table D.9 orbit at the leader's true anomaly.
    Elements,
}

/// Both orbits at t = 0.
pub fn initial_pair(
    leader: &Elements,
    e_follower: f64,
    start: FollowerStart,
    r_rel0_eci_m: &V3,
    v_rel0_eci_mps: &V3,
    mu_m3ps2: f64,
) -> OrbitPair {
    let (rl, vl) = state_from_elements(leader, mu_m3ps2);
    let (rr, vr) = match start {
        FollowerStart::Relative => (*r_rel0_eci_m, *v_rel0_eci_mps),
        FollowerStart::Elements => {
            let (rf, vf) = state_from_elements(&Elements { e: e_follower, ..*leader }, mu_m3ps2);
            (rf - rl, vf - vl)
        }
    };
    OrbitPair { r_leader_eci_m: rl, v_leader_eci_mps: vl, r_rel_eci_m: rr, v_rel_eci_mps: vr }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::orbit::{Gravity, MU_EARTH_M3PS2, generic_periapsis_state};

    fn table_d9(e: f64, nu: f64) -> Elements {
        Elements {
            a_m: 45_300e3,
            e,
            inc_rad: 0.34f64.to_radians(),
            raan_rad: 0.0,
            argp_rad: 4.6743f64.to_radians(),
            true_anomaly_rad: nu,
        }
    }

    #[test]
    fn periapsis_state_matches_the_generic_module() {
        let el = table_d9(0.7125, 0.0);
        let (r, v) = state_from_elements(&el, MU_EARTH_M3PS2);
        let (rg, vg) = generic_periapsis_state(el.a_m, el.e, el.inc_rad, el.raan_rad, el.argp_rad);
        assert!((r - rg).norm() < 1e-6 && (v - vg).norm() < 1e-9, "{} m, {} m/s", (r - rg).norm(), (v - vg).norm());
    }

    /// Time of the first return of the in-plane angle to its start, by RK4 at `dt_s` and a final
    /// bisection on a partial step.
    fn measured_period_s(el: &Elements, gravity: &Gravity, dt_s: f64) -> f64 {
        let (r0, v0) = state_from_elements(el, MU_EARTH_M3PS2);
        let h = r0.cross(&v0).normalize();
        let (e1, e2) = (r0.normalize(), h.cross(&r0.normalize()));
        // The angle from the start direction is 2π when the component along e2 turns from negative
        // to non-negative with a positive component along e1.
        let side = |r: &V3| r.dot(&e2);
        let mut pair = OrbitPair {
            r_leader_eci_m: r0,
            v_leader_eci_mps: v0,
            r_rel_eci_m: V3::zeros(),
            v_rel_eci_mps: V3::zeros(),
        };
        let zero = V3::zeros();
        let mut t = 0.0;
        let mut half_way = false;
        loop {
            let before = pair.clone();
            pair.rk4_step(gravity, &zero, &zero, dt_s);
            t += dt_s;
            let s = side(&pair.r_leader_eci_m);
            half_way |= s < 0.0;
            if half_way && s >= 0.0 && pair.r_leader_eci_m.dot(&e1) > 0.0 {
                let (mut lo, mut hi) = (0.0, dt_s);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    let mut p = before.clone();
                    p.rk4_step(gravity, &zero, &zero, mid);
                    if side(&p.r_leader_eci_m) >= 0.0 { hi = mid } else { lo = mid }
                }
                return t - dt_s + hi;
            }
        }
    }

    #[test]
    fn two_body_period_is_keplers_for_table_d9() {
        let el = table_d9(0.7125, 0.0);
        let want = kepler_period_s(el.a_m, MU_EARTH_M3PS2);
        let got = measured_period_s(&el, &Gravity::earth(false), 1.0);
        let rel = (got - want).abs() / want;
        assert!(rel < 1e-6, "period {got} s vs 2π√(a³/μ) = {want} s (rel {rel:e})");
        // 26.65 h, not the paper's 32.5 h.
        assert!((want / 3600.0 - 26.65).abs() < 0.01, "{} h", want / 3600.0);
    }

    #[test]
    fn relative_start_is_the_sec7_offset_and_elements_start_is_on_the_follower_orbit() {
        let el = table_d9(0.7125, std::f64::consts::PI);
        let (dr, dv) = (V3::new(1e3, 2e3, 10e3), V3::new(1.0, 1.0, 1.0));
        let p = initial_pair(&el, 0.7336, FollowerStart::Relative, &dr, &dv, MU_EARTH_M3PS2);
        assert_eq!((p.r_rel_eci_m, p.v_rel_eci_mps), (dr, dv));
        let q = initial_pair(&el, 0.7336, FollowerStart::Elements, &dr, &dv, MU_EARTH_M3PS2);
        let ra = |e: f64| 45_300e3 * (1.0 + e);
        assert!((q.r_follower_eci_m().norm() - ra(0.7336)).abs() < 1e-6);
        assert!((q.r_leader_eci_m.norm() - ra(0.7125)).abs() < 1e-6);
    }
}
