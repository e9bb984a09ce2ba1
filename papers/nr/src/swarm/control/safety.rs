//! A distributed safety filter for the swarm (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883):
//! the last thing a vehicle does to its command, with what it hears from within R_comm only.
//!
//! Why it exists: the paper's distributed policy is GLAS's (its ref. [42], "GLAS: Global-to-Local
//! Safe Autonomy Synthesis for Multi-Robot Motion Planning with End-to-End Learning"), and GLAS's
//! safety comes from a barrier-function module around the learned network, not from the network;
//! the Neural-Rendezvous layer over it (roll the policy ahead, track the roll-out) adds robustness
//! to the roll-out, not avoidance. Our campaign measured exactly that: NR over the deep set
//! collides where the deep set alone collides. The paper's module is not given, so ours is the
//! standard one for double integrators with bounded acceleration, the barrier certificates of
//! "Safety Barrier Certificates for Collisions-Free Multirobot Systems" (Wang, Ames, Egerstedt,
//! IEEE T-RO 2017), in the tall-ellipsoid metric of the collision check.
//!
//! For a heard neighbour j, with E = diag(0.12, 0.12, 0.30 m), q = E⁻¹(pᵢ − pⱼ) (collision iff
//! ‖q‖ < 1), d = ‖q‖, n̂ = q/d, w = E⁻¹(vᵢ − vⱼ), ḋ = n̂·w:
//!
//!   h = √(2A(d − D)) + ḋ ≥ 0
//!
//! says the pair can still stop before d = D (the margin, D > 1) when both brake with the combined
//! rate A (in E-scaled units). We take A = κ · 2(a_max − d̄)/max(E): the worst axis's braking of two
//! vehicles after the disturbance d̄, times the share κ < 1 the filter may claim of it. Asking
//! ḣ ≥ −γh, with ḣ = Aḋ/√(2A(d − D)) + (‖w‖² − ḋ²)/d + n̂·E⁻¹(aᵢ − aⱼ + dᵢ − dⱼ), and splitting
//! the burden reciprocally (every vehicle flies this filter, each takes half), vehicle i asks of
//! its own command
//!
//!   cᵀaᵢ ≥ b/2 + d̄‖c‖,   c = E⁻¹n̂,   b = −γh − Aḋ/√(2A(d − D)) − (‖w‖² − ḋ²)/d,
//!
//! the d̄‖c‖ guarding against its own disturbance in the worst direction. The command is the
//! nearest to the nominal one (‖a − a_nom‖²) that meets every such row and |aₖ| ≤ a_max; each row
//! has a slack under an exact (linear) penalty, so rows that can be met are met exactly and an
//! over-constrained vehicle does the best it can instead of failing (the slack used is reported). When the nominal command already meets every row it is kept
//! as it is (bit for bit) and no solver runs.
//!
//! Departures and choices (ours; the paper gives no safety module): the barrier above in place of
//! GLAS's; D, κ, γ and d̄ are scenario keys (`algorithm.safety`); the neighbours' states are the
//! agent's (their shares of the last step propagated by their command), and a vehicle beyond
//! R_comm is not seen, so a pair closing faster than the barrier allows at R_comm starts inside
//! h < 0 and recovers at rate γ; the condition holds at the control instants only (the command is
//! held over the interval), which the margin D − 1 absorbs.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus, SupportedConeT};
use serde::{Deserialize, Serialize};

use cohort_scenario::Problem;

use crate::iso::config::positive;
use crate::swarm::dynamics::setup::{ELLIPSOID_RADII_M, dot, norm};

type V3 = [f64; 3];

/// Linear weight of a row's slack against ‖a − a_nom‖² (rows normalised to m/s²): an exact
/// penalty (a feasible set of rows is met exactly) as long as it exceeds the rows' multipliers,
/// which are at most 2‖a − a_nom‖ ≤ 4√3 a_max here.
const SLACK_WEIGHT: f64 = 1e3;
/// Floor of d − D under the square root's derivative (E-scaled units).
const MIN_GAP: f64 = 1e-4;
/// A row counts as met within this (m/s², normalised).
const ROW_TOL: f64 = 1e-9;

fn d_margin() -> f64 {
    1.15
}
fn d_braking_share() -> f64 {
    0.5
}
fn d_gamma() -> f64 {
    2.0
}

/// `[algorithm.safety]`: the barrier filter's settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SafetyConfig {
    /// D: the ellipsoid distance the filter keeps a pair from (collision at 1). Below the 1.25 at
    /// which goals are drawn apart, or vehicles at neighbouring goals would push each other off.
    #[serde(default = "d_margin")]
    pub margin: f64,
    /// κ: the share of two vehicles' worst-axis braking the barrier assumes, in (0, 1].
    #[serde(default = "d_braking_share")]
    pub braking_share: f64,
    /// γ of ḣ ≥ −γh, 1/s.
    #[serde(default = "d_gamma")]
    pub gamma_per_s: f64,
    /// d̄ the filter guards against, m/s² (a vehicle's disturbance bound; the plant's is
    /// `plant.disturbance_mps2`).
    #[serde(default)]
    pub disturbance_mps2: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        toml::from_str("").expect("every key has a default")
    }
}

impl SafetyConfig {
    /// Every problem, with its key path; `a_max_mps2` is the plant's limit (the braking).
    pub fn validate(&self, a_max_mps2: f64) -> Vec<Problem> {
        let mut p = Vec::new();
        if !(self.margin.is_finite() && self.margin >= 1.0) {
            p.push(Problem::new(
                "algorithm.safety.margin",
                Some(self.margin.to_string()),
                "must be at least 1 (the collision ellipsoid)",
            ));
        }
        if !(self.braking_share > 0.0 && self.braking_share <= 1.0) {
            p.push(Problem::new(
                "algorithm.safety.braking_share",
                Some(self.braking_share.to_string()),
                "must be in (0, 1]",
            ));
        }
        positive(&mut p, "algorithm.safety.gamma_per_s", self.gamma_per_s);
        let d = self.disturbance_mps2;
        if !(d.is_finite() && d >= 0.0 && d < a_max_mps2) {
            p.push(Problem::new(
                "algorithm.safety.disturbance_mps2",
                Some(d.to_string()),
                format!("must be in [0, a_max = {a_max_mps2}): the vehicles must out-brake it"),
            ));
        }
        p
    }

    /// A, the combined braking rate in E-scaled units (1/s²).
    pub fn braking(&self, a_max_mps2: f64) -> f64 {
        let e_max = ELLIPSOID_RADII_M.iter().fold(0.0f64, |a, &r| a.max(r));
        self.braking_share * 2.0 * (a_max_mps2 - self.disturbance_mps2) / e_max
    }
}

/// One row cᵀa ≥ β, normalised (‖c‖ = 1), and its pair's barrier value h.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    pub c: V3,
    pub beta_mps2: f64,
    pub h: f64,
}

/// The row vehicle (p, v) asks of its own command for the neighbour (pⱼ, vⱼ); None when they
/// coincide (no direction to push along).
pub fn row(cfg: &SafetyConfig, a_max_mps2: f64, p: V3, v: V3, pj: V3, vj: V3) -> Option<Row> {
    let e = ELLIPSOID_RADII_M;
    let q: V3 = [0, 1, 2].map(|k| (p[k] - pj[k]) / e[k]);
    let w: V3 = [0, 1, 2].map(|k| (v[k] - vj[k]) / e[k]);
    let d = norm(q);
    if !(d > 0.0 && d.is_finite() && w.iter().all(|x| x.is_finite())) {
        return None;
    }
    let n = q.map(|x| x / d);
    let d_dot = dot(n, w);
    let c: V3 = [0, 1, 2].map(|k| n[k] / e[k]);
    let c_norm = norm(c);
    let a = cfg.braking(a_max_mps2);
    let gap = d - cfg.margin;
    let h = (2.0 * a * gap.max(0.0)).sqrt() + d_dot;
    let root = (2.0 * a * gap.max(MIN_GAP)).sqrt();
    let b = -cfg.gamma_per_s * h - a * d_dot / root - (dot(w, w) - d_dot * d_dot) / d;
    let beta = 0.5 * b + cfg.disturbance_mps2 * c_norm;
    Some(Row { c: c.map(|x| x / c_norm), beta_mps2: beta / c_norm, h })
}

/// What the filter did to one command.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Filtered {
    pub u_mps2: V3,
    /// Rows the nominal command broke (0: kept as it was).
    pub active: usize,
    /// Largest slack the solution needed, m/s² (0: every row met).
    pub slack_mps2: f64,
    /// Least barrier value h over the heard neighbours (∞ without any).
    pub min_h: f64,
    /// The solver failed: the nominal command was kept.
    pub failed: bool,
}

/// Filter `nominal` (already within ±a_max) for the vehicle at (p, v) among `others` (the heard
/// neighbours within R_comm, as (p, v)).
pub fn filter(cfg: &SafetyConfig, a_max_mps2: f64, p: V3, v: V3, nominal: V3, others: &[(V3, V3)]) -> Filtered {
    let rows: Vec<Row> = others.iter().filter_map(|&(pj, vj)| row(cfg, a_max_mps2, p, v, pj, vj)).collect();
    let min_h = rows.iter().fold(f64::INFINITY, |m, r| m.min(r.h));
    let active = rows.iter().filter(|r| dot(r.c, nominal) < r.beta_mps2 - ROW_TOL).count();
    let kept = Filtered { u_mps2: nominal, active, slack_mps2: 0.0, min_h, failed: false };
    if active == 0 {
        return kept;
    }
    match solve(&rows, nominal, a_max_mps2) {
        Some((u, slack)) => Filtered { u_mps2: u, slack_mps2: slack, ..kept },
        None => Filtered { failed: true, ..kept },
    }
}

/// min ‖a − a_nom‖² + ρΣsⱼ s.t. cⱼᵀa + sⱼ ≥ βⱼ, sⱼ ≥ 0, |aₖ| ≤ a_max; x = [a; s].
fn solve(rows: &[Row], nominal: V3, a_max: f64) -> Option<(V3, f64)> {
    let m = rows.len();
    let nv = 3 + m;
    // Constraint rows (b − Ax ≥ 0): 0..m the barrier rows, m..2m the slacks' signs, then the box.
    let n_rows = 2 * m + 6;
    let (mut colptr, mut rowval, mut nzval) = (vec![0usize], Vec::new(), Vec::new());
    for k in 0..3 {
        for (j, r) in rows.iter().enumerate() {
            rowval.push(j);
            nzval.push(-r.c[k]);
        }
        rowval.extend([2 * m + 2 * k, 2 * m + 2 * k + 1]);
        nzval.extend([1.0, -1.0]);
        colptr.push(rowval.len());
    }
    for j in 0..m {
        rowval.extend([j, m + j]);
        nzval.extend([-1.0, -1.0]);
        colptr.push(rowval.len());
    }
    let a = CscMatrix::new(n_rows, nv, colptr, rowval, nzval);
    let p = CscMatrix::new(nv, nv, (0..=3).chain(std::iter::repeat_n(3, m)).collect(), vec![0, 1, 2], vec![2.0; 3]);
    let mut q = vec![SLACK_WEIGHT; nv];
    for k in 0..3 {
        q[k] = -2.0 * nominal[k];
    }
    let mut b: Vec<f64> = rows.iter().map(|r| -r.beta_mps2).collect();
    b.extend(std::iter::repeat_n(0.0, m));
    b.extend(std::iter::repeat_n(a_max, 6));
    let cones: [SupportedConeT<f64>; 1] = [NonnegativeConeT(n_rows)];
    let settings = DefaultSettings { verbose: false, max_iter: 100, ..DefaultSettings::default() };
    let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings).ok()?;
    solver.solve();
    let x = &solver.solution.x;
    let usable = matches!(solver.solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved)
        && x.iter().all(|v| v.is_finite());
    if !usable {
        return None;
    }
    // The box exactly (the solver's interior point may sit a hair outside).
    let u = [x[0], x[1], x[2]].map(|v| v.clamp(-a_max, a_max));
    let slack = rows.iter().map(|r| (r.beta_mps2 - dot(r.c, u)).max(0.0)).fold(0.0, f64::max);
    Some((u, slack))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> SafetyConfig {
        SafetyConfig::default()
    }

    #[test]
    fn a_far_or_separating_neighbour_leaves_the_command_as_it_is() {
        let nominal = [0.3, -1.2, 0.7];
        // 0.9 m away in x, at rest: no row is active.
        let f = filter(&cfg(), 2.0, [0.0, 0.0, 1.0], [0.0; 3], nominal, &[([0.9, 0.0, 1.0], [0.0; 3])]);
        assert_eq!((f.u_mps2, f.active, f.failed), (nominal, 0, false));
        // 0.2 m away and separating at 1 m/s: nothing to do either.
        let f = filter(&cfg(), 2.0, [0.0, 0.0, 1.0], [-0.5, 0.0, 0.0], nominal, &[([0.2, 0.0, 1.0], [0.5, 0.0, 0.0])]);
        assert_eq!((f.u_mps2, f.active), (nominal, 0));
        assert!(f.min_h > 0.0);
        // Nobody heard.
        let f = filter(&cfg(), 2.0, [0.0; 3], [0.0; 3], nominal, &[]);
        assert_eq!((f.u_mps2, f.min_h), (nominal, f64::INFINITY));
    }

    #[test]
    fn a_closing_pair_brakes_and_the_row_is_met() {
        // Head-on in x at 0.8 m/s each, 0.3 m apart (2.5 in the metric): both push to brake.
        let (p, v) = ([0.0, 0.0, 1.0], [0.8, 0.0, 0.0]);
        let other = ([0.3, 0.0, 1.0], [-0.8, 0.0, 0.0]);
        let nominal = [2.0, 0.0, 0.0];
        let r = row(&cfg(), 2.0, p, v, other.0, other.1).unwrap();
        assert!(r.h < 0.0, "h = {}", r.h);
        let f = filter(&cfg(), 2.0, p, v, nominal, &[other]);
        assert_eq!(f.active, 1);
        assert!(!f.failed);
        assert!(f.u_mps2[0] < 0.0, "must brake: {:?}", f.u_mps2);
        assert!(f.u_mps2.iter().all(|x| x.abs() <= 2.0));
        // Either the row holds or the box stopped it (then the slack says by how much).
        assert!(dot(r.c, f.u_mps2) >= r.beta_mps2 - 1e-6 || f.slack_mps2 > 0.0);
    }

    #[test]
    fn the_filter_is_the_nearest_command_that_meets_the_row() {
        // One active row, box not binding: the projection of the nominal onto the half-space.
        let (p, v) = ([0.0, 0.0, 1.0], [0.0, 0.2, 0.0]);
        let other = ([0.0, 0.2, 1.0], [0.0, -0.2, 0.0]);
        let nominal = [0.1, 0.5, 0.0];
        let r = row(&cfg(), 2.0, p, v, other.0, other.1).unwrap();
        assert!(dot(r.c, nominal) < r.beta_mps2);
        assert!(r.beta_mps2.abs() < 1.5, "the test needs an unbinding box: β = {}", r.beta_mps2);
        let f = filter(&cfg(), 2.0, p, v, nominal, &[other]);
        let t = r.beta_mps2 - dot(r.c, nominal);
        let want: V3 = [0, 1, 2].map(|k| nominal[k] + t * r.c[k]);
        for k in 0..3 {
            assert!((f.u_mps2[k] - want[k]).abs() < 1e-7, "{:?} vs {want:?}", f.u_mps2);
        }
        assert!(f.slack_mps2 < 1e-7);
    }

    #[test]
    fn two_vehicles_with_the_filter_do_not_collide_head_on_where_they_would_without() {
        // Both fly straight at each other's start at full thrust; exact double integrators.
        for (filtered, want_collision) in [(false, true), (true, false)] {
            let mut s: [(V3, V3); 2] = [([-0.8, 0.0, 1.0], [0.0; 3]), ([0.8, 0.02, 1.0], [0.0; 3])];
            let goals = [[0.8, 0.0, 1.0], [-0.8, 0.0, 1.0]];
            let mut least = f64::INFINITY;
            for _ in 0..40 {
                let mut u = [[0.0; 3]; 2];
                for i in 0..2 {
                    let (p, v) = s[i];
                    let nominal: V3 = [0, 1, 2].map(|k| (4.0 * (goals[i][k] - p[k]) - 2.0 * v[k]).clamp(-2.0, 2.0));
                    u[i] = if filtered { filter(&cfg(), 2.0, p, v, nominal, &[s[1 - i]]).u_mps2 } else { nominal };
                }
                for m in 1..=10 {
                    let t = 0.01 * m as f64;
                    let at = |i: usize| {
                        let (p, v) = s[i];
                        [0, 1, 2].map(|k| p[k] + v[k] * t + 0.5 * u[i][k] * t * t)
                    };
                    let (a, b) = (at(0), at(1));
                    let q: V3 = [0, 1, 2].map(|k| (a[k] - b[k]) / ELLIPSOID_RADII_M[k]);
                    least = least.min(norm(q));
                }
                for i in 0..2 {
                    let (p, v) = s[i];
                    s[i] = (
                        [0, 1, 2].map(|k| p[k] + v[k] * 0.1 + 0.005 * u[i][k]),
                        [0, 1, 2].map(|k| v[k] + 0.1 * u[i][k]),
                    );
                }
            }
            assert_eq!(least < 1.0, want_collision, "filtered {filtered}: least ellipsoid distance {least}");
        }
    }

    #[test]
    fn bad_settings_are_named() {
        assert!(cfg().validate(2.0).is_empty());
        let bad = SafetyConfig { margin: 0.9, braking_share: 1.5, gamma_per_s: 0.0, disturbance_mps2: 2.0 };
        let e: Vec<String> = bad.validate(2.0).iter().map(|p| p.to_string()).collect();
        for key in ["margin", "braking_share", "gamma_per_s", "disturbance_mps2"] {
            assert!(e.iter().any(|p| p.contains(&format!("algorithm.safety.{key}"))), "{key} not in {e:?}");
        }
        assert!(toml::from_str::<SafetyConfig>("radius = 1.0").is_err());
    }
}
