//! Inter-satellite links from the geometry (`[links]` model `geometric`) with real processes: the
//! multi-process run and the in-process reference agree bit for bit under delay, the rate cap,
//! losses and link faults on top, every loss is counted, and the plant reports each directed link.
//! Heavy: serialised.

use std::path::Path;

use cohort::{describe_output, heavy_scratch, launch_scenario, summary, telemetry_bits, telemetry_table};
use serde_json::Value;

/// `topologies/fig1-isl.toml` with its link-budget loss (nil at fig1's ranges) replaced by a
/// constant 20 % so that the run loses shares.
fn lossy_fig1_isl(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string("topologies/fig1-isl.toml").expect("the shipped fig1-isl scenario");
    let start = text.find("[links.loss]").expect("fig1-isl has a [links.loss] table");
    let end = start + text[start..].find("\n\n").expect("a blank line after [links.loss]");
    let lossy = format!("{}[links.loss]\nlaw = \"constant\"\np = 0.2{}", &text[..start], &text[end..]);
    let path = dir.join("fig1-isl-lossy.toml");
    std::fs::write(&path, lossy).unwrap();
    path
}

/// `orchestrator links study ARGS --out OUT`, which must succeed; its `links-study.md`.
fn study(args: &[&str], out: &Path) -> String {
    let o = cohort::orchestrator_command().args(["links", "study"]).args(args).arg("--out").arg(out).output().unwrap();
    assert!(o.status.success(), "{}", describe_output(&o));
    std::fs::read_to_string(out.join("links-study.md")).unwrap()
}

fn plant_links(s: &Value) -> Vec<Value> {
    let plant = s["processes"].as_array().unwrap().iter().find(|p| p["process"] == "plant").unwrap();
    plant["links"].as_array().expect("the plant reports every link").clone()
}

#[test]
fn geometric_links_with_losses_are_bit_identical_multi_process_and_in_reference() {
    let (_g, dir) = heavy_scratch("links-lossy");
    let file = lossy_fig1_isl(&dir);
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    // The fault plan on top: agent 2's shares dropped, agent 5's held 3 steps.
    let faults = ["--fault", "drop:agent=2@t=5,p=0.3", "--fault", "delay:agent=5@t=8,for=4,steps=3"];
    for (run, extra) in [(&mp, &[][..]), (&rf, &["--reference"][..])] {
        let o = launch_scenario(&file, run, &[&["--duration", "20"][..], &faults, extra].concat());
        assert!(o.status.success(), "{}", describe_output(&o));
    }
    let (a, b) = (telemetry_bits(&mp), telemetry_bits(&rf));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x, y, "value differs (file, line, column, bits)");
    }
    let s = summary(&mp);
    assert_eq!(s["status"], "ok");
    let links = plant_links(&s);
    assert_eq!(links.len(), 12, "6 servicers on a ring: 12 directed links");
    assert_eq!(links, plant_links(&summary(&rf)), "the link record differs between the modes");
    let count = |key: &str| links.iter().map(|l| l[key].as_u64().unwrap()).sum::<u64>();
    let (sent, lost) = (count("delivered") + count("lost"), count("lost"));
    // Sent shares are lost with p = 0.2: within 4 σ of the binomial.
    let sigma = (sent as f64 * 0.2 * 0.8).sqrt();
    assert!((lost as f64 - 0.2 * sent as f64).abs() < 4.0 * sigma, "{lost} of {sent} lost");
    assert!(count("busy") > sent, "256 kbit/s sends one share in three: {} busy, {sent} sent", count("busy"));
    // Every share a link did not deliver is one its reader set aside, none other.
    let undelivered: u64 = s["processes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["process"] != "plant")
        .map(|p| p["faults"]["link_undelivered"].as_u64().unwrap())
        .sum();
    assert!(undelivered > 0 && undelivered <= lost + count("busy"), "{undelivered}");
    let dropped = s["processes"].as_array().unwrap().iter().find(|p| p["process"] == "agent-2").unwrap()["faults"]
        ["shares_dropped"]
        .as_u64()
        .unwrap();
    assert!(dropped > 100, "the drop fault ran too: {dropped}");
    let plant = telemetry_table(&mp, "plant");
    // Over each last second: one share in three sent, 80 % of those delivered.
    let delivered = plant.col("links_delivered_frac_1s");
    assert!(delivered[100..].iter().all(|f| (0.18..0.36).contains(f)), "delivered fraction {delivered:?}");
    // 20 ms of processing is 2 steps; with a share's bits at 256 kbit/s on top, 5 (the first
    // shares, sent before the plant has seen one, have no serialisation time).
    let delays = plant.col("links_delay_mean_steps_1s");
    assert!(delays.iter().all(|d| (2.0..=5.0).contains(d)), "{delays:?}");
    assert_eq!(delays[100..].iter().copied().fold(0.0, f64::max), 5.0);
}

#[test]
fn the_links_study_tabulates_every_rung_and_its_ideal_rung_is_the_plain_run() {
    let (_g, dir) = heavy_scratch("links-study");
    let out = dir.join("study");
    let md = study(&["topologies/fig1.toml", "--duration", "5", "--metric", "servicer_1.e_norm_last10s_mean_m"], &out);
    for rung in
        ["ideal", "range-only delay", "+ blockage", "+ loss 1 %", "+ loss 10 %", "+ loss 30 %", "+ rate cap 64 kbit/s"]
    {
        assert!(md.contains(&format!("| {rung} |")), "no row {rung:?} in\n{md}");
    }
    // The ideal rung is the scenario as shipped: the same metrics, bit for bit, as a plain run.
    let plain = dir.join("plain");
    let o = launch_scenario(Path::new("topologies/fig1.toml"), &plain, &["--reference", "--duration", "5"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let (a, b) = (summary(&out.join("fig1/rung-0")), summary(&plain));
    assert_eq!(a["metrics"], b["metrics"]);
    // Geometric rungs report their links; the delay rung delivers every share one step late.
    let delay = plant_links(&summary(&out.join("fig1/rung-1")));
    assert!(delay.iter().all(|l| l["delivered"] == l["steps"] && l["delay_max_steps"] == 1), "{delay:?}");
    // A plant with no positions is refused, naming it.
    let o = cohort::orchestrator_command().args(["links", "study", "topologies/dai.toml"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("gives no positions"), "{}", describe_output(&o));
}

#[test]
fn a_links_study_over_seeds_gives_each_rungs_spread_and_how_many_seeds_fail() {
    let (_g, dir) = heavy_scratch("links-study-seeds");
    let out = dir.join("study");
    let md = study(&["topologies/tsnr-case1.toml", "--duration", "5", "--seeds", "3"], &out);
    assert!(md.contains("3 seeds per rung"), "{md}");
    let ideal = md.lines().find(|l| l.starts_with("| ideal |")).unwrap();
    assert!(ideal.contains("3/3 ok"), "{ideal}");
    // Each seed's run is kept, and a seed's ideal rung is that seed's plain run.
    for seed in [1, 2, 3] {
        assert!(out.join(format!("tsnr-case1/rung-0/seed-{seed}/summary.json")).is_file());
    }
    let plain = dir.join("plain");
    let o = launch_scenario(
        Path::new("topologies/tsnr-case1.toml"),
        &plain,
        &["--reference", "--duration", "5", "--seed", "2"],
    );
    assert!(o.status.success(), "{}", describe_output(&o));
    // (Its QP solve times are wall-clock: compared are the deterministic metrics.)
    let (a, b) = (summary(&out.join("tsnr-case1/rung-0/seed-2")), summary(&plain));
    for key in ["fuel_total_ns", "mu_1.terminal_err_m", "mu_4.err_rms_0_10_m", "net.max_edge_tension_n"] {
        assert_eq!(a["metrics"][key], b["metrics"][key], "{key}");
    }
}
