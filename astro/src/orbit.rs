//! Orbital mechanics: Earth's gravity (two-body + J2), drag with an exponential atmosphere,
//! fixed-step RK4 in ECI, Keplerian propagation of a reference orbit, and the LVLH (Hill) frame.
//! Conventions are Basilisk's (exponential atmosphere, spherical harmonics), so a plant built on
//! them can be cross-checked against it (the Lb-DNN servicing paper's plant is).

use nalgebra::{Matrix3, Vector3};

pub type V3 = Vector3<f64>;

/// Earth's gravitational parameter, m³/s².
pub const MU_EARTH_M3PS2: f64 = 3.986004418e14;
/// Earth's equatorial radius, m.
pub const R_EARTH_M: f64 = 6_378_137.0;
/// Earth's J2 (unnormalised).
pub const J2_EARTH: f64 = 1.08262668e-3;
/// Exponential atmosphere: ρ(h) = ρ₀ exp(−h / H), h above R_EARTH_M.
pub const ATMO_BASE_DENSITY_KGPM3: f64 = 6.500_396_690_704_936e-9;
pub const ATMO_SCALE_HEIGHT_M: f64 = 53_628.0;

/// A body's physical properties as the force models see them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyProps {
    pub mass_kg: f64,
    pub area_m2: f64,
    pub drag_coeff: f64,
}

/// Accelerations acting on a body, other than its commanded thrust (dynamics behind a trait).
pub trait ForceModel: Send + Sync {
    /// Acceleration in ECI, m/s², at position `r` and inertial velocity `v`. `density` is the
    /// atmospheric density held over the current integration step (see [`DensityHold`]).
    fn accel(&self, r: &V3, v: &V3, body: &BodyProps, density_kgpm3: f64) -> V3;
    /// Density at `r` (0 for models without an atmosphere).
    fn density(&self, r: &V3) -> f64;
}

/// Two-body gravity, optionally with J2 and drag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EarthForces {
    pub mu_m3ps2: f64,
    pub j2: f64,
    pub drag: bool,
}

impl EarthForces {
    pub fn full() -> Self {
        Self { mu_m3ps2: MU_EARTH_M3PS2, j2: J2_EARTH, drag: true }
    }
    pub fn two_body() -> Self {
        Self { mu_m3ps2: MU_EARTH_M3PS2, j2: 0.0, drag: false }
    }
}

impl ForceModel for EarthForces {
    fn accel(&self, r: &V3, v: &V3, body: &BodyProps, density_kgpm3: f64) -> V3 {
        let r2 = r.norm_squared();
        let rn = r2.sqrt();
        let mut a = -self.mu_m3ps2 / (r2 * rn) * r;
        if self.j2 != 0.0 {
            // a_J2 = −(3/2) J2 μ Rₑ² / r⁵ · [x(1 − 5z²/r²), y(1 − 5z²/r²), z(3 − 5z²/r²)]
            let k = -1.5 * self.j2 * self.mu_m3ps2 * R_EARTH_M * R_EARTH_M / (r2 * r2 * rn);
            let zz = 5.0 * r.z * r.z / r2;
            a += k * V3::new(r.x * (1.0 - zz), r.y * (1.0 - zz), r.z * (3.0 - zz));
        }
        if self.drag && density_kgpm3 > 0.0 {
            // a = −½ ρ C_D (A/m) |v| v, inertial velocity (Basilisk's dragDynamicEffector).
            a -= 0.5 * density_kgpm3 * body.drag_coeff * body.area_m2 / body.mass_kg * v.norm() * v;
        }
        a
    }
    fn density(&self, r: &V3) -> f64 {
        if self.drag { ATMO_BASE_DENSITY_KGPM3 * (-(r.norm() - R_EARTH_M) / ATMO_SCALE_HEIGHT_M).exp() } else { 0.0 }
    }
}

/// When the atmospheric density is evaluated during an RK4 step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DensityHold {
    /// Once, at the start of the step, held through the four stages (Basilisk's convention: its
    /// atmosphere module updates once per task step).
    Step,
    /// At every stage's position.
    Stage,
}

/// One RK4 step of a body's ECI state with an extra acceleration `thrust(t_offset)` (the command
/// rotated to ECI at the stage time).
pub fn rk4_step(
    forces: &dyn ForceModel,
    body: &BodyProps,
    hold: DensityHold,
    r: &mut V3,
    v: &mut V3,
    dt_s: f64,
    thrust: &dyn Fn(f64) -> V3,
) {
    let rho0 = forces.density(r);
    let rho = |x: &V3| match hold {
        DensityHold::Step => rho0,
        DensityHold::Stage => forces.density(x),
    };
    let h = dt_s;
    let (r0, v0) = (*r, *v);
    let a1 = forces.accel(&r0, &v0, body, rho0) + thrust(0.0);
    let (r2, v2) = (r0 + 0.5 * h * v0, v0 + 0.5 * h * a1);
    let a2 = forces.accel(&r2, &v2, body, rho(&r2)) + thrust(0.5 * h);
    let (r3, v3) = (r0 + 0.5 * h * v2, v0 + 0.5 * h * a2);
    let a3 = forces.accel(&r3, &v3, body, rho(&r3)) + thrust(0.5 * h);
    let (r4, v4) = (r0 + h * v3, v0 + h * a3);
    let a4 = forces.accel(&r4, &v4, body, rho(&r4)) + thrust(h);
    *r = r0 + h / 6.0 * (v0 + 2.0 * v2 + 2.0 * v3 + v4);
    *v = v0 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
}

/// A Keplerian orbit propagated analytically from an epoch state (Lagrange f and g with the
/// eccentric-anomaly difference: valid for every ellipse, circular included).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeplerOrbit {
    pub r0: V3,
    pub v0: V3,
    pub mu_m3ps2: f64,
    a_m: f64,
    n_radps: f64,
    sigma0: f64,
    r0n: f64,
}

impl KeplerOrbit {
    /// `None` when the state is not on an ellipse (energy ≥ 0).
    pub fn new(r0: V3, v0: V3, mu_m3ps2: f64) -> Option<Self> {
        let r0n = r0.norm();
        let energy = 0.5 * v0.norm_squared() - mu_m3ps2 / r0n;
        if energy >= 0.0 || !energy.is_finite() {
            return None;
        }
        let a_m = -mu_m3ps2 / (2.0 * energy);
        Some(Self { r0, v0, mu_m3ps2, a_m, n_radps: (mu_m3ps2 / a_m.powi(3)).sqrt(), sigma0: r0.dot(&v0), r0n })
    }
    pub fn period_s(&self) -> f64 {
        std::f64::consts::TAU / self.n_radps
    }
    /// Position and velocity at `t_s` after the epoch.
    pub fn state(&self, t_s: f64) -> (V3, V3) {
        let (a, mu) = (self.a_m, self.mu_m3ps2);
        let sqa_mu = (a / mu).sqrt();
        let s = self.sigma0 / (mu * a).sqrt();
        let c = 1.0 - self.r0n / a;
        // Kepler's equation in ΔE: n t = ΔE + s (1 − cos ΔE) − c sin ΔE, solved by Newton.
        let m = self.n_radps * t_s;
        let mut de = m;
        for _ in 0..50 {
            let (sn, cs) = de.sin_cos();
            let f = de + s * (1.0 - cs) - c * sn - m;
            let fp = 1.0 + s * sn - c * cs;
            let step = f / fp;
            de -= step;
            if step.abs() < 1e-15 * (1.0 + de.abs()) {
                break;
            }
        }
        let (sn, cs) = de.sin_cos();
        let r = a + (self.r0n - a) * cs + self.sigma0 * sqa_mu * sn;
        let f = 1.0 - a / self.r0n * (1.0 - cs);
        let g = t_s - (a * a * a / mu).sqrt() * (de - sn);
        let fdot = -(mu * a).sqrt() / (r * self.r0n) * sn;
        let gdot = 1.0 - a / r * (1.0 - cs);
        (f * self.r0 + g * self.v0, fdot * self.r0 + gdot * self.v0)
    }
}

/// The LVLH (Hill) frame of an orbiting point: x radial, z along the orbit normal, y = z × x
/// (in-track). `rot` has the frame's unit vectors as columns (LVLH → ECI); `omega` is the frame's
/// angular velocity expressed in LVLH.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lvlh {
    pub origin_r: V3,
    pub origin_v: V3,
    pub rot: Matrix3<f64>,
    pub omega: V3,
}

impl Lvlh {
    pub fn of(r: &V3, v: &V3) -> Self {
        let h = r.cross(v);
        let x = r.normalize();
        let z = h.normalize();
        let y = z.cross(&x);
        let rot = Matrix3::from_columns(&[x, y, z]);
        // For a Keplerian point the frame turns about z at |h|/r².
        let omega = V3::new(0.0, 0.0, h.norm() / r.norm_squared());
        Self { origin_r: *r, origin_v: *v, rot, omega }
    }
    /// Coordinates of an ECI position in this frame, relative to its origin.
    pub fn position(&self, r: &V3) -> V3 {
        self.rot.transpose() * (r - self.origin_r)
    }
    /// Rate of change of those coordinates (velocity as seen in the rotating frame).
    pub fn velocity(&self, r: &V3, v: &V3) -> V3 {
        let q = self.position(r);
        self.rot.transpose() * (v - self.origin_v) - self.omega.cross(&q)
    }
    pub fn to_eci(&self, x: &V3) -> V3 {
        self.rot * x
    }
}

/// Periapsis state of an orbit given by periapsis/apoapsis radii, inclination, RAAN and argument
/// of periapsis (true anomaly 0), speed from vis-viva.
pub fn periapsis_state(rp_m: f64, ra_m: f64, inc_rad: f64, raan_rad: f64, argp_rad: f64, mu: f64) -> (V3, V3) {
    let a = 0.5 * (rp_m + ra_m);
    let vp = (mu * (2.0 / rp_m - 1.0 / a)).sqrt();
    // Perifocal → ECI: R3(−Ω) R1(−i) R3(−ω).
    let rot = Matrix3::new(raan_rad.cos(), -raan_rad.sin(), 0.0, raan_rad.sin(), raan_rad.cos(), 0.0, 0.0, 0.0, 1.0)
        * Matrix3::new(1.0, 0.0, 0.0, 0.0, inc_rad.cos(), -inc_rad.sin(), 0.0, inc_rad.sin(), inc_rad.cos())
        * Matrix3::new(argp_rad.cos(), -argp_rad.sin(), 0.0, argp_rad.sin(), argp_rad.cos(), 0.0, 0.0, 0.0, 1.0);
    (rot * V3::new(rp_m, 0.0, 0.0), rot * V3::new(0.0, vp, 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    const BODY: BodyProps = BodyProps { mass_kg: 100.0, area_m2: 1.0, drag_coeff: 2.2 };

    fn leo() -> (V3, V3) {
        periapsis_state(R_EARTH_M + 300e3, R_EARTH_M + 700e3, std::f64::consts::FRAC_PI_6, 0.0, 0.0, MU_EARTH_M3PS2)
    }

    fn propagate(forces: &EarthForces, r: &mut V3, v: &mut V3, dt: f64, steps: usize) {
        for _ in 0..steps {
            rk4_step(forces, &BODY, DensityHold::Step, r, v, dt, &|_| V3::zeros());
        }
    }

    #[test]
    fn two_body_conserves_energy_and_angular_momentum_over_an_orbit() {
        let (mut r, mut v) = leo();
        let kep = KeplerOrbit::new(r, v, MU_EARTH_M3PS2).unwrap();
        let energy = |r: &V3, v: &V3| 0.5 * v.norm_squared() - MU_EARTH_M3PS2 / r.norm();
        let (e0, h0) = (energy(&r, &v), r.cross(&v));
        let dt = 0.5;
        let steps = (kep.period_s() / dt).round() as usize;
        propagate(&EarthForces::two_body(), &mut r, &mut v, dt, steps);
        let de = ((energy(&r, &v) - e0) / e0).abs();
        let dh = (r.cross(&v) - h0).norm() / h0.norm();
        assert!(de <= 1e-9, "relative energy drift {de:e}");
        assert!(dh <= 1e-9, "relative angular-momentum drift {dh:e}");
    }

    #[test]
    fn kepler_propagation_matches_numerical_two_body() {
        let (mut r, mut v) = leo();
        let kep = KeplerOrbit::new(r, v, MU_EARTH_M3PS2).unwrap();
        propagate(&EarthForces::two_body(), &mut r, &mut v, 0.1, 36_000);
        let (rk, vk) = kep.state(3600.0);
        assert!((r - rk).norm() < 1e-3, "position differs by {} m", (r - rk).norm());
        assert!((v - vk).norm() < 1e-6, "velocity differs by {} m/s", (v - vk).norm());
        // And a full period returns to the start.
        let (rp, _) = kep.state(kep.period_s());
        assert!((rp - kep.r0).norm() < 1e-5, "{}", (rp - kep.r0).norm());
    }

    #[test]
    fn j2_nodal_regression_matches_the_secular_rate() {
        let (r0, v0) = leo();
        let forces = EarthForces { mu_m3ps2: MU_EARTH_M3PS2, j2: J2_EARTH, drag: false };
        let kep = KeplerOrbit::new(r0, v0, MU_EARTH_M3PS2).unwrap();
        let (period, dt) = (kep.period_s(), 1.0);
        let raan = |r: &V3, v: &V3| {
            let h = r.cross(v);
            h.x.atan2(-h.y)
        };
        // Osculating RAAN sampled once per Keplerian period (short-period terms nearly repeat),
        // straight-line fit over 10 orbits.
        let (mut r, mut v) = (r0, v0);
        let mut samples = vec![(0.0, raan(&r, &v))];
        let mut t = 0.0;
        for k in 1..=10 {
            let target = k as f64 * period;
            while t + dt <= target {
                propagate(&forces, &mut r, &mut v, dt, 1);
                t += dt;
            }
            propagate(&forces, &mut r, &mut v, target - t, 1);
            t = target;
            samples.push((t, raan(&r, &v)));
        }
        let n = samples.len() as f64;
        let (st, sy) = samples.iter().fold((0.0, 0.0), |(a, b), (t, y)| (a + t, b + y));
        let (mt, my) = (st / n, sy / n);
        let num: f64 = samples.iter().map(|(t, y)| (t - mt) * (y - my)).sum();
        let den: f64 = samples.iter().map(|(t, _)| (t - mt).powi(2)).sum();
        let rate = num / den;
        let a = 0.5 * (2.0 * R_EARTH_M + 1000e3);
        let e = 200e3 / a;
        let p = a * (1.0 - e * e);
        let nmean = (MU_EARTH_M3PS2 / a.powi(3)).sqrt();
        let secular = -1.5 * nmean * J2_EARTH * (R_EARTH_M / p).powi(2) * std::f64::consts::FRAC_PI_6.cos();
        let rel = (rate - secular).abs() / secular.abs();
        assert!(rel <= 0.01, "RAAN rate {rate:e} rad/s vs secular {secular:e} ({:.3} %)", rel * 100.0);
    }

    #[test]
    fn drag_takes_energy_and_density_matches_the_model() {
        let forces = EarthForces::full();
        let r300 = V3::new(R_EARTH_M + 300e3, 0.0, 0.0);
        let rho = forces.density(&r300);
        assert!((rho - 2.42e-11).abs() / 2.42e-11 < 0.01, "ρ(300 km) = {rho:e}");
        let v = V3::new(0.0, 7700.0, 0.0);
        let a =
            forces.accel(&r300, &v, &BODY, rho) - EarthForces { drag: false, ..forces }.accel(&r300, &v, &BODY, rho);
        let want = -0.5 * rho * 2.2 * 1.0 / 100.0 * 7700.0 * 7700.0;
        assert!((a.y - want).abs() < 1e-15 && a.x == 0.0 && a.z == 0.0, "{a:?}");
    }

    #[test]
    fn lvlh_coordinates_of_a_co_moving_point_are_constant() {
        let (r, v) = leo();
        let kep = KeplerOrbit::new(r, v, MU_EARTH_M3PS2).unwrap();
        let f0 = Lvlh::of(&r, &v);
        // The frame's origin has zero coordinates and zero coordinate rate.
        assert!(f0.position(&r).norm() < 1e-9 && f0.velocity(&r, &v).norm() < 1e-12);
        // A point 100 m radially out moving with the frame (v + ω × offset) has zero coordinate rate.
        let off = f0.to_eci(&V3::new(100.0, 0.0, 0.0));
        let vv = v + f0.to_eci(&f0.omega.cross(&V3::new(100.0, 0.0, 0.0)));
        assert!(f0.velocity(&(r + off), &vv).norm() < 1e-9);
        let (r1, v1) = kep.state(10.0);
        let f1 = Lvlh::of(&r1, &v1);
        assert!((f1.rot.transpose() * f1.rot - Matrix3::identity()).norm() < 1e-12);
    }
}
