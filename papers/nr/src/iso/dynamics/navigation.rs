//! Navigation of Sec. 6.2.1 of "Neural-Rendezvous" (arXiv:2208.04883): each body's estimated
//! absolute state is drawn about the truth, x̂ ~ N(x, P(t)), with P(t) decaying exponentially in
//! time (Example 1). The standard deviations are given along-track (the body's own velocity
//! direction) and cross-track (the two directions normal to it: orbit normal and the third
//! axis), for position and velocity.
//!
//! The printed values are lost. Ours (reference values, scenario keys): position along-track
//! 100 km → 10 m, cross-track 10 km → 1 m; velocity along-track 1 m/s → 1 mm/s, cross-track
//! 0.1 m/s → 0.1 mm/s, from t = 0 to t_f, log-linear in between (σ(t) = σ₀ (σ_f/σ₀)^{t/t_f}, an
//! exponential decay), all times a scale `nav_scale` (0: perfect navigation). Departure: the
//! errors are drawn independently at every step (white), not from a filter, as the reference
//! fixes; the same σ(t) shapes the initial dispersion of the truth about the ideal trajectory.

use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::iso::dynamics::two_body::{Inertial, V3};

/// Start and end value of one standard deviation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Decay {
    /// At t = 0.
    pub start: f64,
    /// At t = t_f.
    pub end: f64,
}

impl Decay {
    /// Log-linear between the two values; held outside [0, t_f].
    pub fn at(&self, t_s: f64, t_f_s: f64) -> f64 {
        let f = (t_s / t_f_s).clamp(0.0, 1.0);
        self.start * (self.end / self.start).powf(f)
    }
}

/// The four standard deviations of Sec. 6.2.1 (keys `plant.nav.*`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NavSigmas {
    /// Position along-track, m.
    #[serde(default = "d_pos_along")]
    pub pos_along_m: Decay,
    /// Position cross-track (each of the two axes), m.
    #[serde(default = "d_pos_cross")]
    pub pos_cross_m: Decay,
    /// Velocity along-track, m/s.
    #[serde(default = "d_vel_along")]
    pub vel_along_mps: Decay,
    /// Velocity cross-track (each of the two axes), m/s.
    #[serde(default = "d_vel_cross")]
    pub vel_cross_mps: Decay,
}

fn d_pos_along() -> Decay {
    Decay { start: 100e3, end: 10.0 }
}
fn d_pos_cross() -> Decay {
    Decay { start: 10e3, end: 1.0 }
}
fn d_vel_along() -> Decay {
    Decay { start: 1.0, end: 1e-3 }
}
fn d_vel_cross() -> Decay {
    Decay { start: 0.1, end: 1e-4 }
}

impl Default for NavSigmas {
    fn default() -> Self {
        Self {
            pos_along_m: d_pos_along(),
            pos_cross_m: d_pos_cross(),
            vel_along_mps: d_vel_along(),
            vel_cross_mps: d_vel_cross(),
        }
    }
}

/// The standard deviations at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Sigma {
    pub pos_along_m: f64,
    pub pos_cross_m: f64,
    pub vel_along_mps: f64,
    pub vel_cross_mps: f64,
}

impl NavSigmas {
    pub fn at(&self, t_s: f64, t_f_s: f64, scale: f64) -> Sigma {
        Sigma {
            pos_along_m: scale * self.pos_along_m.at(t_s, t_f_s),
            pos_cross_m: scale * self.pos_cross_m.at(t_s, t_f_s),
            vel_along_mps: scale * self.vel_along_mps.at(t_s, t_f_s),
            vel_cross_mps: scale * self.vel_cross_mps.at(t_s, t_f_s),
        }
    }
}

impl Sigma {
    /// RMS norm of one body's position error, √(σ_a² + 2σ_c²), m.
    pub fn pos_rms_m(&self) -> f64 {
        (self.pos_along_m.powi(2) + 2.0 * self.pos_cross_m.powi(2)).sqrt()
    }
    /// RMS norm of one body's velocity error, m/s.
    pub fn vel_rms_mps(&self) -> f64 {
        (self.vel_along_mps.powi(2) + 2.0 * self.vel_cross_mps.powi(2)).sqrt()
    }
}

/// Along-track, orbit-normal and third (completing) unit vectors of a body.
fn axes(body: &Inertial) -> [V3; 3] {
    let along = body.v_mps.normalize();
    let normal = body.r_m.cross(&body.v_mps).normalize();
    [along, normal, along.cross(&normal)]
}

/// One draw of a body's state about the truth: six standard normals from `rng`, in the order
/// position (along, normal, third), velocity (along, normal, third).
pub fn draw(body: &Inertial, s: &Sigma, rng: &mut impl Rng) -> Inertial {
    let [a, n, c] = axes(body);
    let mut g = || -> f64 { rng.sample(StandardNormal) };
    let dp = s.pos_along_m * g() * a + s.pos_cross_m * g() * n + s.pos_cross_m * g() * c;
    let dv = s.vel_along_mps * g() * a + s.vel_cross_mps * g() * n + s.vel_cross_mps * g() * c;
    Inertial::new(body.r_m + dp, body.v_mps + dv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn sigmas_decay_log_linearly_from_start_to_end() {
        let n = NavSigmas::default();
        let (s0, sh, sf) = (n.at(0.0, 100.0, 1.0), n.at(50.0, 100.0, 1.0), n.at(100.0, 100.0, 2.0));
        assert_eq!(s0.pos_along_m, 100e3);
        assert!((sh.pos_along_m - 1000.0).abs() < 1e-9, "{}", sh.pos_along_m);
        assert!((sf.vel_cross_mps - 2e-4).abs() < 1e-15);
        assert_eq!(n.at(0.0, 100.0, 0.0).pos_along_m, 0.0);
    }

    #[test]
    fn draws_have_the_stated_spread_along_and_across_track() {
        let body = Inertial::new(V3::new(1e11, 2e10, 0.0), V3::new(-3e3, 30e3, 2e3));
        let s = Sigma { pos_along_m: 100.0, pos_cross_m: 10.0, vel_along_mps: 1.0, vel_cross_mps: 0.1 };
        let [a, nrm, c] = axes(&body);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 20_000;
        let (mut sa, mut sn, mut sc, mut va) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let d = draw(&body, &s, &mut rng);
            let (dp, dv) = (d.r_m - body.r_m, d.v_mps - body.v_mps);
            sa += dp.dot(&a).powi(2);
            sn += dp.dot(&nrm).powi(2);
            sc += dp.dot(&c).powi(2);
            va += dv.dot(&a).powi(2);
        }
        let rms = |x: f64| (x / n as f64).sqrt();
        assert!((rms(sa) / 100.0 - 1.0).abs() < 0.03, "{}", rms(sa));
        assert!((rms(sn) / 10.0 - 1.0).abs() < 0.03, "{}", rms(sn));
        assert!((rms(sc) / 10.0 - 1.0).abs() < 0.03, "{}", rms(sc));
        assert!((rms(va) - 1.0).abs() < 0.03, "{}", rms(va));
    }
}
