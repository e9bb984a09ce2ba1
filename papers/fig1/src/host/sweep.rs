//! Seed 000's criterion over an `orchestrator sweep`: the paper's "‖eᵢ‖ ≈ 5 m after ≈ 200 s"
//! (Fig. 4) and "‖ζ̃ᵢ‖ ≈ 5 m/s after ≈ 150 s" (Fig. 3), checked per seed on the worst servicer's
//! RMS over those windows (`servicer_<i>.e_rms_200_<end>_m`, `servicer_<i>.zeta_err_rms_150_<end>_mps`).

use std::fmt::Write as _;

use cohort_host::Metrics;
use cohort_report::markdown::MdTable;

use crate::host::verdict::{E_LEVEL_M, ZETA_LEVEL_MPS};

/// Numbers as the sweep's tables print them: 4 decimals, scientific outside [1e-3, 1e5).
fn g(x: f64) -> String {
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) { format!("{x:.3e}") } else { format!("{x:.4}") }
}

/// The largest value of the metrics whose name holds `stem` (none: no such metric).
fn worst(m: &Metrics, stem: &str) -> Option<f64> {
    let xs: Vec<f64> = m.iter().filter(|(k, _)| k.contains(stem)).map(|(_, v)| *v).collect();
    (!xs.is_empty()).then(|| xs.into_iter().fold(f64::MIN, f64::max))
}

/// The criterion's table, one row per seed, and how many seeds meet both levels; none unless
/// every seed has both metrics.
pub fn section(rows: &[(u64, Metrics)]) -> Option<String> {
    let has = rows.iter().all(|(_, m)| worst(m, ".e_rms_200_").is_some() && worst(m, ".zeta_err_rms_150_").is_some());
    if !has || rows.is_empty() {
        return None;
    }
    let mut md = String::new();
    let _ = writeln!(
        md,
        "Seed 000 criterion (paper: ‖eᵢ‖ ≈ {E_LEVEL_M} m after 200 s, ‖ζ̃ᵢ‖ ≈ {ZETA_LEVEL_MPS} m/s after 150 s): \
         worst servicer per seed.\n"
    );
    let mut table = MdTable::new(["seed", "max e_rms_200_end (m)", "max zeta_err_rms_150_end (m/s)", "within both"]);
    let mut pass = 0;
    for (seed, m) in rows {
        let (e, z) = (worst(m, ".e_rms_200_").unwrap_or(f64::NAN), worst(m, ".zeta_err_rms_150_").unwrap_or(f64::NAN));
        let ok = e <= E_LEVEL_M && z <= ZETA_LEVEL_MPS;
        pass += usize::from(ok);
        table.row([seed.to_string(), g(e), g(z), (if ok { "yes" } else { "no" }).to_string()]);
    }
    let _ = write!(md, "{table}");
    let _ = writeln!(md, "\n{pass} of {} seeds meet both bounds for every servicer.", rows.len());
    Some(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed(e: f64, z: f64) -> Metrics {
        Metrics::from([
            ("servicer_1.e_rms_200_360_m".to_string(), e),
            ("servicer_2.e_rms_200_360_m".to_string(), 0.5 * e),
            ("servicer_1.zeta_err_rms_150_360_mps".to_string(), z),
        ])
    }

    #[test]
    fn each_seed_is_held_to_both_levels_on_its_worst_servicer() {
        let md = section(&[(1, seed(2.0, 3.0)), (2, seed(6.0, 1.0))]).unwrap();
        assert!(md.contains("| 1 | 2.0000 | 3.0000 | yes |"), "{md}");
        assert!(md.contains("| 2 | 6.0000 | 1.0000 | no |"), "{md}");
        assert!(md.contains("1 of 2 seeds meet both bounds"), "{md}");
    }

    #[test]
    fn a_sweep_without_the_metrics_has_no_section() {
        assert!(section(&[(1, Metrics::from([("x_m".to_string(), 1.0)]))]).is_none());
        assert!(section(&[]).is_none());
    }
}
