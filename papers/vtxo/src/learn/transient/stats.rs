//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! Table 2 of the paper ("Data statistics with 99 percentile values of DNN predicted outputs")
//! for a transient data table: mean, mode, variance, P₁, max and P₉₉ of k₁, k₂, e, E and T.
//!
//! The print does not define its mode or percentiles: the mode here is the centre of the fullest
//! of 50 equal bins between the column's minimum and maximum, the variance is the sample variance
//! (n − 1), and percentiles are the one quantile rule of every Cohort table,
//! [`cohort_report::stats::quantile`] (linear interpolation between order statistics, numpy's
//! default), so the same numbers come out of any table read by the same rules.

use std::path::Path;

use cohort_report::markdown::MdTable;
use cohort_report::stats::quantile;

/// Bins of the mode's histogram.
const MODE_BINS: usize = 50;

/// The six statistics of one column.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stats {
    pub mean: f64,
    pub mode: f64,
    pub var: f64,
    pub p1: f64,
    pub max: f64,
    pub p99: f64,
}

/// The statistics of a non-empty column.
pub fn stats(x: &[f64]) -> Stats {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
    let mut s = x.to_vec();
    s.sort_by(f64::total_cmp);
    let (lo, hi) = (s[0], s[s.len() - 1]);
    let width = (hi - lo) / MODE_BINS as f64;
    let mode = if width > 0.0 {
        let mut counts = [0usize; MODE_BINS];
        for v in &s {
            counts[(((v - lo) / width) as usize).min(MODE_BINS - 1)] += 1;
        }
        let best = (0..MODE_BINS).fold(0, |b, i| if counts[i] > counts[b] { i } else { b });
        lo + (best as f64 + 0.5) * width
    } else {
        lo
    };
    Stats { mean, mode, var, p1: quantile(&s, 0.01), max: hi, p99: quantile(&s, 0.99) }
}

/// Table 2's rows in its order: (name, column of the data table).
pub const ROWS: [(&str, &str); 5] =
    [("k1", "k1_N_m"), ("k2", "k2_N_m_s"), ("e (deg)", "e_deg"), ("E (J)", "E_J"), ("T (s)", "T_s")];

/// Read the named columns of a table written by [`crate::learn::transient::data`] ('#' lines skipped).
pub fn read_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().ok_or_else(|| format!("{}: no header", path.display()))?.split(',').collect();
    let idx = names
        .iter()
        .map(|n| header.iter().position(|h| h == n).ok_or_else(|| format!("{}: no column {n:?}", path.display())))
        .collect::<Result<Vec<_>, _>>()?;
    let mut cols = vec![Vec::new(); names.len()];
    for (ln, l) in lines.enumerate() {
        let f: Vec<&str> = l.split(',').collect();
        for (c, &i) in idx.iter().enumerate() {
            let v = f.get(i).and_then(|s| s.parse::<f64>().ok()).ok_or_else(|| {
                format!("{}: data line {}: column {:?} is not a number", path.display(), ln + 1, names[c])
            })?;
            cols[c].push(v);
        }
    }
    if cols[0].is_empty() {
        return Err(format!("{}: no rows", path.display()));
    }
    Ok(cols)
}

/// Table 2's analogue of a data table, as markdown.
pub fn table2_markdown(path: &Path) -> Result<String, String> {
    let names: Vec<&str> = ROWS.iter().map(|r| r.1).collect();
    Ok(table2_of(&read_columns(path, &names)?))
}

/// Table 2's analogue of columns in [`ROWS`]' order, as markdown.
pub fn table2_of(cols: &[Vec<f64>]) -> String {
    let mut t = MdTable::new(["y", "mean", "mode", "variance", "P1", "max", "P99"]);
    for ((name, _), c) in ROWS.iter().zip(cols) {
        let s = stats(c);
        let f4 = |x: f64| format!("{x:.4}");
        t.row([name.to_string(), f4(s.mean), f4(s.mode), format!("{:.4e}", s.var), f4(s.p1), f4(s.max), f4(s.p99)]);
    }
    format!("{} points\n\n{t}", cols.first().map_or(0, Vec::len))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statistics_of_a_known_column() {
        let x: Vec<f64> = (0..=100).map(f64::from).collect();
        let s = stats(&x);
        assert_eq!((s.mean, s.p1, s.p99, s.max), (50.0, 1.0, 99.0, 100.0));
        assert!((s.var - 858.5).abs() < 1e-9, "{}", s.var);
        // One dominant value: the mode's bin holds it.
        let mut y = vec![0.0, 10.0];
        y.extend(std::iter::repeat_n(7.0, 20));
        assert!((stats(&y).mode - 7.0).abs() <= 0.2, "{}", stats(&y).mode);
    }
}
