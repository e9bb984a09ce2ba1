//! Seed 001's formation controllers (AEMC, DMPC, SMC) on the net plant through the orchestrator:
//! each closes the net on its target in both cases without exceeding the thrust bound, every QP
//! is solved, and the multi-process run is bit-identical to its in-process reference. Build the
//! binaries first (`scripts/test` does).

use std::path::{Path, PathBuf};

use cohort::{
    describe_output, heavy_scratch, launch_scenario, orchestrator_command, read_json, repo_root,
    scenario_text_with_absolute_paths, telemetry_table,
};

/// `topologies/tsnr-case{case}.toml` with `method` selected, written into `dir`.
fn scenario(case: u32, method: &str, dir: &Path) -> PathBuf {
    let text = scenario_text_with_absolute_paths(&format!("tsnr-case{case}.toml"));
    let line = "\nmethod = \"aemc\"\n";
    assert_eq!(text.matches(line).count(), 1, "tsnr-case{case}.toml selects AEMC on one line");
    let path = dir.join(format!("case{case}-{method}.toml"));
    std::fs::write(&path, text.replace(line, &format!("\nmethod = \"{method}\"\n"))).unwrap();
    path
}

#[test]
fn every_method_closes_the_net_within_the_thrust_bound_in_both_cases() {
    let (_g, dir) = heavy_scratch("tsnr-formation");
    for case in [1, 2] {
        for method in ["aemc", "dmpc", "smc"] {
            let what = format!("case {case}, {method}");
            let out = dir.join(format!("run-{case}-{method}"));
            let o = launch_scenario(&scenario(case, method, &dir), &out, &["--reference"]);
            assert!(o.status.success(), "{what}: {}", describe_output(&o));
            let s = read_json(&out.join("summary.json"));
            assert_eq!(s["metrics"]["thrust_bound_violations"].as_f64(), Some(0.0), "{what}");
            for id in 1..=4 {
                let table = telemetry_table(&out, &format!("agent-{id}"));
                let column = |name: &str| table.get(name).unwrap().to_vec();
                // At the end the net must be closed on the target: every MU within 5 cm (a tenth
                // of the 0.5 m mesh) of its desired position in the last row (t = 29.9 s).
                let err: f64 = ["x", "y", "z"]
                    .iter()
                    .map(|ax| column(&format!("err_{ax}_m")).last().copied().unwrap().powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(err < 0.05, "{what}: MU {id} is {err} m off at the end");
                for ax in ["x", "y", "z"] {
                    let u = column(&format!("u_{ax}_n"));
                    assert!(u.iter().all(|u| u.abs() <= 5.0), "{what}: MU {id} thrust {ax} beyond 5 N");
                }
                let report = read_json(&out.join(format!("status/agent-{id}.json")));
                if method == "smc" {
                    assert!(report.get("solver").is_none(), "{what}: SMC solves no QP");
                } else {
                    assert!(column("qp_status").iter().all(|s| *s == 0.0), "{what}: MU {id} QP status");
                    let st = &report["solver"];
                    assert_eq!(st["solves"].as_u64(), Some(300), "{what}: {st}");
                    assert_eq!(st["solved"].as_u64(), Some(300), "{what}: {st}");
                    let (p50, max) =
                        (st["solve_time_p50_s"].as_f64().unwrap(), st["solve_time_max_s"].as_f64().unwrap());
                    assert!(p50 > 0.0 && p50 <= max, "{what}: {st}");
                }
            }
        }
    }
}

#[test]
fn aemc_multi_process_run_is_bit_identical_to_the_reference() {
    let (_g, dir) = heavy_scratch("tsnr-aemc-mp");
    let file = repo_root().join("topologies/tsnr-case2.toml");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let o = launch_scenario(&file, &mp, &[]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = launch_scenario(&file, &rf, &["--reference"]);
    assert!(o.status.success(), "--reference: {}", describe_output(&o));
    assert_eq!(read_json(&mp.join("summary.json"))["mode"], "multi-process");
    for f in ["plant.parquet", "agent-1.parquet", "agent-2.parquet", "agent-3.parquet", "agent-4.parquet"] {
        let a = std::fs::read(mp.join("telemetry").join(f)).unwrap();
        let b = std::fs::read(rf.join("telemetry").join(f)).unwrap();
        assert!(a == b, "telemetry/{f} differs between the multi-process run and the reference");
    }
}

/// A launch with plots (the default) draws the seed-001 figures: Figs. 8/9's tension panels and
/// the 3-D net at the snapshot times.
#[test]
fn launch_draws_the_tension_and_net_figures() {
    let (_g, dir) = heavy_scratch("tsnr-figures");
    let out = dir.join("run");
    // Not `launch_scenario`: it passes --no-plots.
    let o =
        orchestrator_command().arg("launch").arg(scenario(1, "aemc", &dir)).arg("--out").arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", describe_output(&o));
    for name in ["tsnr_tension.png", "tsnr_net_3d.png"] {
        let path = out.join("plots").join(name);
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "{} is not a PNG", path.display());
        // A blank canvas compresses to a few kB; these figures are a few hundred kB.
        assert!(bytes.len() > 20_000, "{}: only {} bytes", path.display(), bytes.len());
    }
}

/// 5 s of a shipped scenario (with `edit` applied), multi-process and reference: the telemetry
/// must be identical bit for bit. Returns the reference run's directory.
fn mp_equals_reference(name: &str, edit: &dyn Fn(String) -> String, dir: &Path) -> PathBuf {
    let text = scenario_text_with_absolute_paths(name)
        .replace("duration_s = 30.0", "duration_s = 5.0")
        .replace("thrust_bound_n = 5.0\n", "thrust_bound_n = 5.0\nsnapshot_times_s = [0.0]\n");
    let file = dir.join(format!("{}.toml", name.trim_end_matches(".toml")));
    std::fs::write(&file, edit(text)).unwrap();
    let (mp, rf) = (dir.join(format!("{name}-mp")), dir.join(format!("{name}-ref")));
    let o = launch_scenario(&file, &mp, &[]);
    assert!(o.status.success(), "{name}: {}", describe_output(&o));
    let o = launch_scenario(&file, &rf, &["--reference"]);
    assert!(o.status.success(), "{name} --reference: {}", describe_output(&o));
    for f in ["plant.parquet", "agent-1.parquet", "agent-2.parquet", "agent-3.parquet", "agent-4.parquet"] {
        let a = std::fs::read(mp.join("telemetry").join(f)).unwrap();
        let b = std::fs::read(rf.join("telemetry").join(f)).unwrap();
        assert!(a == b, "{name}: telemetry/{f} differs between the multi-process run and the reference");
    }
    rf
}

/// The Clarabel-only scenario and the oracle forecast (replaying a run's recorded tension) are
/// as deterministic as the default.
#[test]
fn clarabel_and_oracle_runs_are_bit_identical_multi_process_and_reference() {
    let (_g, dir) = heavy_scratch("tsnr-variants-mp");
    let first = mp_equals_reference("tsnr-case1-clarabel.toml", &|t| t, &dir);
    let plant = first.join("telemetry/plant.parquet");
    let oracle = move |t: String| {
        let weights = t.lines().find(|l| l.starts_with("tension_weights")).unwrap().to_string();
        t.replace(&weights, &format!("tension_oracle = {:?}", plant.display().to_string()))
            .replace("tension_forecast = \"dnn\"", "tension_forecast = \"oracle\"")
    };
    let rf = mp_equals_reference("tsnr-case1.toml", &oracle, &dir);
    let scenario = std::fs::read_to_string(rf.join("scenario.toml")).unwrap();
    assert!(scenario.contains("tension_forecast = \"oracle\""), "{scenario}");
}
