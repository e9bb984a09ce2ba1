//! The drivers over the in-memory transport with toy models: two runs agree bit for bit with
//! each other and with the values the models held in memory, and a silent agent is a timeout
//! naming it, never a hang.

use super::wait::{BACKOFF_GROWTH, BACKOFF_MAX, BACKOFF_MIN, SPIN_MODE_BUDGET, SPIN_MODE_MAX, spin_mode_budget};
use super::*;
use crate::model::{AgentInput, Neighbour};
use crate::model::{Algorithm, PlantModel, RestoreStateError, ShareOut};
use crate::record::{ProcessReport, RunDirs, WaitStats};
use crate::rng::process_rng;
use cohort_scenario::faults::*;
use cohort_wire::auth::MacKey;
use cohort_wire::msg::*;
use cohort_wire::transport::memory::MemoryBus;
use cohort_wire::transport::{DataPath, Proc, Topology};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::sync::Mutex;
use std::time::Duration;
use std::time::Instant;

/// 1-D integrators ẋ = u, read with uniform noise (also the recording tests' plant).
pub(crate) struct ToyPlant {
    pub(crate) x: Vec<f64>,
    pub(crate) u: Vec<f64>,
}
impl PlantModel for ToyPlant {
    fn columns(&self) -> Vec<String> {
        (1..=self.x.len()).map(|i| format!("x{i}")).collect()
    }
    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        out.push(self.x[agent as usize - 1] + rng.random::<f64>() * 1e-3);
    }
    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        self.u[agent as usize - 1] = command.first().copied().unwrap_or(0.0);
    }
    fn advance(&mut self, dt_s: f64) {
        for (x, u) in self.x.iter_mut().zip(&self.u) {
            *x += u * dt_s;
        }
    }
    fn row(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&self.x);
    }
    fn metrics(&self) -> Vec<(String, f64)> {
        vec![]
    }
}

/// Average consensus: u = Σ (x̂ⱼ − y). Records every value it shares.
struct ToyAgent {
    y: f64,
    nbr: Vec<f64>,
    shared: Arc<Mutex<Vec<f64>>>,
}
impl Algorithm for ToyAgent {
    fn columns(&self) -> Vec<String> {
        vec!["y".into(), "u".into()]
    }
    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        self.y = input.readings[0];
        let u: f64 = self.nbr.iter().map(|x| x - self.y).sum::<f64>() * 0.7;
        out.command.push(u);
        out.values.push(self.y);
        self.shared.lock().unwrap().extend([self.y, u]);
    }
    fn step(&mut self, _dt_s: f64, neighbours: &[Neighbour<'_>]) {
        self.nbr = neighbours.iter().map(|n| n.values[0]).collect();
    }
    fn row(&self, out: &mut Vec<f64>) {
        let u: f64 = self.nbr.iter().map(|x| x - self.y).sum::<f64>() * 0.7;
        out.extend([self.y, u]);
    }
    fn save_state(&self) -> Vec<u8> {
        crate::checkpoint::encode_state(&(self.y, &self.nbr))
    }
    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        (self.y, self.nbr) = crate::checkpoint::decode_state(bytes)?;
        Ok(())
    }
}

fn params(dir: &std::path::Path, n_steps: u64, timeout: Duration) -> DriveParams {
    let dirs = RunDirs::new(dir);
    dirs.create_all().unwrap();
    DriveParams::basic(99, n_steps, 0.1, timeout, dirs)
}

#[derive(Default)]
struct Setup {
    silent: Option<u32>,
    abort: bool,
    faults: Vec<cohort_scenario::faults::FaultSpec>,
    /// run.authenticate: the run's key, and a process (0: the plant) whose messages carry
    /// another one (as if damaged in place, or forged).
    key: Option<MacKey>,
    wrong_key: Option<u32>,
    /// A measurement to slip into agent 1's inbox before the run starts.
    inject: Option<Measurement>,
    /// `run.telemetry_every_steps` (0 taken as 1).
    telemetry_every: u64,
}

/// Run 4 agents on a ring; returns (plant report, agent reports, in-memory shared values).
fn run(dir: &std::path::Path, setup: Setup) -> (ProcessReport, Vec<ProcessReport>, Vec<Vec<f64>>) {
    let topo = Topology { neighbours: vec![vec![2, 4], vec![1, 3], vec![2, 4], vec![3, 1]] };
    let bus = MemoryBus::new(topo.clone());
    let silent = setup.silent;
    let quick = silent.is_some() || setup.wrong_key.is_some();
    let mut p = params(dir, 50, Duration::from_millis(if quick { 300 } else { 20_000 }));
    p.degrade = !setup.abort;
    // These tests read the rows as text; the Parquet writer has its own tests.
    p.telemetry = cohort_scenario::TelemetryFormat::Csv;
    p.faults = Arc::new(FaultPlan::new(&setup.faults, 11, p.dt_s));
    p.key = setup.key;
    let mut forged = p.clone();
    forged.key = Some(MacKey::from_bytes([0xEE; 32]));
    if let Some(m) = &setup.inject {
        bus.endpoint(Proc::Plant).send_measurement(1, m).unwrap();
    }
    p.telemetry_every = setup.telemetry_every.max(1);
    let shared: Vec<Arc<Mutex<Vec<f64>>>> = (0..4).map(|_| Arc::new(Mutex::new(Vec::new()))).collect();
    std::thread::scope(|sc| {
        let plant = {
            let p = if setup.wrong_key == Some(0) { &forged } else { &p };
            let bus = &bus;
            sc.spawn(move || {
                let mut t = bus.endpoint(Proc::Plant);
                let mut m = ToyPlant { x: vec![1.0, -2.0, 3.5, 0.25], u: vec![0.0; 4] };
                let mut rng = process_rng(5, Proc::Plant);
                let r = run_plant(&mut t, &mut m, &mut rng, 4, p);
                if r.error.is_some() {
                    // As the reference run does: the others stop at their next wait.
                    bus.request_stop();
                }
                r
            })
        };
        let agents: Vec<_> = (1..=4u32)
            .filter(|&i| Some(i) != silent)
            .map(|i| {
                let p = if setup.wrong_key == Some(i) { &forged } else { &p };
                let (bus, topo, sh) = (&bus, &topo, Arc::clone(&shared[i as usize - 1]));
                sc.spawn(move || {
                    let mut t = bus.endpoint(Proc::Agent(i));
                    let mut a = ToyAgent { y: 0.0, nbr: vec![], shared: sh };
                    run_agent(&mut t, &mut a, i, topo.neighbours_of(i), p, None)
                })
            })
            .collect();
        let pr = plant.join().unwrap();
        let ars = agents.into_iter().map(|h| h.join().unwrap()).collect();
        (pr, ars, shared.iter().map(|s| s.lock().unwrap().clone()).collect())
    })
}

#[test]
fn two_in_memory_runs_agree_bit_for_bit_with_memory_and_with_each_other() {
    let base = std::env::temp_dir().join(format!("cohort-drive-{}", std::process::id()));
    let (a, b) = (base.join("a"), base.join("b"));
    let (pa, ra, sa) = run(&a, Setup::default());
    let (pb, _, sb) = run(&b, Setup::default());
    assert!(pa.error.is_none() && pb.error.is_none(), "{:?} {:?}", pa.error, pb.error);
    assert!(ra.iter().all(|r| r.error.is_none() && r.steps_completed == 50));
    // The values each agent held in memory are exactly what its telemetry says.
    for i in 1..=4usize {
        let text = std::fs::read_to_string(a.join(format!("telemetry/agent-{i}.csv"))).unwrap();
        let from_csv: Vec<u64> = text
            .lines()
            .skip(1)
            .flat_map(|l| l.split(',').skip(2).map(|v| v.parse::<f64>().unwrap().to_bits()).collect::<Vec<_>>())
            .collect();
        let in_memory: Vec<u64> = sa[i - 1].iter().map(|x| x.to_bits()).collect();
        assert_eq!(from_csv, in_memory, "agent {i}");
        assert_eq!(
            sa[i - 1].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            sb[i - 1].iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            "agent {i}: runs differ"
        );
    }
    let pa_csv = std::fs::read(a.join("telemetry/plant.csv")).unwrap();
    let pb_csv = std::fs::read(b.join("telemetry/plant.csv")).unwrap();
    assert_eq!(pa_csv, pb_csv);
    // The consensus actually ran (values moved toward each other), so equality is not vacuous.
    let last = String::from_utf8(pa_csv).unwrap().lines().last().unwrap().to_string();
    let xs: Vec<f64> = last.split(',').skip(2).map(|v| v.parse().unwrap()).collect();
    let spread = xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread < 1.0, "spread {spread} (started at 5.5)");
    let _ = std::fs::remove_dir_all(&base);
}

/// `run.telemetry_every_steps`: rows at k = 0, n, 2n, … and the last step, each equal to
/// the same step's row of a run that writes every step (the models run every step either way).
#[test]
fn a_telemetry_stride_keeps_every_nth_row_and_the_last_unchanged() {
    let base = std::env::temp_dir().join(format!("cohort-drive-stride-{}", std::process::id()));
    let (all, every7) = (base.join("all"), base.join("every7"));
    let (pa, _, _) = run(&all, Setup::default());
    let (pb, rb, _) = run(&every7, Setup { telemetry_every: 7, ..Default::default() });
    assert!(pa.error.is_none() && pb.error.is_none() && rb.iter().all(|r| r.error.is_none()));
    for f in ["plant.csv", "agent-1.csv", "agent-4.csv"] {
        let full = std::fs::read_to_string(all.join("telemetry").join(f)).unwrap();
        let strided = std::fs::read_to_string(every7.join("telemetry").join(f)).unwrap();
        let (mut full, mut strided) = (full.lines(), strided.lines());
        assert_eq!(full.next(), strided.next(), "{f}: header");
        let want: Vec<&str> = full
            .filter(|l| l.split(',').next().unwrap().parse::<u64>().unwrap() % 7 == 0 || l.starts_with("49,"))
            .collect();
        let got: Vec<&str> = strided.collect();
        let ks: Vec<&str> = got.iter().map(|l| l.split(',').next().unwrap()).collect();
        assert_eq!(ks, ["0", "7", "14", "21", "28", "35", "42", "49"], "{f}");
        assert_eq!(got, want, "{f}");
    }
    // Timing keeps every step.
    let timing = std::fs::read_to_string(every7.join("timing/plant.csv")).unwrap();
    assert_eq!(timing.lines().count(), 51);
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_silent_agent_is_a_timeout_naming_it_not_a_hang() {
    let base = std::env::temp_dir().join(format!("cohort-drive-silent-{}", std::process::id()));
    let started = Instant::now();
    let (pr, _, _) = run(&base, Setup { silent: Some(3), abort: true, ..Default::default() });
    let err = pr.error.expect("the plant must fail").message;
    assert!(err.contains("timeout at step 0") && err.contains("agent 3"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(30));
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn degrade_mode_marks_a_silent_agent_dead_and_finishes_without_it() {
    let base = std::env::temp_dir().join(format!("cohort-drive-degrade-{}", std::process::id()));
    let (pr, ars, _) = run(&base, Setup { silent: Some(3), ..Default::default() });
    assert!(pr.error.is_none(), "{:?}", pr.error);
    assert_eq!(pr.steps_completed, 50);
    assert_eq!(pr.faults.roster.len(), 1, "{:?}", pr.faults.roster);
    let c = &pr.faults.roster[0];
    assert_eq!((c.step, c.agent, c.live, c.reason.as_str()), (0, 3, false, "silent"));
    assert!(ars.iter().all(|r| r.error.is_none() && r.steps_completed == 50), "{ars:?}");
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn an_authenticated_run_is_bit_identical_and_a_wrongly_keyed_plant_is_named_as_rejected() {
    // Issue 18, finding 6: a message that fails its MAC is counted, the wait goes on, and the
    // run's error names the process whose message was rejected (not "went silent").
    let base = std::env::temp_dir().join(format!("cohort-drive-mac-{}", std::process::id()));
    let key = Some(MacKey::from_bytes([5; 32]));
    let (plain, _, sp) = run(&base.join("plain"), Setup::default());
    let (sealed, ra, ss) = run(&base.join("sealed"), Setup { key, ..Default::default() });
    assert!(plain.error.is_none() && sealed.error.is_none(), "{:?}", sealed.error);
    let bits = |v: &Vec<Vec<f64>>| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&sp), bits(&ss), "the MAC changed the results");
    assert!(ra.iter().chain([&sealed]).all(|r| r.messages_rejected.values().sum::<u64>() == 0));
    // Every measurement fails its tag: each agent counts it, waits on, and ends naming the
    // plant's rejected message as the reason it got nothing.
    let (pr, ars, _) = run(&base.join("forged"), Setup { key, wrong_key: Some(0), ..Default::default() });
    assert!(pr.error.is_none(), "degrade mode: the plant goes on without the agents: {:?}", pr.error);
    for a in &ars {
        let err = &a.error.as_ref().expect("the agent must time out").message;
        assert!(err.contains("from the plant (its latest message was rejected: mac"), "{err}");
        assert!(a.messages_rejected.get("mac").copied().unwrap_or(0) >= 1, "{:?}", a.messages_rejected);
    }
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_measurement_naming_a_step_past_the_run_is_rejected_not_propagated_through() {
    // Issue 18, finding 6: a step read from a message was trusted as a loop bound (an agent
    // would have propagated through 2^40 steps).
    let base = std::env::temp_dir().join(format!("cohort-drive-far-{}", std::process::id()));
    let far = Measurement::new(Header::new(99, PLANT_ID, 1 << 40, 1e9), &[0.0]);
    let (pr, ars, _) = run(&base, Setup { inject: Some(far), ..Default::default() });
    assert!(pr.error.is_none() && ars.iter().all(|r| r.error.is_none()), "{pr:?} {ars:?}");
    assert_eq!(ars[0].steps_completed, 50);
    assert_eq!(ars[0].messages_rejected.get("step"), Some(&1), "{:?}", ars[0].messages_rejected);
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn contention_backs_off_while_stalls_are_common_and_forgets_a_lone_one() {
    let blocked = |c: &mut Contention| (0..10_000).take_while(|_| !c.may_spin()).count();
    let mut c = Contention::default();
    assert!(c.may_spin());
    c.spun(true);
    assert_eq!(blocked(&mut c), BACKOFF_MIN as usize);
    c.spun(true);
    assert_eq!(blocked(&mut c), (BACKOFF_GROWTH * BACKOFF_MIN) as usize);
    // Sustained contention where every other spin stalls still grows the gap to its maximum.
    for _ in 0..20 {
        c.spun(false);
        c.spun(true);
    }
    assert_eq!(blocked(&mut c), BACKOFF_MAX as usize);
    // A lone stall on an idle machine: a few clean spins forget it.
    let mut c = Contention::default();
    c.spun(true);
    for _ in 0..5 {
        c.spun(false);
    }
    c.spun(true);
    assert_eq!(blocked(&mut c), BACKOFF_MIN as usize);
    assert_eq!(c.stalls, 2);
}

/// Once a trial chose spinning, a wait spins 10 ms, or four typical waits when those are
/// longer (hundreds of agents on two cores), never more than a second.
#[test]
fn a_chosen_spin_lasts_four_typical_waits_between_its_bounds() {
    assert_eq!(spin_mode_budget(0.0), SPIN_MODE_BUDGET);
    assert_eq!(spin_mode_budget(300.0), SPIN_MODE_BUDGET, "four 300 µs waits are below the 10 ms floor");
    assert_eq!(spin_mode_budget(20_000.0), Duration::from_millis(80));
    assert_eq!(spin_mode_budget(5e6), SPIN_MODE_MAX);
    assert_eq!(spin_mode_budget(f64::NAN), SPIN_MODE_BUDGET, "no typical wait yet spins the floor");
}

#[test]
fn wait_stats_count_spins_stalls_and_expiries() {
    let mut w = WaitStats::default();
    w.count(false, false, false, Duration::ZERO);
    w.count(true, false, false, Duration::from_micros(30));
    w.count(true, true, true, Duration::from_millis(2));
    w.count(true, false, true, Duration::from_micros(80));
    assert_eq!((w.waits, w.spun, w.spin_stalls, w.spin_expired), (4, 3, 1, 1));
    assert!((w.spin_s - 2.11e-3).abs() < 1e-12, "{}", w.spin_s);
}

fn fault(kind: &str, agent: u32, t_s: f64) -> cohort_scenario::faults::FaultSpec {
    cohort_scenario::faults::FaultSpec { kind: kind.into(), agent, t_s, for_s: None, p: None, delay_steps: None }
}

#[test]
fn link_faults_are_deterministic_and_every_lost_share_is_counted() {
    let base = std::env::temp_dir().join(format!("cohort-drive-links-{}", std::process::id()));
    let faults = || {
        let mut drop = fault("drop", 2, 0.5);
        drop.p = Some(0.3);
        let mut corrupt = fault("corrupt", 4, 0.0);
        corrupt.p = Some(0.3);
        let mut delay = fault("delay", 1, 1.0);
        (delay.delay_steps, delay.for_s) = (Some(2), Some(2.0));
        vec![drop, corrupt, delay]
    };
    let (pa, ra, sa) = run(&base.join("a"), Setup { faults: faults(), ..Default::default() });
    let (pb, _, sb) = run(&base.join("b"), Setup { faults: faults(), ..Default::default() });
    assert!(pa.error.is_none() && ra.iter().all(|r| r.error.is_none()), "{pa:?} {ra:?}");
    let bits = |v: &Vec<Vec<f64>>| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&sa), bits(&sb), "two runs with the same plan differ");
    assert_eq!(pa.faults, pb.faults);
    let by = |id: u32| &ra[id as usize - 1].faults;
    let dropped = by(2).shares_dropped;
    let corrupted: u64 = by(4).shares_corrupted.values().sum();
    assert!(dropped > 3 && corrupted > 3, "too few faults drawn: {dropped} {corrupted}");
    assert_eq!(by(1).shares_delayed, 20);
    // The plant holds a command for every lost share, and for the two steps at the start of
    // the delay window when nothing of agent 1 arrives.
    assert_eq!(pa.faults.held.get("agent-2"), Some(&dropped));
    assert_eq!(pa.faults.held.get("agent-4"), Some(&corrupted));
    assert_eq!(pa.faults.held.get("agent-1"), Some(&2));
    // Every garbled share was rejected, for the reason it was garbled, by each of its readers.
    for reader in [&pa, &ra[0], &ra[2]] {
        for (why, n) in &by(4).shares_corrupted {
            assert_eq!(reader.messages_rejected.get(why), Some(n), "{} rejects {why}", reader.process);
        }
    }
    assert_eq!(pa.messages_rejected.values().sum::<u64>(), corrupted);
    // The other agents used agent 2's last valid share in place of each dropped one.
    assert_eq!(ra[0].faults.held.get("agent-2"), Some(&dropped));
    assert_eq!(ra[2].faults.held.get("agent-2"), Some(&dropped));
    assert_eq!(ra[1].faults.max_age_steps, 2, "agent 2 used agent 1's shares 2 steps late");
    let _ = std::fs::remove_dir_all(&base);
}

/// The transport-free loop of campaigns and studies ([`crate::lockstep::Lockstep`]) flies the
/// drivers' ring exactly: the same readings (the plant process's generator), the same shares.
#[test]
fn the_lockstep_loop_flies_the_drivers_ring_bit_for_bit() {
    let base = std::env::temp_dir().join(format!("cohort-drive-lockstep-{}", std::process::id()));
    let (pr, ars, driven) = run(&base, Setup::default());
    assert!(pr.error.is_none() && ars.iter().all(|r| r.error.is_none()));
    let shared: Vec<Arc<Mutex<Vec<f64>>>> = (0..4).map(|_| Arc::new(Mutex::new(Vec::new()))).collect();
    let mut plant = ToyPlant { x: vec![1.0, -2.0, 3.5, 0.25], u: vec![0.0; 4] };
    let mut agents: Vec<ToyAgent> =
        shared.iter().map(|sh| ToyAgent { y: 0.0, nbr: vec![], shared: Arc::clone(sh) }).collect();
    let ring = vec![vec![2, 4], vec![1, 3], vec![2, 4], vec![3, 1]];
    let mut lockstep = crate::lockstep::Lockstep::new(ring, 0.1, 5);
    let mut refs: Vec<&mut ToyAgent> = agents.iter_mut().collect();
    let mut looked = 0;
    for _ in 0..50 {
        lockstep.step(&mut plant, &mut refs, &mut |k, _, agents, shares| {
            assert_eq!((k, agents.len(), shares.len()), (looked, 4, 4));
            looked += 1;
        });
    }
    assert_eq!((lockstep.k, looked), (50, 50));
    for i in 0..4 {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let flown = shared[i].lock().unwrap().clone();
        assert_eq!(flown.len(), 100, "agent {}", i + 1);
        assert_eq!(bits(&flown), bits(&driven[i]), "agent {}", i + 1);
    }
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_returning_agent_keeps_its_neighbours_shares_of_the_return_step_met_before_the_measurement() {
    // Frozen at step 10 000 in the middle of a drain (its measurement queue read, a neighbour's
    // not yet), thawed late: the neighbour's share of the return step 10 500 comes out of the
    // drain before the plant's measurement 10 500 does. The agent then catches up and waits for
    // that share's token; a share taken as "too far ahead" was a wait until the plant declared
    // the agent dead one step after its return.
    let base = std::env::temp_dir().join(format!("cohort-drive-return-{}", std::process::id()));
    let p = params(&base, 20_000, Duration::from_secs(1));
    let mut inbox = super::agent_inbox::AgentInbox::new(&p, 2, &[1], 1);
    let all = Roster::all(2);
    let measurement = |step: u64| {
        let mut m = Measurement::new(Header::new(99, PLANT_ID, step, step as f64 * 0.1), &[0.0]);
        m.live = all;
        m
    };
    use super::wait::Inbox;
    use cohort_wire::transport::Incoming;
    inbox.take(Incoming::Measurement(&measurement(9_999)));
    inbox.meas = None;
    inbox.k = 10_000;
    let share = Share::new(Header::new(99, 1, 10_500, 1050.0), &[0.0], &[1.0]);
    inbox.take(Incoming::Share { from: 1, share: &share });
    inbox.take(Incoming::Measurement(&measurement(10_500)));
    assert_eq!(inbox.rejects.total(), 0, "{:?}", inbox.rejects);
    // As after the catch-up: step 10 500's share is what completes the wait.
    inbox.k = 10_500;
    inbox.want_measurement = false;
    inbox.need_shares = Some(10_500);
    assert!(inbox.complete(), "the neighbour's token of the return step was lost");
    let _ = std::fs::remove_dir_all(&base);
}

/// Records what each `step` was given: (neighbour's value, its age).
struct Heard(Vec<Vec<(f64, u64)>>);
impl Algorithm for Heard {
    fn columns(&self) -> Vec<String> {
        Vec::new()
    }
    fn share(&mut self, _input: &AgentInput<'_>, _out: &mut ShareOut) {}
    fn step(&mut self, _dt_s: f64, neighbours: &[Neighbour<'_>]) {
        self.0.push(neighbours.iter().map(|n| (n.values[0], n.age_steps)).collect());
    }
    fn row(&self, _out: &mut Vec<f64>) {}
    fn save_state(&self) -> Vec<u8> {
        Vec::new()
    }
    fn restore_state(&mut self, _bytes: &[u8]) -> Result<(), RestoreStateError> {
        Ok(())
    }
}

#[test]
fn a_reader_never_uses_a_share_its_link_did_not_deliver_and_uses_a_delayed_one_from_its_arrival() {
    use super::wait::Inbox;
    use cohort_wire::transport::Incoming;
    let base = std::env::temp_dir().join(format!("cohort-drive-links-{}", std::process::id()));
    let p = params(&base, 100, Duration::from_secs(1));
    let mut inbox = super::agent_inbox::AgentInbox::new(&p, 2, &[1], 1);
    let mut algo = Heard(Vec::new());
    let mut report = ProcessReport::new("agent-2".into());
    // Agent 1's link to agent 2 per step: delivered at once, blocked, lost, two steps late, busy,
    // busy, at once.
    let codes = [0, LINK_BLOCKED, LINK_LOST_IN_TRANSIT, 2, LINK_BUSY, LINK_BUSY, 0];
    for (k, code) in codes.iter().enumerate() {
        let k = k as u64;
        let mut m = Measurement::new(Header::new(99, PLANT_ID, k, k as f64 * 0.1), &[0.0]);
        m.live = Roster::all(2);
        m.set_links(&[*code]);
        inbox.k = k;
        inbox.want_measurement = true;
        inbox.take(Incoming::Measurement(&m));
        // Every share travels at once; its value is the step it was sent at.
        let share = Share::new(Header::new(99, 1, k, k as f64 * 0.1), &[0.0], &[k as f64]);
        inbox.take(Incoming::Share { from: 1, share: &share });
        inbox.advance(&mut algo, Some(k), 0.1, &mut report);
    }
    // Step 0's share at once; steps 1 and 2 never (blocked, lost): step 0's is held, aging; step
    // 3's is used from step 5 (2 steps late), 4's and 5's never (busy); step 6's at once.
    let want: Vec<Vec<(f64, u64)>> = vec![
        vec![(0.0, 0)],
        vec![(0.0, 1)],
        vec![(0.0, 2)],
        vec![(0.0, 3)],
        vec![(0.0, 4)],
        vec![(3.0, 2)],
        vec![(6.0, 0)],
    ];
    assert_eq!(algo.0, want);
    assert_eq!(report.faults.link_undelivered, 4, "blocked, lost and busy twice");
    let _ = std::fs::remove_dir_all(&base);
}
