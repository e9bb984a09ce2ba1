//! The link model on hand geometry: blockage, delay, loss frequency, the rate cap.

use super::*;
use cohort_scenario::links::{LinkKind, Loss};
use rand::SeedableRng;

const R_EARTH_M: f64 = 6_378_137.0;

fn links(f: impl FnOnce(&mut Links)) -> Links {
    let mut l = Links { model: LinkKind::Geometric, ..Links::default() };
    f(&mut l);
    l
}

/// Two agents reading each other.
fn pair(cfg: Links, dt_s: f64) -> LinkModel {
    LinkModel::new(cfg, dt_s, vec![vec![2], vec![1]], ChaCha8Rng::seed_from_u64(7))
}

fn codes_at(m: &mut LinkModel, k: u64, pos: &[[f64; 3]; 2], bits: u64) -> [u32; 2] {
    let mut codes = vec![Vec::new(), Vec::new()];
    m.decide(k, pos, &[bits, bits], &mut codes);
    [codes[0][0], codes[1][0]]
}

#[test]
fn earth_between_two_spacecraft_blocks_both_directions_and_clear_sky_does_not() {
    let r = R_EARTH_M + 500e3;
    let mut m = pair(links(|l| l.occulting_radius_m = Some(R_EARTH_M + 100e3)), 0.1);
    // Opposite sides of the Earth: the segment passes through its centre.
    assert_eq!(codes_at(&mut m, 0, &[[r, 0.0, 0.0], [-r, 0.0, 0.0]], 0), [LINK_BLOCKED; 2]);
    // 60° apart in a 500 km orbit: the chord's lowest point is r·cos 30° = 5 957 km from the
    // centre, below the 6 478 km sphere → blocked; 20° apart: r·cos 10° = 6 774 km → visible.
    let at = |deg: f64| [r * deg.to_radians().cos(), r * deg.to_radians().sin(), 0.0];
    assert_eq!(codes_at(&mut m, 1, &[at(0.0), at(60.0)], 0), [LINK_BLOCKED; 2]);
    let seen = codes_at(&mut m, 2, &[at(0.0), at(20.0)], 0);
    assert!(seen.iter().all(|c| delay_of(*c).is_some()), "{seen:?}");
    assert!(!occulted(&at(0.0), &at(20.0), R_EARTH_M + 100e3));
    assert!(occulted(&at(0.0), &at(60.0), R_EARTH_M + 100e3));
    let s = m.stats();
    assert_eq!((s[0].stats.blocked, s[0].stats.delivered, s[0].stats.steps), (2, 1, 3));
}

#[test]
fn the_delay_is_the_light_time_and_processing_rounded_up_to_whole_steps() {
    let dt_s = 0.001;
    for (range_m, processing_s) in [(10e3, 0.0), (299_792.458, 0.0), (1_000e3, 0.0025), (1.0, 0.0)] {
        let mut m = pair(links(|l| l.processing_latency_s = processing_s), dt_s);
        let want = ((range_m / C_MPS + processing_s) / dt_s).ceil() as u32;
        let got = codes_at(&mut m, 0, &[[0.0; 3], [range_m, 0.0, 0.0]], 0);
        assert_eq!(got, [want; 2], "range {range_m} m, processing {processing_s} s");
    }
    // By hand: 299 792.458 m is 1 ms of light, exactly one step; 1 000 km + 2.5 ms is 5.84 ms → 6.
    let mut m = pair(links(|l| l.processing_latency_s = 0.0025), dt_s);
    assert_eq!(codes_at(&mut m, 0, &[[0.0; 3], [1_000e3, 0.0, 0.0]], 0), [6, 6]);
}

#[test]
fn losses_fall_within_the_binomial_band_of_the_configured_rate() {
    let p = 0.1;
    let n = 20_000u64;
    let mut m = pair(links(|l| l.loss = Some(Loss::Constant { p })), 0.1);
    let mut lost = 0u64;
    for k in 0..n {
        lost +=
            codes_at(&mut m, k, &[[0.0; 3], [1e3, 0.0, 0.0]], 0).iter().filter(|c| **c == LINK_LOST_IN_TRANSIT).count()
                as u64;
    }
    let trials = 2.0 * n as f64;
    let sigma = (trials * p * (1.0 - p)).sqrt();
    assert!((lost as f64 - trials * p).abs() < 4.0 * sigma, "{lost} lost of {trials}, expected {}", trials * p);
}

#[test]
fn the_same_seed_decides_the_same_and_another_does_not() {
    let cfg = links(|l| l.loss = Some(Loss::Constant { p: 0.5 }));
    let run = |seed: u64| {
        let mut m = LinkModel::new(cfg.clone(), 0.1, vec![vec![2], vec![1]], ChaCha8Rng::seed_from_u64(seed));
        (0..200).map(|k| codes_at(&mut m, k, &[[0.0; 3], [1e3, 0.0, 0.0]], 0)).collect::<Vec<_>>()
    };
    assert_eq!(run(1), run(1));
    assert_ne!(run(1), run(2));
}

#[test]
fn out_of_range_wins_over_blockage_and_a_slow_link_skips_shares_while_busy() {
    let mut m = pair(links(|l| l.max_range_m = Some(5e3)), 0.1);
    assert_eq!(codes_at(&mut m, 0, &[[0.0; 3], [6e3, 0.0, 0.0]], 0), [LINK_OUT_OF_RANGE; 2]);
    // 25 000 bits at 100 kbit/s take 0.25 s: of steps of 0.1 s, one share in three is sent, and
    // each arrives 3 steps later (0.25 s + 3.3 µs of light, rounded up).
    let mut m = pair(links(|l| l.data_rate_bps = Some(1e5)), 0.1);
    let got: Vec<u32> = (0..6).map(|k| codes_at(&mut m, k, &[[0.0; 3], [1e3, 0.0, 0.0]], 25_000)[0]).collect();
    assert_eq!(got, [3, LINK_BUSY, LINK_BUSY, 3, LINK_BUSY, LINK_BUSY]);
}
