//! `orchestrator tsnr compare`: one multi-process run per method, then the analogue of the paper's
//! Tables 1–2 — fuel per MU and method beside the published figures — with the tracking, thrust
//! and solver metrics of each run (`compare.md`, `compare.csv`). The numbers are the runs'
//! `summary.json` metrics (plant: fuel, thrust, tension; [`crate::host::analysis`]: tracking errors, QP
//! statistics).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort_host::{CommandError, Launcher, Mode, RunOptions};
use cohort_scenario::{Overrides, ScenarioError};

use crate::config::formation::{Method, with_method};

use crate::host::analysis::{TERMINAL_POSITION_TOL_M, TERMINAL_VELOCITY_TOL_MPS};

/// MUs in the paper's tables.
const PAPER_MUS: usize = 4;

/// One column of Table 1 or 2: the published "fuel" per MU and the printed total (unit "N", the
/// "total control input generated").
struct PaperFuel {
    method: &'static str,
    per_mu: [f64; PAPER_MUS],
    total: f64,
}

/// Table 1 (Case 1) and Table 2 (Case 2) as printed.
const PAPER: [(u32, [PaperFuel; 3]); 2] = [
    (
        1,
        [
            PaperFuel { method: "aemc", per_mu: [35.19, 35.23, 35.13, 35.22], total: 140.77 },
            PaperFuel { method: "dmpc", per_mu: [35.44, 35.23, 34.87, 35.44], total: 140.98 },
            PaperFuel { method: "smc", per_mu: [37.08, 37.21, 37.12, 37.27], total: 148.68 },
        ],
    ),
    (
        2,
        [
            PaperFuel { method: "aemc", per_mu: [56.21, 55.16, 56.21, 55.18], total: 222.77 },
            // The per-MU values sum to 222.37, not the printed 223.53 (said in compare.md).
            PaperFuel { method: "dmpc", per_mu: [55.32, 56.50, 55.23, 55.32], total: 223.53 },
            PaperFuel { method: "smc", per_mu: [55.78, 56.56, 55.79, 56.56], total: 224.71 },
        ],
    ),
];

fn paper(case: u32, method: &str) -> Option<&'static PaperFuel> {
    PAPER.iter().find(|(c, _)| *c == case)?.1.iter().find(|p| p.method == method)
}

/// The total "fuel" Table 1 (case 1) or Table 2 (case 2) prints for `method`, N.
pub fn paper_fuel_total_n(case: u32, method: &str) -> Option<f64> {
    paper(case, method).map(|p| p.total)
}

/// The paper's case a scenario reproduces, from its name (`tsnr-case1`, `tsnr-case2`); None for
/// any other scenario, which then has no published column.
pub fn paper_case(scenario_name: &str) -> Option<u32> {
    match scenario_name {
        "tsnr-case1" => Some(1),
        "tsnr-case2" => Some(2),
        _ => None,
    }
}

/// `--algorithms` as a list of methods: each known, each once, in the order given.
pub fn parse_algorithms(list: &str) -> Result<Vec<String>, String> {
    let mut out: Vec<String> = Vec::new();
    for m in list.split(',').map(str::trim) {
        if m.is_empty() {
            return Err(format!("--algorithms {list:?}: an empty entry (expected a comma list of aemc, dmpc, smc)"));
        }
        if m.parse::<Method>().is_err() {
            return Err(format!("--algorithms {list:?}: {m:?} is not a method (expected aemc, dmpc or smc)"));
        }
        if out.iter().any(|x| x == m) {
            return Err(format!("--algorithms {list:?}: {m:?} is listed twice"));
        }
        out.push(m.to_string());
    }
    Ok(out)
}

/// The command: one multi-process run per method into `root/<method>/`, then the tables.
pub fn command(
    launcher: &dyn Launcher,
    file: &Path,
    algorithms: &str,
    out: Option<&Path>,
    plots: bool,
) -> Result<String, CommandError> {
    let methods = parse_algorithms(algorithms).map_err(CommandError::invalid)?;
    // Validate every method's scenario up front, so a bad file or method fails before any run.
    let mut setups = Vec::new();
    for m in &methods {
        let scenario = cohort_scenario::load(file, &Overrides::default())?;
        let method: Method = m.parse().map_err(CommandError::invalid)?;
        let scenario =
            with_method(scenario, method).map_err(|p| ScenarioError { file: file.to_path_buf(), problems: vec![p] })?;
        setups.push((m.clone(), launcher.configure(scenario, &file.display().to_string())?));
    }
    let Some((_, first)) = setups.first() else {
        return Err(CommandError::invalid(format!("--algorithms {algorithms:?}: no method")));
    };
    let root = cohort_host::fresh_out_dir(out, &format!("{}-compare", first.scenario.name))?;
    tracing::info!("comparing {} over {} (multi-process) → {}", file.display(), methods.join(", "), root.display());
    let mut runs = Vec::new();
    for (method, s) in &setups {
        let dir = root.join(method);
        let r = launcher
            .run(s, &dir, RunOptions { mode: Mode::MultiProcess, plots })
            .map_err(|e| CommandError::failed(e.to_string()))?;
        if let Some(e) = &r.error {
            tracing::info!("run directory (partial): {}", dir.display());
            return Err(CommandError { message: format!("{method}: {e}"), exit_code: r.exit_code() });
        }
        tracing::info!(
            "{method}: {} steps in {:.2} s; fuel {:.2} N·s",
            r.steps_completed,
            r.wall_s,
            r.metric("fuel_total_ns")
        );
        runs.push((method.clone(), r.metrics));
    }
    // The Figs. 10/11 analogue: every method's tracking error on one figure. A figure is not
    // worth losing the tables over, so a failure is a warning.
    let figures = if plots {
        let dirs: Vec<(String, PathBuf)> = methods.iter().map(|m| (m.clone(), root.join(m))).collect();
        crate::host::figures::draw_comparison(&root, &dirs, Some(&first.scenario.name)).unwrap_or_else(|e| {
            tracing::warn!("comparison figures not drawn: {e}");
            Vec::new()
        })
    } else {
        Vec::new()
    };
    let ctx = Context {
        file,
        scenario_name: &first.scenario.name,
        seed: first.scenario.seed,
        n_mus: first.n_agents(),
        steps: first.n_steps(),
        dt_s: first.scenario.dt_s,
        figures: &figures,
    };
    let md = write(&root, &ctx, &runs).map_err(CommandError::failed)?;
    Ok(format!("{md}\ncomparison: {} and {}", root.join("compare.md").display(), root.join("compare.csv").display()))
}

/// What compare.md says about the runs besides their metrics.
pub struct Context<'a> {
    pub file: &'a Path,
    pub scenario_name: &'a str,
    pub seed: u64,
    pub n_mus: u32,
    pub steps: u64,
    pub dt_s: f64,
    /// The comparison figures, when drawn.
    pub figures: &'a [PathBuf],
}

/// Numbers for people: 4 significant digits, scientific outside [1e-3, 1e5).
fn g(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) {
        format!("{x:.3e}")
    } else {
        let digits = if x == 0.0 { 0 } else { (3 - x.abs().log10().floor() as i32).clamp(0, 6) as usize };
        format!("{x:.digits$}")
    }
}

/// Metric names that depend on the trajectory's knots (`err_rms_<a>_<b>_m`, `err_peak_…`), in
/// time order, as the runs have them for MU `id`.
fn windowed(runs: &[(String, BTreeMap<String, f64>)], id: u32, stem: &str) -> Vec<String> {
    let prefix = format!("mu_{id}.{stem}_");
    let mut keys: Vec<(f64, String)> = Vec::new();
    for (_, m) in runs {
        for k in m.keys().filter(|k| k.starts_with(&prefix)) {
            let start = k[prefix.len()..].split('_').next().and_then(|a| a.parse().ok()).unwrap_or(f64::INFINITY);
            if !keys.iter().any(|(_, x)| x == k) {
                keys.push((start, k.clone()));
            }
        }
    }
    keys.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    keys.into_iter().map(|(_, k)| k).collect()
}

/// "0_10" of `mu_1.err_rms_0_10_m` as "0–10 s".
fn window_label(key: &str, stem: &str) -> String {
    let rest = key.split_once(&format!("{stem}_")).map_or(key, |(_, r)| r);
    let rest = rest.strip_suffix("_m").unwrap_or(rest);
    match rest.split_once('_') {
        Some((a, b)) => format!("{a}–{b} s"),
        None => rest.to_string(),
    }
}

/// One line of compare.csv: a metric, its value per method run, and the published value per
/// method (fuel rows of a paper case only).
type Row = (String, Vec<Option<f64>>, Vec<Option<f64>>);

/// Write `compare.csv` and `compare.md` under `root`; returns the Markdown. `runs` holds each
/// method's summary metrics, in the order run.
pub fn write(root: &Path, ctx: &Context, runs: &[(String, BTreeMap<String, f64>)]) -> Result<String, String> {
    let c = Compare::new(root, ctx, runs);
    let rows = c.rows();
    let csv_path = root.join("compare.csv");
    std::fs::write(&csv_path, c.csv(&rows)).map_err(|e| format!("{}: {e}", csv_path.display()))?;
    let mut md = c.intro();
    c.fuel(&mut md, &rows);
    c.tracking(&mut md);
    c.thrust_and_solver(&mut md);
    c.figures(&mut md);
    let md_path = root.join("compare.md");
    std::fs::write(&md_path, &md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    Ok(md)
}

/// A metric of a run's summary.
fn get(m: &BTreeMap<String, f64>, k: &str) -> Option<f64> {
    m.get(k).copied()
}

/// What every part of the comparison reads: the runs, their methods, and the paper's case when
/// its table applies.
struct Compare<'a> {
    root: &'a Path,
    ctx: &'a Context<'a>,
    runs: &'a [(String, BTreeMap<String, f64>)],
    case: Option<u32>,
    methods: Vec<&'a str>,
    aemc: Option<&'a BTreeMap<String, f64>>,
    /// The paper's case, when the scenario is one and has the table's 4 MUs.
    with_paper: Option<u32>,
    mu_ids: Vec<u32>,
}

impl<'a> Compare<'a> {
    fn new(root: &'a Path, ctx: &'a Context<'a>, runs: &'a [(String, BTreeMap<String, f64>)]) -> Self {
        let case = paper_case(ctx.scenario_name);
        Self {
            root,
            ctx,
            runs,
            case,
            methods: runs.iter().map(|(m, _)| m.as_str()).collect(),
            aemc: runs.iter().find(|(m, _)| m == "aemc").map(|(_, m)| m),
            with_paper: case.filter(|_| ctx.n_mus as usize == PAPER_MUS),
            mu_ids: (1..=ctx.n_mus).collect(),
        }
    }

    /// compare.csv's rows: one per metric, one column per method (and per published method).
    /// Values are the summaries' own (`{:?}` round-trips), so a reader can check them exactly.
    fn rows(&self) -> Vec<Row> {
        let (runs, methods, aemc, with_paper, mu_ids) =
            (self.runs, self.methods.clone(), self.aemc, self.with_paper, self.mu_ids.clone());
        let mut rows: Vec<Row> = Vec::new();
        let ours = |key: &str| -> Vec<Option<f64>> { runs.iter().map(|(_, m)| get(m, key)).collect() };
        let theirs = |f: &dyn Fn(&PaperFuel) -> f64| -> Vec<Option<f64>> {
            methods.iter().map(|m| with_paper.and_then(|c| paper(c, m)).map(f)).collect()
        };
        for &id in &mu_ids {
            let i = id as usize - 1;
            let key = format!("mu_{id}.fuel_ns");
            rows.push((key.clone(), ours(&key), theirs(&|p| p.per_mu[i])));
        }
        rows.push(("fuel_total_ns".into(), ours("fuel_total_ns"), theirs(&|p| p.total)));
        let paper_aemc = with_paper.and_then(|c| paper(c, "aemc"));
        let ratio_of = |key: &str, base: Option<f64>| -> Vec<Option<f64>> {
            runs.iter().map(|(_, m)| Some(get(m, key)? / base?)).collect()
        };
        for &id in &mu_ids {
            let i = id as usize - 1;
            let key = format!("mu_{id}.fuel_ns");
            let base = aemc.and_then(|m| get(m, &key));
            let paper_ratio = theirs(&|p| p.per_mu[i]).into_iter().map(|x| Some(x? / paper_aemc?.per_mu[i])).collect();
            rows.push((format!("mu_{id}.fuel_ratio_to_aemc"), ratio_of(&key, base), paper_ratio));
        }
        let base = aemc.and_then(|m| get(m, "fuel_total_ns"));
        let paper_ratio = theirs(&|p| p.total).into_iter().map(|x| Some(x? / paper_aemc?.total)).collect();
        rows.push(("fuel_total_ratio_to_aemc".into(), ratio_of("fuel_total_ns", base), paper_ratio));
        let none = vec![None; runs.len()];
        let plain = |key: String, rows: &mut Vec<_>| {
            let v = ours(&key);
            rows.push((key, v, none.clone()));
        };
        for &id in &mu_ids {
            for k in windowed(runs, id, "err_rms").into_iter().chain(windowed(runs, id, "err_peak")) {
                plain(k, &mut rows);
            }
            for s in ["terminal_err_m", "terminal_err_v_mps", "terminal_ok"] {
                plain(format!("mu_{id}.{s}"), &mut rows);
            }
        }
        plain("thrust_bound_violations".into(), &mut rows);
        for ax in ["x", "y", "z"] {
            plain(format!("thrust_max_abs_{ax}_n"), &mut rows);
        }
        for &id in &mu_ids {
            plain(format!("mu_{id}.tension_max_n"), &mut rows);
        }
        for &id in &mu_ids {
            for s in ["qp_p50_s", "qp_p99_s", "qp_max_s"] {
                plain(format!("mu_{id}.{s}"), &mut rows);
            }
        }
        plain("qp_not_converged".into(), &mut rows);
        plain("qp_infeasible".into(), &mut rows);
        rows
    }

    /// compare.csv: `rows` under a header of the methods (and the published methods).
    fn csv(&self, rows: &[Row]) -> String {
        let (methods, with_paper) = (self.methods.clone(), self.with_paper);
        let mut csv = String::from("metric");
        for m in &methods {
            let _ = write!(csv, ",{m}");
        }
        if with_paper.is_some() {
            for m in &methods {
                let _ = write!(csv, ",paper_{m}");
            }
        }
        csv.push('\n');
        let cell = |x: &Option<f64>| x.map_or(String::new(), |v| format!("{v:?}"));
        for (key, ours, paper) in rows {
            csv.push_str(key);
            for x in ours {
                let _ = write!(csv, ",{}", cell(x));
            }
            if with_paper.is_some() {
                for x in paper {
                    let _ = write!(csv, ",{}", cell(x));
                }
            }
            csv.push('\n');
        }
        csv
    }

    /// compare.md's heading: the scenario, the runs, and which published table applies.
    fn intro(&self) -> String {
        let (ctx, methods, case, with_paper) = (self.ctx, self.methods.clone(), self.case, self.with_paper);
        let mut md = format!(
            "# `{}`: {}\n\nScenario `{}`, seed {}, {} MUs, {} steps of {} s; each method run multi-process (one \
             process per MU, the plant, the orchestrator). Run directories: {}.\n\n",
            ctx.file.display(),
            methods.join(", "),
            ctx.scenario_name,
            ctx.seed,
            ctx.n_mus,
            ctx.steps,
            ctx.dt_s,
            methods.iter().map(|m| format!("`{m}/`")).collect::<Vec<_>>().join(", "),
        );
        match (case, with_paper) {
            (Some(c), Some(_)) => {
                let _ = writeln!(md, "Published values: Case {c}, Table {c} of the paper.\n");
            }
            (Some(c), None) => {
                let _ = writeln!(
                    md,
                    "Case {c} by name, but {} MUs: the paper's table has 4, so it is not shown.\n",
                    ctx.n_mus
                );
            }
            _ => md.push_str("Not one of the paper's cases (`tsnr-case1`, `tsnr-case2`): no published column.\n\n"),
        }
        md
    }

    /// The fuel table (ours against the published), the paper's unit, and the methods' order.
    fn fuel(&self, md: &mut String, rows: &[Row]) {
        let (ctx, runs, methods, aemc, with_paper, mu_ids) =
            (self.ctx, self.runs, self.methods.clone(), self.aemc, self.with_paper, self.mu_ids.clone());
        md.push_str(
            "## Fuel\n\nOurs: ∫‖uᵢ‖dt over the run, N·s. The paper's Tables 1–2 give \"the total control input \
             generated\" in N without saying how it is summed, so the absolute figures are not comparable: we \
             compare the methods by their ratio to AEMC and by their order.\n\n| MU |",
        );
        for m in &methods {
            let _ = write!(md, " {m} (N·s) |");
        }
        if with_paper.is_some() {
            for m in &methods {
                let _ = write!(md, " paper {m} (N) |");
            }
        }
        let ncols = methods.len() * if with_paper.is_some() { 2 } else { 1 };
        let _ = writeln!(md, "\n|---|{}", "---|".repeat(ncols));
        let fuel_rows = mu_ids.len() + 1;
        for (r, (key, ours, paper)) in rows.iter().take(fuel_rows).enumerate() {
            let label = if key == "fuel_total_ns" { "total".to_string() } else { (r + 1).to_string() };
            let _ = write!(md, "| {label} |");
            for x in ours {
                let _ = write!(md, " {} |", x.map_or("–".into(), |v| format!("{v:.2}")));
            }
            if with_paper.is_some() {
                for x in paper {
                    let _ = write!(md, " {} |", x.map_or("–".into(), |v| format!("{v:.2}")));
                }
            }
            md.push('\n');
        }
        if let Some((_, ours, paper)) = rows.iter().find(|(k, _, _)| k == "fuel_total_ratio_to_aemc") {
            md.push_str("| total / AEMC |");
            for x in ours {
                let _ = write!(md, " {} |", x.map_or("–".into(), |v| format!("{v:.4}")));
            }
            if with_paper.is_some() {
                for x in paper {
                    let _ = write!(md, " {} |", x.map_or("–".into(), |v| format!("{v:.4}")));
                }
            }
            md.push('\n');
        }
        if aemc.is_none() {
            md.push_str("\nAEMC was not run: no ratios of ours.\n");
        }
        // The paper's unit: Σ‖u_k‖ over the control steps. With the thrust held over each step it is
        // ∫‖u‖dt / Δt exactly, so the published totals (≈ 140 N in Case 1) would be ≈ 14 N·s of
        // ours, a thirtieth of what our net demands.
        let per_step: Vec<String> = runs
            .iter()
            .map(|(m, r)| {
                format!("{m} {}", get(r, "fuel_total_ns").map_or("–".into(), |f| format!("{:.0}", f / ctx.dt_s)))
            })
            .collect();
        let _ = writeln!(
            md,
            "\nIn the paper's unit, Σₖ‖uᵢ(t_k)‖ over the {} s steps summed over the MUs (∫‖u‖dt / Δt, the thrust being \
             held over each step): {} N.",
            ctx.dt_s,
            per_step.join(", ")
        );
        // Orders, least fuel first.
        let order = |vals: Vec<(&str, Option<f64>)>| -> Option<Vec<String>> {
            let mut v: Vec<(&str, f64)> = vals.into_iter().map(|(m, x)| Some((m, x?))).collect::<Option<_>>()?;
            v.sort_by(|a, b| a.1.total_cmp(&b.1));
            Some(v.into_iter().map(|(m, _)| m.to_string()).collect())
        };
        let ours_order = order(runs.iter().map(|(m, r)| (m.as_str(), get(r, "fuel_total_ns"))).collect());
        let paper_order =
            with_paper.and_then(|c| order(methods.iter().map(|m| (*m, paper(c, m).map(|p| p.total))).collect()));
        md.push('\n');
        if let Some(o) = &ours_order {
            let _ = writeln!(md, "Order by total fuel, least first — ours: {}.", o.join(" < "));
        }
        if let Some(p) = &paper_order {
            let same = ours_order.as_ref() == Some(p);
            let _ = writeln!(
                md,
                "Paper: {} ({}).",
                p.join(" < "),
                if same { "the same order" } else { "a different order" }
            );
        }
        if with_paper == Some(2) && methods.contains(&"dmpc") {
            md.push_str(
                "\nTable 2's DMPC column sums to 222.37, not the printed total 223.53; the total ratio uses the printed \
                 total.\n",
            );
        }
    }

    /// The tracking errors per MU and method: RMS per phase, peaks, terminal error.
    fn tracking(&self, md: &mut String) {
        let (runs, mu_ids) = (self.runs, self.mu_ids.clone());
        let _ = write!(
            md,
            "\n## Tracking error ‖r − r_d‖\n\nRMS per phase of the trajectory, peak around the end of deployment (the \
             paper has DMPC and SMC peak at 10 s, AEMC not), and the terminal error in the last row (t = T − Δt) \
             against {TERMINAL_POSITION_TOL_M} m and {TERMINAL_VELOCITY_TOL_MPS} m/s.\n\n| MU | method |"
        );
        let rms_keys = windowed(runs, 1, "err_rms");
        let peak_keys = windowed(runs, 1, "err_peak");
        for k in &rms_keys {
            let _ = write!(md, " RMS {} (m) |", window_label(k, "err_rms"));
        }
        for k in &peak_keys {
            let _ = write!(md, " peak {} (m) |", window_label(k, "err_peak"));
        }
        md.push_str(" terminal ‖e‖ (m) | terminal ‖v − v_d‖ (m/s) | terminal ok |\n|---|---|");
        md.push_str(&"---|".repeat(rms_keys.len() + peak_keys.len() + 3));
        md.push('\n');
        let num = |m: &BTreeMap<String, f64>, k: &str| get(m, k).map_or("–".into(), g);
        for &id in &mu_ids {
            let swap = |k: &str| k.replacen("mu_1.", &format!("mu_{id}."), 1);
            for (method, m) in runs {
                let _ = write!(md, "| {id} | {method} |");
                for k in rms_keys.iter().chain(&peak_keys) {
                    let _ = write!(md, " {} |", num(m, &swap(k)));
                }
                let ok = match get(m, &format!("mu_{id}.terminal_ok")) {
                    Some(1.0) => "yes",
                    Some(_) => "**no**",
                    None => "–",
                };
                let _ = writeln!(
                    md,
                    " {} | {} | {ok} |",
                    num(m, &format!("mu_{id}.terminal_err_m")),
                    num(m, &format!("mu_{id}.terminal_err_v_mps"))
                );
            }
        }
        if let Some(pk) = peak_keys.first() {
            md.push_str("\nLargest peak over the MUs: ");
            let parts: Vec<String> = runs
                .iter()
                .map(|(method, m)| {
                    let peak = mu_ids
                        .iter()
                        .filter_map(|id| get(m, &pk.replacen("mu_1.", &format!("mu_{id}."), 1)))
                        .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))));
                    format!("{method} {} m", peak.map_or("–".into(), g))
                })
                .collect();
            let _ = writeln!(md, "{}.", parts.join(", "));
        }
    }

    /// Thrust bounds and QP solve times per method.
    fn thrust_and_solver(&self, md: &mut String) {
        let (runs, mu_ids) = (self.runs, self.mu_ids.clone());
        let num = |m: &BTreeMap<String, f64>, k: &str| get(m, k).map_or("–".into(), g);
        md.push_str(
            "\n## Thrust and solver\n\nQP solve wall times per MU (1 / 2 / 3 / …), ms; failures summed over the MUs. \
             SMC solves no QP.\n\n| method | thrust-bound violations | largest thrust component (N) | QP p50 (ms) | QP p99 \
             (ms) | QP max (ms) | not converged | infeasible |\n|---|---|---|---|---|---|---|---|\n",
        );
        for (method, m) in runs {
            let per_mu = |s: &str| -> String {
                let xs: Vec<String> = mu_ids
                    .iter()
                    .map(|id| get(m, &format!("mu_{id}.{s}")).map_or("–".into(), |v| g(v * 1e3)))
                    .collect();
                if xs.iter().all(|x| x == "–") { "–".into() } else { xs.join(" / ") }
            };
            let umax = ["x", "y", "z"]
                .iter()
                .filter_map(|ax| get(m, &format!("thrust_max_abs_{ax}_n")))
                .fold(None, |a: Option<f64>, x| Some(a.map_or(x, |a| a.max(x))));
            let _ = writeln!(
                md,
                "| {method} | {} | {} | {} | {} | {} | {} | {} |",
                num(m, "thrust_bound_violations"),
                umax.map_or("–".into(), g),
                per_mu("qp_p50_s"),
                per_mu("qp_p99_s"),
                per_mu("qp_max_s"),
                num(m, "qp_not_converged"),
                num(m, "qp_infeasible"),
            );
        }
    }

    /// The figures' list and the closing line.
    fn figures(&self, md: &mut String) {
        let (ctx, root) = (self.ctx, self.root);
        if !ctx.figures.is_empty() {
            md.push_str("\n## Figures\n\n");
            for f in ctx.figures {
                let shown = f.strip_prefix(root).unwrap_or(f);
                let _ = writeln!(md, "- `{}`", shown.display());
            }
        }
        md.push_str("\nEvery number above is in `compare.csv` (exact) and the runs' `summary.json`.\n");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_algorithm_list_is_checked_naming_the_bad_entry() {
        assert_eq!(parse_algorithms("aemc,dmpc,smc").unwrap(), ["aemc", "dmpc", "smc"]);
        assert_eq!(parse_algorithms("smc, aemc").unwrap(), ["smc", "aemc"]);
        let e = parse_algorithms("aemc,foo").unwrap_err();
        assert!(e.contains("\"foo\" is not a method"), "{e}");
        let e = parse_algorithms("dmpc,smc,dmpc").unwrap_err();
        assert!(e.contains("\"dmpc\" is listed twice"), "{e}");
        assert!(parse_algorithms("aemc,,smc").unwrap_err().contains("empty entry"));
        assert!(parse_algorithms("").unwrap_err().contains("empty entry"));
    }

    #[test]
    fn the_published_totals_are_the_printed_ones() {
        assert_eq!(paper_case("tsnr-case2"), Some(2));
        assert_eq!(paper_case("tsnr-case1-long"), None);
        // Case 1's columns add up to their totals; Case 2's DMPC column does not (222.37).
        for p in &PAPER[0].1 {
            assert!((p.per_mu.iter().sum::<f64>() - p.total).abs() < 0.011, "{}", p.method);
        }
        let dmpc2 = paper(2, "dmpc").unwrap();
        assert!((dmpc2.per_mu.iter().sum::<f64>() - 222.37).abs() < 1e-9);
        assert_eq!(dmpc2.total, 223.53);
    }
}
