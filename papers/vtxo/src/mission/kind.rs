//! The registry's `vtxo-mission` algorithm kind: the whole mission of Sec. 8 of "Explainable
//! AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation" as a discrete-event
//! run ([`crate::mission::discrete`]), launched by `orchestrator launch topologies/vtxo-mission.toml`
//! through the runtime's coupled mode (in the orchestrator's process, no processes spawned; see
//! [`crate::mission::discrete`] for why the fixed-step lockstep cannot carry it).
//!
//! The scenario is an ordinary one: `[plant] kind = "vtxo"` (validated; its dynamics are what the
//! timers abstract, and its orbit gives their period, [`crate::mission::period`]),
//! `[algorithm] kind = "vtxo-mission"` ([`crate::mission::config`]), the leader
//! (agent 1) and the follower (agent 2) each listing the other (the supervisor's state and the
//! leader's acknowledgement pass between them). `scenario.dt_s` is the mission's tick and
//! `scenario.duration_s` its horizon: the run ends at s6 or there, whichever comes first
//! (`--duration 10` stops it in s0).
//!
//! The run directory: `telemetry/plant.csv` (one row per event: location, Id, the formation flag,
//! u2), `telemetry/agent-2.csv` (the master's automaton: location, Id, clocks t0..t5 and tw in s,
//! u2, its T̂, k1, k2), `telemetry/agent-1.csv` (the leader's acknowledgement and prediction),
//! `derived/vtxo_mission_timeline.csv` (the timeline: state, Id, the state it came from, entry
//! time in s and days, dwell), the summary metrics below, and the figure `vtxo_mission_timeline.png`
//! ([`crate::mission::figure`]).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use cohort_runtime::model::Algorithm;
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, CoupledCtx, CoupledOutcome, CoupledRun, PlantSetup,
    Setup, section_as, table_of,
};
use cohort_runtime::record::{CsvWriter, ErrorKind, ProcessError, ProcessReport, RunDirs};
use cohort_scenario::{Checker, Scenario};

use crate::automaton::lockstep::SupervisorAgent;
use crate::automaton::share::{LEADER_SHARE_LEN, MASTER_SHARE_LEN};
use crate::automaton::table::{Automaton, S1, S2, S3};
use crate::formation::kinds::check_pair_kind;
use crate::learn::transient::gains::{FixedTransient, TransientGains, TransientPredictor};
use crate::mission::config::{PredictorKind, VtxoMissionConfig};
use crate::mission::discrete::{Mission, MissionParams};
use crate::model::config::VtxoPlantConfig;

pub const MISSION_KIND: &str = "vtxo-mission";
/// The timeline table of a mission run.
pub const TIMELINE_FILE: &str = "derived/vtxo_mission_timeline.csv";

pub struct VtxoMissionKind;

impl AlgorithmKind for VtxoMissionKind {
    fn kind(&self) -> &'static str {
        MISSION_KIND
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<VtxoMissionConfig>(&ctx.scenario.algorithm.body, "algorithm", c);
        check_pair_kind(
            ctx.scenario,
            MISSION_KIND,
            "the supervisor's state (follower, the master) and the acknowledgement (leader) pass between them",
            c,
        );
        let mut a = a?;
        if let Some(p) = plant.and_then(|p| p.downcast_ref::<VtxoPlantConfig>()) {
            c.problems.extend(a.timers.follow_plant("algorithm", p));
        }
        let dt = ctx.scenario.scenario.dt_s;
        let problems = a.validate("algorithm", dt);
        let valid = problems.is_empty();
        c.problems.extend(problems);
        if valid && dt.is_finite() && dt > 0.0 {
            // The table the timers build (always valid today; a wrong object count would show).
            if let Err(e) = Automaton::vtxo(a.timers.last_object()).validate() {
                let e: Vec<String> = e.iter().map(ToString::to_string).collect();
                c.fail("algorithm.timers.u3_h", format!("{:?}", a.timers.u3_h), e.join("; "));
            }
        }
        Some(Arc::new(a))
    }
}

impl VtxoMissionConfig {
    /// The predictor a spacecraft uses (both the same today).
    pub fn predictor(&self) -> Box<dyn TransientPredictor> {
        let x = &self.transient;
        match x.predictor {
            PredictorKind::Fixed => Box::new(FixedTransient(TransientGains { k1: x.k1, k2: x.k2, t_s: x.t_s })),
        }
    }
}

impl AlgorithmSetup for VtxoMissionConfig {
    fn kind(&self) -> &'static str {
        MISSION_KIND
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        MASTER_SHARE_LEN.max(LEADER_SHARE_LEN)
    }
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        Box::new(SupervisorAgent::new(self, setup.scenario.dt_s, id))
    }
    fn coupled(&self) -> Option<&dyn CoupledRun> {
        Some(&MissionRun)
    }
    fn labels(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        m.insert("supervisor".into(), "discrete-event".into());
        m.insert("transient_predictor".into(), "fixed".into());
        m
    }
}

/// The coupled mode of a `vtxo-mission` scenario.
pub struct MissionRun;

impl CoupledRun for MissionRun {
    fn name(&self) -> &'static str {
        "discrete-event"
    }
    fn describe(&self) -> &'static str {
        "discrete-event: the VTXO supervisor of both spacecraft, event by event, in this process (no processes spawned)"
    }
    fn run(&self, setup: &Setup, dirs: &RunDirs, ctx: &CoupledCtx<'_>) -> CoupledOutcome {
        let started = Instant::now();
        let out = run_into(setup, dirs, ctx);
        CoupledOutcome { error: out.err(), interrupted: None, wall_s: started.elapsed().as_secs_f64() }
    }
}

fn io(path: &std::path::Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", path.display())
}

/// Run the mission of a validated setup and write its run directory.
fn run_into(s: &Setup, dirs: &RunDirs, ctx: &CoupledCtx<'_>) -> Result<(), String> {
    let cfg = s.algorithm_as::<VtxoMissionConfig>().ok_or("not a vtxo-mission scenario")?;
    let p = MissionParams::of(cfg, s.scenario.dt_s);
    let (lead, fol) = (cfg.predictor(), cfg.predictor());
    let started = Instant::now();
    let m = crate::mission::discrete::run(&p, lead.as_ref(), fol.as_ref(), s.scenario.seed, s.n_steps());
    let wall_s = started.elapsed().as_secs_f64();
    let (m, error) = match m {
        Ok(m) => (m, None),
        Err(e) => (Mission { events: Vec::new(), end_tick: 0, finished: false }, Some(e.to_string())),
    };
    write_telemetry(dirs, &p, &m)?;
    write_timeline(dirs, &p, &m)?;
    let metrics = metrics(&p, &m);
    let report = |process: &str, metrics: BTreeMap<String, f64>| ProcessReport {
        steps_completed: m.end_tick,
        wall_s,
        metrics,
        error: error.clone().map(|e| ProcessError::new(ErrorKind::Diverged, e)),
        ..ProcessReport::new(process.to_string())
    };
    for (name, mm) in [("plant", metrics), ("agent-1", BTreeMap::new()), ("agent-2", BTreeMap::new())] {
        report(name, mm).write(dirs).map_err(|e| format!("status/{name}.json: {e}"))?;
        let log = format!(
            "discrete-event mission: {} events, ended at t = {} s ({}), {:.3} s wall\n",
            m.events.len(),
            p.seconds(m.end_tick),
            if m.finished { "s6" } else { "the horizon" },
            wall_s
        );
        std::fs::write(dirs.logs().join(format!("{name}.log")), log).map_err(|e| format!("logs/{name}.log: {e}"))?;
    }
    (ctx.progress)(m.end_tick);
    error.map_or(Ok(()), Err)
}

fn write_telemetry(dirs: &RunDirs, p: &MissionParams, m: &Mission) -> Result<(), String> {
    let cols = |names: &[&str]| -> Vec<String> { ["k", "t_s"].iter().chain(names).map(|s| s.to_string()).collect() };
    let plant_cols = cols(&["state", "id", "formation_reached", "u2_s"]);
    let master_cols =
        cols(&["state", "id", "t0_s", "t1_s", "t2_s", "t3_s", "t4_s", "t5_s", "tw_s", "u2_s", "t_hat_s", "k1", "k2"]);
    let leader_cols = cols(&["state", "id", "t_hat_s", "k1", "k2"]);
    let files = [("plant", plant_cols), ("agent-2", master_cols), ("agent-1", leader_cols)];
    for (name, columns) in files {
        let path = dirs.telemetry().join(format!("{name}.csv"));
        let mut w = CsvWriter::create(&path, &columns).map_err(io(&path))?;
        let mut row = Vec::new();
        for e in &m.events {
            row.clear();
            row.extend([p.seconds(e.tick), e.sup.state as f64, f64::from(e.sup.id)]);
            match name {
                "plant" => row.extend([f64::from(u8::from(e.formation)), p.seconds(e.u2_ticks)]),
                "agent-2" => {
                    row.extend(e.sup.clocks.iter().map(|c| p.seconds(*c)));
                    row.extend([p.seconds(e.u2_ticks), e.follower.t_s, e.follower.k1, e.follower.k2]);
                }
                _ => row.extend([e.leader.t_hat_s, e.leader.k1, e.leader.k2]),
            }
            w.row(e.tick, &row).map_err(io(&path))?;
        }
        w.flush().map_err(io(&path))?;
    }
    Ok(())
}

/// The timeline table (state, Id, entry time, dwell), one row per entry.
pub fn timeline_csv(p: &MissionParams, m: &Mission) -> String {
    let a = Automaton::vtxo(p.last_object);
    let mut out = String::from("state,state_name,id,from,entry_t_s,entry_t_d,dwell_s\n");
    let mut from = "-".to_string();
    for (e, d) in m.events.iter().zip(m.dwells()) {
        let t = p.seconds(e.tick);
        out.push_str(&format!(
            "s{},{},{},{},{},{},{}\n",
            e.sup.state,
            a.states[e.sup.state].name,
            e.sup.id,
            from,
            t,
            t / 86_400.0,
            p.seconds(d)
        ));
        from = format!("s{}", e.sup.state);
    }
    out
}

fn write_timeline(dirs: &RunDirs, p: &MissionParams, m: &Mission) -> Result<(), String> {
    std::fs::create_dir_all(dirs.root.join("derived")).map_err(|e| format!("derived/: {e}"))?;
    let path = dirs.root.join(TIMELINE_FILE);
    std::fs::write(&path, timeline_csv(p, m)).map_err(io(&path))
}

/// The summary metrics of a mission run.
pub fn metrics(p: &MissionParams, m: &Mission) -> BTreeMap<String, f64> {
    let count = |s| m.events.iter().filter(|e| e.sup.state == s).count() as f64;
    let last = m.events.last();
    let dwells = m.dwells();
    // The final entry (s6) has no dwell; a run stopped at the horizon has its last one cut short.
    let min_dwell = dwells[..dwells.len().saturating_sub(1)].iter().min().map_or(f64::NAN, |d| p.seconds(*d));
    let end_s = p.seconds(m.end_tick);
    [
        ("mission_finished", f64::from(u8::from(m.finished))),
        ("mission_final_state", last.map_or(f64::NAN, |e| e.sup.state as f64)),
        ("mission_final_id", last.map_or(f64::NAN, |e| f64::from(e.sup.id))),
        ("mission_end_s", end_s),
        ("mission_end_d", end_s / 86_400.0),
        ("mission_events", m.events.len() as f64),
        ("science_windows", count(S3)),
        ("science_windows_by_timers", p.science_windows_by_timers() as f64),
        ("science_time_h", p.seconds(m.time_in(S3)) / 3600.0),
        ("transients", count(S2)),
        ("stabilisations", count(S1)),
        ("min_dwell_s", min_dwell),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use cohort_runtime::paper::{Paper, configure};
    use cohort_scenario::{Overrides, parse};

    use super::*;

    const PAPERS: &[&dyn Paper] = &[&crate::Vtxo];

    fn shipped() -> String {
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/vtxo-mission.toml"))
            .unwrap()
    }

    fn configured(text: &str) -> Result<Setup, String> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies");
        let s = parse(text, &dir.join("x.toml"), &Overrides::default()).map_err(|e| e.to_string())?;
        configure(s, PAPERS).map_err(|p| p.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n"))
    }

    /// The shipped mission takes its period from the plant's orbit and writes it into the resolved
    /// scenario, which configures to itself; so does a plant on another orbit.
    #[test]
    fn the_shipped_mission_runs_on_the_plants_period_and_its_resolved_self_agrees() {
        let s = configured(&shipped()).unwrap();
        let a = s.algorithm_as::<VtxoMissionConfig>().unwrap();
        let want = s.plant_as::<VtxoPlantConfig>().unwrap().orbit_period_s().unwrap();
        assert_eq!(a.timers.orbit_period_s.map(f64::to_bits), Some(want.to_bits()));
        assert!((want - 95_952.939).abs() < 1e-3, "{want}");
        assert_eq!(MissionParams::of(a, 0.1).u1, 597_729, "(95 952.939 − 36 180) s at 0.1 s, rounded");
        let resolved = s.to_toml().unwrap();
        assert!(resolved.contains("orbit_period_s = 95952.939"), "{resolved}");
        let again = configured(&resolved).unwrap();
        assert_eq!(again.algorithm_as::<VtxoMissionConfig>().unwrap(), a);
        let wider = shipped().replace("kind = \"vtxo\"\n", "kind = \"vtxo\"\n[plant.orbit]\na_m = 51703100.514\n");
        let s = configured(&wider).unwrap();
        let p = s.algorithm_as::<VtxoMissionConfig>().unwrap().timers.orbit_period_s.unwrap();
        assert!((p - 117_000.0).abs() < 1e-3, "a = 51 703 km: the paper's 32.5 h, {p} s");
    }

    /// An explicit period is refused when it disagrees with the plant's (naming both key paths and
    /// both values) and accepted as given when it agrees.
    #[test]
    fn an_explicit_period_must_agree_with_the_plants_orbit() {
        let with =
            |v: &str| shipped().replace("[algorithm.timers]\n", &format!("[algorithm.timers]\norbit_period_s = {v}\n"));
        let e = configured(&with("117000.0")).expect_err("32.5 h over Table D.9's orbit");
        for want in [
            "algorithm.timers.orbit_period_s = 117000.000 s (32.5000 h)",
            "plant.orbit.a_m = 45300000.0 m",
            "95952.939 s (26.6536 h)",
        ] {
            assert!(e.contains(want), "{want:?} not in {e}");
        }
        assert_eq!(e.lines().count(), 1, "one problem: {e}");
        let s = configured(&with("95952.9")).unwrap();
        assert_eq!(s.algorithm_as::<VtxoMissionConfig>().unwrap().timers.orbit_period_s, Some(95_952.9));
    }
}
