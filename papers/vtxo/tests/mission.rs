//! The VTXO mission of Sec. 8 ("Explainable AI-Enhanced Supervisory Control for High-Precision
//! Spacecraft Formation", Tables 6–8 as corrected in papers/vtxo/README.md) through the
//! orchestrator: `launch topologies/vtxo-mission.toml` runs the supervisor of both spacecraft event
//! by event to s6 through Id 0 → 9 with the science windows the timers imply, never dwelling zero
//! time in a state; writes the timeline table and its figure; is identical on a rerun; and a
//! shortened run stops where the horizon falls. Build the binaries first (`scripts/test` does).

use std::path::Path;
use std::process::Output;

use cohort::{describe_output, orchestrator_command, scratch_dir, summary};

fn launch(args: &[&str], out: &Path) -> Output {
    orchestrator_command().arg("launch").args(args).arg("--out").arg(out).output().expect("running the orchestrator")
}

fn metric(s: &serde_json::Value, key: &str) -> f64 {
    s["metrics"][key].as_f64().unwrap_or_else(|| panic!("summary.json has no metric {key}: {}", s["metrics"]))
}

/// The timeline rows: (state, Id, entry time s, dwell s).
fn timeline(run: &Path) -> Vec<(String, u32, f64, f64)> {
    let text = std::fs::read_to_string(run.join("derived/vtxo_mission_timeline.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("state,state_name,id,from,entry_t_s,entry_t_d,dwell_s"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].to_string(), f[2].parse().unwrap(), f[4].parse().unwrap(), f[6].parse().unwrap())
        })
        .collect()
}

#[test]
fn the_mission_reaches_s6_through_every_id_with_the_science_windows_the_timers_imply() {
    let dir = scratch_dir("vtxo-mission");
    let run = dir.join("a");
    let o = launch(&["topologies/vtxo-mission.toml"], &run);
    assert!(o.status.success(), "{}", describe_output(&o));
    let s = summary(&run);
    assert_eq!(s["status"], "ok");
    assert_eq!(s["mode"], "discrete-event");
    assert_eq!(metric(&s, "mission_finished"), 1.0);
    assert_eq!((metric(&s, "mission_final_state"), metric(&s, "mission_final_id")), (6.0, 9.0));
    // By hand from Table 6 and the 10 h window: ⌈u3/10 h⌉ = 1 for 0.2, 1.5, 4.2, 4.9, 5.4 h; 2 for
    // 19 h; 15 for 146 h; 46 for 452 h: 68 windows, 60 of them followed by a stabilisation.
    assert_eq!(metric(&s, "science_windows"), 68.0);
    assert_eq!(metric(&s, "stabilisations"), 60.0);
    assert_eq!(metric(&s, "science_time_h"), 633.2);
    // 60 d + 8 × 9 001 s + 68 × 48 s + 633.2 h + 60 × u1 + 5 d, u1 = the plant's period
    // 2π√(a³/μ) = 95 952.939 s (a = 45 300 km, by hand) − 10 h − 3 min = 59 772.939 s, which the
    // 0.1 s tick makes 59 772.9 s.
    assert_eq!(metric(&s, "mission_end_s"), 11_557_166.0);
    let rows = timeline(&run);
    let stabilisations: Vec<f64> = rows.iter().filter(|r| r.0 == "s1").map(|r| r.3).collect();
    assert_eq!(stabilisations.len(), 60);
    assert!(stabilisations.iter().all(|d| *d == 59_772.9), "u1 from the plant's orbit: {stabilisations:?}");
    assert_eq!(rows.len() as f64, metric(&s, "mission_events"));
    let ids: Vec<u32> = rows.iter().map(|r| r.1).collect();
    assert_eq!((ids[0], *ids.last().unwrap()), (0, 9));
    assert!(ids.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1), "Id goes up one at a time: {ids:?}");
    assert!((1..=9).all(|i| ids.contains(&i)));
    assert_eq!(rows.last().unwrap().0, "s6");
    assert!(rows[..rows.len() - 1].iter().all(|r| r.3 > 0.0), "a zero dwell in {rows:?}");
    assert!(metric(&s, "min_dwell_s") > 0.0);
    for w in rows.windows(2) {
        // Each time is exact ticks / 10; their f64 sum need not be (u1 = 59 772.9 s is not whole).
        assert!((w[0].2 + w[0].3 - w[1].2).abs() < 1e-6, "entry + dwell = next entry: {w:?}");
    }
    assert!(run.join("plots/vtxo_mission_timeline.png").is_file());
    // The same scenario again: the same bytes.
    let again = dir.join("b");
    assert!(launch(&["topologies/vtxo-mission.toml", "--no-plots"], &again).status.success());
    for f in ["derived/vtxo_mission_timeline.csv", "telemetry/agent-2.csv", "telemetry/agent-1.csv"] {
        assert_eq!(std::fs::read(run.join(f)).unwrap(), std::fs::read(again.join(f)).unwrap(), "{f}");
    }
}

#[test]
fn a_shortened_mission_stops_at_its_horizon() {
    let dir = scratch_dir("vtxo-mission-short");
    // 61 days: past the commissioning, into the first objects.
    let o = launch(&["topologies/vtxo-mission.toml", "--duration", "5270400", "--no-plots"], &dir);
    assert!(o.status.success(), "{}", describe_output(&o));
    let s = summary(&dir);
    assert_eq!(s["status"], "ok");
    assert_eq!(metric(&s, "mission_finished"), 0.0);
    assert_eq!(metric(&s, "mission_end_s"), 5_270_400.0);
    let rows = timeline(&dir);
    assert_eq!(rows[1], ("s4".to_string(), 1, 5_184_000.0, 9_001.0));
    assert!(rows.last().unwrap().1 >= 2);
}
