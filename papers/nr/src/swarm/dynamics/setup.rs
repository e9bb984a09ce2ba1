//! The swarm's geometry and its random reconfiguration problems (Sec. 7.2 of "Neural-Rendezvous",
//! arXiv:2208.04883): where the vehicles start, where they must go, and the tall-ellipsoid
//! distance that defines a collision.
//!
//! The paper samples starts and targets in a cuboid such that (i) each vehicle's start and target
//! are at least some distance apart and (ii) every sampled point is at least some distance from
//! every other; the collision constraint is a tall ellipsoid (downwash). Its numbers are lost;
//! ours (the Crazyswarm convention): ellipsoid radii (0.12, 0.12, 0.30) m, so two vehicles collide
//! iff ‖diag(0.12, 0.12, 0.30)⁻¹(p_i − p_j)‖ < 1; cuboid [−2, 2] × [−2, 2] × [0.5, 2] m;
//! start–target ≥ 1 m (Euclidean); every two of the 2N sampled points ≥ 1.25 in the ellipsoid
//! metric (a vehicle's own start and target included: at ≥ 1 m they are ≥ 3.3 apart in it).
//!
//! [`draw`] is the one sampler: the scenarios' plant and the training data of the global solution
//! call it, so a seed means the same problem everywhere. It is sequential rejection sampling,
//! deterministic in (n, seed): starts 1..N first, then goals 1..N, each point drawn uniformly in
//! the cuboid until it keeps its distances to every point accepted before it (and a goal ≥ 1 m
//! from its own start), at most [`MAX_TRIES`] draws per point.

use cohort_runtime::rng::setup_rng;
use rand::Rng;

/// Ellipsoid radii (x, y, z) of the collision metric, m.
pub const ELLIPSOID_RADII_M: [f64; 3] = [0.12, 0.12, 0.30];
/// A cuboid as `[[x_min, x_max], [y_min, y_max], [z_min, z_max]]`, m (the plant's `cuboid_m`).
pub type Cuboid = [[f64; 2]; 3];
/// The paper's cuboid starts and goals are sampled in, m (the plant's default `cuboid_m`).
pub const CUBOID_M: Cuboid = [[-2.0, 2.0], [-2.0, 2.0], [0.5, 2.0]];
/// Least start–target distance of one vehicle, m (Euclidean).
pub const MIN_TRAVEL_M: f64 = 1.0;
/// Least ellipsoid distance between any two sampled points.
pub const MIN_SAMPLE_SEPARATION: f64 = 1.25;
/// Per-axis acceleration limit, m/s².
pub const A_MAX_MPS2: f64 = 2.0;
/// Reconfiguration time T, s.
pub const T_RECONFIG_S: f64 = 8.0;
/// Control interval, s.
#[cfg(feature = "host")]
pub const DT_S: f64 = 0.1;
/// Communication radius R_comm, m.
pub const R_COMM_M: f64 = 1.0;
/// Draws per point before [`draw`] gives up.
pub const MAX_TRIES: usize = 10_000;
/// The set-up stream's name (`cohort_runtime::rng::setup_rng`).
const STREAM: &str = "nr-swarm-setup";

/// ‖diag(radii)⁻¹ dp‖: < 1 is a collision.
pub fn ellipsoid_distance(dp_m: [f64; 3]) -> f64 {
    (0..3).map(|a| (dp_m[a] / ELLIPSOID_RADII_M[a]).powi(2)).sum::<f64>().sqrt()
}

/// Euclidean distance, m.
pub fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt()
}

/// aᵀb.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// ‖a‖ (Euclidean).
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn diff(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Points of the swarm, vehicle i at index i − 1.
pub type Points = Vec<[f64; 3]>;

/// Why no problem could be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DrawError {
    #[error("a swarm needs at least one vehicle")]
    Empty,
    #[error(
        "could not place {what} of vehicle {vehicle} after {MAX_TRIES} draws: {n} vehicles do not fit the cuboid \
         with the separations"
    )]
    Crowded { what: &'static str, vehicle: usize, n: usize },
}

/// Starts and goals of `n` vehicles for `seed` in the paper's cuboid [`CUBOID_M`] (see the
/// module docs), vehicle i at index i − 1.
pub fn draw(n: usize, seed: u64) -> Result<(Points, Points), DrawError> {
    draw_in(n, seed, &CUBOID_M)
}

/// [`draw`] in `cuboid` (the plant's `cuboid_m`): the same sampler, the same stream.
pub fn draw_in(n: usize, seed: u64, cuboid: &Cuboid) -> Result<(Points, Points), DrawError> {
    if n == 0 {
        return Err(DrawError::Empty);
    }
    let mut rng = setup_rng(seed, STREAM);
    let mut placed: Vec<[f64; 3]> = Vec::with_capacity(2 * n);
    for k in 0..2 * n {
        let (what, vehicle) = if k < n { ("the start", k + 1) } else { ("the goal", k - n + 1) };
        let own_start = (k >= n).then(|| placed[k - n]);
        let point = (0..MAX_TRIES)
            .map(|_| cuboid.map(|[lo, hi]| rng.random_range(lo..hi)))
            .find(|p| {
                placed.iter().all(|q| ellipsoid_distance(diff(*p, *q)) >= MIN_SAMPLE_SEPARATION)
                    && own_start.is_none_or(|s| distance_m(*p, s) >= MIN_TRAVEL_M)
            })
            .ok_or(DrawError::Crowded { what, vehicle, n })?;
        placed.push(point);
    }
    let goals = placed.split_off(n);
    Ok((placed, goals))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_problems_keep_every_separation_and_repeat_exactly() {
        for (n, seed) in [(1, 0), (8, 1), (8, 2), (20, 3), (20, 4)] {
            let (s, g) = draw(n, seed).unwrap();
            assert_eq!((s.len(), g.len()), (n, n));
            let all: Vec<[f64; 3]> = s.iter().chain(&g).copied().collect();
            for (i, p) in all.iter().enumerate() {
                for a in 0..3 {
                    assert!(p[a] >= CUBOID_M[a][0] && p[a] < CUBOID_M[a][1], "point {i} outside: {p:?}");
                }
                for q in &all[i + 1..] {
                    assert!(ellipsoid_distance(diff(*p, *q)) >= MIN_SAMPLE_SEPARATION);
                }
            }
            for i in 0..n {
                assert!(distance_m(s[i], g[i]) >= MIN_TRAVEL_M);
            }
            assert_eq!(draw(n, seed).unwrap(), (s, g), "deterministic in (n, seed)");
        }
        assert_ne!(draw(8, 1).unwrap(), draw(8, 2).unwrap());
        assert_eq!(draw(0, 1), Err(DrawError::Empty));
    }

    #[test]
    fn the_collision_metric_is_the_tall_ellipsoid() {
        assert!((ellipsoid_distance([0.12, 0.0, 0.0]) - 1.0).abs() < 1e-15);
        assert!((ellipsoid_distance([0.0, 0.0, 0.30]) - 1.0).abs() < 1e-15);
        // 0.2 m apart horizontally is clear, 0.2 m above each other a collision (downwash).
        assert!(ellipsoid_distance([0.2, 0.0, 0.0]) > 1.0 && ellipsoid_distance([0.0, 0.0, 0.2]) < 1.0);
    }

    #[test]
    fn an_impossible_crowd_is_an_error_not_a_hang() {
        // In a 0.1 m cube no two points are 1.25 apart in the metric (its diagonal is 1.22), nor
        // 1 m apart.
        let tiny = [[0.0, 0.1]; 3];
        assert_eq!(draw_in(1, 1, &tiny), Err(DrawError::Crowded { what: "the goal", vehicle: 1, n: 1 }));
        assert_eq!(draw_in(2, 1, &tiny), Err(DrawError::Crowded { what: "the start", vehicle: 2, n: 2 }));
        // 20 vehicles, the most the scenarios fly, fit easily: every seed of a range draws.
        assert!((0..50).all(|seed| draw(20, seed).is_ok()));
    }
}
