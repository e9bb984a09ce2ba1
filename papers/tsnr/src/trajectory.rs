//! Desired MU trajectories x_i^d(t): piecewise quintic polynomials through waypoints.
//!
//! The paper plans its capture trajectories with the method of its ref. [8], which is not in the
//! text; papers/tsnr/README.md gives our choice: quintic segments through the phases deploy (0–10 s),
//! approach (10–20 s) and close (20–30 s). Each segment matches position, velocity and
//! acceleration at both of its knots, so the trajectory is C² (no jump in the feedforward force).
//! Velocities at the knots are given with the waypoints (zero unless the scenario says otherwise —
//! the Case 2 terminal states move at [0.25, 0.43, 0] m/s); accelerations at the knots are zero.
//!
//! Outside the knots the trajectory continues at constant velocity with zero acceleration: before
//! the first knot from the first waypoint, after the last from the last one. A receding-horizon
//! controller looks up to N_p·Δt past the end of the run, and a terminal state that moves must
//! keep moving there rather than stop dead.

/// One waypoint: where the MU should be at a knot, and how fast it should move there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Waypoint {
    pub r_m: [f64; 3],
    pub v_mps: [f64; 3],
}

/// Position, velocity and acceleration of the desired trajectory at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Desired {
    pub r_m: [f64; 3],
    pub v_mps: [f64; 3],
    pub a_mps2: [f64; 3],
}

impl Desired {
    /// [r; v], the state the controllers track.
    pub fn state(&self) -> [f64; 6] {
        [self.r_m[0], self.r_m[1], self.r_m[2], self.v_mps[0], self.v_mps[1], self.v_mps[2]]
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrajectoryError {
    #[error("need at least 2 knots, got {0}")]
    TooFewKnots(usize),
    #[error("knot {index} ({t_s} s) is not after the previous one: knots must be finite and strictly increasing")]
    KnotsNotIncreasing { index: usize, t_s: f64 },
    #[error("{waypoints} waypoints for {knots} knots: one waypoint per knot")]
    WrongCount { waypoints: usize, knots: usize },
    #[error("waypoint {0} has a non-finite component")]
    NotFinite(usize),
}

/// Coefficients c₀…c₅ of p(τ) = Σ c_j τʲ, τ = t − t_start.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Quintic([f64; 6]);

impl Quintic {
    /// The quintic on [0, h] with p, p′, p″ given at both ends.
    fn new(h: f64, p0: f64, v0: f64, a0: f64, p1: f64, v1: f64, a1: f64) -> Self {
        let (h2, h3) = (h * h, h * h * h);
        // Remaining conditions after c0..c2 are fixed by the start: solve the 3×3 system in
        // closed form (standard minimum-jerk boundary-value solution).
        let d0 = p1 - (p0 + v0 * h + 0.5 * a0 * h2);
        let d1 = v1 - (v0 + a0 * h);
        let d2 = a1 - a0;
        let c3 = (10.0 * d0 - 4.0 * d1 * h + 0.5 * d2 * h2) / h3;
        let c4 = (-15.0 * d0 + 7.0 * d1 * h - d2 * h2) / (h3 * h);
        let c5 = (6.0 * d0 - 3.0 * d1 * h + 0.5 * d2 * h2) / (h3 * h2);
        Quintic([p0, v0, 0.5 * a0, c3, c4, c5])
    }

    fn eval(&self, tau: f64) -> (f64, f64, f64) {
        let c = &self.0;
        let p = c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * (c[4] + tau * c[5]))));
        let v = c[1] + tau * (2.0 * c[2] + tau * (3.0 * c[3] + tau * (4.0 * c[4] + tau * 5.0 * c[5])));
        let a = 2.0 * c[2] + tau * (6.0 * c[3] + tau * (12.0 * c[4] + tau * 20.0 * c[5]));
        (p, v, a)
    }
}

/// A piecewise-quintic trajectory through waypoints at the knot times.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    knots_s: Vec<f64>,
    waypoints: Vec<Waypoint>,
    /// One quintic per axis per segment.
    segments: Vec<[Quintic; 3]>,
}

impl Trajectory {
    pub fn new(knots_s: &[f64], waypoints: &[Waypoint]) -> Result<Self, TrajectoryError> {
        if knots_s.len() < 2 {
            return Err(TrajectoryError::TooFewKnots(knots_s.len()));
        }
        if waypoints.len() != knots_s.len() {
            return Err(TrajectoryError::WrongCount { waypoints: waypoints.len(), knots: knots_s.len() });
        }
        for (i, t) in knots_s.iter().enumerate() {
            if !t.is_finite() || (i > 0 && knots_s[i - 1] >= *t) {
                return Err(TrajectoryError::KnotsNotIncreasing { index: i, t_s: *t });
            }
        }
        for (i, w) in waypoints.iter().enumerate() {
            if !w.r_m.iter().chain(&w.v_mps).all(|x| x.is_finite()) {
                return Err(TrajectoryError::NotFinite(i));
            }
        }
        let segments = knots_s
            .windows(2)
            .zip(waypoints.windows(2))
            .map(|(t, w)| {
                let h = t[1] - t[0];
                std::array::from_fn(|ax| {
                    Quintic::new(h, w[0].r_m[ax], w[0].v_mps[ax], 0.0, w[1].r_m[ax], w[1].v_mps[ax], 0.0)
                })
            })
            .collect();
        Ok(Self { knots_s: knots_s.to_vec(), waypoints: waypoints.to_vec(), segments })
    }

    pub fn knots_s(&self) -> &[f64] {
        &self.knots_s
    }

    /// The desired position, velocity and acceleration at `t_s`.
    pub fn at(&self, t_s: f64) -> Desired {
        let first = self.knots_s[0];
        let last = *self.knots_s.last().expect("at least 2 knots");
        let coast = |w: &Waypoint, dt: f64| Desired {
            r_m: std::array::from_fn(|ax| w.r_m[ax] + w.v_mps[ax] * dt),
            v_mps: w.v_mps,
            a_mps2: [0.0; 3],
        };
        if t_s < first {
            return coast(&self.waypoints[0], t_s - first);
        }
        if t_s > last {
            return coast(self.waypoints.last().expect("at least 2 knots"), t_s - last);
        }
        // The segment whose interval holds t (the last one for t = last knot).
        let seg = self.knots_s[1..].partition_point(|&k| k < t_s).min(self.segments.len() - 1);
        let tau = t_s - self.knots_s[seg];
        let mut d = Desired::default();
        for ax in 0..3 {
            let (p, v, a) = self.segments[seg][ax].eval(tau);
            d.r_m[ax] = p;
            d.v_mps[ax] = v;
            d.a_mps2[ax] = a;
        }
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wp(r: [f64; 3], v: [f64; 3]) -> Waypoint {
        Waypoint { r_m: r, v_mps: v }
    }

    /// MU 1 of Case 2 (papers/tsnr/README.md): deploy, turn the net plane while approaching, close with
    /// the terminal velocity.
    fn case2_mu1() -> Trajectory {
        Trajectory::new(
            &[0.0, 10.0, 20.0, 30.0],
            &[
                wp([-10.0, 0.75, 0.75], [0.0; 3]),
                wp([-5.0, 2.55, 2.55], [0.0; 3]),
                wp([0.6526, 6.2033, 2.55], [0.0; 3]),
                wp([3.41, 5.43, 0.5], [0.25, 0.43, 0.0]),
            ],
        )
        .unwrap()
    }

    #[test]
    fn hits_every_waypoint_exactly() {
        let tr = case2_mu1();
        for (k, t) in tr.knots_s.clone().iter().enumerate() {
            let d = tr.at(*t);
            let w = tr.waypoints[k];
            for ax in 0..3 {
                assert!((d.r_m[ax] - w.r_m[ax]).abs() < 1e-12, "knot {k} r[{ax}] {} vs {}", d.r_m[ax], w.r_m[ax]);
                assert!((d.v_mps[ax] - w.v_mps[ax]).abs() < 1e-12, "knot {k} v[{ax}]");
                assert!(d.a_mps2[ax].abs() < 1e-12, "knot {k} a[{ax}] = {}", d.a_mps2[ax]);
            }
        }
    }

    #[test]
    fn continuous_in_position_velocity_and_acceleration_at_segment_boundaries() {
        let tr = case2_mu1();
        let eps = 1e-7;
        for &t in &tr.knots_s[1..tr.knots_s.len() - 1] {
            let (l, r) = (tr.at(t - eps), tr.at(t + eps));
            for ax in 0..3 {
                // Jumps would show as O(1) differences; smooth curves move O(eps) (a is bounded).
                assert!((l.r_m[ax] - r.r_m[ax]).abs() < 1e-6, "r jump at {t}");
                assert!((l.v_mps[ax] - r.v_mps[ax]).abs() < 1e-6, "v jump at {t}");
                assert!((l.a_mps2[ax] - r.a_mps2[ax]).abs() < 1e-5, "a jump at {t}");
            }
        }
    }

    #[test]
    fn velocity_and_acceleration_are_the_derivatives_of_position() {
        let tr = case2_mu1();
        let h = 1e-4;
        for k in 0..300 {
            let t = 0.05 + 0.1 * k as f64;
            let (m, p, c) = (tr.at(t - h), tr.at(t + h), tr.at(t));
            for ax in 0..3 {
                let v_fd = (p.r_m[ax] - m.r_m[ax]) / (2.0 * h);
                let a_fd = (p.v_mps[ax] - m.v_mps[ax]) / (2.0 * h);
                assert!((v_fd - c.v_mps[ax]).abs() < 1e-7, "t {t} v[{ax}] {v_fd} vs {}", c.v_mps[ax]);
                assert!((a_fd - c.a_mps2[ax]).abs() < 1e-7, "t {t} a[{ax}] {a_fd} vs {}", c.a_mps2[ax]);
            }
        }
    }

    #[test]
    fn coasts_at_the_end_velocity_after_the_last_knot() {
        let tr = case2_mu1();
        let d = tr.at(32.0);
        assert_eq!(d.v_mps, [0.25, 0.43, 0.0]);
        assert_eq!(d.a_mps2, [0.0; 3]);
        assert!((d.r_m[0] - (3.41 + 0.5)).abs() < 1e-12 && (d.r_m[1] - (5.43 + 0.86)).abs() < 1e-12);
        assert_eq!(tr.at(-1.0).r_m, [-10.0, 0.75, 0.75]);
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let w = [wp([0.0; 3], [0.0; 3]); 3];
        assert_eq!(Trajectory::new(&[0.0], &w[..1]), Err(TrajectoryError::TooFewKnots(1)));
        assert!(matches!(
            Trajectory::new(&[0.0, 10.0, 10.0], &w),
            Err(TrajectoryError::KnotsNotIncreasing { index: 2, .. })
        ));
        assert!(matches!(
            Trajectory::new(&[0.0, f64::NAN, 20.0], &w),
            Err(TrajectoryError::KnotsNotIncreasing { index: 1, .. })
        ));
        assert!(matches!(Trajectory::new(&[0.0, 10.0], &w), Err(TrajectoryError::WrongCount { .. })));
        let mut bad = w;
        bad[1].r_m[2] = f64::INFINITY;
        assert_eq!(Trajectory::new(&[0.0, 1.0, 2.0], &bad), Err(TrajectoryError::NotFinite(1)));
    }
}
