//! What `launch` prints at the end of a run (everything is also in `summary.json`): a table per
//! agent of the per-agent metrics, the run-level metrics sorted by name, the verdict against the
//! paper, and one line per fault or roster change of the timeline. Numbers have 4 significant
//! digits (whole numbers are printed whole), so a line reads at a glance; the exact values are
//! in the summary.
//!
//! A metric is agent i's when its name is `<word>_<i>.<metric>` (e.g. `servicer_3.e_rms_m`) or
//! `a<i>_<metric>` (e.g. `a1_delivery_error_m`) with 1 ≤ i ≤ the number of agents: the two
//! conventions the papers name per-agent metrics by.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;

use cohort_host::Verdict;

use crate::summary::Summary;

/// Widest line of a table before its columns are split over several tables.
const MAX_WIDTH: usize = 100;

/// `x` with 4 significant digits: whole numbers below 10⁹ whole, 10⁻³ ≤ |x| < 10⁴ in fixed
/// notation, anything else in scientific notation (`1.235e5`).
pub fn sig4(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x.fract() == 0.0 && x.abs() < 1e9 {
        return format!("{x:.0}");
    }
    let e = x.abs().log10().floor() as i32;
    if (-3..4).contains(&e) {
        // Rounding can carry into the next decade (9.9996 → 10.000): one decimal fewer then.
        let s = format!("{x:.*}", (3 - e) as usize);
        let digits = s.chars().filter(|c| c.is_ascii_digit()).collect::<String>();
        if digits.trim_start_matches('0').len() > 4 && e < 3 {
            return format!("{x:.*}", (2 - e).max(0) as usize);
        }
        s
    } else {
        format!("{x:.3e}")
    }
}

/// (agent, metric) if `key` names a per-agent metric of one of `n` agents.
pub fn agent_metric(key: &str, n: u32) -> Option<(u32, &str)> {
    let in_range = |i: u32| (1..=n).contains(&i);
    if let Some((head, rest)) = key.split_once('.')
        && let Some((_, id)) = head.rsplit_once('_')
        && let Ok(i) = id.parse::<u32>()
        && in_range(i)
        && !rest.is_empty()
    {
        return Some((i, rest));
    }
    let tail = key.strip_prefix('a')?;
    let (id, rest) = tail.split_once('_')?;
    let i = id.parse::<u32>().ok().filter(|&i| in_range(i))?;
    (!rest.is_empty() && id.bytes().all(|b| b.is_ascii_digit())).then_some((i, rest))
}

/// Rows of cells as aligned text, columns separated by two spaces (first column left-aligned,
/// the others right-aligned).
fn table(rows: &[Vec<String>]) -> String {
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0);
    let width: Vec<usize> =
        (0..cols).map(|c| rows.iter().filter_map(|r| r.get(c)).map(|s| s.chars().count()).max().unwrap_or(0)).collect();
    let mut out = String::new();
    for r in rows {
        let mut line = String::new();
        for (c, cell) in r.iter().enumerate() {
            let pad = width[c] - cell.chars().count();
            if c == 0 {
                let _ = write!(line, "  {cell}{}", " ".repeat(pad));
            } else {
                let _ = write!(line, "  {}{cell}", " ".repeat(pad));
            }
        }
        let _ = writeln!(out, "{}", line.trim_end());
    }
    out
}

/// The per-agent metrics as tables (rows = agents), split by columns to stay within
/// [`MAX_WIDTH`]; the keys they used.
fn agent_tables(metrics: &BTreeMap<String, f64>, n: u32) -> (String, BTreeSet<String>) {
    let mut by: BTreeMap<&str, BTreeMap<u32, f64>> = BTreeMap::new();
    let mut used = BTreeSet::new();
    for (k, v) in metrics {
        if let Some((i, m)) = agent_metric(k, n) {
            by.entry(m).or_default().insert(i, *v);
            used.insert(k.clone());
        }
    }
    if by.is_empty() {
        return (String::new(), used);
    }
    let agents: BTreeSet<u32> = by.values().flat_map(|m| m.keys().copied()).collect();
    let columns: Vec<(&str, Vec<String>)> = by
        .iter()
        .map(|(m, vals)| (*m, agents.iter().map(|i| vals.get(i).map_or("–".into(), |v| sig4(*v))).collect()))
        .collect();
    let mut out = String::new();
    let mut start = 0;
    while start < columns.len() {
        let mut width = "agent".len() + 2;
        let mut end = start;
        while end < columns.len() {
            let w = columns[end].0.len().max(columns[end].1.iter().map(|c| c.chars().count()).max().unwrap_or(0)) + 2;
            if end > start && width + w > MAX_WIDTH {
                break;
            }
            width += w;
            end += 1;
        }
        let mut rows = vec![
            std::iter::once("agent".to_string()).chain(columns[start..end].iter().map(|c| c.0.to_string())).collect(),
        ];
        for (r, i) in agents.iter().enumerate() {
            rows.push(
                std::iter::once(i.to_string()).chain(columns[start..end].iter().map(|c| c.1[r].clone())).collect(),
            );
        }
        out.push_str(&table(&rows));
        start = end;
    }
    (out, used)
}

/// The run's end-of-launch text (after the "done:" line).
pub fn render(summary: &Summary) -> String {
    let mut out = String::new();
    let (agents, used) = agent_tables(&summary.metrics, summary.n_agents);
    if !agents.is_empty() {
        out.push_str("per agent:\n");
        out.push_str(&agents);
    }
    let run: Vec<Vec<String>> =
        summary.metrics.iter().filter(|(k, _)| !used.contains(*k)).map(|(k, v)| vec![k.clone(), sig4(*v)]).collect();
    if !run.is_empty() {
        out.push_str("run:\n");
        out.push_str(&table(&run));
    }
    if let Some(overall) = summary.verdict_overall {
        let count = |v: Verdict| summary.verdict.iter().filter(|l| l.verdict == v).count();
        let _ = writeln!(
            out,
            "verdict against the paper: {} ({} pass, {} fail, {} n/a)",
            overall.to_uppercase(),
            count(Verdict::Pass),
            count(Verdict::Fail),
            count(Verdict::NotApplicable)
        );
        for l in &summary.verdict {
            let unit = if l.unit.is_empty() { String::new() } else { format!(" {}", l.unit) };
            let ours = l.ours.map_or("–".to_string(), sig4);
            let _ = write!(
                out,
                "  {:<4}  {}: ours {ours}{unit} {} paper {}{unit} ({})",
                l.verdict.label(),
                l.name,
                l.criterion.describe(),
                sig4(l.paper),
                l.source
            );
            if let Some(n) = &l.note {
                let _ = write!(out, " — {n}");
            }
            out.push('\n');
        }
    }
    let events = timeline_lines(summary);
    if !events.is_empty() {
        out.push_str("timeline:\n");
        for e in events {
            let _ = writeln!(out, "  {e}");
        }
    }
    out
}

/// One line per fault, death and roster change, with who is live after a roster change.
fn timeline_lines(summary: &Summary) -> Vec<String> {
    let mut live: BTreeSet<u32> = (1..=summary.n_agents).collect();
    let mut out = Vec::new();
    for e in &summary.timeline {
        let t = format!("t = {:.3} s", e.t_s);
        let line = match e.event.as_str() {
            "dead" | "alive" => {
                if e.event == "dead" {
                    live.remove(&e.agent);
                } else {
                    live.insert(e.agent);
                }
                let ids: Vec<String> = live.iter().map(u32::to_string).collect();
                let state = if e.event == "dead" { "off the roster" } else { "back on the roster" };
                format!("{t}  agent {} {state} ({}) → agents {} continue", e.agent, e.detail, ids.join(","))
            }
            _ if e.agent == 0 => format!("{t}  {}: {}", e.event, e.detail),
            _ => format!("{t}  {} agent {}: {}", e.event, e.agent, e.detail),
        };
        out.push(line);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_significant_digits() {
        let cases = [
            (0.0, "0"),
            (36000.0, "36000"),
            (3.0, "3"),
            (1.234_567, "1.235"),
            (12.345_67, "12.35"),
            (123.456_7, "123.5"),
            (1234.567, "1235"),
            (0.012_345_6, "0.01235"),
            (0.001_234_6, "0.001235"),
            (12_345.67, "1.235e4"),
            (0.000_123_456, "1.235e-4"),
            (-2.345_678, "-2.346"),
            (9.999_96, "10.00"),
            (f64::NAN, "NaN"),
        ];
        for (x, want) in cases {
            assert_eq!(sig4(x), want, "{x}");
        }
    }

    #[test]
    fn per_agent_metric_names() {
        assert_eq!(agent_metric("servicer_3.e_rms_200_360_m", 6), Some((3, "e_rms_200_360_m")));
        assert_eq!(agent_metric("mu_4.fuel_ns", 4), Some((4, "fuel_ns")));
        assert_eq!(agent_metric("a1_delivery_error_m", 1), Some((1, "delivery_error_m")));
        assert_eq!(agent_metric("a7_dv_mps", 6), None);
        assert_eq!(agent_metric("net.max_edge_tension_n", 4), None);
        assert_eq!(agent_metric("fuel_total_ns", 4), None);
        assert_eq!(agent_metric("abc_x", 4), None);
    }
}
