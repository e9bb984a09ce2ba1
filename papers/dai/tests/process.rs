//! Seed 004 (deterministic-AI attitude learning) through the orchestrator: the continuous-time
//! reproduction (the paper's final error ratios and Table 4's trend) and the sampled-data mode's
//! multi-process run, bit-identical to its in-process reference. Build the binaries first
//! (`scripts/test` does).

use std::path::{Path, PathBuf};
use std::process::Output;

use cohort::{describe_output, heavy_scratch, launch_scenario, repo_root, summary};

fn topology(name: &str) -> PathBuf {
    repo_root().join("topologies").join(name)
}

fn launch(file: &Path, out: &Path, extra: &[&str]) -> Output {
    launch_scenario(file, out, extra)
}

fn metric(s: &serde_json::Value, key: &str) -> f64 {
    s["metrics"][key].as_f64().unwrap_or_else(|| panic!("summary.json has no metric {key}: {}", s["metrics"]))
}

/// Launch a continuous scenario and return its summary.
fn continuous(name: &str, dir: &Path) -> serde_json::Value {
    let out = dir.join(name);
    let o = launch(&topology(&format!("{name}.toml")), &out, &[]);
    assert!(o.status.success(), "{name}: {}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("continuous: plant and learner integrated as one ODE in this process"), "{err}");
    let s = summary(&out);
    assert_eq!(s["mode"], "continuous");
    assert_eq!(s["status"], "ok");
    assert_eq!(s["labels"]["coupling"], "continuous");
    // The paper's output grid t = 0:0.001:5: 5001 rows.
    let rows = cohort::telemetry_table(&out, "plant").rows();
    assert_eq!(rows, 5001, "{name}");
    s
}

#[test]
fn continuous_time_reproduces_the_final_error_ratios_and_the_r_trend_of_table_4() {
    let (_g, dir) = heavy_scratch("dai-continuous");
    let specific = continuous("dai", &dir);
    let original = continuous("dai-original", &dir);
    assert_eq!(specific["labels"]["law"], "specific");
    assert_eq!(original["labels"]["law"], "original");
    for s in [&specific, &original] {
        for key in ["tracking_error_mean", "tracking_error_dev", "final_error_ratio", "r"] {
            assert!(metric(s, key).is_finite(), "{key}");
        }
    }
    // Sec. 4: the final state-error norm ratio of (15), ‖ω′‖²/‖ω_d‖², is of order 1e−8 for the
    // specific law and 1e−3 for the original one.
    let sp = metric(&specific, "final_state_error_norm_ratio_eq15");
    let or = metric(&original, "final_state_error_norm_ratio_eq15");
    assert!(sp <= 1e-6, "specific: {sp:e}");
    assert!((1e-4..=1e-2).contains(&or), "original: {or:e}");
    // The specific law tracks better than the original one.
    assert!(metric(&specific, "tracking_error_dev") < metric(&original, "tracking_error_dev"));
    // Table 4: the tracking-error deviation falls as r grows.
    let devs: Vec<f64> = ["dai-r0_5", "dai-r1", "dai-r2", "dai-r4"]
        .iter()
        .map(|n| metric(&continuous(n, &dir), "tracking_error_dev"))
        .collect();
    assert!(devs.windows(2).all(|w| w[1] < w[0]), "{devs:?}");
    // ... and within 30 % of the published values for r = 2 and 4 (r = 0.5 and 1 are not: see
    // the issue-6 note).
    for (dev, published) in devs[2..].iter().zip([0.0189, 0.0143]) {
        assert!((dev - published).abs() <= 0.3 * published, "{dev} vs {published}");
    }
}

#[test]
fn sampled_data_multi_process_run_is_bit_identical_to_the_reference() {
    let (_g, dir) = heavy_scratch("dai-sampled");
    // The specific law's sampled loop diverges after ≈ 2.4 s at 1 ms (a finding, see the note):
    // 2 s keep it finite; the general law (matrix-exponential update) runs the full 5 s.
    for (file, duration) in [("dai-sampled-diverges.toml", "2"), ("dai-sampled-general.toml", "5")] {
        let mp = dir.join(format!("{file}-mp"));
        let rf = dir.join(format!("{file}-ref"));
        let o = launch(&topology(file), &mp, &["--duration", duration]);
        assert!(o.status.success(), "{file}: {}", describe_output(&o));
        let o = launch(&topology(file), &rf, &["--duration", duration, "--reference"]);
        assert!(o.status.success(), "{file} --reference: {}", describe_output(&o));
        assert_eq!(summary(&mp)["mode"], "multi-process");
        for f in ["plant", "agent-1"] {
            let a = std::fs::read(cohort::telemetry_path(&mp, f)).unwrap();
            let b = std::fs::read(cohort::telemetry_path(&rf, f)).unwrap();
            assert!(a == b, "{file}: telemetry/{f} differs between multi-process and reference");
        }
        let s = summary(&mp);
        assert_eq!(s["labels"]["coupling"], "sampled");
        assert_eq!(metric(&s, "control_period_s"), 1e-3);
        for key in ["tracking_error_mean", "tracking_error_dev", "final_error_ratio", "sampling_index_final"] {
            assert!(metric(&s, key).is_finite(), "{file}: {key}");
            assert_eq!(metric(&s, key), metric(&summary(&rf), key), "{file}: {key}");
        }
    }
}

#[test]
fn sampled_specific_law_runs_at_100_ms_when_the_body_spins_slowly() {
    // The paper's spin-up makes the sampled specific law diverge at every period from 0.1 ms up
    // (its sampling index ‖K_d‖²Δt/λ_min(J) reaches ≈ 100); at a hundredth of the test torque the
    // index stays small and the same law runs all 5 s at a 100 ms period.
    let (_g, dir) = heavy_scratch("dai-slow");
    let out = dir.join("run");
    let o = launch(&topology("dai-sampled-slow.toml"), &out, &[]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let s = summary(&out);
    assert_eq!(s["mode"], "multi-process");
    assert_eq!(metric(&s, "control_period_s"), 0.1);
    assert!((metric(&s, "final_time_s") - 4.9).abs() < 1e-9);
    let index = metric(&s, "sampling_index_final");
    assert!(index > 0.0 && index < 0.1, "{index}");
    assert!(metric(&s, "tracking_error_dev") < 0.1 && metric(&s, "param_error_final") < 0.1);
}
