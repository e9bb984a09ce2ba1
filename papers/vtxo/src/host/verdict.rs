//! Seed 002's verdict (Pirayeshshirazinezhad, *Explainable AI-Enhanced Supervisory Control for
//! High-Precision Spacecraft Formation*, arXiv:2509.13331): the mission requirements of Sec. 2.3
//! against the run, each where it applies:
//!
//! - transverse alignment < 1 mm and distance 1 km ± 1 m, with relative control on: ours are the
//!   largest transverse error and range error over the plant's last window
//!   (`plant.metrics.transverse_window_s`, 15 s by default) of the formation reached;
//! - R2, attitude error P99 < 0.18°, in the science phase, for each spacecraft: ours is the P99 of
//!   the run's attitude error over its steps (the paper's P99 is over Monte Carlo runs of a
//!   phase's mean error: ours is the stricter reading for one run).
//!
//! The formation lines are n/a when the formation was not reached in a run shorter than the
//! Sec. 7 case's 9 300 s (the sign SMC's reaching time is ≈ 9 001 s); every line is n/a for a
//! fault run or a run that did not end normally.

use cohort_host::{Criterion, VerdictInput, VerdictLine};

use crate::flight::config::{Phase, RelativeController, VtxoAlgorithmConfig};

/// The Sec. 7 case's length, s: the sign SMC's reaching time |s_z(0)|/Z = 9 001 s and 300 s more.
pub const SEC7_DURATION_S: f64 = 9300.0;
/// Sec. 2.3: transverse alignment, mm.
pub const TRANSVERSE_MM: f64 = 1.0;
/// Sec. 2.3: distance tolerance about 1 km, m.
pub const RANGE_M: f64 = 1.0;
/// Sec. 2.3, R2: attitude error P99, degrees.
pub const ATTITUDE_P99_DEG: f64 = 0.18;

pub fn lines(input: &VerdictInput<'_>) -> Vec<VerdictLine> {
    let Some(a) = input.run.setup.algorithm_as::<VtxoAlgorithmConfig>() else { return Vec::new() };
    let mut out = Vec::new();
    if a.relative.controller != RelativeController::Off {
        let formation = [
            VerdictLine::compare(
                "transverse alignment error, last window (max)",
                "Pirayeshshirazinezhad, Sec. 2.3",
                TRANSVERSE_MM,
                input.metric("transverse_max_mm"),
                "mm",
                Criterion::AtMost,
            ),
            VerdictLine::compare(
                "range error about 1 km, last window (max)",
                "Pirayeshshirazinezhad, Sec. 2.3",
                RANGE_M,
                input.metric("range_error_max_m"),
                "m",
                Criterion::AtMost,
            ),
        ];
        let unreached = input.metric("formation_reached") != Some(1.0) && input.duration_s() < SEC7_DURATION_S;
        out.extend(formation.into_iter().map(|l| {
            if unreached {
                l.not_applicable(format!(
                    "run of {} s did not reach the formation (the Sec. 7 case needs ≈ 9001 s): shortened",
                    input.duration_s()
                ))
            } else {
                l
            }
        }));
    }
    if a.phase == Phase::Science {
        for role in ["leader", "follower"] {
            out.push(VerdictLine::compare(
                format!("{role} attitude error P99 (R2)"),
                "Pirayeshshirazinezhad, Sec. 2.3",
                ATTITUDE_P99_DEG,
                input.metric(&format!("{role}_attitude_error_p99_deg")),
                "deg",
                Criterion::AtMost,
            ));
        }
    }
    match input.not_judgeable() {
        Some(why) => out.into_iter().map(|l| l.not_applicable(why.clone())).collect(),
        None => out,
    }
}
