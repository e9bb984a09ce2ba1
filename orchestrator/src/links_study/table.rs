//! The study's Markdown: a table per scenario, a row per rung, and the first failing rung.

use std::path::Path;

use super::RungResult;
use crate::campaign::row::Outcome;

/// What every directed link of a rung did together (from the plant's report).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LinkTotals {
    pub steps: u64,
    pub delivered: u64,
    pub blocked: u64,
    pub delay_sum_steps: u64,
}

impl LinkTotals {
    /// The totals of a run's summary (zero on ideal links, where the plant reports none).
    pub fn of(summary: &crate::summary::Summary) -> Self {
        let plant = summary.processes.iter().find(|p| p.process == "plant");
        let mut t = LinkTotals::default();
        for l in plant.map_or(&[][..], |p| &p.links) {
            t.steps += l.stats.steps;
            t.delivered += l.stats.delivered;
            t.blocked += l.stats.blocked;
            t.delay_sum_steps += l.stats.delay_sum_steps;
        }
        t
    }
    fn add(&mut self, o: &LinkTotals) {
        self.steps += o.steps;
        self.delivered += o.delivered;
        self.blocked += o.blocked;
        self.delay_sum_steps += o.delay_sum_steps;
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
            r.flown.first().map(|(o, _)| o.verdict.iter().map(|v| format!("{} ({})", v.name, v.unit)).collect())
        })
        .unwrap_or_default();
    names.extend(metrics.iter().map(|m| format!("`{m}`")));
    let seeds = results.iter().map(|r| r.flown.len()).max().unwrap_or(0);
    let mut md = format!("## {name} (`{}`)\n\n", file.display());
    if seeds > 1 {
        md.push_str(&format!("{seeds} seeds per rung: each value is the mean [min, max] over them.\n\n"));
    }
    md.push_str("| rung | shares delivered | blocked | mean delay (steps) | status | verdict |");
    for n in &names {
        md.push_str(&format!(" {n} |"));
    }
    md.push_str(&format!("\n|{}\n", "---|".repeat(6 + names.len())));
    for r in results {
        md.push_str(&row(r, names.len(), metrics));
    }
    let judged = results.iter().flat_map(|r| &r.flown).any(|(o, _)| o.verdict_overall != "n/a");
    let failing = |r: &RungResult| r.flown.iter().filter(|(o, _)| fails(&o.status, &o.verdict_overall)).count();
    md.push_str(&match results.iter().find(|r| failing(r) > 0) {
        Some(r) if seeds > 1 => {
            format!("\nThe verdict first fails at **{}** ({} of {} seeds).\n\n", r.rung, failing(r), r.flown.len())
        }
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
    let Some((first, _)) = r.flown.first() else {
        return format!("| {} | (no central body: as the rung before) |{}\n", r.rung, " |".repeat(4 + n_cells));
    };
    let mut links = LinkTotals::default();
    for (_, l) in &r.flown {
        links.add(l);
    }
    let [delivered, blocked, delay] = links.cells(r.rung == "ideal");
    let outcomes: Vec<&Outcome> = r.flown.iter().map(|(o, _)| o).collect();
    let (status, verdict) = match outcomes.len() {
        1 => (first.status.clone(), first.verdict_overall.clone()),
        n => {
            let failing = outcomes.iter().filter(|o| fails(&o.status, &o.verdict_overall)).count();
            let ok = outcomes.iter().filter(|o| matches!(o.status.as_str(), "ok" | "degraded")).count();
            (format!("{ok}/{n} ok"), format!("{failing}/{n} fail"))
        }
    };
    let mut s = format!("| {} | {delivered} | {blocked} | {delay} | {status} | {verdict} |", r.rung);
    for (k, v) in first.verdict.iter().enumerate() {
        let values: Vec<Option<f64>> =
            outcomes.iter().map(|o| o.verdict.get(k).and_then(|c| c.ours).map(f64::from_bits)).collect();
        let fail = outcomes.iter().filter(|o| o.verdict.get(k).is_some_and(|c| c.verdict == "fail")).count();
        let judged = if outcomes.len() == 1 { v.verdict.clone() } else { format!("{fail}/{} fail", outcomes.len()) };
        s.push_str(&format!(" {} ({judged}) |", spread(&values)));
    }
    for m in metrics {
        let values: Vec<Option<f64>> = outcomes.iter().map(|o| o.metrics.get(m).map(|b| f64::from_bits(*b))).collect();
        s.push_str(&format!(" {} |", spread(&values)));
    }
    s.push('\n');
    s
}

/// One value as is; several as mean [min, max] (over those present).
fn spread(values: &[Option<f64>]) -> String {
    let present: Vec<f64> = values.iter().flatten().copied().collect();
    match present.as_slice() {
        [] => "–".into(),
        [x] if values.len() == 1 => format!("{x:.4}"),
        xs => {
            let d = cohort_report::stats::describe(xs);
            format!("{:.4} [{:.4}, {:.4}]", d.mean, d.min, d.max)
        }
    }
}
