//! The cost of `run.authenticate`: the N = 6 ring with it against without, and ns to seal and
//! check one share.

use std::fmt::Write as _;
use std::time::Instant;

use super::report::{f0, get};
use super::types::Aggregate;

/// ns per message to seal and check a share of `values` values (what `run.authenticate` adds to
/// every message, once at its sender and once at each reader).
pub(super) fn mac_ns(values: usize) -> (f64, f64) {
    use cohort_wire::msg::{Header, Share};
    let key = cohort_wire::auth::MacKey::from_bytes([7; 32]);
    let vals: Vec<f64> = (0..values).map(|i| i as f64 * 0.5).collect();
    let mut s = Share::new(Header::new(1, 2, 3, 0.03), &[1.0, 2.0, 3.0], &vals);
    let n = 200_000u32;
    let t0 = Instant::now();
    for k in 0..n {
        s.header.step = u64::from(k);
        key.seal_share(std::hint::black_box(&mut s));
    }
    let seal = t0.elapsed().as_secs_f64() * 1e9 / f64::from(n);
    let t1 = Instant::now();
    let mut ok = 0u32;
    for _ in 0..n {
        ok += u32::from(key.check_share(std::hint::black_box(&s)));
    }
    let check = t1.elapsed().as_secs_f64() * 1e9 / f64::from(n);
    assert_eq!(ok, n, "a sealed share always checks");
    (seal, check)
}

/// The `run.authenticate` section: the N = 6 ring's steps/s without and with, and the ns to seal
/// and check a share of each size in `mac`.
pub(super) fn mac_markdown(a: &[Aggregate], mac: &[(usize, (f64, f64))]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "\n## run.authenticate (keyed BLAKE3 MAC on every message)\n");
    if let (Some(off), Some(on)) = (get(a, "ring/N=6/adaptive"), get(a, "mac/N=6/adaptive+authenticate")) {
        let _ = writeln!(
            md,
            "Consensus ring N = 6, adaptive: {} steps/s without, {} steps/s with (×{:.2}).\n",
            f0(off.steps_per_s_median),
            f0(on.steps_per_s_median),
            on.steps_per_s_median / off.steps_per_s_median
        );
    }
    md.push_str("| share values | seal ns | check ns |\n|---|---|---|\n");
    for (v, (seal, check)) in mac {
        let _ = writeln!(md, "| {v} | {seal:.0} | {check:.0} |");
    }
    md
}
