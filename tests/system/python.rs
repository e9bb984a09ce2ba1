//! `kind = "python"` (kinds/python): the three examples of docs/python-algorithms.md fly as
//! processes and in `--reference` with the same telemetry bit for bit; the Python consensus ring
//! equals the Rust kind's; a restarted Python agent resumes its checkpointed state exactly; and
//! every mistake a user makes is a named error (fixtures: `python/`, beside this file).

use std::path::{Path, PathBuf};

use cohort::OutputWithin;
use cohort::{
    describe_output, heavy_scratch, launch_scenario, orchestrator_command, repo_root, scratch_dir, summary,
    telemetry_bits,
};

fn example(file: &str) -> PathBuf {
    repo_root().join("examples/python").join(file)
}

fn fixtures() -> PathBuf {
    repo_root().join("tests/system/python")
}

/// Every telemetry value of two runs, equal bit for bit.
fn assert_same_bits(a: &Path, b: &Path, what: &str) {
    let (ta, tb) = (telemetry_bits(a), telemetry_bits(b));
    assert!(ta.len() > 1000, "{what}: too few values ({})", ta.len());
    assert_eq!(ta.len(), tb.len(), "{what}: value counts differ");
    for (x, y) in ta.iter().zip(&tb) {
        assert_eq!(x, y, "{what}: value differs (file, line, column, bits)");
    }
}

fn launch_ok(file: &Path, run: &Path, extra: &[&str]) -> serde_json::Value {
    let o = launch_scenario(file, run, extra);
    assert!(o.status.success(), "{}", describe_output(&o));
    summary(run)
}

#[test]
fn the_python_consensus_ring_equals_the_rust_kind_and_its_reference_bit_for_bit() {
    let (_g, dir) = heavy_scratch("python-consensus");
    let (py, py_ref, rust) = (dir.join("py"), dir.join("py-ref"), dir.join("rust"));
    let s = launch_ok(&example("consensus-ring.toml"), &py, &[]);
    assert_eq!(s["status"], "ok");
    assert_eq!(s["steps_completed"], 2000);
    launch_ok(&example("consensus-ring.toml"), &py_ref, &["--reference"]);
    assert_same_bits(&py, &py_ref, "python: processes vs --reference");
    launch_ok(Path::new("topologies/consensus-ring.toml"), &rust, &[]);
    assert_same_bits(&py, &rust, "python kind vs the Rust consensus-formation kind");
}

#[test]
fn a_python_plant_flown_by_rust_agents_is_the_same_as_processes_and_in_reference() {
    let (_g, dir) = heavy_scratch("python-plant");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let s = launch_ok(&example("hcw-ring.toml"), &mp, &[]);
    assert_eq!(s["steps_completed"], 2000);
    assert!(s["metrics"]["dv_total_mps"].as_f64().is_some_and(|dv| dv > 0.0), "{}", s["metrics"]);
    launch_ok(&example("hcw-ring.toml"), &rf, &["--reference"]);
    assert_same_bits(&mp, &rf, "python plant: processes vs --reference");
    // The Rust agents formed the hexagon in the Python plant: the spread ends near its radius.
    let spread = cohort::telemetry_column(&mp, "plant", "spread_m");
    let last = *spread.last().unwrap();
    assert!((9.0..11.0).contains(&last), "spread {last} m after 20 s (hexagon of radius 10 m)");
}

#[test]
fn python_station_keeping_on_the_orbital_plant_survives_a_restart_and_repeats_bit_for_bit() {
    let (_g, dir) = heavy_scratch("python-hcw");
    let (a, b) = (dir.join("a"), dir.join("b"));
    let s = launch_ok(&example("hcw-station-keeping.toml"), &a, &[]);
    assert_eq!(s["status"], "ok", "{s}");
    let a2 = s["processes"].as_array().unwrap().iter().find(|p| p["process"] == "agent-2").unwrap().clone();
    assert_eq!(a2["faults"]["restored_from_step"], 2000, "killed at step 2000, checkpoints every 100");
    let ck = a.join("checkpoints");
    let loaded = std::fs::read(ck.join("agent-2.loaded.ckpt")).expect("the checkpoint it loaded");
    let restored = std::fs::read(ck.join("agent-2.restored.ckpt")).expect("its restored state");
    assert!(loaded.len() > 500, "a real state: {} bytes", loaded.len());
    assert_eq!(loaded, restored, "the restored Python state differs from the checkpointed one");
    for i in 1..=3 {
        let err = cohort::telemetry_column(&a, &format!("agent-{i}"), "slot_error_m");
        let last = *err.last().unwrap();
        assert!(last < 5.0, "servicer {i} ends {last} m from its slot");
    }
    launch_ok(&example("hcw-station-keeping.toml"), &b, &[]);
    assert_same_bits(&a, &b, "a faulted Python run, twice");
    // Without its fault plan (reference runs refuse process faults): processes == reference.
    let text = std::fs::read_to_string(example("hcw-station-keeping.toml")).unwrap();
    let unfaulted = dir.join("unfaulted.toml");
    let text = text
        .split("[[faults]]")
        .next()
        .unwrap()
        .replace("\"hcw_station_keeping.py\"", &format!("{:?}", example("hcw_station_keeping.py")));
    std::fs::write(&unfaulted, text).unwrap();
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    launch_ok(&unfaulted, &mp, &["--duration", "100"]);
    launch_ok(&unfaulted, &rf, &["--duration", "100", "--reference"]);
    assert_same_bits(&mp, &rf, "python on the orbital plant: processes vs --reference");
}

/// A two-agent double-integrator scenario flying `class` of `module` (a fixture file).
fn fixture_scenario(dir: &Path, module: &str, class: &str) -> PathBuf {
    let path = dir.join(format!("{class}.toml"));
    let module = fixtures().join(module);
    std::fs::write(
        &path,
        format!(
            "[scenario]\nname = \"py-{class}\"\nseed = 1\ndt_s = 0.01\nduration_s = 1.0\n\n[run]\nstep_timeout_s = 3.0\n\n\
             [plant]\nkind = \"double-integrator\"\nposition_noise_std_m = 0.01\n\n\
             [algorithm]\nkind = \"python\"\nmodule = {:?}\nclass = \"{class}\"\nshare_values = 3\n\n\
             [[agents]]\nid = 1\nneighbours = [2]\nr0_m = [0.0, 0.0, 0.0]\nv0_mps = [0.0, 0.0, 0.0]\n\n\
             [[agents]]\nid = 2\nneighbours = [1]\nr0_m = [1.0, 0.0, 0.0]\nv0_mps = [0.0, 0.0, 0.0]\n",
            module.display().to_string()
        ),
    )
    .unwrap();
    path
}

#[test]
fn check_names_each_mistake_in_a_python_module_at_its_key_path() {
    let dir = scratch_dir("python-check");
    let cases = [
        ("missing.py", "Fine", "algorithm.module", "no such file"),
        ("faulty.py", "Nope", "algorithm.class", "defines no class \"Nope\""),
        ("faulty.py", "MissingStep", "algorithm.class", "has no method step(dt_s, neighbours)"),
        ("faulty.py", "WrongSignature", "algorithm.class", "WrongSignature.share must take (self, k, t_s, y)"),
        ("crashes_on_import.py", "Controller", "algorithm.class", "raised KeyError: 'kd'"),
    ];
    for (module, class, key, expect) in cases {
        let file = fixture_scenario(&dir, module, class);
        let o = orchestrator_command()
            .arg("check")
            .arg(&file)
            .output_within(cohort::QUICK_LIMIT, "check of a faulty Python module");
        assert_eq!(o.status.code(), Some(2), "{module}:{class}\n{}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(key) && err.contains(expect), "{module}:{class}: expected {key} … {expect}:\n{err}");
        assert!(err.contains(&file.display().to_string()), "names the scenario file:\n{err}");
    }
    let ok = fixture_scenario(&dir, "faulty.py", "Fine");
    let o = orchestrator_command()
        .arg("check")
        .arg(&ok)
        .output_within(cohort::QUICK_LIMIT, "check of a sound Python module");
    assert!(o.status.success(), "{}", describe_output(&o));
}

#[test]
fn a_python_algorithm_that_raises_or_returns_the_wrong_thing_fails_the_run_naming_it() {
    let (_g, dir) = heavy_scratch("python-run-errors");
    let cases = [
        ("RaisesInStep", "RaisesInStep.step() raised ValueError: agent 1: gain matrix not positive definite"),
        ("WrongLength", "WrongLength.share() command: expected 3 values, got 2"),
        ("NotFinite", "NotFinite.share() command: value 1 is NaN (not finite)"),
        ("WrongType", "WrongType.share() command: expected a sequence of 3 floats, got a str"),
    ];
    for (class, expect) in cases {
        let file = fixture_scenario(&dir, "faulty.py", class);
        let run = dir.join(class);
        let o = launch_scenario(&file, &run, &[]);
        assert_eq!(o.status.code(), Some(1), "{class}\n{}", describe_output(&o));
        let s = summary(&run);
        let errors: Vec<String> = s["processes"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|p| p["error"]["message"].as_str().map(|m| format!("{}: {m}", p["process"])))
            .collect();
        assert!(errors.iter().any(|e| e.contains(expect)), "{class}: expected {expect:?} in {errors:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(expect), "{class}: the terminal says it too:\n{err}");
        if class == "RaisesInStep" {
            let log = std::fs::read_to_string(run.join("logs/agent-1.log")).unwrap();
            assert!(log.contains("Traceback (most recent call last)") && log.contains("faulty.py"), "{log}");
            assert!(errors.iter().any(|e| e.contains("agent-1") && e.contains("step 0")), "{errors:?}");
        }
    }
    // A Python that never returns: the step timeout, as for any silent agent; nothing left over.
    let file = fixture_scenario(&dir, "faulty.py", "NeverReturns");
    let run = dir.join("never");
    let o = launch_scenario(&file, &run, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("agent 2 went silent") && err.contains("run.step_timeout_s"), "{err}");
    let id = summary(&run)["run_id"].as_str().unwrap().to_string();
    assert!(cohort::processes_mentioning(&id).is_empty(), "{:?}", cohort::processes_mentioning(&id));
}

/// The debugging loop of docs/python-algorithms.md: record, replay (identical), edit the module,
/// replay again (the first differing share named); and the same ring over zenoh on one host.
#[test]
fn a_recorded_python_agent_replays_and_an_edit_is_named_at_its_first_differing_share() {
    let (_g, dir) = heavy_scratch("python-replay");
    let module = dir.join("consensus.py");
    std::fs::copy(example("consensus.py"), &module).unwrap();
    let text = std::fs::read_to_string(example("consensus-ring.toml")).unwrap();
    let file = dir.join("ring.toml");
    std::fs::write(&file, text.replace("duration_s = 20.0", "duration_s = 2.0")).unwrap();
    let run = dir.join("run");
    launch_ok(&file, &run, &["--record"]);
    let replay = |what: &str| {
        let o = orchestrator_command()
            .args(["replay"])
            .arg(&run)
            .args(["--agent", "3"])
            .output_within(cohort::RUN_LIMIT, "replay of a Python agent");
        (o.status.code(), format!("{what}:\n{}", describe_output(&o)))
    };
    let (code, out) = replay("as recorded");
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("all 200 shares identical"), "{out}");
    // An edit that changes the damping: the first share that differs is named.
    let edited = std::fs::read_to_string(&module)
        .unwrap()
        .replace("u[a] -= self.kd * self.v[a]", "u[a] -= 1.01 * self.kd * self.v[a]");
    std::fs::write(&module, edited).unwrap();
    let (code, out) = replay("edited");
    assert_eq!(code, Some(1), "{out}");
    assert!(out.contains("step") && out.contains("differs"), "names the first difference: {out}");

    let (zenoh, reference) = (dir.join("zenoh"), dir.join("reference"));
    launch_ok(&example("consensus-ring.toml"), &zenoh, &["--transport", "zenoh", "--duration", "5"]);
    launch_ok(&example("consensus-ring.toml"), &reference, &["--reference", "--duration", "5"]);
    assert_same_bits(&zenoh, &reference, "python over zenoh vs --reference");
}

/// docs/python-algorithms.md's tutorial, as written: its class and scenario (the page's first
/// Python and TOML blocks) check and fly, and bring the spacecraft to rest.
#[test]
fn the_tutorials_class_and_scenario_fly_as_written() {
    let (_g, dir) = heavy_scratch("python-tutorial");
    let page = std::fs::read_to_string(repo_root().join("docs/python-algorithms.md")).unwrap();
    let block = |lang: &str| {
        let start = page.find(&format!("```{lang}\n")).unwrap_or_else(|| panic!("no {lang} block")) + lang.len() + 4;
        page[start..start + page[start..].find("```").unwrap()].to_string()
    };
    std::fs::write(dir.join("damper.py"), block("python")).unwrap();
    std::fs::write(dir.join("damper.toml"), block("toml")).unwrap();
    let o = orchestrator_command()
        .arg("check")
        .arg(dir.join("damper.toml"))
        .output_within(cohort::QUICK_LIMIT, "check of the tutorial's scenario");
    assert!(o.status.success(), "{}", describe_output(&o));
    let run = dir.join("run");
    launch_ok(&dir.join("damper.toml"), &run, &["--duration", "10"]);
    // Agent 1 starts at 1 m/s along x (the truth, in the plant's telemetry).
    let v = cohort::telemetry_column(&run, "plant", "a1_v_x_mps");
    let (first, last) = (v[0], *v.last().unwrap());
    assert!(first == 1.0 && last.abs() < 0.05, "v_x of agent 1 from {first} to {last} m/s");
}
