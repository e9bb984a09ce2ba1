//! The swarm campaign's outputs (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883; see
//! [`crate::swarm::campaign::command`]): `cases.csv`, one row per case × method with units in the
//! column names, and `summary.md`, per group and method, with verdict lines against the issue's
//! goals (0 collisions for NR in every case; every vehicle within 0.1 m of its goal at T + 2 s;
//! ∫‖u‖dt ≤ 1.3× the SCP's; per-step compute ≥ 100× faster than one SCP solve).

use std::fmt::Write as _;
use std::path::Path;

use cohort_report::markdown::MdTable;
use cohort_report::stats;

use crate::swarm::campaign::case::{CampaignMethod, CaseResult};

/// Effort goal: ∫‖u‖dt at most this times the SCP's.
pub const EFFORT_GOAL: f64 = 1.3;
/// Speed goal: one SCP solve at least this times one vehicle's step.
pub const SPEEDUP_GOAL: f64 = 100.0;

const HEADER: &str = "group,case,seed,n_vehicles,disturbance_mps2,method,status,collisions_count,collision_pairs_count,\
min_ellipsoid_distance_unitless,within_0_1_m_at_t_plus_2_s_count,max_goal_dist_at_t_plus_2_s_m,effort_mps,\
effort_ratio_to_scp,compute_p50_us,compute_p99_us,compute_total_s,scp_solve_s,speedup_vs_scp_solve,\
speedup_total_vs_scp_solve,filtered_vehicle_steps_count,vehicle_steps_count,run_dir";

/// `cases.csv`.
pub fn csv(rows: &[CaseResult]) -> String {
    let mut s = format!("{HEADER}\n");
    for r in rows {
        let dir = r.run_dir.as_ref().and_then(|d| d.file_name()).map(|d| d.to_string_lossy().to_string());
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:?},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.group,
            r.case,
            r.seed,
            r.n,
            r.disturbance_mps2,
            r.method.name(),
            r.status,
            r.collisions,
            r.collision_pairs,
            r.min_ellipsoid,
            r.within_0_1_m,
            r.max_goal_dist_m,
            r.effort_mps,
            r.effort_ratio,
            r.compute_p50_s * 1e6,
            r.compute_p99_s * 1e6,
            r.compute_total_s,
            r.scp_solve_s,
            r.speedup(),
            r.speedup_total(),
            r.filtered_steps,
            r.vehicle_steps,
            dir.map_or(String::new(), |d| format!("runs/{d}"))
        );
    }
    s
}

/// The median of the finite values (`cohort_report::stats`'s rule); NaN when none is finite.
fn median(xs: Vec<f64>) -> f64 {
    stats::median(&stats::sorted(xs.into_iter().filter(|x| x.is_finite())))
}

fn fold(xs: impl Iterator<Item = f64>, f: fn(f64, f64) -> f64, init: f64) -> f64 {
    xs.filter(|x| x.is_finite()).fold(init, f)
}

/// The mean of the finite values; NaN when none is finite.
fn mean(xs: &[f64]) -> f64 {
    stats::mean(&xs.iter().copied().filter(|x| x.is_finite()).collect::<Vec<f64>>())
}

fn ok(rows: &[CaseResult]) -> Vec<&CaseResult> {
    rows.iter().filter(|r| r.status == "ok").collect()
}

/// One row of the per-group table.
fn table_row(group: &str, m: CampaignMethod, rows: &[CaseResult]) -> [String; 12] {
    let good = ok(rows);
    let free = good.iter().filter(|r| r.collisions == 0.0).count();
    let collisions: f64 = good.iter().map(|r| r.collisions).sum();
    let arrived = good.iter().filter(|r| r.within_0_1_m == r.n as f64).count();
    let ratios: Vec<f64> = good.iter().map(|r| r.effort_ratio).collect();
    let speed: Vec<f64> = good.iter().map(|r| r.speedup()).collect();
    let per_run: Vec<f64> = good.iter().map(|r| r.speedup_total()).collect();
    [
        group.to_string(),
        m.name().to_string(),
        format!("{} ({} failed)", good.len(), rows.len() - good.len()),
        free.to_string(),
        collisions.to_string(),
        format!("{:.3}", fold(good.iter().map(|r| r.min_ellipsoid), f64::min, f64::INFINITY)),
        arrived.to_string(),
        format!("{:.3} / {:.3}", mean(&ratios), fold(ratios.iter().copied(), f64::max, f64::NEG_INFINITY)),
        format!("{:.1}", median(good.iter().map(|r| r.compute_p50_s * 1e6).collect())),
        format!("{:.3}", median(good.iter().map(|r| r.scp_solve_s).collect())),
        format!("{:.0} / {:.0}", fold(speed.iter().copied(), f64::min, f64::INFINITY), median(speed)),
        format!("{:.2} / {:.2}", fold(per_run.iter().copied(), f64::min, f64::INFINITY), median(per_run)),
    ]
}

fn verdict(met: bool) -> &'static str {
    if met { "MET" } else { "NOT MET" }
}

/// The verdict lines for NR over every case (the deep set's count beside it).
fn verdicts(rows: &[CaseResult]) -> String {
    let of = |m: CampaignMethod| rows.iter().filter(|r| r.method == m).cloned().collect::<Vec<_>>();
    let (nr, ds) = (of(CampaignMethod::Nr), of(CampaignMethod::DeepSet));
    if nr.is_empty() {
        return "No NR cases flown: no verdict.\n".into();
    }
    let good = ok(&nr);
    let failed = nr.len() - good.len();
    let free = good.iter().filter(|r| r.collisions == 0.0).count();
    let total: f64 = good.iter().map(|r| r.collisions).sum();
    let ds_free = ok(&ds).iter().filter(|r| r.collisions == 0.0).count();
    let ds_total: f64 = ok(&ds).iter().map(|r| r.collisions).sum();
    let arrived = good.iter().filter(|r| r.within_0_1_m == r.n as f64).count();
    let ratios: Vec<f64> = good.iter().map(|r| r.effort_ratio).filter(|x| x.is_finite()).collect();
    let within = ratios.iter().filter(|x| **x <= EFFORT_GOAL).count();
    let speed: Vec<f64> = good.iter().map(|r| r.speedup()).filter(|x| x.is_finite()).collect();
    let slowest = fold(speed.iter().copied(), f64::min, f64::INFINITY);
    let mut s = String::new();
    let ds_note = if ds.is_empty() {
        "the deep set alone: not flown".to_string()
    } else {
        format!("the deep set alone: {ds_free} of {} cases, {ds_total} collisions", ds.len())
    };
    let _ = writeln!(
        s,
        "- **0 collisions for NR in every case: {}** — {free} of {} NR cases collision-free, {total} collisions in all{} \
         ({ds_note}).",
        verdict(failed == 0 && free == nr.len()),
        nr.len(),
        if failed > 0 { format!(", {failed} runs failed") } else { String::new() },
    );
    let _ = writeln!(
        s,
        "- **Every vehicle within 0.1 m of its goal at T + 2 s (NR): {}** — {arrived} of {} cases.",
        verdict(failed == 0 && arrived == nr.len()),
        nr.len()
    );
    let _ = writeln!(
        s,
        "- **∫‖u‖dt ≤ {EFFORT_GOAL}× the SCP's (NR): {}** — {within} of {} cases; mean ratio {:.3}, largest {:.3}.",
        verdict(!ratios.is_empty() && within == nr.len()),
        nr.len(),
        mean(&ratios),
        fold(ratios.iter().copied(), f64::max, f64::NEG_INFINITY)
    );
    let _ = writeln!(
        s,
        "- **Per-step compute ≥ {SPEEDUP_GOAL}× faster than one SCP solve (NR): {}** — least speed-up {slowest:.0}×, \
         median {:.0}× (p50 of one vehicle's share + step against the wall time of the whole SCP of the case).",
        verdict(!speed.is_empty() && speed.len() == nr.len() && slowest >= SPEEDUP_GOAL),
        median(speed.clone())
    );
    s += &filter_work(&good);
    let totals: Vec<f64> = good.iter().map(|r| r.speedup_total()).filter(|x| x.is_finite()).collect();
    let _ = writeln!(
        s,
        "- Per run, like for like (no goal): every vehicle's compute over every step of a run, summed, took {} s \
         (median over the cases) against the {} s of the one SCP solve the run needs (its open-loop plan): the SCP \
         solve is {}× (least) to {}× (median) the whole run's compute.",
        fmt_sig(median(good.iter().map(|r| r.compute_total_s).collect())),
        fmt_sig(median(good.iter().map(|r| r.scp_solve_s).collect())),
        fmt_sig(fold(totals.iter().copied(), f64::min, f64::INFINITY)),
        fmt_sig(median(totals))
    );
    s
}

/// How often the safety filter had to act in the NR runs (no goal: the policy's own avoidance is
/// the `deep-set` rows').
fn filter_work(nr: &[&CaseResult]) -> String {
    let filtered: f64 = nr.iter().map(|r| r.filtered_steps).filter(|x| x.is_finite()).sum();
    let steps: f64 = nr.iter().map(|r| r.vehicle_steps).filter(|x| x.is_finite()).sum();
    let acted = nr.iter().filter(|r| r.filtered_steps > 0.0).count();
    let most = fold(nr.iter().map(|r| r.filtered_steps / r.vehicle_steps), f64::max, f64::NEG_INFINITY);
    format!(
        "- The safety filter's work (NR, no goal): it changed the command at {filtered} of {steps} vehicle-steps \
         ({}), in {acted} of {} cases; at most {} of one case's vehicle-steps.\n",
        pct(filtered / steps),
        nr.len(),
        pct(most)
    )
}

fn pct(x: f64) -> String {
    if x.is_finite() { format!("{:.2} %", 100.0 * x) } else { "—".into() }
}

/// Three significant digits.
fn fmt_sig(x: f64) -> String {
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.digits$}")
}

/// `summary.md`.
pub fn summary(rows: &[CaseResult], command: &str, wall_s: f64, out: &Path) -> String {
    let mut s = format!(
        "# Swarm campaign (Sec. 7.2)\n\n`{command}` — {} rows in {wall_s:.0} s; every row in `cases.csv`.\n\n",
        rows.len()
    );
    let mut table = MdTable::new([
        "group",
        "method",
        "cases (failed)",
        "collision-free",
        "collisions",
        "least ellipsoid distance",
        "all within 0.1 m at T + 2 s",
        "∫‖u‖dt / SCP mean / max",
        "compute p50 median (µs)",
        "SCP solve median (s)",
        "speed-up least / median",
        "per run: SCP solve / all vehicles' compute, least / median",
    ]);
    let mut groups: Vec<&str> = rows.iter().map(|r| r.group.as_str()).collect();
    groups.dedup();
    for g in &groups {
        for m in CampaignMethod::ALL {
            let sel: Vec<CaseResult> = rows.iter().filter(|r| r.group == *g && r.method == m).cloned().collect();
            if !sel.is_empty() {
                table.row(table_row(g, m, &sel));
            }
        }
    }
    s += &table.to_string();
    s += "\n## Verdict\n\n";
    s += &verdicts(rows);
    s += "\nThe SCP row: the global solution flown in the same plant, its planned accelerations open-loop at d̄ = 0 \
          (the plan exactly), tracked with u = a* + 4(p* − p̂) + 4(v* − v̂) at d̄ > 0 (open-loop, the disturbance \
          drifts it by metres); its compute is one solve of the whole SCP.\n";
    let failed: Vec<&CaseResult> = rows.iter().filter(|r| r.status != "ok").collect();
    if !failed.is_empty() {
        s += "\n## Failed\n\n";
        for r in failed {
            let _ = writeln!(s, "- {} case {} (seed {}) {}: {}", r.group, r.case, r.seed, r.method.name(), r.status);
        }
    }
    let figs: Vec<String> = rows
        .iter()
        .filter_map(|r| r.run_dir.as_ref())
        .filter(|d| d.join("plots").join("swarm_trajectories.png").is_file())
        .map(|d| d.strip_prefix(out).unwrap_or(d).display().to_string())
        .collect();
    if !figs.is_empty() {
        s += "\n## Figures\n\n";
        for d in figs {
            let _ = writeln!(s, "- `{d}/plots/swarm_trajectories.png`, `{d}/plots/swarm_min_distance.png`");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: CampaignMethod, collisions: f64, ratio: f64, p50_s: f64) -> CaseResult {
        CaseResult {
            group: "n8".into(),
            case: 0,
            seed: 3,
            n: 8,
            disturbance_mps2: 0.0,
            method,
            status: "ok".into(),
            collisions,
            collision_pairs: collisions,
            min_ellipsoid: if collisions > 0.0 { 0.8 } else { 1.2 },
            within_0_1_m: 8.0,
            max_goal_dist_m: 0.01,
            effort_mps: 10.0 * ratio,
            effort_ratio: ratio,
            compute_p50_s: p50_s,
            compute_p99_s: p50_s,
            compute_total_s: p50_s * 8.0 * 100.0,
            scp_solve_s: 0.1,
            filtered_steps: if method == CampaignMethod::Nr { 12.0 } else { 0.0 },
            vehicle_steps: 800.0,
            run_dir: None,
        }
    }

    #[test]
    fn the_verdicts_follow_the_numbers() {
        let good = [row(CampaignMethod::Nr, 0.0, 1.1, 1e-5), row(CampaignMethod::DeepSet, 1.0, 1.0, 1e-5)];
        let v = verdicts(&good);
        assert!(v.contains("every case: MET") && v.contains("SCP's (NR): MET") && v.contains("solve (NR): MET"), "{v}");
        assert!(v.contains("1 of 1 NR cases collision-free") && v.contains("0 of 1 cases, 1 collisions"), "{v}");
        // 8 vehicles × 100 steps × 10 µs = 8 ms in all against a 0.1 s solve: 12.5×.
        assert!(v.contains("took 0.00800 s") && v.contains("12.5× (least)"), "{v}");
        // The filter acted at 12 of 800 vehicle-steps of the one NR case.
        assert!(v.contains("at 12 of 800 vehicle-steps (1.50 %), in 1 of 1 cases; at most 1.50 %"), "{v}");
        let bad = [row(CampaignMethod::Nr, 2.0, 1.4, 1e-2)];
        let v = verdicts(&bad);
        assert!(v.contains("every case: NOT MET") && v.contains("SCP's (NR): NOT MET"), "{v}");
        assert!(v.contains("solve (NR): NOT MET") && v.contains("least speed-up 10×"), "{v}");
        assert!(v.contains("the deep set alone: not flown") && !v.contains("-0"), "{v}");
        let c = csv(&good);
        assert_eq!(c.lines().count(), 3);
        assert!(c.lines().next().unwrap().split(',').count() == c.lines().nth(1).unwrap().split(',').count());
    }
}
