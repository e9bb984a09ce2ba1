//! `campaign.md` and the campaign's plots: the dispersions and what they drew, the runs' statuses,
//! each verdict line's pass rate, every metric's distribution (min, P1, median, P99, max, mean ±
//! the 95 % interval), and for the chosen metric a histogram and its scatter against every
//! numeric drawn value (`plots/`). Nothing here depends on wall time or on the workers, so a
//! campaign's report is the same however it was run.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort_report::markdown::MdTable;
use cohort_report::stats::describe;

use super::row::CaseRow;
use super::table::{metric_names, verdict_names};

/// What the report says about the campaign besides its rows.
pub struct Header<'a> {
    pub file: &'a Path,
    pub seed: u64,
    pub mode: &'a str,
    pub columns: &'a [String],
    /// The dispersions as written.
    pub spec_text: &'a str,
    /// The metric of the plots and the running estimate, if chosen.
    pub metric: Option<&'a str>,
    /// `--until` met at this many cases, or the planned count when it ran them all.
    pub stopped: Option<String>,
}

fn g(x: f64) -> String {
    if !x.is_finite() {
        return "–".into();
    }
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) { format!("{x:.3e}") } else { format!("{x:.4}") }
}

/// The Markdown of the campaign.
pub fn markdown(h: &Header, rows: &[CaseRow], plots: &[PathBuf]) -> String {
    let mut md = format!(
        "# Campaign of `{}`\n\n{} cases ({}), campaign seed {}.\n\n",
        h.file.display(),
        rows.len(),
        h.mode,
        h.seed
    );
    if let Some(s) = &h.stopped {
        let _ = writeln!(md, "{s}\n");
    }
    if h.columns.is_empty() {
        let _ = writeln!(md, "## Dispersions\n\nNone: case i flies the nominal scenario with seed {} + i.\n", h.seed);
    } else {
        let _ = writeln!(md, "## Dispersions\n\n```toml\n{}```\n", h.spec_text);
        drawn(&mut md, h, rows);
    }
    let mut status: BTreeMap<&str, usize> = BTreeMap::new();
    rows.iter().for_each(|r| *status.entry(r.outcome.status.as_str()).or_default() += 1);
    let status: Vec<String> = status.iter().map(|(s, n)| format!("{s} {n}")).collect();
    let _ = writeln!(md, "## Runs\n\nStatus: {}.\n", status.join(", "));
    verdicts(&mut md, rows);
    let _ = writeln!(md, "## Metrics\n");
    let mut t = MdTable::new(["metric", "min", "P1", "median", "P99", "max", "mean ± 95 %"]);
    for name in metric_names(rows) {
        let xs: Vec<f64> = rows.iter().filter_map(|r| r.metric(&name)).filter(|x| x.is_finite()).collect();
        if !xs.is_empty() {
            t.row(distribution(&name, &xs));
        }
    }
    let _ = writeln!(md, "{t}");
    if !plots.is_empty() {
        let _ = writeln!(md, "## Plots of `{}`\n", h.metric.unwrap_or(""));
        for p in plots {
            let name = p.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
            let _ = writeln!(md, "![{name}](plots/{name})");
        }
    }
    md
}

/// A row of a distribution table: name, min, P1, median, P99, max, mean ± half-width (n if some
/// cases lack it).
fn distribution(name: &str, xs: &[f64]) -> [String; 7] {
    let d = describe(xs);
    [
        name.to_string(),
        g(d.min),
        g(d.p1),
        g(d.median),
        g(d.p99),
        g(d.max),
        format!("{} ± {} (n = {})", g(d.mean), g(d.ci95_half), d.n),
    ]
}

/// Each verdict line's pass / fail / n/a counts and pass rate, and the overall verdict's.
fn verdicts(md: &mut String, rows: &[CaseRow]) {
    let lines = verdict_names(rows);
    if lines.is_empty() {
        return;
    }
    let _ = writeln!(md, "## Verdict against the paper\n");
    let mut t = MdTable::new(["line", "pass", "fail", "n/a", "pass rate"]);
    let mut count = |name: &str, of: &dyn Fn(&CaseRow) -> Option<String>| {
        let (mut p, mut f, mut na) = (0, 0, 0);
        for r in rows {
            match of(r).as_deref() {
                Some("pass") => p += 1,
                Some("fail") => f += 1,
                _ => na += 1,
            }
        }
        let rate = if p + f > 0 { format!("{:.1} %", 100.0 * p as f64 / (p + f) as f64) } else { "–".into() };
        t.row([name.to_string(), p.to_string(), f.to_string(), na.to_string(), rate]);
    };
    for (name, _) in &lines {
        count(name, &|r| r.outcome.verdict.iter().find(|v| v.name == *name).map(|v| v.verdict.clone()));
    }
    count("overall", &|r| Some(r.outcome.verdict_overall.clone()));
    let _ = writeln!(md, "{t}");
}

/// The chosen metric's histogram and its scatter against every numeric drawn value, in
/// `root/plots/`; the files drawn (a failed plot is a warning, not a lost campaign).
pub fn plots(root: &Path, metric: &str, columns: &[String], rows: &[CaseRow]) -> Vec<PathBuf> {
    let dir = root.join("plots");
    if let Err(e) = std::fs::create_dir_all(&dir) {
        tracing::warn!("{}: {e}: no plots", dir.display());
        return Vec::new();
    }
    let safe =
        |s: &str| s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '-' }).collect::<String>();
    let ys: Vec<Option<f64>> = rows.iter().map(|r| r.value(metric)).collect();
    let mut out = Vec::new();
    let hist = dir.join(format!("{}-histogram.png", safe(metric)));
    let values: Vec<f64> = ys.iter().flatten().copied().collect();
    match cohort_report::samples::histogram(
        &hist,
        &format!("{metric} over {} cases", rows.len()),
        metric,
        &values,
        None,
    ) {
        Ok(()) => out.push(hist),
        Err(e) => tracing::warn!("plot not drawn: {e}"),
    }
    for (k, c) in columns.iter().enumerate() {
        let pts: Vec<(f64, f64)> =
            rows.iter().zip(&ys).filter_map(|(r, y)| Some((r.values[k].as_f64()?, (*y)?))).collect();
        if pts.is_empty() {
            continue;
        }
        let path = dir.join(format!("{}-vs-{}.png", safe(metric), safe(c)));
        match cohort_report::samples::scatter(&path, &format!("{metric} against {c}"), c, metric, &pts) {
            Ok(()) => out.push(path),
            Err(e) => tracing::warn!("plot not drawn: {e}"),
        }
    }
    out
}

/// The distribution of each drawn column (numbers) or its counts (choices).
fn drawn(md: &mut String, h: &Header, rows: &[CaseRow]) {
    let mut t = MdTable::new(["drawn", "min", "P1", "median", "P99", "max", "mean ± 95 %"]);
    for (k, c) in h.columns.iter().enumerate() {
        let xs: Vec<f64> = rows.iter().filter_map(|r| r.values[k].as_f64()).collect();
        if xs.len() == rows.len() && !xs.is_empty() {
            t.row(distribution(c, &xs));
        } else {
            let mut counts: BTreeMap<String, usize> = BTreeMap::new();
            for r in rows {
                *counts.entry(r.values[k].to_string()).or_default() += 1;
            }
            let text: Vec<String> = counts.iter().map(|(v, n)| format!("{v}: {n}")).collect();
            t.row([
                c.clone(),
                text.join(", "),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
            ]);
        }
    }
    let _ = writeln!(md, "{t}");
}
