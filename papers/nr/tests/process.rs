//! Seed 003's scenarios through the orchestrator, one OS process per spacecraft:
//! `topologies/nr-iso.toml` (one spacecraft) and `topologies/nr-iso-fleet.toml` (four on one
//! plant) each run the whole day to the encounter multi-process and as the in-process reference,
//! and every telemetry value, the plant's end-of-run file and every summary metric are
//! bit-identical (`f64::to_bits`). The multi-process run draws the paper's figures; its summary
//! holds the analysis per spacecraft; nothing is left running or in /dev/shm. A full day is 144
//! control intervals and takes well under a second of wall time, so no shorter horizon is needed.
//! Killing one spacecraft of the fleet changes no value of the other three.
//! Build the binaries first (`scripts/test` does).

use std::path::Path;

use cohort::{
    describe_output, heavy, iceoryx2_leftovers, orchestrator_command, processes_mentioning, scratch_dir, summary,
    telemetry_bits,
};

/// The analysis metrics every spacecraft of a Neural-Rendezvous run must have (see `analysis`).
const PER_CRAFT: [&str; 6] =
    ["delivery_error_m", "dv_mps", "bound_tf_m", "error_over_bound", "tracking_error_max_m", "t_switch_s"];

fn launch(file: &str, out: &Path, extra: &[&str]) {
    let o = orchestrator_command()
        .args(["launch", file, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("running the orchestrator");
    assert!(o.status.success(), "{file} {extra:?}: {}", describe_output(&o));
}

/// Every metric of a run's summary as (name, bits), sorted by name.
fn metric_bits(run: &Path) -> Vec<(String, u64)> {
    let s = summary(run);
    let m = s["metrics"].as_object().expect("metrics in summary.json");
    m.iter()
        .map(|(k, v)| (k.clone(), v.as_f64().unwrap_or_else(|| panic!("metric {k} = {v} is not a number")).to_bits()))
        .collect()
}

/// Launch `file` multi-process (with plots) and `--reference`; compare them bit for bit; check the
/// analysis of each of `n` spacecraft and that the processes and iceoryx2 resources are gone.
fn mp_equals_reference(file: &str, n: u32) {
    let _g = heavy();
    let dir = scratch_dir("nr-process");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    launch(file, &mp, &[]);
    launch(file, &rf, &["--reference", "--no-plots"]);

    let (a, b) = (telemetry_bits(&mp), telemetry_bits(&rf));
    assert_eq!(a.len(), b.len(), "{file}: the runs recorded different numbers of values");
    // Each spacecraft and the plant record a row per control interval: 144 of 600 s.
    assert!(a.len() > 144 * (n as usize + 1), "{file}: only {} values", a.len());
    if let Some((x, y)) = a.iter().zip(&b).find(|(x, y)| x != y) {
        panic!("{file}: multi-process {x:?} differs from the reference {y:?} (file, line, column, bits)");
    }
    let enc = |r: &Path| std::fs::read(r.join("snapshots/encounter.csv")).expect("snapshots/encounter.csv");
    assert!(enc(&mp) == enc(&rf), "{file}: snapshots/encounter.csv differs");
    assert_eq!(metric_bits(&mp), metric_bits(&rf), "{file}: summary metrics differ");

    let s = summary(&mp);
    assert_eq!(s["steps_completed"], 144, "{file}");
    assert_eq!(s["sim_time_s"], 86400.0, "{file}");
    assert_eq!(s["mode"], "multi-process", "{file}");
    let m = s["metrics"].as_object().unwrap();
    let get = |k: &str| m.get(k).and_then(|v| v.as_f64()).unwrap_or_else(|| panic!("{file}: {k} missing"));
    assert_eq!(get("encounter_reached"), 1.0, "{file}");
    for j in 1..=n {
        for k in PER_CRAFT {
            let v = get(&format!("a{j}_{k}"));
            assert!(v.is_finite() && v >= 0.0, "{file}: a{j}_{k} = {v}");
        }
        // The analysis' delivery error is the plant's own (one number, two readers).
        let plant = s["processes"][0]["metrics"][format!("a{j}_delivery_error_m")].as_f64();
        assert_eq!(plant.map(f64::to_bits), Some(get(&format!("a{j}_delivery_error_m")).to_bits()), "{file}: a{j}");
        // Neural-Rendezvous switches to tracking at t_s = 0.75 t_f (the scenario's t_s_fraction).
        assert_eq!(get(&format!("a{j}_t_switch_s")), 64800.0, "{file}: a{j}");
        assert_eq!(get(&format!("a{j}_bad_readings")), 0.0, "{file}: a{j}");
    }
    for png in ["nr_relative_trajectory.png", "nr_error_bound.png", "nr_control.png"] {
        let p = mp.join("plots").join(png);
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 5_000, "{file}: {} missing or empty ({len} bytes)", p.display());
    }
    for run in [&mp, &rf] {
        let id = summary(run)["run_id"].as_str().expect("run_id").to_string();
        assert!(iceoryx2_leftovers(&id).is_empty(), "{file}: iceoryx2 leftovers {:?}", iceoryx2_leftovers(&id));
        let left = processes_mentioning(&run.display().to_string());
        assert!(left.is_empty(), "{file}: processes left running: {left:?}");
    }
}

#[test]
fn one_spacecraft_multi_process_is_bit_identical_to_the_reference() {
    mp_equals_reference("topologies/nr-iso.toml", 1);
}

#[test]
fn four_spacecraft_multi_process_are_bit_identical_to_the_reference() {
    mp_equals_reference("topologies/nr-iso-fleet.toml", 4);
}

#[test]
fn killing_one_spacecraft_leaves_the_others_bit_identical() {
    // The fleet's spacecraft read no neighbour and the plant draws each one's navigation from its
    // own stream, so losing spacecraft 2 at t = 10 h (a planned fault: the run goes on without it)
    // must not change a single value of the other three.
    let _g = heavy();
    let file = "topologies/nr-iso-fleet.toml";
    let dir = scratch_dir("nr-fleet-kill");
    let (clean, killed) = (dir.join("clean"), dir.join("killed"));
    launch(file, &clean, &["--no-plots"]);
    launch(file, &killed, &["--no-plots", "--fault", "kill:agent=2@t=36000", "--on-agent-loss", "degrade"]);
    let bits = |run: &Path, j: u32| {
        // Whichever format the run wrote (Parquet by default).
        let stem = format!("agent-{j}.");
        telemetry_bits(run).into_iter().filter(|v| v.0.starts_with(&stem)).collect::<Vec<_>>()
    };
    for j in [1, 3, 4] {
        let (a, b) = (bits(&clean, j), bits(&killed, j));
        assert!(a.len() > 144, "agent-{j}'s telemetry has {} values", a.len());
        assert!(a == b, "agent-{j}'s telemetry changed when spacecraft 2 was lost");
    }
    let (c, k) = (summary(&clean), summary(&killed));
    for j in [1, 3, 4] {
        let key = format!("a{j}_delivery_error_m");
        assert_eq!(
            c["metrics"][&key].as_f64().map(f64::to_bits),
            k["metrics"][&key].as_f64().map(f64::to_bits),
            "{key}"
        );
    }
    // Spacecraft 2 coasts from t = 10 h on the course it had then: it misses by kilometres
    // (22 km when measured), no longer tens of metres.
    let miss = k["metrics"]["a2_delivery_error_m"].as_f64().expect("a2_delivery_error_m");
    assert!(miss > 1_000.0, "spacecraft 2 coasted for 14 h and still delivered within {miss} m");
    assert_eq!(k["metrics"]["within_bound"].as_f64(), Some(3.0));
}
