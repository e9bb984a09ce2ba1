//! The plant's telemetry row (after the driver's `k,t_s`): the truth at t_k and the actuation
//! applied over [t_k, t_{k+1}]. Everything the summary metrics and the Figs. 6–8 analogue plots
//! need (r_rel components and the transverse error vs t), and the attitude truth the MEKF
//! consistency join needs (`leader_q1…q4`, `follower_q1…q4` against the agents' `q_hat_*` and
//! `sigma_theta_*`, row k with row k).

use crate::model::metrics::attitude_error_deg;
use crate::model::plant::VtxoPlant;

const XYZ: [&str; 3] = ["x", "y", "z"];

fn vec3(c: &mut Vec<String>, name: &str, unit: &str) {
    for ax in XYZ {
        c.push(format!("{name}_{ax}_{unit}"));
    }
}

pub fn columns() -> Vec<String> {
    let mut c = Vec::new();
    for role in ["leader", "follower"] {
        vec3(&mut c, &format!("{role}_r_eci"), "m");
        vec3(&mut c, &format!("{role}_v_eci"), "mps");
    }
    vec3(&mut c, "r_rel_eci", "m");
    vec3(&mut c, "v_rel_eci", "mps");
    c.push("formation_error_m".into());
    c.push("transverse_error_x_m".into());
    c.push("transverse_error_y_m".into());
    c.push("transverse_error_m".into());
    c.push("range_error_m".into());
    for role in ["leader", "follower"] {
        for n in ["q1", "q2", "q3", "q4"] {
            c.push(format!("{role}_{n}"));
        }
        vec3(&mut c, &format!("{role}_omega_body"), "rad_s");
        c.push(format!("{role}_attitude_error_deg"));
        vec3(&mut c, &format!("{role}_tau_in_body"), "n_m");
        vec3(&mut c, &format!("{role}_thrust_eci"), "n");
        vec3(&mut c, &format!("{role}_force_disturbance_eci"), "n");
    }
    c
}

pub fn row(p: &VtxoPlant, out: &mut Vec<f64>) {
    for i in 0..2 {
        let (r, v) = p.rv_eci(i);
        out.extend(r.iter());
        out.extend(v.iter());
    }
    let (rr, vr) = (p.orbit.r_rel_eci_m, p.orbit.v_rel_eci_mps);
    out.extend(rr.iter());
    out.extend(vr.iter());
    let e = rr - p.r_target_eci_m;
    out.extend([e.norm(), e.x, e.y, e.x.hypot(e.y), rr.norm() - p.r_target_eci_m.norm()]);
    for c in &p.craft {
        out.extend(c.attitude.q_body_eci.iter());
        out.extend(c.attitude.omega_body_rad_s.iter());
        out.push(attitude_error_deg(&c.attitude.q_body_eci, &p.q_target));
        out.extend(c.applied_torque_n_m().iter());
        out.extend(c.applied_force_n().iter());
        out.extend(c.force_disturbance.value.iter());
    }
}
