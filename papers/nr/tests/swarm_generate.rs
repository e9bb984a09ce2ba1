//! `orchestrator generate swarm` (papers/nr/src/swarm/generate.rs) through the orchestrator: bad
//! arguments are refused with exit 2 naming the flag; a generated 50-vehicle swarm (sparse
//! neighbour lists, the cuboid scaled to swarm-20's density) runs as 51 processes bit-identical to
//! `--reference` and leaves nothing behind; flown in-process with every list made all-to-all it
//! gives the same telemetry, bit for bit (the sparse lists held everyone who mattered). Build the
//! binaries first (`scripts/test` does).

use std::path::Path;

use cohort::{
    describe_output, heavy_scratch, iceoryx2_leftovers, orchestrator_command, processes_mentioning, summary,
    telemetry_bits,
};

fn generate(args: &[&str], out: &Path) -> std::process::Output {
    orchestrator_command().args(["generate", "swarm"]).args(args).arg("--out").arg(out).output().expect("orchestrator")
}

fn launch(file: &Path, out: &Path, extra: &[&str]) {
    let mut cmd = orchestrator_command();
    let o =
        cmd.arg("launch").arg(file).arg("--out").arg(out).arg("--no-plots").args(extra).output().expect("orchestrator");
    assert!(o.status.success(), "{} {extra:?}: {}", file.display(), describe_output(&o));
}

#[test]
fn bad_generate_arguments_exit_2_naming_the_flag() {
    let (_g, dir) = heavy_scratch("nr-swarm-gen-args");
    let out = dir.join("s.toml");
    for (args, flag) in [
        (&["--agents", "1"][..], "--agents"),
        (&["--agents", "1001"][..], "--agents"),
        (&["--agents", "ten"][..], "--agents"),
        (&["--agents", "20", "--seed", "9223372036854775808"][..], "--seed"),
        (&["--agents", "20", "--weights", "/nonexistent/w.safetensors"][..], "--weights"),
    ] {
        let o = generate(args, &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
    let o = orchestrator_command().args(["generate", "swarm"]).output().expect("orchestrator");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--agents"));
}

/// Every `neighbours = [...]` line of a scenario made all-to-all.
fn all_to_all(text: &str, n: u32) -> String {
    let mut id = 0;
    let lines = text.lines().map(|l| {
        if let Some(v) = l.strip_prefix("id = ") {
            id = v.parse::<u32>().unwrap();
        }
        if l.starts_with("neighbours = ") {
            let all: Vec<String> = (1..=n).filter(|j| *j != id).map(|j| j.to_string()).collect();
            format!("neighbours = [{}]", all.join(", "))
        } else {
            l.to_string()
        }
    });
    lines.collect::<Vec<_>>().join("\n") + "\n"
}

#[test]
fn a_generated_fifty_vehicle_swarm_runs_multi_process_bit_identical_to_the_reference_and_to_all_to_all() {
    let (_g, dir) = heavy_scratch("nr-swarm-gen-50");
    let file = dir.join("swarm50.toml");
    let o = generate(&["--agents", "50", "--seed", "3"], &file);
    assert!(o.status.success(), "{}", describe_output(&o));
    let text = std::fs::read_to_string(&file).unwrap();
    let dense = all_to_all(&text, 50);
    let count =
        |t: &str| t.lines().filter(|l| l.starts_with("neighbours")).map(|l| l.matches(',').count() + 1).sum::<usize>();
    assert!(count(&text) < count(&dense), "the generated lists are not sparser than all-to-all");
    let dense_file = dir.join("swarm50-all.toml");
    std::fs::write(&dense_file, dense).unwrap();
    let (mp, rf, all) = (dir.join("mp"), dir.join("ref"), dir.join("all"));
    // 4 s: eight rebuilds of the roll-out, the first close passes.
    launch(&file, &mp, &["--duration", "4"]);
    launch(&file, &rf, &["--duration", "4", "--reference"]);
    launch(&dense_file, &all, &["--duration", "4", "--reference"]);
    let (a, b, c) = (telemetry_bits(&mp), telemetry_bits(&rf), telemetry_bits(&all));
    assert!(a.len() > 40 * 50 * 10, "only {} values", a.len());
    assert_eq!(a, b, "multi-process differs from the reference");
    assert_eq!(b, c, "the sparse lists fly differently from all-to-all");
    let s = summary(&mp);
    assert_eq!((s["processes"].as_array().map(Vec::len), s["status"].as_str()), (Some(51), Some("ok")));
    assert_eq!(s["metrics"]["unlisted_pairs_within_r_comm"].as_f64(), Some(0.0));
    assert!(s["metrics"]["max_observed"].as_f64() >= Some(1.0), "nobody heard anybody");
    let id = s["run_id"].as_str().unwrap().to_string();
    assert!(iceoryx2_leftovers(&id).is_empty(), "iceoryx2 leftovers {:?}", iceoryx2_leftovers(&id));
    let left = processes_mentioning(&mp.display().to_string());
    assert!(left.is_empty(), "processes left running: {left:?}");
}

/// Every (i, j), i < j, of the `neighbours` lists of a scenario text (both must list the other).
fn listed_pairs(text: &str) -> std::collections::BTreeSet<(u32, u32)> {
    let mut id = 0;
    let mut lists = std::collections::BTreeMap::new();
    for l in text.lines() {
        if let Some(v) = l.strip_prefix("id = ") {
            id = v.parse::<u32>().unwrap();
        }
        if let Some(v) = l.strip_prefix("neighbours = [") {
            let ids: Vec<u32> =
                v.trim_end_matches(']').split(", ").filter(|x| !x.is_empty()).map(|x| x.parse().unwrap()).collect();
            lists.insert(id, ids);
        }
    }
    let hears = |a: u32, b: u32| lists.get(&a).is_some_and(|l| l.contains(&b));
    lists
        .keys()
        .flat_map(|i| lists.keys().map(move |j| (*i, *j)))
        .filter(|(i, j)| i < j && hears(*i, *j) && hears(*j, *i))
        .collect()
}

/// The pairs (i < j) that came within `r_m` of each other at some row of a run's plant.csv.
fn pairs_within(run: &Path, n: u32, r_m: f64) -> std::collections::BTreeSet<(u32, u32)> {
    let text = std::fs::read_to_string(run.join("telemetry/plant.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: String| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let cols: Vec<[usize; 3]> = (1..=n).map(|j| ["x", "y", "z"].map(|a| col(format!("a{j}_p_{a}_m")))).collect();
    let mut met = std::collections::BTreeSet::new();
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap_or(f64::NAN)).collect();
        let p: Vec<[f64; 3]> = cols.iter().map(|c| c.map(|k| v[k])).collect();
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                let d = (0..3).map(|a| (p[i][a] - p[j][a]).powi(2)).sum::<f64>().sqrt();
                if d < r_m {
                    met.insert((i as u32 + 1, j as u32 + 1));
                }
            }
        }
    }
    met
}

/// swarm-20 (seed 2, all-to-all) flown in-process: every pair that came within R_comm = 1 m is in
/// the lists the rule generates for the same problem (20 vehicles, seed 2: swarm-20's cuboid), so
/// flying those lists could not have changed anything. And a 50-vehicle swarm's own run keeps
/// them too (a generated scenario checked against its own flight, with real sparsity).
#[test]
fn the_generated_lists_hold_every_pair_that_comes_within_r_comm_in_flight() {
    let (_g, dir) = heavy_scratch("nr-swarm-gen-sound");
    for (n, seed, shipped) in [(20, 2, Some("topologies/swarm-20.toml")), (50, 3, None)] {
        let file = dir.join(format!("gen{n}.toml"));
        let o = generate(&["--agents", &n.to_string(), "--seed", &seed.to_string()], &file);
        assert!(o.status.success(), "{}", describe_output(&o));
        let run = dir.join(format!("run{n}"));
        let flown = shipped.map_or(file.clone(), |f| Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(f));
        launch(&flown, &run, &["--reference", "--telemetry", "csv"]);
        let listed = listed_pairs(&std::fs::read_to_string(&file).unwrap());
        let met = pairs_within(&run, n, 1.0);
        assert!(met.len() > n as usize, "N = {n}: only {} pairs met", met.len());
        let missing: Vec<_> = met.difference(&listed).collect();
        assert!(missing.is_empty(), "N = {n}: pairs that met within R_comm but are not listed: {missing:?}");
    }
}
