//! The one table of unit suffixes in telemetry column names (`omega_x_rad_s`, `torque_x_n_m`,
//! `u_x_mps2`): the suffix each writer appends and the unit it means. The telemetry writer puts
//! each column's unit into the file's schema, and the plots label their axes with it, so a
//! column's unit is read the same way everywhere.

/// Suffix (snake case, as it ends a column name) → unit as shown to people. The longest suffix
/// that matches wins (`rad_s` before `s`). Watts and hours are left out on purpose: `q_w` is a
/// quaternion's scalar part, not a power.
pub const UNITS: &[(&str, &str)] = &[
    ("n_m_s", "N·m·s"),
    ("kg_m2", "kg·m²"),
    ("rad_s2", "rad/s²"),
    ("rad_s", "rad/s"),
    ("deg_s", "deg/s"),
    ("n_m", "N·m"),
    ("n_s", "N·s"),
    ("m_s2", "m/s²"),
    ("mps2", "m/s²"),
    ("kmps2", "km/s²"),
    ("mps", "m/s"),
    ("kmps", "km/s"),
    ("radps2", "rad/s²"),
    ("radps", "rad/s"),
    ("degps", "deg/s"),
    ("au", "AU"),
    ("km", "km"),
    ("mm", "mm"),
    ("um", "µm"),
    ("m", "m"),
    ("ms", "ms"),
    ("us", "µs"),
    ("ns", "ns"),
    ("s", "s"),
    ("rad", "rad"),
    ("deg", "deg"),
    ("n", "N"),
    ("kg", "kg"),
    ("j", "J"),
    ("hz", "Hz"),
    ("pct", "%"),
];

/// Split a column name into its stem and its unit: `omega_x_rad_s` → (`omega_x`, `rad_s`,
/// `rad/s`). A name that is only a unit, or ends in none, has no unit.
pub fn split_unit(name: &str) -> (&str, Option<(&'static str, &'static str)>) {
    let mut best: Option<(&'static str, &'static str)> = None;
    for &(suffix, label) in UNITS {
        let long_enough = name.len() > suffix.len() + 1;
        if long_enough
            && name.ends_with(suffix)
            && name.as_bytes()[name.len() - suffix.len() - 1] == b'_'
            && best.is_none_or(|(b, _)| suffix.len() > b.len())
        {
            best = Some((suffix, label));
        }
    }
    match best {
        Some((suffix, label)) => (&name[..name.len() - suffix.len() - 1], Some((suffix, label))),
        None => (name, None),
    }
}

/// The unit of column `name` as shown to people, if its name carries one.
pub fn unit_of(name: &str) -> Option<&'static str> {
    split_unit(name).1.map(|(_, label)| label)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_suffix_wins() {
        assert_eq!(split_unit("omega_x_rad_s"), ("omega_x", Some(("rad_s", "rad/s"))));
        assert_eq!(split_unit("h_inertial_x_n_m_s"), ("h_inertial_x", Some(("n_m_s", "N·m·s"))));
        assert_eq!(split_unit("torque_x_n_m").1.map(|u| u.1), Some("N·m"));
        assert_eq!(split_unit("u_x_n").1.map(|u| u.1), Some("N"));
        assert_eq!(split_unit("omega_d_dot_x_rad_s2").1.map(|u| u.1), Some("rad/s²"));
        assert_eq!(split_unit("theta_hat_xx_kg_m2").1.map(|u| u.1), Some("kg·m²"));
        assert_eq!(split_unit("u_x_mps2").1.map(|u| u.1), Some("m/s²"));
        assert_eq!(split_unit("e_norm_m").0, "e_norm");
    }

    #[test]
    fn names_without_a_unit_keep_their_whole_name() {
        assert_eq!(split_unit("theta_norm"), ("theta_norm", None));
        assert_eq!(split_unit("qp_status"), ("qp_status", None));
        assert_eq!(split_unit("m"), ("m", None));
        assert_eq!(split_unit("q_w"), ("q_w", None));
    }
}
