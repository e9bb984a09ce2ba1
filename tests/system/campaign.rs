//! `orchestrator campaign`: a dispersed fig1 gives one table (compared value by value, doubles by
//! `f64::to_bits`) whatever the workers, in-process or as processes, interrupted and resumed or
//! not, and cut by `--until` exactly where the interval rule says; a bad dispersion is refused
//! by name before any case runs; spread over three host daemons (network namespaces, or loopback
//! ports where `ip netns` is refused) the table is the local one, also when a host is killed
//! mid-campaign. Fixtures: `campaign/` beside this file.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use arrow_array::{Array, Float64Array, RecordBatch, StringArray, UInt64Array};
use cohort::{OutputWithin, bin_path, describe_output, heavy_scratch, orchestrator_command, repo_root};

use crate::multihost::{Daemons, NAMES, Net};

fn fixture(name: &str) -> PathBuf {
    repo_root().join("tests/system/campaign").join(name)
}

/// fig1-fixed for `duration` s, dispersed by the fixture's offsets, mass and gain.
fn fig1_args(out: &Path, cases: u32, duration: &str, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = ["campaign", "topologies/fig1-fixed.toml", "--dispersions"].map(String::from).to_vec();
    a.push(fixture("fig1-dispersions.toml").display().to_string());
    a.extend(["--duration", duration, "--cases", &cases.to_string(), "--no-plots", "--out"].map(String::from));
    a.push(out.display().to_string());
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

fn campaign(args: &[String], what: &str) -> std::process::Output {
    let o = orchestrator_command().args(args).current_dir(repo_root()).output_within(cohort::RUN_LIMIT, what);
    assert!(o.status.success(), "{what}: {}", describe_output(&o));
    o
}

fn table(dir: &Path) -> RecordBatch {
    let f = std::fs::File::open(dir.join("campaign.parquet")).unwrap();
    let r = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(f).unwrap().build().unwrap();
    let mut batches: Vec<RecordBatch> = r.map(|b| b.unwrap()).collect();
    assert_eq!(batches.len(), 1, "a campaign table of a few rows is one batch");
    batches.remove(0)
}

/// Every column of two tables equal: names, types, and values (doubles by their bits).
fn assert_same_table(a: &RecordBatch, b: &RecordBatch, what: &str) {
    assert_eq!(a.schema().fields().len(), b.schema().fields().len(), "{what}: columns");
    for (i, f) in a.schema().fields().iter().enumerate() {
        let g = b.schema().field(i).clone();
        assert_eq!((f.name(), f.data_type()), (g.name(), g.data_type()), "{what}: column {i}");
        let (x, y) = (a.column(i), b.column(i));
        match x.as_any().downcast_ref::<Float64Array>() {
            Some(xf) => {
                let yf = y.as_any().downcast_ref::<Float64Array>().unwrap();
                let bits = |c: &Float64Array| {
                    (0..c.len()).map(|k| c.is_valid(k).then(|| c.value(k).to_bits())).collect::<Vec<_>>()
                };
                assert_eq!(bits(xf), bits(yf), "{what}: column {}", f.name());
            }
            None => assert_eq!(x.to_data(), y.to_data(), "{what}: column {}", f.name()),
        }
    }
}

fn column_f64(t: &RecordBatch, name: &str) -> Vec<f64> {
    let c = t.column_by_name(name).unwrap_or_else(|| panic!("no column {name}"));
    let c = c.as_any().downcast_ref::<Float64Array>().unwrap();
    (0..c.len()).map(|k| c.value(k)).collect()
}

#[test]
fn one_table_whatever_the_workers_or_the_mode() {
    let (_g, dir) = heavy_scratch("campaign-modes");
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        campaign(&fig1_args(&out, 6, "4", extra), name);
        table(&out)
    };
    let one = run("w1", &["--workers", "1"]);
    assert_eq!(one.num_rows(), 6);
    // The drawn values are in the table with their units, and the scenario got them.
    let mass = column_f64(&one, "agents[1].mass_kg");
    assert!(mass.iter().all(|m| (1000.0..=1200.0).contains(m)), "{mass:?}");
    let unit = one.schema().field_with_name("agents[1].mass_kg").unwrap().metadata().get("unit").cloned();
    assert_eq!(unit.as_deref(), Some("kg"));
    let case3 = std::fs::read_to_string(dir.join("w1/cases/case-000003/scenario.toml")).unwrap();
    assert!(
        case3.contains(&format!("mass_kg = {:?}", mass[3])) || case3.contains(&format!("mass_kg = {}", mass[3])),
        "{case3}"
    );
    let seeds = one.column_by_name("seed").unwrap().as_any().downcast_ref::<UInt64Array>().unwrap().values().to_vec();
    assert_eq!(seeds, [1, 2, 3, 4, 5, 6]);
    let status = one.column_by_name("status").unwrap().as_any().downcast_ref::<StringArray>().unwrap().clone();
    assert!((0..6).all(|k| status.value(k) == "ok"), "{status:?}");
    assert_same_table(&one, &run("w2", &["--workers", "2"]), "2 workers");
    assert_same_table(&one, &run("mp", &["--workers", "2", "--multi-process"]), "multi-process, 2 workers");
}

#[test]
fn a_dispersed_kill_time_flies_as_processes_the_same_on_one_or_two_workers() {
    let (_g, dir) = heavy_scratch("campaign-kill");
    let args = |out: &str, extra: &[&str]| {
        let mut a: Vec<String> = vec!["campaign".into(), fixture("fig1-kill.toml").display().to_string()];
        a.extend(["--cases", "4", "--no-plots", "--out"].map(String::from));
        a.push(dir.join(out).display().to_string());
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    // In-process, a kill cannot fly: refused before anything runs.
    let o = orchestrator_command()
        .args(args("ref", &[]))
        .current_dir(repo_root())
        .output_within(cohort::QUICK_LIMIT, "ref");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot kill agent 3"), "{}", describe_output(&o));
    assert!(!dir.join("ref").exists());
    campaign(&args("w1", &["--multi-process", "--workers", "1"]), "kill, 1 worker");
    campaign(&args("w2", &["--multi-process", "--workers", "2"]), "kill, 2 workers");
    let (a, b) = (table(&dir.join("w1")), table(&dir.join("w2")));
    let t = column_f64(&a, "faults[0].t_s");
    assert!(t.iter().all(|t| (1.0..=3.0).contains(t)) && t[0] != t[1], "{t:?}");
    assert_same_table(&a, &b, "kill campaign, 1 and 2 workers");
}

#[test]
fn an_interrupted_campaign_resumes_to_the_same_table_and_until_cuts_where_the_rule_says() {
    let (_g, dir) = heavy_scratch("campaign-resume");
    let long = |out: &Path| fig1_args(out, 10, "40", &["--workers", "1"]);
    let whole = dir.join("whole");
    campaign(&long(&whole), "uninterrupted");
    let cut = dir.join("cut");
    let mut child = orchestrator_command()
        .args(long(&cut))
        .current_dir(repo_root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(300);
    while !cut.join("cases/case-000002/row.json").exists() {
        assert!(Instant::now() < deadline, "waited 300 s for three cases");
        assert!(child.try_wait().unwrap().is_none(), "the campaign ended before it was interrupted");
        std::thread::sleep(Duration::from_millis(5));
    }
    // SAFETY: kill(2) on the child we spawned.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "the campaign sent SIGINT");
    assert_eq!(o.status.code(), Some(130), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("continues"), "{}", describe_output(&o));
    assert!(!cut.join("campaign.parquet").exists());
    let again = campaign(&long(&cut), "resumed");
    assert!(String::from_utf8_lossy(&again.stderr).contains("done before"), "{}", describe_output(&again));
    let full = table(&whole);
    assert_same_table(&full, &table(&cut), "resumed after SIGINT");

    // --until: the first n ≥ --min-cases whose 95 % interval of the mean is within ±X, computed
    // here from the full table's column.
    let metric = "servicer_1.e_norm_last10s_mean_m";
    let xs = column_f64(&full, metric);
    let half = |n: usize| {
        let m = xs[..n].iter().sum::<f64>() / n as f64;
        let var = xs[..n].iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
        1.959964 * var.sqrt() / (n as f64).sqrt()
    };
    let x = half(6) * 1.000001;
    let expect = (3..=10).find(|&n| half(n) < x).unwrap();
    let until = dir.join("until");
    let mut a = long(&until);
    a.extend(["--until".into(), format!("{metric}:±{x}"), "--min-cases".into(), "3".into()]);
    campaign(&a, "until");
    let t = table(&until);
    assert_eq!(t.num_rows(), expect);
    assert_same_table(&t, &full.slice(0, expect), "the --until table is the full table's first rows");
    let md = std::fs::read_to_string(until.join("campaign.md")).unwrap();
    assert!(md.contains(&format!("at {expect} cases")), "{md}");
}

#[test]
fn a_bad_dispersion_is_refused_by_name_before_any_case_runs() {
    let (_g, dir) = heavy_scratch("campaign-bad");
    let cases: &[(&str, &str)] = &[
        (
            "key = \"agents[1].mas_kg\"\ndist = \"normal\"\nsigma = 1.0",
            "dispersions[0].key = \"agents[1].mas_kg\": agents[1] has no key \"mas_kg\" (did you mean \"mass_kg\"?)",
        ),
        ("key = \"agents[9].mass_kg\"\ndist = \"normal\"\nsigma = 1.0", "agents has 6 element(s), no index 9"),
        ("key = \"agents[1].mass_kg\"\ndist = \"normal\"\nsigma = 2000.0", "dispersions[0] drew agents[1].mass_kg = -"),
        (
            "key = \"agents[1].mass_kg\"\ndist = \"poisson\"\nsigma = 1.0",
            "dispersions[0].dist = \"poisson\": must be one of",
        ),
        (
            "key = \"agents[0].offset_lvlh_m\"\ndist = \"normal\"\nsigma = [1.0, 2.0]",
            "dispersions[0].sigma: 2 values for a key of 3 component(s)",
        ),
        ("key = \"agents[0].id\"\ndist = \"normal\"\nsigma = 1.0", "dispersions[0].dist: the key holds a whole number"),
        // --duration (given below) sets it for every case: a draw would never fly.
        (
            "key = \"scenario.duration_s\"\ndist = \"uniform\"\nlow = 2.0\nhigh = 3.0",
            "dispersions[0].key = \"scenario.duration_s\": --duration sets it for every case",
        ),
    ];
    for (k, (body, expect)) in cases.iter().enumerate() {
        let spec = dir.join(format!("bad-{k}.toml"));
        std::fs::write(&spec, format!("[[dispersions]]\n{body}\n")).unwrap();
        let out = dir.join(format!("out-{k}"));
        let o = orchestrator_command()
            .args(["campaign", "topologies/fig1-fixed.toml", "--cases", "30", "--duration", "4", "--dispersions"])
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .current_dir(repo_root())
            .output_within(cohort::QUICK_LIMIT, "a bad dispersion");
        assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expect), "{expect}\n{}", describe_output(&o));
        assert!(!out.exists(), "{body}: the campaign created its directory");
    }
    // No dispersions with every case on one seed; a dispersions file without any; a directory
    // holding another campaign.
    let empty = dir.join("empty.toml");
    std::fs::write(&empty, "").unwrap();
    for (extra, expect) in [
        (vec!["--fixed-seed"], "no [[dispersions]] and --fixed-seed: every case would be the same run"),
        (vec!["--dispersions", empty.to_str().unwrap()], "empty.toml: no [[dispersions]] in it"),
    ] {
        let o = orchestrator_command()
            .args(["campaign", "topologies/fig1-fixed.toml", "--cases", "3"])
            .args(&extra)
            .current_dir(repo_root())
            .output_within(cohort::QUICK_LIMIT, "no dispersions");
        assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
        assert!(String::from_utf8_lossy(&o.stderr).contains(expect), "{expect}: {}", describe_output(&o));
    }
    let first = dir.join("first");
    campaign(&fig1_args(&first, 2, "1", &[]), "a short campaign");
    let o = orchestrator_command()
        .args(fig1_args(&first, 2, "1", &["--seed", "5"]))
        .current_dir(repo_root())
        .output_within(cohort::QUICK_LIMIT, "another campaign in its directory");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("holds another campaign (seed differ"),
        "{}",
        describe_output(&o)
    );
}

/// The same campaign in-process here and over three host daemons (2 workers each), twice: once
/// as is, once with host b's daemon killed (SIGKILL) as soon as a case is sent to it. Every
/// table is the local one, bit for bit; the killed host's case went to another host.
#[test]
fn a_campaign_over_three_hosts_is_the_local_table_also_when_a_host_is_lost() {
    let (_g, dir) = heavy_scratch("campaign-hosts");
    let net = Net::make();
    let mut daemons = Daemons::start(&net);
    let hosts = dir.join("hosts.toml");
    let text: String = NAMES
        .iter()
        .enumerate()
        .map(|(k, x)| format!("[[hosts]]\nname = \"{x}\"\nendpoint = \"{}\"\n\n", net.endpoint(k)))
        .collect();
    std::fs::write(&hosts, text).unwrap();
    // 30 s cases: long enough that a case sent to b is still running when b is killed.
    let args = |out: &str, extra: &[&str]| fig1_args(&dir.join(out), 9, "30", extra);
    campaign(&args("local", &["--workers", "2"]), "local");
    let local = table(&dir.join("local"));
    let on_hosts = |out: &str| {
        let mut c = net.command("a", &bin_path("orchestrator"));
        c.args(args(out, &["--hosts", &hosts.display().to_string()])).current_dir(repo_root());
        c.env("RUST_LOG", "info,cohort_supervisor::farm=debug").stdout(Stdio::piped()).stderr(Stdio::piped());
        c
    };
    let o = on_hosts("three").output_within(cohort::RUN_LIMIT, "campaign on three hosts");
    assert!(o.status.success(), "{}", describe_output(&o));
    assert_same_table(&local, &table(&dir.join("three")), "campaign on three hosts");
    let ran_on = |out: &str| -> Vec<String> {
        (0..9)
            .map(|i| {
                let row = std::fs::read_to_string(dir.join(out).join(format!("cases/case-{i:06}/row.json"))).unwrap();
                let v: serde_json::Value = serde_json::from_str(&row).unwrap();
                v["host"].as_str().unwrap_or("(none)").to_string()
            })
            .collect()
    };
    let hosts_used = ran_on("three");
    assert!(NAMES.iter().all(|x| hosts_used.iter().any(|h| h == x)), "every host ran cases: {hosts_used:?}");
    // A local case's directory keeps its scenario and summary; so does a remote one's.
    assert!(dir.join("three/cases/case-000004/scenario.toml").is_file());
    assert!(dir.join("three/cases/case-000004/summary.json").is_file());

    let mut child = on_hosts("lost").spawn().unwrap();
    let mut err = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut log = String::new();
    let sent_to_b = loop {
        let mut line = String::new();
        let n = std::io::BufRead::read_line(&mut err, &mut line).unwrap();
        assert!(n > 0, "the campaign ended before a case went to b:\n{log}");
        log.push_str(&line);
        if let Some(case) = line.split("case ").nth(1).and_then(|r| r.strip_suffix(" sent to host b\n")) {
            break case.to_string();
        }
    };
    daemons.kill(1);
    let rest = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut err, &mut s).unwrap();
        s
    });
    let o = cohort::finish_within(child, cohort::RUN_LIMIT, "campaign losing host b");
    log.push_str(&rest.join().unwrap());
    assert!(o.status.success(), "{}\n{log}", describe_output(&o));
    assert!(log.contains(&format!("case {sent_to_b} was on host b: it goes to another host")), "{log}");
    assert_same_table(&local, &table(&dir.join("lost")), "campaign that lost host b");
    let hosts_used = ran_on("lost");
    assert_ne!(hosts_used[sent_to_b.parse::<usize>().unwrap()], "b", "{hosts_used:?}");
    // The killed daemon could not remove its scratch; the test does.
    let base = cohort_wire::transport::iox::ensure_user_files_base().unwrap();
    let _ = std::fs::remove_dir_all(base.join("b"));
}

/// A scenario without `[[dispersions]]` is a seed sweep with the campaign's table: case i flies
/// seed + i, and its metrics are those `launch --reference --seed` gives, bit for bit.
#[test]
fn without_dispersions_a_campaign_sweeps_the_seed() {
    let (_g, dir) = heavy_scratch("campaign-seeds");
    let out = dir.join("seeds");
    let args = ["campaign", "topologies/fig1-fixed.toml", "--cases", "3", "--seed", "40", "--duration", "12"];
    let o = orchestrator_command()
        .args(args)
        .args(["--no-plots", "--out", out.to_str().unwrap()])
        .current_dir(repo_root())
        .output_within(cohort::RUN_LIMIT, "seed campaign");
    assert!(o.status.success(), "{}", describe_output(&o));
    let t = table(&out);
    let seeds = t.column_by_name("seed").unwrap().as_any().downcast_ref::<UInt64Array>().unwrap().values().to_vec();
    assert_eq!(seeds, [40, 41, 42]);
    let metric = "servicer_1.e_norm_last10s_mean_m";
    let ours = column_f64(&t, metric);
    let run = dir.join("run-41");
    let o = cohort::launch_scenario(
        Path::new("topologies/fig1-fixed.toml"),
        &run,
        &["--reference", "--seed", "41", "--duration", "12"],
    );
    assert!(o.status.success(), "{}", describe_output(&o));
    let theirs = cohort::summary(&run)["metrics"][metric].as_f64().unwrap();
    assert_eq!(ours[1].to_bits(), theirs.to_bits(), "case 1 against launch --seed 41");
    assert_ne!(ours[0].to_bits(), ours[1].to_bits(), "the seeds differ, so do the runs");
}

/// A hosts file a campaign cannot use is exit 2 naming it, before any case runs: a placement of
/// processes, a daemon that is not there, `--hosts` with `--multi-process`.
#[test]
fn hosts_a_campaign_cannot_use_are_refused_before_any_case_runs() {
    let dir = cohort::scratch_dir("campaign-bad-hosts");
    let cases: &[(&str, &[&str], &str)] = &[
        (
            "[[hosts]]\nname = \"a\"\nendpoint = \"tcp/127.0.0.1:9\"\nplant = true\n",
            &[],
            "hosts[0]: a campaign sends whole cases to each host",
        ),
        (
            "[[hosts]]\nname = \"a\"\nendpoint = \"tcp/127.0.0.1:9\"\n",
            &[],
            "hosts[0] (a at tcp/127.0.0.1:9): unreachable",
        ),
        ("[[hosts]]\nname = \"a\"\nendpoint = \"tcp/127.0.0.1:9\"\n", &["--multi-process"], "cannot be used with"),
    ];
    for (k, (text, extra, expect)) in cases.iter().enumerate() {
        let hosts = dir.join(format!("hosts-{k}.toml"));
        std::fs::write(&hosts, text).unwrap();
        let out = dir.join(format!("out-{k}"));
        let mut a = fig1_args(&out, 2, "1", &["--hosts", &hosts.display().to_string()]);
        a.extend(extra.iter().map(|s| s.to_string()));
        let o = orchestrator_command().args(&a).current_dir(repo_root()).output_within(cohort::QUICK_LIMIT, expect);
        assert_eq!(o.status.code(), Some(2), "{k}: {}", describe_output(&o));
        assert!(String::from_utf8_lossy(&o.stderr).contains(expect), "{k}: {}", describe_output(&o));
        assert!(!out.exists(), "{k}: nothing made");
    }
}
