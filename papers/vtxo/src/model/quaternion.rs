//! Attitude quaternions in the paper's convention (Markley & Crassidis, *Fundamentals of
//! Spacecraft Attitude Determination and Control*): scalar last, q = [q₁ q₂ q₃ q₄]ᵀ, q = q^{bi}
//! maps ECI vectors into the body frame through the attitude matrix A(q), and the product ⊗
//! composes like the matrices, A(q ⊗ p) = A(q) A(p) (4)–(5).
//!
//! - (13) q̇ = ½ ω ⊗ q = ½ Ξ(q) ω, with ω the body rate in the body frame;
//! - (47)–(50) δq = q ⊗ q_f⁻¹, δq₁:₃ = Ξ(q_f)ᵀ q (the paper's E(q) (49) is Ξ(q)), δq₄ = qᵀ q_f;
//! - (7), (C.6) small rotations δq(θ) ≈ [θ/2; 1].
//!
//! Departures from the print: (3) prints only the 4×3 block Ξ(q) of the product matrix (the 4th
//! column, q itself, is missing); we use the full product. Small rotations are built with the
//! exact exponential [sin(|θ|/2) θ/|θ|; cos(|θ|/2)] rather than the first-order (7), so a noise or
//! filter correction never changes the norm. The principal angle 2 acos|δq₄| is evaluated as
//! 2 atan2(|δq₁:₃|, |δq₄|) (the same number, without acos's loss of precision near 1).

use nalgebra::{Matrix3, Matrix4x3, Vector3, Vector4};

pub type Quat = Vector4<f64>;
pub type V3 = Vector3<f64>;

/// The identity quaternion (9).
pub fn identity() -> Quat {
    Quat::new(0.0, 0.0, 0.0, 1.0)
}

/// [x×] (8).
pub fn skew(x: &V3) -> Matrix3<f64> {
    Matrix3::new(0.0, -x.z, x.y, x.z, 0.0, -x.x, -x.y, x.x, 0.0)
}

fn vec_part(q: &Quat) -> V3 {
    V3::new(q[0], q[1], q[2])
}

/// q ⊗ p, with A(q ⊗ p) = A(q) A(p).
pub fn compose(q: &Quat, p: &Quat) -> Quat {
    let (qv, pv) = (vec_part(q), vec_part(p));
    let v = q[3] * pv + p[3] * qv - qv.cross(&pv);
    Quat::new(v.x, v.y, v.z, q[3] * p[3] - qv.dot(&pv))
}

/// The inverse of a unit quaternion.
pub fn conjugate(q: &Quat) -> Quat {
    Quat::new(-q[0], -q[1], -q[2], q[3])
}

/// Ξ(q) (the paper's E(q), (49)).
pub fn xi(q: &Quat) -> Matrix4x3<f64> {
    Matrix4x3::new(q[3], -q[2], q[1], q[2], q[3], -q[0], -q[1], q[0], q[3], -q[0], -q[1], -q[2])
}

/// A(q): ECI vector → body frame.
pub fn attitude_matrix(q: &Quat) -> Matrix3<f64> {
    let v = vec_part(q);
    (q[3] * q[3] - v.norm_squared()) * Matrix3::identity() + 2.0 * v * v.transpose() - 2.0 * q[3] * skew(&v)
}

/// q̇ of (13).
pub fn rate(q: &Quat, omega_body_rad_s: &V3) -> Quat {
    0.5 * xi(q) * omega_body_rad_s
}

/// δq = q ⊗ q_f⁻¹ of (47)–(50).
pub fn error(q: &Quat, q_target: &Quat) -> Quat {
    let v = xi(q_target).transpose() * q;
    Quat::new(v.x, v.y, v.z, q.dot(q_target))
}

/// The rotation by the rotation vector θ (rad): the exact form of δq(θ) (7).
pub fn from_rotation_vector(theta_rad: &V3) -> Quat {
    let angle = theta_rad.norm();
    if angle < 1e-300 {
        return identity();
    }
    let (s, c) = (0.5 * angle).sin_cos();
    let v = theta_rad * (s / angle);
    Quat::new(v.x, v.y, v.z, c)
}

/// The rotation vector of q (the shorter of the two rotations q and −q describe), rad.
pub fn rotation_vector(q: &Quat) -> V3 {
    let v = vec_part(q);
    let n = v.norm();
    if n < 1e-300 {
        return V3::zeros();
    }
    let sign = if q[3] < 0.0 { -1.0 } else { 1.0 };
    v * (sign * 2.0 * n.atan2(q[3].abs()) / n)
}

/// The principal angle 2 acos|δq₄| of a (unit) error quaternion, rad.
pub fn principal_angle(dq: &Quat) -> f64 {
    2.0 * vec_part(dq).norm().atan2(dq[3].abs())
}

/// Exact propagation of (13) over `dt_s` with ω held: q ← exp(½ ω dt) ⊗ q.
pub fn propagate_held_rate(q: &Quat, omega_body_rad_s: &V3, dt_s: f64) -> Quat {
    compose(&from_rotation_vector(&(omega_body_rad_s * dt_s)), q)
}

/// sign(x) with sign(0) = +1: the controllers' sign(δq₄) picks one of the two equivalent
/// error quaternions and must never give zero.
pub fn sign_nonzero(x: f64) -> f64 {
    if x < 0.0 { -1.0 } else { 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(a: [f64; 4]) -> Quat {
        Quat::from_row_slice(&a).normalize()
    }

    #[test]
    fn product_composes_like_the_attitude_matrices() {
        let (a, b) = (q([0.1, -0.4, 0.3, 0.8]), q([-0.6, 0.2, 0.1, 0.5]));
        let lhs = attitude_matrix(&compose(&a, &b));
        let rhs = attitude_matrix(&a) * attitude_matrix(&b);
        assert!((lhs - rhs).norm() < 1e-14, "{}", (lhs - rhs).norm());
        // A is a proper rotation.
        let m = attitude_matrix(&a);
        assert!((m * m.transpose() - Matrix3::identity()).norm() < 1e-14);
        assert!((m.determinant() - 1.0).abs() < 1e-14);
    }

    #[test]
    fn error_quaternion_matches_the_product_form() {
        let (a, f) = (q([0.1, -0.4, 0.3, 0.8]), q([-0.6, 0.2, 0.1, 0.5]));
        let d = error(&a, &f);
        let p = compose(&a, &conjugate(&f));
        assert!((d - p).norm() < 1e-15, "{d} vs {p}");
    }

    #[test]
    fn kinematics_agree_with_the_held_rate_exponential() {
        // One small Euler step of (13) against the exact exponential.
        let (q0, w, h) = (q([0.2, 0.1, -0.3, 0.9]), V3::new(0.3, -0.2, 0.5), 1e-6);
        let euler = q0 + h * rate(&q0, &w);
        let exact = propagate_held_rate(&q0, &w, h);
        assert!((euler - exact).norm() < 1e-12, "{}", (euler - exact).norm());
        // And body-frame rotation: a vector fixed in ECI turns by −ω × in the body frame.
        let x = V3::new(0.3, 0.5, -0.2);
        let dx = (attitude_matrix(&exact) * x - attitude_matrix(&q0) * x) / h;
        let want = -w.cross(&(attitude_matrix(&q0) * x));
        assert!((dx - want).norm() < 1e-6, "{dx} vs {want}");
    }

    #[test]
    fn rotation_vector_round_trips_and_angle_is_principal() {
        let th = V3::new(0.3, -1.2, 0.7);
        let r = rotation_vector(&from_rotation_vector(&th));
        assert!((r - th).norm() < 1e-14);
        assert!((principal_angle(&from_rotation_vector(&th)) - th.norm()).abs() < 1e-14);
        // −q is the same rotation.
        assert!((rotation_vector(&-from_rotation_vector(&th)) - th).norm() < 1e-14);
        let tiny = V3::new(1e-9, -2e-9, 3e-10);
        assert!((principal_angle(&from_rotation_vector(&tiny)) - tiny.norm()).abs() < 1e-22);
    }
}
