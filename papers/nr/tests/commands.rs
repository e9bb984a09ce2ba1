//! Seed 003's orchestrator commands end to end, each on a tiny case: `orchestrator train nr-iso`
//! (two training ISOs, two epochs) writes the weights and a report naming the command that
//! reproduces them, and the same arguments give the same bytes; `orchestrator nr campaign` (one
//! test ISO, the two learned methods, one Δt) writes its tables; `orchestrator nr swarm-campaign`
//! (one N = 8 case, the three methods) writes its CSV and summary; bad arguments are refused with
//! exit code 2 naming the flag. The full runs are the commands in papers/nr/README.md. Build the
//! binaries first (`scripts/test` does).

use std::path::Path;
use std::process::Output;

use cohort::{describe_output, orchestrator_command, scratch_dir};

fn orchestrator(args: &[&str]) -> Output {
    orchestrator_command().args(args).output().expect("running the orchestrator")
}

fn train_tiny(out: &Path) -> Output {
    let out = out.display().to_string();
    orchestrator(&[
        "train",
        "nr-iso",
        "--seed",
        "7",
        "--isos",
        "0..2",
        "--samples",
        "3",
        "--epochs",
        "2",
        "--cache",
        "none",
        "--out",
        &out,
    ])
}

#[test]
fn the_trainer_writes_the_same_weights_and_report_twice() {
    let dir = scratch_dir("nr-train");
    let (a, b) = (dir.join("a/net.safetensors"), dir.join("b/net.safetensors"));
    for w in [&a, &b] {
        std::fs::create_dir_all(w.parent().unwrap()).unwrap();
        let o = train_tiny(w);
        assert!(o.status.success(), "{}", describe_output(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("ε_train"), "{}", describe_output(&o));
    }
    let read = |p: &Path| std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert!(read(&a) == read(&b), "the weights differ between two identical trainings");
    let (ra, rb) = (dir.join("a/net-report.md"), dir.join("b/net-report.md"));
    let text = |p: &Path, w: &Path| String::from_utf8(read(p)).unwrap().replace(&w.display().to_string(), "W");
    assert_eq!(text(&ra, &a), text(&rb, &b), "the reports differ (beyond the weights path)");
    let report = text(&ra, &a);
    assert!(
        report.contains("orchestrator train nr-iso --seed 7 --out W --epochs 2 --isos 0..2 --samples 3"),
        "{report}"
    );
}

#[test]
fn a_tiny_campaign_writes_its_tables() {
    let dir = scratch_dir("nr-campaign");
    let out = dir.join("c");
    let o = orchestrator(&[
        "nr",
        "campaign",
        "--isos",
        "200..201",
        "--methods",
        "neural-rendezvous,sn-dnn",
        "--dts",
        "600",
        "--gammas",
        "none",
        "--realisations",
        "2",
        "--no-plots",
        "--out",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let md = std::fs::read_to_string(out.join("campaign.md")).expect("campaign.md");
    assert!(md.contains("## Across the 2 noise realisations") && md.contains("| sn-dnn | 2 |"), "{md}");
    for row in ["| neural-rendezvous | 2 |", "| sn-dnn | 2 |", "| neural-rendezvous, perfect navigation | 1 |"] {
        assert!(md.contains(row), "campaign.md has no row {row:?}:\n{md}");
    }
    // The bound's tightness, per navigation.
    assert!(md.contains("## The bound b_e(t_f)") && md.contains("| perfect | 1 |"), "{md}");
    let runs = std::fs::read_to_string(out.join("runs.csv")).expect("runs.csv");
    // A header and one row per (method, ISO, realisation), and NR's perfect-navigation run; the
    // realisations fly their own noise.
    assert_eq!(runs.lines().count(), 6, "{runs}");
    let errors: Vec<&str> =
        runs.lines().filter(|l| l.starts_with("sn-dnn,noisy,200,")).map(|l| l.split(',').nth(4).unwrap()).collect();
    assert!(errors.len() == 2 && errors[0] != errors[1], "{runs}");
    assert!(out.join("dt_sweep.csv").is_file() && out.join("summary.csv").is_file());
}

#[test]
fn bad_arguments_are_refused_with_exit_code_2_naming_the_flag() {
    let dir = scratch_dir("nr-bad-args");
    let out = dir.join("x").display().to_string();
    let cases: [(&[&str], &str); 9] = [
        (&["train", "nr-iso", "--gamma=-1", "--out", &out], "--gamma -1"),
        (&["train", "nr-iso", "--isos", "5..3", "--out", &out], "--isos"),
        (&["train", "nr-iso", "--inputs", "7", "--out", &out], "--inputs"),
        (&["nr", "campaign", "--methods", "magic", "--out", &out], "--methods"),
        (&["nr", "campaign", "--dts", "700", "--out", &out], "--dts"),
        (&["nr", "campaign", "--isos", "200..400", "--out", &out], "--isos"),
        (&["nr", "swarm-campaign", "--methods", "nr,magic", "--out", &out], "--methods"),
        (&["nr", "swarm-campaign", "--cases-8", "5000", "--out", &out], "--cases-8 5000"),
        (&["nr", "swarm-campaign", "--scenario-20", "topologies/swarm-8.toml", "--out", &out], "--scenario-20"),
    ];
    for (args, flag) in cases {
        let o = orchestrator(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe_output(&o));
        assert!(
            String::from_utf8_lossy(&o.stderr).contains(flag),
            "{args:?} does not name {flag}: {}",
            describe_output(&o)
        );
    }
    assert!(!dir.join("x").exists(), "a refused command wrote its output");
}

#[test]
fn the_swarm_trainer_writes_the_same_weights_twice_and_refuses_bad_arguments() {
    let dir = scratch_dir("nr-swarm-train");
    let read = |p: &Path| std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let mut files = Vec::new();
    for sub in ["a", "b"] {
        let w = dir.join(sub).join("swarm.safetensors");
        let o = orchestrator(&[
            "train",
            "nr-swarm",
            "--seed",
            "3",
            "--cases",
            "2",
            "--epochs",
            "1",
            "--out",
            &w.display().to_string(),
        ]);
        assert!(o.status.success(), "{}", describe_output(&o));
        let report = String::from_utf8(read(&w.with_file_name("swarm-report.md"))).unwrap();
        assert!(report.contains("--seed 3") && report.contains("--cases 2 --epochs 1"), "{report}");
        files.push(read(&w));
    }
    assert!(files[0] == files[1], "the swarm weights differ between two identical trainings");
    let out = dir.join("x").display().to_string();
    for (args, flag) in [
        (["--cases", "1"], "--cases 1"),
        (["--epochs", "0"], "--epochs 0"),
        (["--dagger-epochs", "0"], "--dagger-epochs 0"),
    ] {
        let o = orchestrator(&["train", "nr-swarm", args[0], args[1], "--out", &out]);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", describe_output(&o));
        assert!(String::from_utf8_lossy(&o.stderr).contains(flag), "{args:?}: {}", describe_output(&o));
    }
}

#[test]
fn a_tiny_swarm_campaign_writes_its_csv_and_summary() {
    let dir = scratch_dir("nr-swarm-campaign");
    let out = dir.join("c");
    let o = orchestrator(&[
        "nr",
        "swarm-campaign",
        "--seed",
        "3",
        "--cases-8",
        "1",
        "--cases-20",
        "0",
        "--cases-20-disturbed",
        "0",
        "--figures",
        "0",
        "--out",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let csv = std::fs::read_to_string(out.join("cases.csv")).expect("cases.csv");
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 5, "a header and one row per method:\n{csv}");
    assert!(lines[0].contains("collisions_count") && lines[0].contains("effort_mps"), "{}", lines[0]);
    for (line, method) in lines[1..].iter().zip(["nr", "nr-no-filter", "deep-set", "scp"]) {
        let cols: Vec<&str> = line.split(',').collect();
        assert_eq!((cols[0], cols[3], cols[5], cols[6]), ("n8", "8", method, "\"ok\""), "{line}");
        // Counts and distances are numbers; the SCP flown open-loop is collision-free.
        let num = |k: usize| cols[k].parse::<f64>().unwrap_or_else(|_| panic!("column {k} of {line}"));
        assert!(num(9) > 0.0 && num(12) > 0.0 && num(14) > 0.0, "{line}");
        if method == "scp" {
            assert!(num(7) == 0.0 && num(9) >= 1.0 && num(13) == 1.0, "{line}");
        }
    }
    let md = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(md.contains("## Verdict") && md.contains("| n8 | nr | 1 (0 failed)"), "{md}");
    // The NR run is a reference run of the swarm-8 scenario with the case's seed.
    let run = out.join("runs/n8-00-nr/summary.json");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&run).expect("the NR run")).unwrap();
    assert_eq!((s["mode"].as_str(), s["steps_completed"].as_u64()), (Some("reference"), Some(100)));
    // NR flies the scenario's safety filter; the other two fly without it.
    for (name, filtered) in [("n8-00-nr", true), ("n8-00-nr-no-filter", false), ("n8-00-deep-set", false)] {
        let sc =
            std::fs::read_to_string(out.join("runs").join(name).join("scenario.toml")).expect("the run's scenario");
        assert_eq!(sc.contains("[algorithm.safety]"), filtered, "{name}:\n{sc}");
    }
}
