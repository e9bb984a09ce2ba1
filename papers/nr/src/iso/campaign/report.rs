//! What `orchestrator nr campaign` ([`crate::iso::campaign::command`]) writes: `campaign.md` (the tables),
//! `summary.csv` (one row per method), `runs.csv` (one row per run), `dt_sweep.csv`,
//! `gamma_sweep.csv`, and `plots/`: `fig10_error_vs_bound.png` (Neural-Rendezvous's delivery
//! error against b_e(t_f) per ISO), `fig11_dt_sweep.png` and `fig9_gamma_sweep.png` (error
//! mean ± std and Δv against the control interval and against γ).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort_report::chart::series_color;
use cohort_report::markdown::MdTable;
use cohort_report::stats::{median, quantile};

use crate::iso::campaign::eval::{CampaignOptions, MethodSummary, RunResult, comparisons, spread};
use crate::iso::config::Method;
use crate::iso::dynamics::constants::DV_BUDGET_MPS;
use crate::plots::{self, Line, Panel, Style};

/// One row of the main table.
#[derive(Debug, Clone)]
pub struct Row {
    pub label: String,
    pub summary: MethodSummary,
}

/// One method at one sweep value (`nav` is "noisy" or "perfect").
#[derive(Debug, Clone)]
pub struct SweepPoint {
    pub x: f64,
    pub nav: &'static str,
    pub summary: MethodSummary,
}

/// Everything the campaign measured.
pub struct Report<'a> {
    pub command: String,
    pub options: &'a CampaignOptions,
    pub rows: &'a [Row],
    /// (navigation, run) of every run of the main table.
    pub runs: &'a [(String, RunResult)],
    pub dt_sweep: &'a [SweepPoint],
    pub gamma_sweep: &'a [SweepPoint],
    pub notes: Vec<String>,
    pub wall_s: f64,
}

fn ms(s: f64) -> f64 {
    1e3 * s
}

fn main_table(rows: &[Row]) -> String {
    let mut t = MdTable::new([
        "method",
        "runs",
        "error median (m)",
        "p99 (m)",
        "max (m)",
        "mean ± std (m)",
        "≤ 200 m",
        "Δv median / max (m/s)",
        "over 20 m/s",
        "step p50 / p99 / max (ms)",
        "≤ b_e(t_f)",
    ]);
    for r in rows {
        let m = &r.summary;
        t.row([
            r.label.clone(),
            m.runs.to_string(),
            format!("{:.3}", m.error_median_m),
            format!("{:.3}", m.error_p99_m),
            format!("{:.3}", m.error_max_m),
            format!("{:.2} ± {:.2}", m.error_mean_m, m.error_std_m),
            format!("{:.0} %", 100.0 * m.share_within_200m),
            format!("{:.3} / {:.3}", m.dv_median_mps, m.dv_max_mps),
            m.runs_over_dv_budget.to_string(),
            format!("{:.4} / {:.3} / {:.3}", ms(m.compute_p50_s), ms(m.compute_p99_s), ms(m.compute_max_s)),
            m.within_bound.map_or("–".to_string(), |k| format!("{k}/{}", m.runs)),
        ]);
    }
    t.to_string()
}

/// Neural-Rendezvous's error against its bound, and its step time against NMPC's.
fn nr_lines(r: &Report<'_>) -> String {
    let mut t = String::new();
    let nr: Vec<&RunResult> = r
        .runs
        .iter()
        .filter(|(nav, x)| nav == "noisy" && x.method == Method::NeuralRendezvous)
        .map(|(_, x)| x)
        .collect();
    let pairs: Vec<(f64, f64)> = nr.iter().filter_map(|x| x.bound_m.map(|b| (x.delivery_error_m, b))).collect();
    if !pairs.is_empty() {
        let mut ratio: Vec<f64> = pairs.iter().map(|(e, b)| e / b).collect();
        ratio.sort_by(f64::total_cmp);
        let (lo, hi) = pairs.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (_, b)| (lo.min(*b), hi.max(*b)));
        let _ = writeln!(
            t,
            "- Neural-Rendezvous: error ≤ b_e(t_f) on {} of {} ISOs; b_e(t_f) = {lo:.1}–{hi:.1} m; error / bound \
             median {:.3}, max {:.3}.",
            pairs.iter().filter(|(e, b)| e <= b).count(),
            pairs.len(),
            median(&ratio),
            ratio.last().copied().unwrap_or(f64::NAN)
        );
    }
    let find = |label: &str| r.rows.iter().find(|x| x.label == label).map(|x| &x.summary);
    if let (Some(nr), Some(nmpc)) = (find(Method::NeuralRendezvous.name()), find(Method::Nmpc.name())) {
        let _ = writeln!(
            t,
            "- Per-step compute, NMPC / Neural-Rendezvous: {:.0}× at p50, {:.0}× at p99 (NR p99 {:.3} ms).",
            nmpc.compute_p50_s / nr.compute_p50_s,
            nmpc.compute_p99_s / nr.compute_p99_s,
            ms(nr.compute_p99_s)
        );
    }
    t
}

fn sweep_table(points: &[SweepPoint], x_name: &str, with_nav: bool) -> String {
    let mut header = vec![x_name];
    if with_nav {
        header.push("navigation");
    }
    header.extend(["method", "runs", "error mean ± std (m)", "median (m)", "max (m)", "Δv mean / max (m/s)"]);
    let mut t = MdTable::new(header);
    for p in points {
        let m = &p.summary;
        let nav = with_nav.then(|| p.nav.to_string());
        t.row([p.x.to_string()].into_iter().chain(nav).chain([
            m.method.name().to_string(),
            m.runs.to_string(),
            format!("{:.2} ± {:.2}", m.error_mean_m, m.error_std_m),
            format!("{:.3}", m.error_median_m),
            format!("{:.3}", m.error_max_m),
            format!("{:.3} / {:.3}", m.dv_mean_mps, m.dv_max_mps),
        ]));
    }
    t.to_string()
}

/// How tight NR's bound b_e(t_f) is, per navigation: the distribution of error / bound, and the
/// runs where the error passes the bound (with by how much).
fn bound_section(runs: &[(String, RunResult)]) -> String {
    let mut t = MdTable::new([
        "navigation",
        "runs",
        "error ≤ b_e(t_f)",
        "error / bound: min",
        "median",
        "p99",
        "max",
        "b_e(t_f) range (m)",
        "where it fails: error, bound (largest)",
    ]);
    let mut any = false;
    for nav in ["noisy", "perfect"] {
        let pairs: Vec<(f64, f64)> = runs
            .iter()
            .filter(|(n, x)| n == nav && x.method == Method::NeuralRendezvous)
            .filter_map(|(_, x)| x.bound_m.map(|b| (x.delivery_error_m, b)))
            .collect();
        if pairs.is_empty() {
            continue;
        }
        any = true;
        let ratio = cohort_report::stats::sorted(pairs.iter().map(|(e, b)| e / b));
        let fails: Vec<&(f64, f64)> = pairs.iter().filter(|(e, b)| e > b).collect();
        let (lo, hi) = pairs.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (_, b)| (lo.min(*b), hi.max(*b)));
        let worst = |f: &dyn Fn(&(f64, f64)) -> f64| fails.iter().map(|x| f(x)).fold(f64::NEG_INFINITY, f64::max);
        t.row([
            nav.to_string(),
            pairs.len().to_string(),
            format!("{} of {}", pairs.len() - fails.len(), pairs.len()),
            format!("{:.3}", ratio.first().copied().unwrap_or(f64::NAN)),
            format!("{:.3}", median(&ratio)),
            format!("{:.3}", quantile(&ratio, 0.99)),
            format!("{:.3}", ratio.last().copied().unwrap_or(f64::NAN)),
            format!("{lo:.4}–{hi:.4}"),
            if fails.is_empty() {
                "–".to_string()
            } else {
                format!("{:.4} m, {:.4} m", worst(&|x| x.0), worst(&|x| x.1))
            },
        ]);
    }
    if !any {
        return String::new();
    }
    format!(
        "\n## The bound b_e(t_f): how tight, and where it fails\n\n{t}\nThe bound restarts at each rebuild from \
         ‖p̂ − p_d‖ + ε_p, so its value at t_f is set by the last rebuild and the navigation error then; with \
         perfect navigation (ε = 0) it shrinks to centimetres, and its continuous-time form does not cover the \
         zero-order hold of the flown control.\n"
    )
}

fn markdown(r: &Report<'_>, plots: &[PathBuf], out: &Path) -> String {
    let o = r.options;
    let mut md = String::from("# Neural-Rendezvous campaign (seed 003, arXiv:2208.04883, Sec. 6.3)\n\n");
    let _ = writeln!(md, "Command: `{}`\n", r.command);
    let _ = writeln!(
        md,
        "ISOs {}..{} ({} each), {} noise realisation(s) per ISO, one spacecraft per run, run seed = {} + ISO index \
         + realisation × {}; Δt = {} s, plant.nav_scale = {}; per-step times on {} thread(s), the smallest of {} \
         identical run(s) per step; wall {:.0} s.\n",
        o.isos.start,
        o.isos.end,
        o.isos.len(),
        o.realisations,
        o.seed_base,
        crate::iso::campaign::eval::REALISATION_SEED_STRIDE,
        o.dt_s,
        o.plant.nav_scale,
        o.threads,
        o.timing_repeats,
        r.wall_s
    );
    md += "## Delivery error, Δv and per-step compute\n\n";
    md += &main_table(r.rows);
    let _ = writeln!(md, "\nΔv budget {DV_BUDGET_MPS} m/s.\n");
    md += &nr_lines(r);
    let noisy_runs: Vec<RunResult> = r.runs.iter().filter(|(n, _)| n == "noisy").map(|(_, x)| x.clone()).collect();
    let sp = spread(o, &noisy_runs);
    if !sp.is_empty() {
        let _ = writeln!(
            md,
            "\n## Across the {} noise realisations of each ISO (each statistic per realisation: least – largest)\n\n{sp}",
            o.realisations
        );
    }
    md += &bound_section(r.runs);
    let cmp = comparisons(&noisy_runs);
    if !cmp.is_empty() {
        md += "\n## Neural-Rendezvous against each method, ISO by ISO\n\n";
        md += &cmp;
    }
    if !r.dt_sweep.is_empty() {
        md += "\n## Fig. 11 analogue: the control interval Δt (the same network)\n\n";
        md += &sweep_table(r.dt_sweep, "Δt (s)", false);
    }
    if !r.gamma_sweep.is_empty() {
        md += "\n## Fig. 9 analogue: γ of the state term C_x = γI (one network per γ)\n\n";
        md += &sweep_table(r.gamma_sweep, "γ", true);
        for n in &r.notes {
            let _ = writeln!(md, "\n{n}.");
        }
    }
    if !plots.is_empty() {
        md += "\n## Plots\n\n";
        for p in plots {
            let _ = writeln!(md, "- `{}`", p.strip_prefix(out).unwrap_or(p).display());
        }
    }
    md
}

fn summary_csv(rows: &[Row]) -> String {
    let mut t = String::from(
        "method,runs,error_median_m,error_p99_m,error_max_m,error_mean_m,error_std_m,share_within_200m,dv_median_mps,\
         dv_max_mps,dv_mean_mps,runs_over_dv_budget,step_p50_s,step_p99_s,step_max_s,within_bound\n",
    );
    for r in rows {
        let m = &r.summary;
        let _ = writeln!(
            t,
            "{},{},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{},{:?},{:?},{:?},{}",
            r.label,
            m.runs,
            m.error_median_m,
            m.error_p99_m,
            m.error_max_m,
            m.error_mean_m,
            m.error_std_m,
            m.share_within_200m,
            m.dv_median_mps,
            m.dv_max_mps,
            m.dv_mean_mps,
            m.runs_over_dv_budget,
            m.compute_p50_s,
            m.compute_p99_s,
            m.compute_max_s,
            m.within_bound.map_or(String::new(), |k| k.to_string())
        );
    }
    t
}

fn runs_csv(runs: &[(String, RunResult)]) -> String {
    let mut t = String::from(
        "method,navigation,iso,realisation,delivery_error_m,dv_mps,bound_m,clipped_steps,step_p50_s,step_max_s\n",
    );
    for (nav, r) in runs {
        let mut c = r.compute_s.clone();
        c.sort_by(f64::total_cmp);
        let _ = writeln!(
            t,
            "{},{nav},{},{},{:?},{:?},{},{},{:?},{:?}",
            r.method.name(),
            r.iso,
            r.realisation,
            r.delivery_error_m,
            r.dv_mps,
            r.bound_m.map_or(String::new(), |b| format!("{b:?}")),
            r.clipped_steps,
            median(&c),
            c.last().copied().unwrap_or(f64::NAN)
        );
    }
    t
}

fn sweep_csv(points: &[SweepPoint], x_name: &str) -> String {
    let mut t = format!(
        "{x_name},navigation,method,runs,error_mean_m,error_std_m,error_median_m,error_max_m,dv_mean_mps,dv_max_mps\n"
    );
    for p in points {
        let m = &p.summary;
        let _ = writeln!(
            t,
            "{:?},{},{},{},{:?},{:?},{:?},{:?},{:?},{:?}",
            p.x,
            p.nav,
            m.method.name(),
            m.runs,
            m.error_mean_m,
            m.error_std_m,
            m.error_median_m,
            m.error_max_m,
            m.dv_mean_mps,
            m.dv_max_mps
        );
    }
    t
}

/// Error mean ± std and Δv mean against the sweep value, one line per (method, navigation).
fn sweep_panels(points: &[SweepPoint], x_desc: &str, log_x: bool) -> Vec<Panel> {
    let mut keys: Vec<(Method, &str)> = Vec::new();
    for p in points {
        if !keys.contains(&(p.summary.method, p.nav)) {
            keys.push((p.summary.method, p.nav));
        }
    }
    let panel = |caption: &str, y_desc: &str| Panel {
        caption: caption.into(),
        x_desc: x_desc.into(),
        y_desc: y_desc.into(),
        log_x,
        ..Panel::default()
    };
    let mut error = panel("delivery error, mean ± std", "m");
    let mut dv = panel("Δv, mean", "m/s");
    for (i, (method, nav)) in keys.iter().enumerate() {
        let pts: Vec<&SweepPoint> = points.iter().filter(|p| p.summary.method == *method && p.nav == *nav).collect();
        let label = if points.iter().any(|p| p.nav != "noisy") {
            format!("{}, {nav} navigation", method.name())
        } else {
            method.name().to_string()
        };
        let color = series_color(None, i);
        let style = if *nav == "noisy" { Style::SolidMarkers } else { Style::Dashed };
        let mut l = Line::new(&label, color, pts.iter().map(|p| (p.x, p.summary.error_mean_m)).collect(), style);
        l.err = pts.iter().map(|p| p.summary.error_std_m).collect();
        error.lines.push(l);
        dv.lines.push(Line::new(&label, color, pts.iter().map(|p| (p.x, p.summary.dv_mean_mps)).collect(), style));
    }
    vec![error, dv]
}

fn bound_panel(runs: &[(String, RunResult)]) -> Option<Panel> {
    let nr: Vec<&RunResult> = runs
        .iter()
        .filter(|(n, r)| n == "noisy" && r.method == Method::NeuralRendezvous && r.bound_m.is_some())
        .map(|(_, r)| r)
        .collect();
    if nr.is_empty() {
        return None;
    }
    let pts = |f: &dyn Fn(&RunResult) -> f64| nr.iter().map(|r| (f64::from(r.iso), f(r))).collect::<Vec<_>>();
    Some(Panel {
        caption: "Neural-Rendezvous per ISO".into(),
        x_desc: "ISO index".into(),
        y_desc: "m (log scale)".into(),
        log_y: true,
        lines: vec![
            Line::new(
                "delivery error ‖p(t_f) − ρ_f‖",
                series_color(None, 0),
                pts(&|r| r.delivery_error_m),
                Style::Markers,
            ),
            Line::new("bound b_e(t_f)", series_color(None, 3), pts(&|r| r.bound_m.unwrap_or(f64::NAN)), Style::Markers),
        ],
        marks_y: vec![(200.0, "0.2 km".into())],
        ..Panel::default()
    })
}

fn draw_plots(dir: &Path, r: &Report<'_>) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out = Vec::new();
    let mut draw = |name: &str, title: &str, panels: Vec<Panel>, cols: usize, size: (u32, u32)| {
        let path = dir.join(name);
        plots::draw(&path, title, &panels, cols, size).map_err(|e| format!("{}: {e}", path.display()))?;
        out.push(path);
        Ok::<(), String>(())
    };
    if let Some(p) = bound_panel(r.runs) {
        draw(
            "fig10_error_vs_bound.png",
            "Delivery error and its bound b_e(t_f) (Fig. 10 analogue)",
            vec![p],
            1,
            (1300, 700),
        )?;
    }
    if !r.dt_sweep.is_empty() {
        let panels = sweep_panels(r.dt_sweep, "control interval Δt (s)", false);
        draw("fig11_dt_sweep.png", "Control interval sweep (Fig. 11 analogue)", panels, 2, (1600, 700))?;
    }
    if !r.gamma_sweep.is_empty() {
        let panels = sweep_panels(r.gamma_sweep, "γ (log scale)", true);
        draw("fig9_gamma_sweep.png", "State-term weight γ (Fig. 9 analogue)", panels, 2, (1600, 700))?;
    }
    Ok(out)
}

/// Write every file into `out` (which exists); returns the Markdown.
pub fn write(out: &Path, r: &Report<'_>, with_plots: bool) -> Result<String, String> {
    let put = |name: &str, text: &str| std::fs::write(out.join(name), text).map_err(|e| format!("{name}: {e}"));
    put("summary.csv", &summary_csv(r.rows))?;
    put("runs.csv", &runs_csv(r.runs))?;
    if !r.dt_sweep.is_empty() {
        put("dt_sweep.csv", &sweep_csv(r.dt_sweep, "dt_s"))?;
    }
    if !r.gamma_sweep.is_empty() {
        put("gamma_sweep.csv", &sweep_csv(r.gamma_sweep, "gamma"))?;
    }
    let plots = if with_plots { draw_plots(&out.join("plots"), r)? } else { Vec::new() };
    let md = markdown(r, &plots, out);
    put("campaign.md", &md)?;
    Ok(md)
}
