//! The SN-DNN's input (74) of "Neural-Rendezvous" (arXiv:2208.04883, Sec. 6.2.3). The printed
//! transform is lost; ours (15 values, SI units, then each divided by its training maximum
//! |·| as in 6.2.3, inside [`crate::nn::sn_dnn`]):
//!
//! | index | what |
//! |-------|------|
//! | 0–2   | p̂, relative position (LVLH), m |
//! | 3–5   | ṗ̂, its rate, m/s |
//! | 6–8   | ZEM = ballistic p(t_f) − ρ_f (the "zero-effort miss"), m |
//! | 9     | t_f − t, s |
//! | 10    | r̂, the ISO's distance from the Sun, m |
//! | 11    | ḟ̂, the ISO's true-anomaly rate (the dominant element of C in (2)), rad/s |
//! | 12–14 | ρ_f, desired terminal relative position (LVLH), m |
//! | 15–17 | ZEM/t_go², the acceleration that nulls the miss (t_go = t_f − t), m/s² |
//!
//! Why ZEM: the raw p is ~10⁹ m and hides the miss the guidance must null; the ballistic
//! terminal position is an (almost affine) function of x through the state-transition matrix,
//! so the input stays differentiable in x (the training rolls the state through the dynamics).
//!
//! Departure from the reference's transform (values 0–14): ZEM/t_go² is added. The MPC's
//! command is close to −3m·ZEM/t_go² (the minimum-energy command with free terminal velocity),
//! a product the network would otherwise have to form itself; with ZEM alone (normalised by its
//! training maximum, ~10⁵ m) the gain it needs late in the approach exceeds what the
//! spectral normalisation allows (C_sn^L = 16 in normalised units), and the SN-DNN alone missed
//! by ≈ 12 km (median, training ISOs 0–19, perfect navigation; see the crate README).

use nalgebra::SMatrix;

use crate::iso::dynamics::lvlh::{OrbitRates, X6, pos, vel};
use crate::iso::dynamics::relative::{coast_position, coast_position_jac};
use crate::iso::dynamics::two_body::{Inertial, V3};

/// Number of inputs: p (3), ṗ (3), ZEM (3), t_f − t, r, ḟ, ρ_f (3), ZEM/t_go² (3).
pub const N_FEATURES: usize = 18;
/// The reference's transform: the first 15 values (a network with 15 inputs reads only these;
/// kept so the comparison in the crate README can be reproduced).
pub const REFERENCE_INPUTS: usize = 15;
/// Names, for the weights file.
pub const NAMES: [&str; N_FEATURES] = [
    "p_x_m",
    "p_y_m",
    "p_z_m",
    "pdot_x_mps",
    "pdot_y_mps",
    "pdot_z_mps",
    "zem_x_m",
    "zem_y_m",
    "zem_z_m",
    "t_go_s",
    "iso_r_m",
    "iso_fdot_radps",
    "rho_f_x_m",
    "rho_f_y_m",
    "rho_f_z_m",
    "a_req_x_mps2",
    "a_req_y_mps2",
    "a_req_z_mps2",
];
/// Largest RK4 step of the ZEM's coasting propagation (≤ 4 steps over a day; ≈ 0.2 m from the
/// converged value, see `relative`'s tests), s.
pub const ZEM_STEP_S: f64 = 21_600.0;

pub type Features = [f64; N_FEATURES];
/// ∂features/∂x (only the p, ṗ and ZEM rows are nonzero).
pub type FeatureJac = SMatrix<f64, N_FEATURES, 6>;

/// 1/t_go², with t_go floored at one second (the input is never used at t_f itself).
fn inv_tgo2(t_go_s: f64) -> f64 {
    1.0 / t_go_s.max(1.0).powi(2)
}

fn assemble(x: &X6, zem: &V3, t_go_s: f64, iso: &Inertial, rho_f_m: &V3) -> Features {
    let o = OrbitRates::of(iso);
    let (p, q) = (pos(x), vel(x));
    let a = zem * inv_tgo2(t_go_s);
    [
        p.x,
        p.y,
        p.z,
        q.x,
        q.y,
        q.z,
        zem.x,
        zem.y,
        zem.z,
        t_go_s,
        o.r_m,
        o.fdot_radps,
        rho_f_m.x,
        rho_f_m.y,
        rho_f_m.z,
        a.x,
        a.y,
        a.z,
    ]
}

/// The raw (unnormalised) input at estimate (x, œ), time t.
pub fn features(x: &X6, iso: &Inertial, t_s: f64, t_f_s: f64, rho_f_m: &V3) -> Features {
    let t_go = (t_f_s - t_s).max(0.0);
    let zem = coast_position(x, iso, t_go, ZEM_STEP_S) - rho_f_m;
    assemble(x, &zem, t_go, iso, rho_f_m)
}

/// [`features`] and ∂features/∂x.
pub fn features_jac(x: &X6, iso: &Inertial, t_s: f64, t_f_s: f64, rho_f_m: &V3) -> (Features, FeatureJac) {
    let t_go = (t_f_s - t_s).max(0.0);
    let (pf, dpf) = coast_position_jac(x, iso, t_go, ZEM_STEP_S);
    let f = assemble(x, &(pf - rho_f_m), t_go, iso, rho_f_m);
    let mut j = FeatureJac::zeros();
    j.fixed_view_mut::<6, 6>(0, 0).copy_from(&nalgebra::Matrix6::identity());
    j.fixed_view_mut::<3, 6>(6, 0).copy_from(&dpf);
    j.fixed_view_mut::<3, 6>(15, 0).copy_from(&(dpf * inv_tgo2(t_go)));
    (f, j)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::{ISO_SET_SEED, T_F_S};
    use crate::iso::dynamics::iso_set;
    use crate::iso::dynamics::lvlh::IsoFrame;

    #[test]
    fn zem_vanishes_on_the_ideal_trajectory_and_its_jacobian_matches_differences() {
        let ideal = iso_set::ideal(ISO_SET_SEED, 5, 0, T_F_S, 100e3);
        let (iso, sc) = ideal.at(30_000.0);
        let x = IsoFrame::of(&iso).relative(&sc);
        let (f, j) = features_jac(&x, &iso, 30_000.0, T_F_S, &ideal.rho_f_m);
        assert_eq!(f, features(&x, &iso, 30_000.0, T_F_S, &ideal.rho_f_m));
        let zem = V3::new(f[6], f[7], f[8]).norm();
        assert!(zem < 1.0, "ZEM on the ideal coasting trajectory: {zem} m");
        for c in 0..6 {
            // Large steps: the map is nearly affine and the propagated values carry ~1e-7 m roundoff.
            let d = if c < 3 { 1e4 } else { 1.0 };
            let (mut xp, mut xm) = (x, x);
            xp[c] += d;
            xm[c] -= d;
            let (fp, fm) = (
                features(&xp, &iso, 30_000.0, T_F_S, &ideal.rho_f_m),
                features(&xm, &iso, 30_000.0, T_F_S, &ideal.rho_f_m),
            );
            for r in 0..N_FEATURES {
                let fd = (fp[r] - fm[r]) / (2.0 * d);
                assert!((fd - j[(r, c)]).abs() <= 1e-6 * (1.0 + j[(r, c)].abs()), "∂f{r}/∂x{c}: {fd} vs {}", j[(r, c)]);
            }
        }
    }
}
