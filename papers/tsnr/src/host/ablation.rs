//! `orchestrator tsnr ablation FILE…`: where could AEMC's fuel advantage over DMPC come from in
//! our model? Each scenario file is run as given (AEMC, DMPC, SMC) and then under named variants,
//! each ONE change from the file, for the methods the change applies to; the table gives both fuel
//! measures and the tracking of every run (`ablation.md`, `ablation.csv`, run directories
//! `DIR/<scenario>/<variant>/<method>/`). No variant is tuned: the variants are the ablations
//! the comparison asks about, with the file's numbers otherwise.
//!
//! | variant | change (in `[algorithm.mpc]`) | methods |
//! |---|---|---|
//! | `default` | none | aemc, dmpc, smc |
//! | `forecast-hold` | `tension_forecast = "hold-measured"` | aemc |
//! | `forecast-oracle-<m>` | `tension_forecast = "oracle"`, `tension_oracle` = the plant telemetry of the run before (see below) | aemc |
//! | `r-on-thrust` | `force_cost = "thrust"` | aemc, dmpc |
//! | `np10`, `np40` | `horizon_steps = 10`, `40` | aemc, dmpc |
//! | `no-neighbour-costs` | `neighbour_costs = false` | aemc |
//! | `qp-clarabel` | `qp_solver = "clarabel"` | aemc, dmpc |
//!
//! A method a variant does not change keeps its default run. `qp-clarabel` changes no part of
//! the controller: it solves the same QPs to ≈ 1e-5 N instead of exactly, so its spread from the
//! default is what the chaotic net makes of a perturbation that small — the noise floor against
//! which every other row must be read.
//!
//! **Oracle iterations.** `forecast-oracle-1` replays the tension the plant recorded in the
//! default AEMC run; `forecast-oracle-m` the tension of `forecast-oracle-(m−1)`
//! ([`crate::oracle_forecast`] has why). For each iterate the table gives the RMS difference
//! between the tension it replayed and the tension it met, and the first time the two differ by
//! more than 0.1 N.
//!
//! **Fuel.** ∫‖uᵢ‖dt summed over the MUs (N·s, the plant's metric) and, in the unit the paper's
//! Tables 1–2 print, Σₖ‖uᵢ(t_k)‖ over the control steps summed over the MUs (N), from the agents'
//! telemetry (with the thrust held over each step the two differ by the factor Δt).
//! **Tracking.** RMS over the run of ‖r − r_d‖, the mean over the MUs, and its largest value.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort_host::{CommandError, Launcher, Mode, RunOptions};
use cohort_report::Table;
use cohort_report::markdown::MdTable;
use cohort_runtime::paper::Setup;
use cohort_scenario::{Overrides, Scenario, ScenarioError};

use crate::config::formation::{Method, with_method};

/// A named change of `[algorithm.mpc]`: keys to set and keys to drop.
struct Variant {
    name: String,
    change: String,
    set: Vec<(&'static str, toml::Value)>,
    drop: Vec<&'static str>,
    methods: Vec<Method>,
}

fn variant(name: &str, change: &str, set: Vec<(&'static str, toml::Value)>, methods: &[Method]) -> Variant {
    Variant { name: name.into(), change: change.into(), set, drop: Vec::new(), methods: methods.to_vec() }
}

/// The fixed variants (the oracle iterates are made as their references finish).
fn variants() -> Vec<Variant> {
    use Method::{Aemc, Dmpc, Smc};
    use toml::Value::{Boolean, Integer, String as S};
    let mut hold = variant(
        "forecast-hold",
        "tension forecast: the measured tension held",
        vec![("tension_forecast", S("hold-measured".into()))],
        &[Aemc],
    );
    hold.drop.push("tension_weights");
    vec![
        variant("default", "none (the file as it is)", vec![], &[Aemc, Dmpc, Smc]),
        hold,
        variant(
            "r-on-thrust",
            "R on the thrust u, not û = u + T̂",
            vec![("force_cost", S("thrust".into()))],
            &[Aemc, Dmpc],
        ),
        variant("np10", "N_p = 10", vec![("horizon_steps", Integer(10))], &[Aemc, Dmpc]),
        variant("np40", "N_p = 40", vec![("horizon_steps", Integer(40))], &[Aemc, Dmpc]),
        variant("no-neighbour-costs", "game: own cost only", vec![("neighbour_costs", Boolean(false))], &[Aemc]),
        variant(
            "qp-clarabel",
            "QP solved by Clarabel (≈ 1e-5 N): the noise floor",
            vec![("qp_solver", S("clarabel".into()))],
            &[Aemc, Dmpc],
        ),
    ]
}

fn oracle_variant(m: u32, reference: &Path) -> Variant {
    let mut v = variant(
        &format!("forecast-oracle-{m}"),
        &format!(
            "tension forecast: the oracle, iterate {m} (replays the tension of {})",
            if m == 1 { "the default AEMC run".to_string() } else { format!("forecast-oracle-{}", m - 1) }
        ),
        vec![
            ("tension_forecast", toml::Value::String("oracle".into())),
            ("tension_oracle", toml::Value::String(reference.display().to_string())),
        ],
        &[Method::Aemc],
    );
    v.drop.push("tension_weights");
    v
}

/// The scenario of `file` with `method` and the variant's change, validated.
fn configure(
    launcher: &dyn Launcher,
    file: &Path,
    overrides: &Overrides,
    v: &Variant,
    method: Method,
) -> Result<Setup, CommandError> {
    let s: Scenario = cohort_scenario::load(file, overrides)?;
    let mut s = with_method(s, method).map_err(|p| ScenarioError { file: file.to_path_buf(), problems: vec![p] })?;
    if overrides.duration_s.is_some() {
        // A shortened run keeps only the net snapshot at t = 0 (the others may lie past its end).
        s.plant.body.insert("snapshot_times_s".into(), toml::Value::Array(vec![toml::Value::Float(0.0)]));
    }
    if !v.set.is_empty() || !v.drop.is_empty() {
        let Some(toml::Value::Table(mpc)) = s.algorithm.body.get_mut("mpc") else {
            return Err(CommandError::invalid(format!(
                "{}: algorithm.mpc: required by the ablation's variant {:?}",
                file.display(),
                v.name
            )));
        };
        for k in &v.drop {
            mpc.remove(*k);
        }
        for (k, val) in &v.set {
            mpc.insert((*k).into(), val.clone());
        }
    }
    Ok(launcher.configure(s, &format!("{} (variant {}, {})", file.display(), v.name, method.name()))?)
}

/// What one run gave.
#[derive(Debug, Clone, Default)]
pub struct RunFigures {
    pub fuel_ns: f64,
    /// Σₖ‖u(t_k)‖ over steps and MUs, N.
    pub thrust_sum_n: f64,
    /// Mean over MUs of the run's RMS ‖r − r_d‖, m.
    pub err_rms_m: f64,
    /// Largest ‖r − r_d‖ of any MU, m.
    pub err_max_m: f64,
}

/// Fuel in the paper's unit and tracking from a run's agent telemetry.
pub fn run_figures(dir: &Path, n_mus: u32, fuel_ns: f64) -> Result<RunFigures, String> {
    let cols: Vec<String> = ["u", "err"]
        .iter()
        .flat_map(|q| {
            let unit = if *q == "u" { "n" } else { "m" };
            ["x", "y", "z"].map(move |ax| format!("{q}_{ax}_{unit}"))
        })
        .collect();
    let mut f = RunFigures { fuel_ns, ..Default::default() };
    for id in 1..=n_mus {
        let t =
            Table::read_columns(&dir.join(format!("telemetry/agent-{id}.csv")), &cols).map_err(|e| e.to_string())?;
        let norm = |stem: &str, unit: &str, r: usize| -> f64 {
            ["x", "y", "z"].iter().map(|ax| t.col(&format!("{stem}_{ax}_{unit}"))[r].powi(2)).sum::<f64>().sqrt()
        };
        let mut sq = 0.0;
        for r in 0..t.rows() {
            f.thrust_sum_n += norm("u", "n", r);
            let e = norm("err", "m", r);
            sq += e * e;
            f.err_max_m = f.err_max_m.max(e);
        }
        f.err_rms_m += (sq / t.rows().max(1) as f64).sqrt() / f64::from(n_mus);
    }
    Ok(f)
}

/// How far a replayed tension series was from the tension met: RMS of the component
/// differences over MUs and steps (N), and the first time any component differs by more than
/// 0.1 N (None: never).
pub fn oracle_residual(replayed: &Path, met: &Path, n_mus: u32, dt_s: f64) -> Result<(f64, Option<f64>), String> {
    let steps = Table::read_columns(met, &["k"]).map_err(|e| e.to_string())?.rows() as u64;
    let a = crate::oracle_forecast::load(replayed, n_mus, steps, dt_s)?;
    let b = crate::oracle_forecast::load(met, n_mus, steps, dt_s)?;
    let (mut sq, mut n, mut first) = (0.0, 0usize, None::<usize>);
    for (sa, sb) in a.iter().zip(&b) {
        for (k, (ta, tb)) in sa.iter().zip(sb).enumerate().take(steps as usize) {
            for ax in 0..3 {
                let d = ta[ax] - tb[ax];
                sq += d * d;
                n += 1;
                if d.abs() > 0.1 && first.is_none_or(|f| k < f) {
                    first = Some(k);
                }
            }
        }
    }
    Ok(((sq / n.max(1) as f64).sqrt(), first.map(|k| k as f64 * dt_s)))
}

/// A scenario file, its scenario's name and its fixed runs (variant index, method, setup).
type Planned = (PathBuf, String, Vec<(usize, Method, Setup)>);

/// One row of the table: a variant of one scenario, each method's figures (None: not run).
struct Row {
    scenario: String,
    variant: String,
    change: String,
    runs: [Option<RunFigures>; 3],
    oracle: Option<(f64, Option<f64>)>,
}

/// `orchestrator tsnr ablation`.
pub fn command(
    launcher: &dyn Launcher,
    files: &[PathBuf],
    out: Option<&Path>,
    oracle_iterations: u32,
    duration_s: Option<f64>,
    multi_process: bool,
) -> Result<String, CommandError> {
    if files.is_empty() {
        return Err(CommandError::invalid("no scenario file given"));
    }
    if !(1..=10).contains(&oracle_iterations) {
        return Err(CommandError::invalid(format!("--oracle-iterations {oracle_iterations}: must be 1..=10")));
    }
    if let Some(d) = duration_s.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(CommandError::invalid(format!("--duration {d}: must be > 0 s")));
    }
    let overrides = Overrides { duration_s, ..Default::default() };
    // Validate every fixed run up front, so a bad file fails before any run.
    let fixed = variants();
    let mut plan: Vec<Planned> = Vec::new();
    for file in files {
        let mut setups = Vec::new();
        for (vi, v) in fixed.iter().enumerate() {
            for &m in &v.methods {
                setups.push((vi, m, configure(launcher, file, &overrides, v, m)?));
            }
        }
        let name = setups[0].2.scenario.name.clone();
        if plan.iter().any(|(_, n, _)| *n == name) {
            return Err(CommandError::invalid(format!("{}: scenario {name:?} given twice", file.display())));
        }
        plan.push((file.clone(), name, setups));
    }
    let root = cohort_host::fresh_out_dir(out, "tsnr-ablation")?;
    let mode = if multi_process { Mode::MultiProcess } else { Mode::Reference };
    let mut rows: Vec<Row> = Vec::new();
    let mut dt_s = 0.0;
    for (file, name, setups) in &plan {
        let run = |dir: PathBuf, s: &Setup| -> Result<RunFigures, CommandError> {
            if let Some(sig) = launcher.interrupted() {
                return Err(CommandError { message: "interrupted".into(), exit_code: 128 + sig as u8 });
            }
            let r = launcher
                .run(s, &dir, RunOptions { mode, plots: false })
                .map_err(|e| CommandError::failed(e.to_string()))?;
            if let Some(e) = &r.error {
                return Err(CommandError { message: format!("{}: {e}", dir.display()), exit_code: r.exit_code() });
            }
            let f = run_figures(&dir, s.n_agents(), r.metric("fuel_total_ns")).map_err(CommandError::failed)?;
            tracing::info!("{}: fuel {:.2} N·s", dir.display(), f.fuel_ns);
            Ok(f)
        };
        for (vi, v) in fixed.iter().enumerate() {
            let mut figs: [Option<RunFigures>; 3] = Default::default();
            for (_, m, s) in setups.iter().filter(|(i, _, _)| *i == vi) {
                dt_s = s.scenario.dt_s;
                figs[Method::ALL.iter().position(|x| x == m).unwrap_or(0)] =
                    Some(run(root.join(name).join(&v.name).join(m.name()), s)?);
            }
            rows.push(Row {
                scenario: name.clone(),
                variant: v.name.clone(),
                change: v.change.clone(),
                runs: figs,
                oracle: None,
            });
        }
        // The oracle iterates, each replaying the run before.
        let n_mus = setups[0].2.n_agents();
        let mut reference = root.join(name).join("default").join("aemc").join("telemetry/plant.csv");
        for m in 1..=oracle_iterations {
            let v = oracle_variant(m, &reference);
            let s = configure(launcher, file, &overrides, &v, Method::Aemc)?;
            let dir = root.join(name).join(&v.name).join("aemc");
            let f = run(dir.clone(), &s)?;
            let met = dir.join("telemetry/plant.csv");
            let residual = oracle_residual(&reference, &met, n_mus, s.scenario.dt_s).map_err(CommandError::failed)?;
            rows.push(Row {
                scenario: name.clone(),
                variant: v.name.clone(),
                change: v.change.clone(),
                runs: [Some(f), None, None],
                oracle: Some(residual),
            });
            reference = met;
        }
    }
    let md = write(&root, files, &rows, oracle_iterations, dt_s, mode).map_err(CommandError::failed)?;
    Ok(format!("{md}\nablation: {} and {}", root.join("ablation.md").display(), root.join("ablation.csv").display()))
}

fn write(
    root: &Path,
    files: &[PathBuf],
    rows: &[Row],
    iterations: u32,
    dt_s: f64,
    mode: Mode,
) -> Result<String, String> {
    let defaults = |scenario: &str| rows.iter().find(|r| r.scenario == scenario && r.variant == "default");
    // A method a variant does not change keeps its default run.
    let figs = |r: &Row, i: usize| -> Option<(RunFigures, bool)> {
        r.runs[i].clone().map(|f| (f, true)).or_else(|| defaults(&r.scenario)?.runs[i].clone().map(|f| (f, false)))
    };
    let mut csv = String::from(
        "scenario,variant,method,own_run,fuel_ns,thrust_sum_n,err_rms_m,err_max_m,oracle_residual_rms_n,oracle_diverges_s\n",
    );
    for r in rows {
        for (i, m) in Method::ALL.iter().enumerate() {
            if let Some((f, own)) = figs(r, i) {
                let (res, div) = match (i, r.oracle) {
                    (0, Some((res, div))) => (format!("{res:?}"), div.map_or(String::new(), |d| format!("{d:?}"))),
                    _ => (String::new(), String::new()),
                };
                let _ = writeln!(
                    csv,
                    "{},{},{},{own},{:?},{:?},{:?},{:?},{res},{div}",
                    r.scenario,
                    r.variant,
                    m.name(),
                    f.fuel_ns,
                    f.thrust_sum_n,
                    f.err_rms_m,
                    f.err_max_m
                );
            }
        }
    }
    std::fs::write(root.join("ablation.csv"), csv).map_err(|e| format!("{}: {e}", root.display()))?;

    let mut md = format!(
        "# TSNR ablation: {}\n\nEach row is one change from the scenario file (`orchestrator tsnr ablation`, {} runs, \
         {iterations} oracle iterate(s)); a method the change does not apply to shows its default run in *italics*. \
         Fuel: ∫‖u‖dt over the run (N·s) and Σₖ‖u(t_k)‖ over the {dt_s} s steps (N, the unit of the paper's \
         Tables 1–2), both summed over the MUs. Tracking: RMS ‖r − r_d‖ over the run, mean over the MUs (m). \
         AEMC/DMPC < 1 is the paper's claim.\n\n\
         | scenario | variant | change | AEMC ∫‖u‖dt | DMPC ∫‖u‖dt | SMC ∫‖u‖dt | AEMC/DMPC | AEMC Σ‖u_k‖ (N) | DMPC Σ‖u_k‖ (N) | \
         AEMC RMS e | DMPC RMS e | SMC RMS e |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        files.iter().map(|f| format!("`{}`", f.display())).collect::<Vec<_>>().join(", "),
        if mode == Mode::Reference { "in-process reference (bit-identical to multi-process)" } else { "multi-process" },
    );
    let cell = |x: Option<(RunFigures, bool)>, f: &dyn Fn(&RunFigures) -> String| -> String {
        match x {
            Some((v, true)) => f(&v),
            Some((v, false)) => format!("*{}*", f(&v)),
            None => "–".into(),
        }
    };
    let mut holds = Vec::new();
    for r in rows {
        let (a, d, s) = (figs(r, 0), figs(r, 1), figs(r, 2));
        let ratio = match (&a, &d) {
            (Some((a, _)), Some((d, _))) => {
                let x = a.fuel_ns / d.fuel_ns;
                if x <= 1.0 {
                    holds.push(format!("{} `{}` ({:.3})", r.scenario, r.variant, x));
                }
                format!("{x:.3}")
            }
            _ => "–".into(),
        };
        let _ = writeln!(
            md,
            "| {} | `{}` | {} | {} | {} | {} | {ratio} | {} | {} | {} | {} | {} |",
            r.scenario,
            r.variant,
            r.change,
            cell(a.clone(), &|f| format!("{:.1}", f.fuel_ns)),
            cell(d.clone(), &|f| format!("{:.1}", f.fuel_ns)),
            cell(s.clone(), &|f| format!("{:.1}", f.fuel_ns)),
            cell(a.clone(), &|f| format!("{:.0}", f.thrust_sum_n)),
            cell(d.clone(), &|f| format!("{:.0}", f.thrust_sum_n)),
            cell(a, &|f| format!("{:.4}", f.err_rms_m)),
            cell(d, &|f| format!("{:.4}", f.err_rms_m)),
            cell(s, &|f| format!("{:.4}", f.err_rms_m)),
        );
    }
    md.push_str(
        "\nOracle iterates: RMS of (replayed − met) tension components over MUs and steps, and the first time a \
         component differs by more than 0.1 N.\n\n",
    );
    let mut oracle = MdTable::new(["scenario", "variant", "residual RMS (N)", "differs from"]);
    for r in rows {
        if let Some((res, div)) = r.oracle {
            oracle.row([
                r.scenario.to_string(),
                format!("`{}`", r.variant),
                format!("{res:.3}"),
                div.map_or("never".into(), |d| format!("{d:.1} s")),
            ]);
        }
    }
    md.push_str(&oracle.to_string());
    let _ = writeln!(
        md,
        "\nAEMC ≤ DMPC in fuel (∫‖u‖dt) holds for: {}.",
        if holds.is_empty() { "no configuration".to_string() } else { holds.join(", ") }
    );
    md.push_str("\nEvery number is in `ablation.csv` (exact) and the runs' directories.\n");
    std::fs::write(root.join("ablation.md"), &md).map_err(|e| format!("{}: {e}", root.display()))?;
    Ok(md)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_variants_are_one_change_each_with_unique_names() {
        let v = variants();
        let mut names: Vec<&str> = v.iter().map(|x| x.name.as_str()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), v.len());
        for x in &v {
            let changes = x.set.len();
            assert!(x.name == "default" && changes == 0 || changes == 1, "{}: {changes} keys set", x.name);
            assert!(!x.methods.is_empty());
        }
        let o = oracle_variant(2, Path::new("/r/plant.csv"));
        assert_eq!(o.name, "forecast-oracle-2");
        assert!(o.change.contains("forecast-oracle-1"));
        assert_eq!(o.drop, ["tension_weights"]);
    }
}
