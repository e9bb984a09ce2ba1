//! The results of `orchestrator sweep`: every seed's summary metrics (`sweep.csv`) and their
//! distribution (`sweep.md`: min, median, max, mean and the nearest-rank 99th percentile), with seed 000's published criterion checked when its metrics are
//! present.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

/// The paper's "≈ 5 m after ≈ 200 s" and "≈ 5 m/s after ≈ 150 s" (seed 000, Figs. 3–4).
const E_BOUND_M: f64 = 5.0;
const ZETA_BOUND_MPS: f64 = 5.0;

fn stats(xs: &mut [f64]) -> (f64, f64, f64, f64) {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    let median = if n % 2 == 1 { xs[n / 2] } else { 0.5 * (xs[n / 2 - 1] + xs[n / 2]) };
    (xs[0], median, xs[n - 1], xs.iter().sum::<f64>() / n as f64)
}

/// The 99th percentile by the nearest-rank rule (the ⌈0.99 n⌉-th smallest) of sorted `xs`.
fn p99(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    sorted[((0.99 * n as f64).ceil() as usize).clamp(1, n) - 1]
}

fn g(x: f64) -> String {
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) { format!("{x:.3e}") } else { format!("{x:.4}") }
}

/// Write `sweep.csv` and `sweep.md` under `root`; returns the Markdown.
pub fn write(root: &Path, file: &Path, mode: &str, rows: &[(u64, BTreeMap<String, f64>)]) -> Result<String, String> {
    let keys: BTreeSet<&String> = rows.iter().flat_map(|(_, m)| m.keys()).collect();
    let mut csv = String::from("seed");
    for k in &keys {
        csv.push(',');
        csv.push_str(k);
    }
    csv.push('\n');
    for (seed, m) in rows {
        let _ = write!(csv, "{seed}");
        for k in &keys {
            match m.get(*k) {
                Some(v) => {
                    let _ = write!(csv, ",{v:?}");
                }
                None => csv.push(','),
            }
        }
        csv.push('\n');
    }
    let csv_path = root.join("sweep.csv");
    std::fs::write(&csv_path, csv).map_err(|e| format!("{}: {e}", csv_path.display()))?;

    let seeds: Vec<String> = rows.iter().map(|(s, _)| s.to_string()).collect();
    let mut md =
        format!("# Sweep of `{}`\n\n{} runs ({mode}), seeds {}.\n\n", file.display(), rows.len(), seeds.join(", "));
    // Per-servicer metrics as one table: rows servicers, cells "median (min – max)".
    let mut per: BTreeMap<u32, BTreeMap<String, Vec<f64>>> = BTreeMap::new();
    let mut other: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for (_, m) in rows {
        for (k, v) in m {
            let split = k
                .strip_prefix("servicer_")
                .and_then(|r| r.split_once('.'))
                .and_then(|(i, n)| Some((i.parse::<u32>().ok()?, n)));
            match split {
                Some((i, name)) => per.entry(i).or_default().entry(name.to_string()).or_default().push(*v),
                None => other.entry(k.clone()).or_default().push(*v),
            }
        }
    }
    if !per.is_empty() {
        let names: BTreeSet<String> = per.values().flat_map(|m| m.keys().cloned()).collect();
        md.push_str("Per servicer, over the seeds: median (min – max).\n\n| servicer |");
        for n in &names {
            let _ = write!(md, " {n} |");
        }
        md.push_str("\n|---|");
        md.push_str(&"---|".repeat(names.len()));
        md.push('\n');
        for (i, m) in &per {
            let _ = write!(md, "| {i} |");
            for n in &names {
                match m.get(n) {
                    Some(xs) => {
                        let (lo, med, hi, _) = stats(&mut xs.clone());
                        let _ = write!(md, " {} ({} – {}) |", g(med), g(lo), g(hi));
                    }
                    None => md.push_str(" – |"),
                }
            }
            md.push('\n');
        }
        md.push('\n');
    }
    if !other.is_empty() {
        md.push_str("| metric | min | median | max | mean | p99 |\n|---|---|---|---|---|---|\n");
        for (k, xs) in &other {
            let mut sorted = xs.clone();
            let (lo, med, hi, mean) = stats(&mut sorted);
            let _ = writeln!(md, "| {k} | {} | {} | {} | {} | {} |", g(lo), g(med), g(hi), g(mean), g(p99(&sorted)));
        }
        md.push('\n');
    }
    // Seed 000's criterion: every servicer, every seed.
    let crit = |m: &BTreeMap<String, f64>, stem: &str| -> Option<f64> {
        let xs: Vec<f64> = m.iter().filter(|(k, _)| k.contains(stem)).map(|(_, v)| *v).collect();
        (!xs.is_empty()).then(|| xs.into_iter().fold(f64::MIN, f64::max))
    };
    let has = rows.iter().all(|(_, m)| crit(m, ".e_rms_200_").is_some() && crit(m, ".zeta_err_rms_150_").is_some());
    if has && !rows.is_empty() {
        let _ = writeln!(
            md,
            "Seed 000 criterion (paper: ‖eᵢ‖ ≈ {E_BOUND_M} m after 200 s, ‖ζ̃ᵢ‖ ≈ {ZETA_BOUND_MPS} m/s after 150 s): \
             worst servicer per seed.\n\n| seed | max e_rms_200_end (m) | max zeta_err_rms_150_end (m/s) | within both |\n|---|---|---|---|"
        );
        let mut pass = 0;
        for (seed, m) in rows {
            let (e, z) =
                (crit(m, ".e_rms_200_").unwrap_or(f64::NAN), crit(m, ".zeta_err_rms_150_").unwrap_or(f64::NAN));
            let ok = e <= E_BOUND_M && z <= ZETA_BOUND_MPS;
            pass += usize::from(ok);
            let _ = writeln!(md, "| {seed} | {} | {} | {} |", g(e), g(z), if ok { "yes" } else { "no" });
        }
        let _ = writeln!(md, "\n{pass} of {} seeds meet both bounds for every servicer.", rows.len());
    }
    let md_path = root.join("sweep.md");
    std::fs::write(&md_path, &md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    Ok(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p99_is_the_nearest_rank() {
        let xs: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(p99(&xs), 99.0);
        let xs: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(p99(&xs), 10.0);
        assert_eq!(p99(&[3.0]), 3.0);
    }
}
