//! The swarm (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883) through the orchestrator, one OS
//! process per vehicle: `topologies/swarm-8.toml` multi-process and `--reference` over a short
//! horizon are bit-identical (every telemetry value, the plant's end-of-run file, every summary
//! metric, `f64::to_bits`) with the safety filter and the estimator acting, and the multi-process
//! run draws both swarm figures;
//! `topologies/swarm-20.toml` runs as 21 processes (the plant and 20 vehicles, all-to-all
//! shares) and leaves nothing behind: no process mentioning its run directory, no iceoryx2 entry
//! of its run in /dev/shm. Build the binaries first (`scripts/test` does).

use std::path::Path;

use cohort::{
    describe_output, heavy, iceoryx2_leftovers, orchestrator_command, processes_mentioning, scratch_dir, summary,
    telemetry_bits,
};

fn launch(file: &str, out: &Path, extra: &[&str]) {
    let o = orchestrator_command().args(["launch", file, "--out"]).arg(out).args(extra).output().expect("orchestrator");
    assert!(o.status.success(), "{file} {extra:?}: {}", describe_output(&o));
}

fn metric_bits(run: &Path) -> Vec<(String, u64)> {
    let s = summary(run);
    let m = s["metrics"].as_object().expect("metrics in summary.json");
    m.iter().map(|(k, v)| (k.clone(), v.as_f64().unwrap_or_else(|| panic!("{k} = {v}")).to_bits())).collect()
}

fn assert_clean(file: &str, run: &Path) {
    let id = summary(run)["run_id"].as_str().expect("run_id").to_string();
    assert!(iceoryx2_leftovers(&id).is_empty(), "{file}: iceoryx2 leftovers {:?}", iceoryx2_leftovers(&id));
    let left = processes_mentioning(&run.display().to_string());
    assert!(left.is_empty(), "{file}: processes left running: {left:?}");
}

#[test]
fn eight_vehicles_multi_process_are_bit_identical_to_the_reference() {
    let _g = heavy();
    let file = "topologies/swarm-8.toml";
    let dir = scratch_dir("nr-swarm-8");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    // 3 s: past six rebuilds of the roll-out, through the first close passes of this seed.
    launch(file, &mp, &["--duration", "3"]);
    launch(file, &rf, &["--duration", "3", "--reference", "--no-plots"]);
    let (a, b) = (telemetry_bits(&mp), telemetry_bits(&rf));
    assert_eq!(a.len(), b.len(), "{file}: the runs recorded different numbers of values");
    assert!(a.len() > 30 * 9 * 10, "{file}: only {} values", a.len());
    if let Some((x, y)) = a.iter().zip(&b).find(|(x, y)| x != y) {
        panic!("{file}: multi-process {x:?} differs from the reference {y:?} (file, line, column, bits)");
    }
    let end = |r: &Path| std::fs::read(r.join("snapshots/swarm.csv")).expect("snapshots/swarm.csv");
    assert!(end(&mp) == end(&rf), "{file}: snapshots/swarm.csv differs");
    assert_eq!(metric_bits(&mp), metric_bits(&rf), "{file}: summary metrics differ");
    let s = summary(&mp);
    assert_eq!((s["steps_completed"].as_u64(), s["mode"].as_str()), (Some(30), Some("multi-process")));
    let m = &s["metrics"];
    for k in ["collisions", "min_pair_ellipsoid", "max_goal_dist_m", "total_effort_mps", "du_active_share"] {
        assert!(m[k].as_f64().is_some_and(|v| v.is_finite() && v >= 0.0), "{k} = {}", m[k]);
    }
    // Vehicles hear one another: someone observed a neighbour within R_comm.
    assert!(m["max_observed"].as_f64() >= Some(1.0), "{}", m["max_observed"]);
    // The safety filter acted in those passes (so the bit-identity covers its solver), never failing.
    assert!(m["filtered_steps"].as_f64() > Some(0.0), "filtered_steps = {}", m["filtered_steps"]);
    assert_eq!(m["filter_failures"].as_f64(), Some(0.0));
    for png in ["swarm_trajectories.png", "swarm_min_distance.png"] {
        let p = mp.join("plots").join(png);
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 5_000, "{file}: {} missing or empty ({len} bytes)", p.display());
    }
    assert_clean(file, &mp);
    assert_clean(file, &rf);
}

#[test]
fn twenty_vehicles_run_as_twenty_one_processes_and_leave_nothing_behind() {
    let _g = heavy();
    let file = "topologies/swarm-20.toml";
    let dir = scratch_dir("nr-swarm-20");
    let run = dir.join("run");
    launch(file, &run, &["--duration", "2", "--no-plots"]);
    let s = summary(&run);
    let procs = s["processes"].as_array().expect("processes in summary.json");
    assert_eq!(procs.len(), 21, "the plant and 20 vehicles: {procs:?}");
    let names: Vec<&str> = procs.iter().filter_map(|p| p["process"].as_str()).collect();
    assert!(names.contains(&"plant") && (1..=20).all(|j| names.contains(&format!("agent-{j}").as_str())), "{names:?}");
    for p in procs {
        assert_eq!(p["steps_completed"], 20, "{p}");
    }
    assert_eq!(s["status"], "ok");
    assert_clean(file, &run);
}
