//! `orchestrator tsnr compare` (seed 001): one multi-process run per method, each in its own run
//! directory, and compare.md / compare.csv whose numbers are the runs' summaries (and whose
//! tracking metrics are the telemetry's); bad method lists and scenarios exit 2 naming the fault.
//! Build the binaries first (`scripts/test` does).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

use cohort::{
    describe_output, heavy_scratch, orchestrator_command, read_json, repo_root, scenario_text_with_absolute_paths,
    telemetry_table,
};

fn compare(file: &Path, algorithms: &str, out: &Path, extra: &[&str]) -> Output {
    orchestrator_command()
        .args(["tsnr", "compare"])
        .arg(file)
        .args(["--algorithms", algorithms, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("running the orchestrator")
}

/// compare.csv as its header and metric → cells.
fn read_csv(path: &Path) -> (Vec<String>, BTreeMap<String, Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(str::to_string).collect();
    let mut rows = BTreeMap::new();
    for line in lines {
        let cells: Vec<String> = line.split(',').map(str::to_string).collect();
        assert_eq!(cells.len(), header.len(), "{line}");
        rows.insert(cells[0].clone(), cells[1..].to_vec());
    }
    (header, rows)
}

#[test]
fn compare_runs_each_method_multi_process_and_tabulates_their_summaries() {
    let (_g, dir) = heavy_scratch("tsnr-compare");
    let out = dir.join("cmp");
    let methods = ["aemc", "dmpc", "smc"];
    let o = compare(&repo_root().join("topologies/tsnr-case1.toml"), "aemc,dmpc,smc", &out, &[]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let summaries: Vec<serde_json::Value> = methods
        .iter()
        .map(|m| {
            let run = out.join(m);
            let scenario = std::fs::read_to_string(run.join("scenario.toml")).unwrap();
            assert!(scenario.contains(&format!("method = \"{m}\"")), "{m}: the run's scenario.toml:\n{scenario}");
            let s = read_json(&run.join("summary.json"));
            assert_eq!(s["status"], "ok", "{m}");
            assert_eq!(s["mode"], "multi-process", "{m}");
            assert!(run.join("plots").is_dir(), "{m}: the run's plots were not drawn");
            s
        })
        .collect();

    let (header, rows) = read_csv(&out.join("compare.csv"));
    assert_eq!(header, ["metric", "aemc", "dmpc", "smc", "paper_aemc", "paper_dmpc", "paper_smc"]);
    // Every row named after a summary metric holds exactly that metric's value per method.
    let mut checked = 0;
    for (key, cells) in &rows {
        if key.contains("_ratio_to_aemc") {
            continue;
        }
        for (j, m) in methods.iter().enumerate() {
            match summaries[j]["metrics"][key.as_str()].as_f64() {
                Some(v) => {
                    assert_eq!(cells[j].parse::<f64>().ok(), Some(v), "{key} of {m}");
                    checked += 1;
                }
                None => assert_eq!(cells[j], "", "{key} of {m}: not in its summary"),
            }
        }
    }
    assert!(checked > 150, "only {checked} values matched a summary metric");
    // The metrics the comparison is about are there (SMC solves no QP).
    for id in 1..=4 {
        for stem in ["fuel_ns", "err_rms_0_10_m", "err_rms_10_20_m", "err_rms_20_30_m", "err_peak_9_11_m"] {
            assert!(rows[&format!("mu_{id}.{stem}")][..3].iter().all(|c| !c.is_empty()), "mu_{id}.{stem}");
        }
        for stem in ["terminal_err_m", "terminal_err_v_mps", "terminal_ok"] {
            assert!(rows[&format!("mu_{id}.{stem}")][..3].iter().all(|c| !c.is_empty()), "mu_{id}.{stem}");
        }
        let p50 = &rows[&format!("mu_{id}.qp_p50_s")];
        assert!(!p50[0].is_empty() && !p50[1].is_empty() && p50[2].is_empty(), "mu_{id}.qp_p50_s: {p50:?}");
    }
    assert_eq!(rows["qp_not_converged"][2], "", "SMC has no QP failures to count");
    // The published column and the ratios.
    assert_eq!(rows["fuel_total_ns"][3..], ["140.77", "140.98", "148.68"]);
    assert_eq!(rows["mu_3.fuel_ns"][3..], ["35.13", "34.87", "37.12"]);
    let fuel: Vec<f64> = (0..3).map(|j| summaries[j]["metrics"]["fuel_total_ns"].as_f64().unwrap()).collect();
    let ratio: Vec<f64> = rows["fuel_total_ratio_to_aemc"][..3].iter().map(|c| c.parse().unwrap()).collect();
    assert_eq!(ratio, [1.0, fuel[1] / fuel[0], fuel[2] / fuel[0]]);
    assert_eq!(rows["fuel_total_ratio_to_aemc"][5].parse::<f64>().unwrap(), 148.68 / 140.77);

    // The tracking metrics agree with the telemetry (MU 2 of DMPC, computed here independently).
    let table = telemetry_table(&out.join("dmpc"), "agent-2");
    let column = |name: &str| table.get(name).unwrap().to_vec();
    let (t, e): (Vec<f64>, Vec<f64>) = {
        let cols: Vec<Vec<f64>> = ["x", "y", "z"].iter().map(|ax| column(&format!("err_{ax}_m"))).collect();
        let e = (0..cols[0].len()).map(|r| cols.iter().map(|c| c[r] * c[r]).sum::<f64>().sqrt()).collect();
        (column("t_s"), e)
    };
    let first: Vec<f64> = e.iter().zip(&t).filter(|(_, t)| **t < 10.0 - 1e-9).map(|(e, _)| *e).collect();
    assert_eq!(first.len(), 100);
    let rms = (first.iter().map(|e| e * e).sum::<f64>() / 100.0).sqrt();
    let got: f64 = rows["mu_2.err_rms_0_10_m"][1].parse().unwrap();
    assert!((got - rms).abs() <= 1e-12 * rms, "RMS 0–10 s: {got} vs {rms} from the telemetry");
    assert_eq!(rows["mu_2.terminal_err_m"][1].parse::<f64>().unwrap(), *e.last().unwrap());

    let md = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(md.contains("Case 1, Table 1"), "{md}");
    assert!(md.contains("by their ratio to AEMC and by their order"), "{md}");
    let total_row = format!("| total | {:.2} | {:.2} | {:.2} | 140.77 | 140.98 | 148.68 |", fuel[0], fuel[1], fuel[2]);
    assert!(md.contains(&total_row), "no {total_row:?} in\n{md}");
    assert!(md.contains("Paper: aemc < dmpc < smc"), "{md}");
    for m in methods {
        assert!(md.contains(&format!("| 4 | {m} |")), "{m}: no tracking row for MU 4\n{md}");
    }
    // The comparison figures, when listed, exist.
    let figures: Vec<PathBuf> = md
        .lines()
        .filter_map(|l| l.strip_prefix("- `").and_then(|l| l.strip_suffix('`')))
        .map(|f| out.join(f))
        .collect();
    assert!(!figures.is_empty(), "no comparison figure listed in\n{md}");
    for f in figures {
        assert!(f.is_file(), "{} is listed but missing", f.display());
    }
    // A second comparison into the same directory is refused (never mixed with the first).
    let o = compare(&repo_root().join("topologies/tsnr-case1.toml"), "smc", &out, &["--no-plots"]);
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not empty"), "{}", describe_output(&o));
}

#[test]
fn another_scenario_has_no_published_column() {
    let (_g, dir) = heavy_scratch("tsnr-compare-other");
    let text = scenario_text_with_absolute_paths("tsnr-case1.toml");
    assert_eq!(text.matches("name = \"tsnr-case1\"").count(), 1);
    let text = text.replace("name = \"tsnr-case1\"", "name = \"tsnr-case1-copy\"");
    let file = dir.join("copy.toml");
    std::fs::write(&file, text).unwrap();
    let out = dir.join("cmp");
    let o = compare(&file, "smc", &out, &["--no-plots"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let (header, rows) = read_csv(&out.join("compare.csv"));
    assert_eq!(header, ["metric", "smc"]);
    assert_eq!(rows["fuel_total_ratio_to_aemc"], [""], "no AEMC run, no ratio");
    let md = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(md.contains("no published column"), "{md}");
    assert!(md.contains("AEMC was not run"), "{md}");
    assert!(!out.join("smc/plots").exists(), "--no-plots drew plots");
}

#[test]
fn bad_method_lists_and_scenarios_exit_2_naming_the_fault() {
    let (_g, dir) = heavy_scratch("tsnr-compare-bad");
    let case1 = repo_root().join("topologies/tsnr-case1.toml");
    for (file, list, want) in [
        (case1.clone(), "aemc,foo", "\"foo\" is not a method"),
        (case1.clone(), "smc,dmpc,smc", "\"smc\" is listed twice"),
        (case1, "aemc,,smc", "empty entry"),
        (repo_root().join("topologies/consensus-ring.toml"), "aemc", "--algorithms needs a tsnr-formation scenario"),
    ] {
        let out = dir.join("never");
        let o = compare(&file, list, &out, &["--no-plots"]);
        assert_eq!(o.status.code(), Some(2), "{list}: {}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{list}: no {want:?} in {err}");
        assert!(!out.exists(), "{list}: an output directory was created before the input was checked");
    }
}
