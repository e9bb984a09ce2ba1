//! Who must hear whom: the swarm's static neighbour rule. The subscription graph of a run is fixed
//! before it starts, the vehicles move, and a vehicle reads only the shares from within R_comm
//! ([`crate::swarm::control::agent`]). So a vehicle's list must hold everyone who can come within
//! R_comm of it during the run; anyone else's shares it would drop anyway, and leaving them out
//! changes nothing it computes (the shares it keeps are sorted by id, whatever it hears).
//!
//! The rule: vehicles i and j hear each other iff their straight start→goal segments come within
//! [`reach_m`] = R_comm + 2·[`STRAY_M`] + [`ESTIMATE_MARGIN_M`] of each other. It is sound as long
//! as no vehicle strays more than [`STRAY_M`] from its own segment (then two vehicles within
//! R_comm of each other lie within R_comm + 2·STRAY_M of each other's segments at that time), and
//! the distance a vehicle judges (its estimate against the neighbour's share propagated over one
//! interval) is within [`ESTIMATE_MARGIN_M`] of the truth.
//!
//! - [`STRAY_M`] is measured, not proven (the learned policy has no bound of its own, and the
//!   kinematic bound from a_max, ½·√3·a_max·t², passes the whole cuboid within 2 s): over the 60
//!   runs of `swarm-20.toml` and `swarm-20-disturbed.toml` at seeds 1–30 the largest distance of
//!   any vehicle from its segment was 0.78 m; ours 1.0 m. Every run's analysis reports
//!   `max_stray_m` and `unlisted_pairs_within_r_comm` (pairs that came within R_comm, truth,
//!   without hearing each other), so a run where the assumption fails says so.
//! - [`ESTIMATE_MARGIN_M`]: the readings' noise is 1 mm and 1 cm/s (σ), the estimator's error
//!   smaller; one interval's propagation misses only the disturbance (½·0.2·0.1² = 1 mm) and a
//!   clip. 0.05 m is ≥ 10× any of them.

use crate::swarm::dynamics::setup::{Points, dot};

type V3 = [f64; 3];

/// How far a vehicle may stray from its straight start→goal segment over a run, m (see the
/// module docs: measured ≤ 0.78 m on the shipped 20-vehicle scenarios).
pub const STRAY_M: f64 = 1.0;
/// How far the distance a vehicle judges may be from the truth, m (module docs).
pub const ESTIMATE_MARGIN_M: f64 = 0.05;

/// The segments of two vehicles that hear each other come within this, m.
pub fn reach_m(r_comm_m: f64) -> f64 {
    r_comm_m + 2.0 * STRAY_M + ESTIMATE_MARGIN_M
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn at(p: V3, d: V3, t: f64) -> V3 {
    [p[0] + d[0] * t, p[1] + d[1] * t, p[2] + d[2] * t]
}

/// The least distance between the segments [a0, a1] and [b0, b1], m (Ericson, "Real-Time
/// Collision Detection", 5.1.9; a segment may be a point).
pub fn segment_distance_m(a0: V3, a1: V3, b0: V3, b1: V3) -> f64 {
    let (d1, d2, r) = (sub(a1, a0), sub(b1, b0), sub(a0, b0));
    let (a, e, f) = (dot(d1, d1), dot(d2, d2), dot(d2, r));
    let (s, t) = if a <= f64::EPSILON && e <= f64::EPSILON {
        (0.0, 0.0)
    } else if a <= f64::EPSILON {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = dot(d1, r);
        if e <= f64::EPSILON {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = dot(d1, d2);
            let denom = a * e - b * b;
            let s = if denom > 0.0 { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            let t = (b * s + f) / e;
            if t < 0.0 {
                ((-c / a).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((b - c) / a).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    let gap = sub(at(a0, d1, s), at(b0, d2, t));
    dot(gap, gap).sqrt()
}

/// Each vehicle's neighbours by the rule, ids (1-based, ascending); vehicle i at index i − 1.
pub fn neighbour_lists(starts: &Points, goals: &Points, r_comm_m: f64) -> Vec<Vec<u32>> {
    let reach = reach_m(r_comm_m);
    let n = starts.len();
    let mut lists = vec![Vec::new(); n];
    for i in 0..n {
        for j in i + 1..n {
            if segment_distance_m(starts[i], goals[i], starts[j], goals[j]) < reach {
                lists[i].push(j as u32 + 1);
                lists[j].push(i as u32 + 1);
            }
        }
    }
    for l in &mut lists {
        l.sort_unstable();
    }
    lists
}

/// The least distance of `p` from the segment [a, b], m.
pub fn distance_from_segment_m(p: V3, a: V3, b: V3) -> f64 {
    segment_distance_m(p, p, a, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::swarm::dynamics::setup::draw;

    #[test]
    fn segment_distance_covers_crossing_parallel_skew_and_end_cases() {
        let d = segment_distance_m;
        // Crossing in a plane, and the same lifted 0.5 m apart (skew).
        assert!(d([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]).abs() < 1e-15);
        assert!((d([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.5], [0.0, 1.0, 0.5]) - 0.5).abs() < 1e-15);
        // Parallel, overlapping and end to end.
        assert!((d([0.0; 3], [2.0, 0.0, 0.0], [1.0, 0.3, 0.0], [3.0, 0.3, 0.0]) - 0.3).abs() < 1e-15);
        assert!((d([0.0; 3], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0], [4.0, 0.0, 0.0]) - 2.0).abs() < 1e-15);
        // The closest points past an end of the infinite lines: end to end, 3-4-5.
        assert!((d([0.0; 3], [1.0, 0.0, 0.0], [4.0, 4.0, 0.0], [4.0, 9.0, 0.0]) - 5.0).abs() < 1e-15);
        // Points.
        assert!((d([0.0; 3], [0.0; 3], [0.0, 2.0, 0.0], [0.0, 2.0, 0.0]) - 2.0).abs() < 1e-15);
        assert!((distance_from_segment_m([0.5, 1.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0]) - 1.0).abs() < 1e-15);
        assert!((distance_from_segment_m([-3.0, 4.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0]) - 5.0).abs() < 1e-15);
    }

    /// The closest distance against a dense sampling of both segments: never above it, and within
    /// the sampling's resolution of it.
    #[test]
    fn segment_distance_is_the_least_over_both_segments() {
        let (s, g) = draw(20, 7).unwrap();
        for i in 0..20 {
            for j in i + 1..20 {
                let exact = segment_distance_m(s[i], g[i], s[j], g[j]);
                let along = |p: V3, q: V3, k: usize| at(p, sub(q, p), k as f64 / 200.0);
                let sampled = (0..=200)
                    .flat_map(|a| (0..=200).map(move |b| (a, b)))
                    .map(|(a, b)| {
                        let gap = sub(along(s[i], g[i], a), along(s[j], g[j], b));
                        dot(gap, gap).sqrt()
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(exact <= sampled + 1e-12 && sampled - exact < 0.05, "{i}, {j}: {exact} vs {sampled}");
            }
        }
    }

    #[test]
    fn lists_are_symmetric_and_hold_exactly_the_pairs_within_reach() {
        assert_eq!(reach_m(1.0), 3.05);
        let starts = vec![[0.0, 0.0, 1.0], [0.0, 3.0, 1.0], [0.0, 6.1, 1.0], [10.0, 0.0, 1.0]];
        let goals = vec![[1.0, 0.0, 1.0], [1.0, 3.0, 1.0], [1.0, 6.1, 1.0], [10.0, 9.0, 1.0]];
        // 1–2 are 3 m apart (within 3.05), 2–3 3.1 m (not), 1–3 6.1 m; 4 runs past 1, 2 and 3 at 9 m.
        assert_eq!(neighbour_lists(&starts, &goals, 1.0), vec![vec![2], vec![1], vec![], vec![]]);
        let (s, g) = draw(20, 2).unwrap();
        let lists = neighbour_lists(&s, &g, 1.0);
        for (i, l) in lists.iter().enumerate() {
            for j in l {
                assert!(lists[*j as usize - 1].contains(&(i as u32 + 1)), "{i} hears {j}, not back");
            }
            assert!(!l.contains(&(i as u32 + 1)) && l.windows(2).all(|w| w[0] < w[1]), "{l:?}");
        }
    }
}
