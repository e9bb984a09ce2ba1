//! The study's Markdown: a table per scenario, a row per rung, and the first failing rung.

use std::path::Path;

use super::RungResult;

/// What every directed link of a rung did together (from the plant's report).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LinkTotals {
    pub steps: u64,
    pub delivered: u64,
    pub blocked: u64,
    pub delay_sum_steps: u64,
}

impl LinkTotals {
    /// The totals of a run's `summary.json` (zero on ideal links, where the plant reports none).
    pub fn read(summary: &Path) -> Self {
        let s: serde_json::Value =
            std::fs::read_to_string(summary).ok().and_then(|t| serde_json::from_str(&t).ok()).unwrap_or_default();
        let plant = s["processes"].as_array().and_then(|p| p.iter().find(|p| p["process"] == "plant").cloned());
        let links = plant.and_then(|p| p["links"].as_array().cloned()).unwrap_or_default();
        let sum = |key: &str| links.iter().filter_map(|l| l[key].as_u64()).sum::<u64>();
        LinkTotals {
            steps: sum("steps"),
            delivered: sum("delivered"),
            blocked: sum("blocked"),
            delay_sum_steps: sum("delay_sum_steps"),
        }
    }
    fn cells(&self, ideal: bool) -> [String; 3] {
        if self.steps == 0 {
            let what = if ideal { "all (ideal)" } else { "no links (no neighbours)" };
            return [what.into(), "–".into(), "–".into()];
        }
        let pct = |x: u64| format!("{:.1} %", 100.0 * x as f64 / self.steps as f64);
        let delay = if self.delivered == 0 { 0.0 } else { self.delay_sum_steps as f64 / self.delivered as f64 };
        [pct(self.delivered), pct(self.blocked), format!("{delay:.2}")]
    }
}

/// The section of one scenario: its table and the rung where its verdict first fails.
pub fn markdown(name: &str, file: &Path, results: &[RungResult], metrics: &[String]) -> String {
    let mut names: Vec<String> = results
        .iter()
        .find_map(|r| {
            r.flown.as_ref().map(|(o, _)| o.verdict.iter().map(|v| format!("{} ({})", v.name, v.unit)).collect())
        })
        .unwrap_or_default();
    names.extend(metrics.iter().map(|m| format!("`{m}`")));
    let mut md = format!("## {name} (`{}`)\n\n", file.display());
    md.push_str("| rung | shares delivered | blocked | mean delay (steps) | status | verdict |");
    for n in &names {
        md.push_str(&format!(" {n} |"));
    }
    md.push_str(&format!("\n|{}\n", "---|".repeat(6 + names.len())));
    for r in results {
        md.push_str(&row(r, names.len(), metrics));
    }
    let judged = results.iter().any(|r| r.flown.as_ref().is_some_and(|(o, _)| o.verdict_overall != "n/a"));
    let first = results.iter().find(|r| r.flown.as_ref().is_some_and(|(o, _)| fails(&o.status, &o.verdict_overall)));
    md.push_str(&match first {
        Some(r) => format!("\nThe verdict first fails at **{}**.\n\n", r.rung),
        None if judged => "\nThe verdict holds on every rung.\n\n".into(),
        None => "\nThis scenario has no verdict against its paper: read the metrics.\n\n".into(),
    });
    md
}

fn fails(status: &str, verdict: &str) -> bool {
    verdict == "fail" || !matches!(status, "ok" | "degraded")
}

fn row(r: &RungResult, n_cells: usize, metrics: &[String]) -> String {
    let Some((o, links)) = &r.flown else {
        return format!("| {} | (no central body: as the rung before) |{}\n", r.rung, " |".repeat(4 + n_cells));
    };
    let [delivered, blocked, delay] = links.cells(r.rung == "ideal");
    let mut s = format!("| {} | {delivered} | {blocked} | {delay} | {} | {} |", r.rung, o.status, o.verdict_overall);
    for v in &o.verdict {
        let ours = v.ours.map_or("–".to_string(), |b| format!("{:.4}", f64::from_bits(b)));
        s.push_str(&format!(" {ours} ({}) |", v.verdict));
    }
    for m in metrics {
        let value = o.metrics.get(m).map_or("–".to_string(), |b| format!("{:.4}", f64::from_bits(*b)));
        s.push_str(&format!(" {value} |"));
    }
    s.push('\n');
    s
}
