//! Seed 000's headline scenario end to end: `orchestrator launch topologies/fig1.toml` runs
//! multi-process for the full 360 s and its telemetry is bit-identical to the in-process
//! reference; over 10 seeds every servicer meets the paper's published bounds; the figures are
//! drawn. Heavy: serialised, generous timeouts. Run with `scripts/test`.

use std::path::Path;
use std::process::Output;

use cohort::{describe_output, heavy, orchestrator_command, scratch_dir};

fn orchestrator(args: &[&str], out: &Path) -> Output {
    orchestrator_command().args(args).arg("--out").arg(out).output().expect("running the orchestrator")
}

#[test]
fn fig1_runs_multi_process_for_360_s_bit_identical_to_the_reference_with_its_figures() {
    let _g = heavy();
    let dir = scratch_dir("fig1");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let o = orchestrator(&["launch", "topologies/fig1.toml"], &mp);
    assert!(o.status.success(), "{}", describe_output(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("run directory:") && stdout.contains("plots:"), "{stdout}");
    let o = orchestrator(&["launch", "topologies/fig1.toml", "--reference", "--no-plots"], &rf);
    assert!(o.status.success(), "{}", describe_output(&o));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(mp.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["steps_completed"], 36_000);
    assert_eq!(summary["sim_time_s"], 360.0);
    for f in ["plant", "agent-1", "agent-2", "agent-3", "agent-4", "agent-5", "agent-6"].map(|s| format!("{s}.parquet"))
    {
        let a = std::fs::read(mp.join("telemetry").join(&f)).unwrap();
        let b = std::fs::read(rf.join("telemetry").join(&f)).unwrap();
        assert!(a == b, "telemetry/{f} differs between the multi-process run and the reference");
    }
    // Every summary metric the issue names is there, per servicer.
    let m = summary["metrics"].as_object().unwrap();
    for i in 1..=6 {
        for k in [
            "e_rms_200_360_m",
            "e_max_200_360_m",
            "zeta_err_rms_150_360_mps",
            "zeta_err_max_150_360_mps",
            "u_peak_mps2",
            "dv_total_mps",
        ] {
            let key = format!("servicer_{i}.{k}");
            let v = m.get(&key).and_then(|v| v.as_f64()).unwrap_or_else(|| panic!("{key} missing from summary.json"));
            assert!(v.is_finite() && v >= 0.0, "{key} = {v}");
        }
    }
    for png in ["fig2_trajectories_3d.png", "fig3_zeta_error.png", "fig4_tracking_error.png", "u_norm.png"] {
        let p = mp.join("plots").join(png);
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 5_000, "{} missing or empty ({len} bytes)", p.display());
    }
}

#[test]
fn over_10_seeds_every_servicer_meets_the_papers_bounds() {
    // Paper (Figs. 3–4): ‖ζ̃ᵢ‖ ≈ 5 m/s after ≈ 150 s, ‖eᵢ‖ ≈ 5 m after ≈ 200 s. The sweep runs
    // in-process (bit-identical to multi-process, shown by the test above) for speed.
    let _g = heavy();
    let dir = scratch_dir("fig1sweep");
    let o = orchestrator(&["sweep", "topologies/fig1.toml", "--seeds", "10"], &dir);
    assert!(o.status.success(), "{}", describe_output(&o));
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let mut rows = 0;
    for line in lines {
        rows += 1;
        let f: Vec<&str> = line.split(',').collect();
        for (k, v) in header.iter().zip(&f) {
            let x: f64 = if *k == "seed" { continue } else { v.parse().unwrap() };
            if k.ends_with(".e_rms_200_360_m") {
                assert!(x <= 5.0, "seed {}: {k} = {x} m > 5 m", f[0]);
            }
            if k.ends_with(".zeta_err_rms_150_360_mps") {
                assert!(x <= 5.0, "seed {}: {k} = {x} m/s > 5 m/s", f[0]);
            }
        }
        assert_eq!(header.iter().filter(|k| k.ends_with(".e_rms_200_360_m")).count(), 6);
        assert_eq!(header.iter().filter(|k| k.ends_with(".zeta_err_rms_150_360_mps")).count(), 6);
    }
    assert_eq!(rows, 10);
    let md = std::fs::read_to_string(dir.join("sweep.md")).unwrap();
    assert!(md.contains("10 of 10 seeds meet both bounds"), "{md}");
}
