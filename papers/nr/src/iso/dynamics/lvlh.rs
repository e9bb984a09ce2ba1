//! The ISO's LVLH frame (x radial, y along-track, z orbit normal) and the orbital quantities of
//! the relative dynamics (2) of "Neural-Rendezvous" (arXiv:2208.04883): the radius r, its rate ṙ,
//! the true-anomaly rate ḟ = h/r² and its rate f̈ = −2ṙḟ/r (reference [23] of the paper).
//! Conversions between a spacecraft's inertial state and its state x = [p; ṗ] relative to the ISO
//! in that frame (ṗ is the rate seen in the rotating frame).

use nalgebra::{Matrix3, Vector6};

use crate::iso::dynamics::two_body::{Inertial, Lvlh, V3};

/// x = [p; ṗ]: position (m) and its rate in the rotating frame (m/s).
pub type X6 = Vector6<f64>;

/// The scalars of the ISO's orbit the relative dynamics need (œ of the paper, reduced to what
/// (2) reads).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitRates {
    pub r_m: f64,
    pub rdot_mps: f64,
    pub fdot_radps: f64,
    pub fddot_radps2: f64,
}

impl OrbitRates {
    pub fn of(iso: &Inertial) -> Self {
        let r_m = iso.r_m.norm();
        let rdot_mps = iso.r_m.dot(&iso.v_mps) / r_m;
        let fdot_radps = iso.r_m.cross(&iso.v_mps).norm() / (r_m * r_m);
        Self { r_m, rdot_mps, fdot_radps, fddot_radps2: -2.0 * rdot_mps * fdot_radps / r_m }
    }
}

/// The ISO's LVLH frame at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsoFrame {
    pub lvlh: Lvlh,
    pub rates: OrbitRates,
}

impl IsoFrame {
    pub fn of(iso: &Inertial) -> Self {
        Self { lvlh: iso.lvlh(), rates: OrbitRates::of(iso) }
    }

    /// LVLH → inertial rotation (columns: radial, along-track, normal unit vectors).
    pub fn rot(&self) -> &Matrix3<f64> {
        &self.lvlh.rot
    }

    /// A spacecraft's inertial state as x = [p; ṗ] relative to the ISO in this frame.
    pub fn relative(&self, sc: &Inertial) -> X6 {
        let p = self.lvlh.position(&sc.r_m);
        let q = self.lvlh.velocity(&sc.r_m, &sc.v_mps);
        X6::new(p.x, p.y, p.z, q.x, q.y, q.z)
    }

    /// The inertial state of the spacecraft at x relative to the ISO.
    pub fn inertial(&self, x: &X6) -> Inertial {
        let p = V3::new(x[0], x[1], x[2]);
        let q = V3::new(x[3], x[4], x[5]);
        let r = self.lvlh.origin_r + self.lvlh.rot * p;
        let v = self.lvlh.origin_v + self.lvlh.rot * (q + self.lvlh.omega.cross(&p));
        Inertial::new(r, v)
    }

    /// An LVLH vector in inertial axes.
    pub fn to_inertial(&self, v: &V3) -> V3 {
        self.lvlh.rot * v
    }

    /// An inertial vector in LVLH axes.
    pub fn to_lvlh(&self, v: &V3) -> V3 {
        self.lvlh.rot.transpose() * v
    }
}

/// Position and velocity parts of x.
pub fn pos(x: &X6) -> V3 {
    V3::new(x[0], x[1], x[2])
}
pub fn vel(x: &X6) -> V3 {
    V3::new(x[3], x[4], x[5])
}
pub fn join(p: &V3, q: &V3) -> X6 {
    X6::new(p.x, p.y, p.z, q.x, q.y, q.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::{AU_M, MU_SUN_M3PS2};

    fn iso() -> Inertial {
        Inertial::new(V3::new(1.2 * AU_M, 0.3 * AU_M, 0.1 * AU_M), V3::new(-20e3, 35e3, 15e3))
    }

    #[test]
    fn relative_and_inertial_are_inverse() {
        let f = IsoFrame::of(&iso());
        let sc = Inertial::new(iso().r_m + V3::new(3e9, -1e9, 2e8), iso().v_mps + V3::new(-30e3, 12e3, 1e3));
        let back = f.inertial(&f.relative(&sc));
        assert!((back.r_m - sc.r_m).norm() < 1e-4, "{}", (back.r_m - sc.r_m).norm());
        assert!((back.v_mps - sc.v_mps).norm() < 1e-9);
    }

    #[test]
    fn rates_match_their_definitions() {
        let s = iso();
        let o = OrbitRates::of(&s);
        // ḟ by finite differences of the radial direction's angle in the orbit plane.
        let h = 10.0;
        let (a, b) = (s.coast(-h, 1), s.coast(h, 1));
        let (ra, rb) = (a.r_m.normalize(), b.r_m.normalize());
        let fdot_fd = ra.cross(&rb).norm().atan2(ra.dot(&rb)) / (2.0 * h);
        assert!((fdot_fd / o.fdot_radps - 1.0).abs() < 1e-6, "{fdot_fd} vs {}", o.fdot_radps);
        let (oa, ob) = (OrbitRates::of(&a), OrbitRates::of(&b));
        let fddot_fd = (ob.fdot_radps - oa.fdot_radps) / (2.0 * h);
        assert!((fddot_fd / o.fddot_radps2 - 1.0).abs() < 1e-5, "{fddot_fd} vs {}", o.fddot_radps2);
        let rddot = (ob.rdot_mps - oa.rdot_mps) / (2.0 * h);
        // r̈ = r ḟ² − μ/r² for a Keplerian orbit.
        let want = o.r_m * o.fdot_radps.powi(2) - MU_SUN_M3PS2 / o.r_m.powi(2);
        assert!((rddot / want - 1.0).abs() < 1e-6, "{rddot} vs {want}");
    }
}
