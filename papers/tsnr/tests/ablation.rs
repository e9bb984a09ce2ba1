//! `orchestrator tsnr ablation` (seed 001): a shortened run of every variant of Case 1 writes
//! ablation.md / ablation.csv whose fuel is the runs' own; bad arguments and scenarios exit 2
//! naming the fault. Build the binaries first (`scripts/test` does).

use std::path::Path;
use std::process::Output;

use cohort::{describe_output, orchestrator_command, read_json, repo_root, scratch_dir};

fn ablation(args: &[&str], out: &Path) -> Output {
    orchestrator_command().args(["tsnr", "ablation"]).args(args).arg("--out").arg(out).output().expect("orchestrator")
}

#[test]
fn a_short_ablation_runs_every_variant_and_tabulates_the_runs() {
    let dir = scratch_dir("tsnr-ablation");
    let out = dir.join("abl");
    let case1 = repo_root().join("topologies/tsnr-case1.toml");
    let o = ablation(&[case1.to_str().unwrap(), "--duration", "2", "--oracle-iterations", "2"], &out);
    assert!(o.status.success(), "{}", describe_output(&o));
    let md = std::fs::read_to_string(out.join("ablation.md")).unwrap();
    let csv = std::fs::read_to_string(out.join("ablation.csv")).unwrap();
    let runs = [
        ("default", "aemc"),
        ("default", "dmpc"),
        ("default", "smc"),
        ("forecast-hold", "aemc"),
        ("forecast-oracle-1", "aemc"),
        ("forecast-oracle-2", "aemc"),
        ("r-on-thrust", "aemc"),
        ("r-on-thrust", "dmpc"),
        ("np10", "dmpc"),
        ("np40", "aemc"),
        ("no-neighbour-costs", "aemc"),
        ("qp-clarabel", "dmpc"),
    ];
    for (variant, method) in runs {
        assert!(md.contains(&format!("| tsnr-case1 | `{variant}` |")), "no row {variant}:\n{md}");
        let run = out.join("tsnr-case1").join(variant).join(method);
        let s = read_json(&run.join("summary.json"));
        assert_eq!(s["status"], "ok", "{variant}/{method}");
        assert_eq!(s["steps_completed"].as_u64(), Some(20), "{variant}/{method}");
        // The csv row of an own run holds the run's fuel exactly.
        let fuel = s["metrics"]["fuel_total_ns"].as_f64().unwrap();
        let row = csv
            .lines()
            .find(|l| l.starts_with(&format!("tsnr-case1,{variant},{method},true,")))
            .unwrap_or_else(|| panic!("no csv row for {variant}/{method}:\n{csv}"));
        assert_eq!(row.split(',').nth(4).unwrap().parse::<f64>().unwrap(), fuel, "{row}");
        // Σ‖u_k‖ is ∫‖u‖dt / Δt for a thrust held over each step.
        let sum: f64 = row.split(',').nth(5).unwrap().parse().unwrap();
        assert!((sum * 0.1 - fuel).abs() < 1e-9 * fuel.max(1.0), "{row}");
    }
    // What each variant changed is in the run's resolved scenario.
    let scenario = |v: &str, m: &str| {
        std::fs::read_to_string(out.join("tsnr-case1").join(v).join(m).join("scenario.toml")).unwrap()
    };
    assert!(scenario("np40", "dmpc").contains("horizon_steps = 40"));
    assert!(scenario("r-on-thrust", "aemc").contains("force_cost = \"thrust\""));
    let oracle2 = scenario("forecast-oracle-2", "aemc");
    assert!(
        oracle2.contains("tension_forecast = \"oracle\"")
            && oracle2.contains("forecast-oracle-1/aemc/telemetry/plant.csv"),
        "{oracle2}"
    );
    assert!(md.contains("| tsnr-case1 | `forecast-oracle-2` |") && md.contains("AEMC ≤ DMPC in fuel"), "{md}");
}

#[test]
fn bad_arguments_and_scenarios_exit_2_naming_the_fault() {
    let dir = scratch_dir("tsnr-ablation-bad");
    let case1 = repo_root().join("topologies/tsnr-case1.toml");
    let ring = repo_root().join("topologies/consensus-ring.toml");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![case1.to_str().unwrap(), "--oracle-iterations", "0"], "--oracle-iterations 0: must be 1..=10"),
        // clap reads a bare `-1` as a flag; the `=` form reaches our range check.
        (vec![case1.to_str().unwrap(), "--duration=-1"], "--duration -1: must be > 0 s"),
        (vec![ring.to_str().unwrap()], "needs a tsnr-formation scenario"),
        (vec![case1.to_str().unwrap(), case1.to_str().unwrap()], "given twice"),
        (vec!["no/such/file.toml"], "cannot read"),
        (vec![], "FILES"),
    ];
    for (args, want) in cases {
        let o = ablation(&args, &dir.join("out"));
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: want {want:?} in\n{err}");
    }
    // A directory with something in it is refused before any run.
    let full = dir.join("full");
    std::fs::create_dir_all(&full).unwrap();
    std::fs::write(full.join("x"), "").unwrap();
    let o = ablation(&[case1.to_str().unwrap(), "--duration", "1"], &full);
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not empty"));
}
