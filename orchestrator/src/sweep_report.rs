//! The results of `orchestrator sweep`: every seed's summary metrics (`sweep.csv`) and their
//! distribution (`sweep.md`: min, median, max, mean and the 99th percentile, by the one quantile
//! rule of `cohort_report::stats`), followed by the sections the scenario's papers add
//! (`RunHooks::sweep_section`: a published criterion checked per seed).

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

use cohort_report::markdown::MdTable;
use cohort_report::stats::describe;

fn g(x: f64) -> String {
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) { format!("{x:.3e}") } else { format!("{x:.4}") }
}

/// Write `sweep.csv` and `sweep.md` under `root`, the papers' `sections` at the end of the
/// Markdown; returns the Markdown.
pub fn write(
    root: &Path,
    file: &Path,
    mode: &str,
    rows: &[(u64, BTreeMap<String, f64>)],
    sections: &[String],
) -> Result<String, String> {
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
        md.push_str("Per servicer, over the seeds: median (min – max).\n\n");
        let mut t = MdTable::new(std::iter::once("servicer".to_string()).chain(names.iter().cloned()));
        for (i, m) in &per {
            let cells = names.iter().map(|n| match m.get(n) {
                Some(xs) => {
                    let d = describe(xs);
                    format!("{} ({} – {})", g(d.median), g(d.min), g(d.max))
                }
                None => "–".to_string(),
            });
            t.row(std::iter::once(i.to_string()).chain(cells));
        }
        let _ = writeln!(md, "{t}");
    }
    if !other.is_empty() {
        let mut t = MdTable::new(["metric", "min", "median", "max", "mean", "p99"]);
        for (k, xs) in &other {
            let d = describe(xs);
            t.row([k.clone(), g(d.min), g(d.median), g(d.max), g(d.mean), g(d.p99)]);
        }
        let _ = writeln!(md, "{t}");
    }
    for section in sections {
        md.push_str(section);
    }
    let md_path = root.join("sweep.md");
    std::fs::write(&md_path, &md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    Ok(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_metrics_table_uses_the_one_quantile_rule() {
        let root = std::env::temp_dir().join(format!("cohort-sweep-report-{}", std::process::id()));
        std::fs::create_dir_all(&root).unwrap();
        let rows: Vec<(u64, BTreeMap<String, f64>)> =
            (1..=10).map(|s| (s, BTreeMap::from([("x_m".to_string(), s as f64)]))).collect();
        let md = write(&root, Path::new("f.toml"), "reference", &rows, &[]).unwrap();
        let _ = std::fs::remove_dir_all(&root);
        // 1..=10: median 5.5, P99 by linear interpolation 9.91 (the nearest rank would say 10)
        assert!(md.contains("| x_m | 1.0000 | 5.5000 | 10.0000 | 5.5000 | 9.9100 |"), "{md}");
    }
}
