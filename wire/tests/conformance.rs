//! One conformance suite for every `Transport`: what the lockstep drivers rely on, checked the
//! same way against the in-memory bus, iceoryx2, UDP loopback and zenoh over TCP loopback (the way iceoryx2-tunnel runs one
//! suite per backend). A new transport gets a harness and one `conformance!` line.
//!
//! Every endpoint of a run is opened in the test's own thread (iceoryx2 ports are not `Send`);
//! messages are sent, then drained, so no test depends on scheduling.

use std::time::{Duration, Instant};

use cohort_wire::msg::{
    CONTROL_DEAD, CONTROL_RESUME, Header, Measurement, PLANT_ID, Roster, RunControl, STATUS_PROGRESS, Share, Status,
};
use cohort_wire::transport::iox::{IoxData, IoxRun, IoxServices, RunClaim};
use cohort_wire::transport::memory::MemoryBus;
use cohort_wire::transport::udp::UdpData;
use cohort_wire::transport::zenoh::{ZenohData, ZenohHub, ZenohRun, open_on_free_ports};
use cohort_wire::transport::{ControlHub, Incoming, Proc, Split, Topology, Transport};
use cohort_wire::validate::{Expect, RejectCounts, Rejection, validate_share};

/// One backend: opens every endpoint of a run and plays the orchestrator's part.
trait Harness {
    /// The plant's endpoint, then agent i's at index i − 1.
    fn open(&mut self, topo: &Topology) -> (Box<dyn Transport>, Vec<Box<dyn Transport>>);
    fn run_id(&self) -> u64;
    fn request_stop(&mut self);
    fn grant_start(&mut self);
    fn send_control(&mut self, c: RunControl);
    /// Status reports received so far.
    fn statuses(&mut self) -> Vec<Status>;
}

/// A fresh run id per harness: concurrent test threads must not share resources.
fn fresh_run_id() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(1);
    (u64::from(std::process::id()) << 20) ^ 0xC0_0000_0000_0000 ^ N.fetch_add(1, Ordering::SeqCst)
}

struct Memory {
    run_id: u64,
    bus: Option<std::sync::Arc<MemoryBus>>,
}

impl Memory {
    fn new() -> Self {
        Self { run_id: fresh_run_id(), bus: None }
    }
    fn bus(&self) -> &MemoryBus {
        self.bus.as_ref().expect("opened")
    }
}

impl Harness for Memory {
    fn open(&mut self, topo: &Topology) -> (Box<dyn Transport>, Vec<Box<dyn Transport>>) {
        let bus = MemoryBus::new(topo.clone());
        let plant = Box::new(bus.endpoint(Proc::Plant));
        let agents =
            (1..=topo.n_agents()).map(|i| Box::new(bus.endpoint(Proc::Agent(i))) as Box<dyn Transport>).collect();
        self.bus = Some(bus);
        (plant, agents)
    }
    fn run_id(&self) -> u64 {
        self.run_id
    }
    fn request_stop(&mut self) {
        self.bus().request_stop();
    }
    fn grant_start(&mut self) {}
    fn send_control(&mut self, c: RunControl) {
        self.bus().send_control(c);
    }
    fn statuses(&mut self) -> Vec<Status> {
        self.bus().take_status()
    }
}

/// iceoryx2 data and control, or UDP data with iceoryx2 control.
struct Iox {
    run: IoxRun,
    services: Option<IoxServices>,
    udp_dir: Option<std::path::PathBuf>,
    /// Held like an orchestrator holds it: a concurrent launch's sweep leaves the run alone.
    claim: Option<RunClaim>,
}

impl Iox {
    fn new(udp: bool) -> Self {
        let run = IoxRun::new(fresh_run_id());
        let udp_dir = udp.then(|| std::env::temp_dir().join(format!("cohort-conformance-udp-{:016x}", run.run_id)));
        let claim = Some(run.claim().expect("claim the run"));
        Self { run, services: None, udp_dir, claim }
    }
    fn services(&self) -> &IoxServices {
        self.services.as_ref().expect("opened")
    }
}

impl Drop for Iox {
    fn drop(&mut self) {
        self.services = None;
        self.run.remove_all_resources();
        self.claim = None;
        if let Some(d) = &self.udp_dir {
            let _ = std::fs::remove_dir_all(d);
        }
    }
}

impl Harness for Iox {
    fn open(&mut self, topo: &Topology) -> (Box<dyn Transport>, Vec<Box<dyn Transport>>) {
        self.services = Some(IoxServices::create(&self.run, topo, 0).expect("create the run's services"));
        let procs: Vec<Proc> = std::iter::once(Proc::Plant).chain((1..=topo.n_agents()).map(Proc::Agent)).collect();
        let mut endpoints: Vec<Box<dyn Transport>> = match &self.udp_dir {
            None => procs.iter().map(|&p| Box::new(IoxData::open(&self.run, topo, p).expect("open")) as _).collect(),
            Some(dir) => {
                // Bind every socket first, then rendezvous: the order a real run gets from its
                // processes starting together.
                let bound: Vec<_> = procs.iter().map(|&p| UdpData::bind(dir, p).expect("bind")).collect();
                bound
                    .into_iter()
                    .zip(&procs)
                    .map(|(b, &p)| {
                        let data = b.rendezvous(topo, Duration::from_secs(10)).expect("rendezvous");
                        let control =
                            cohort_wire::transport::iox::IoxControl::open(&self.run, p).expect("open run control");
                        Box::new(Split { data, control }) as Box<dyn Transport>
                    })
                    .collect()
            }
        };
        let agents = endpoints.split_off(1);
        (endpoints.pop().expect("the plant"), agents)
    }
    fn run_id(&self) -> u64 {
        self.run.run_id
    }
    fn request_stop(&mut self) {
        self.services().request_stop().expect("stop");
    }
    fn grant_start(&mut self) {
        self.services().grant_start().expect("start");
    }
    fn send_control(&mut self, c: RunControl) {
        match c.command {
            CONTROL_RESUME => self.services().resume(c.step, c.dead, c.alive).expect("resume"),
            _ => self.services().report_dead(c.dead).expect("dead"),
        }
    }
    fn statuses(&mut self) -> Vec<Status> {
        let mut out = Vec::new();
        self.services().poll_status(|s| out.push(*s)).expect("status");
        out
    }
}

/// zenoh data and control over TCP loopback: the orchestrator's session listens, every process
/// connects to it and listens on its own port, and gossip connects the processes to each other.
struct Zenoh {
    run: ZenohRun,
    hub: Option<ZenohHub>,
    session: Option<zenoh::Session>,
}

impl Zenoh {
    fn new() -> Self {
        Self { run: ZenohRun::new(fresh_run_id()), hub: None, session: None }
    }
    fn hub(&self) -> &ZenohHub {
        self.hub.as_ref().expect("opened")
    }
}

impl Harness for Zenoh {
    fn open(&mut self, topo: &Topology) -> (Box<dyn Transport>, Vec<Box<dyn Transport>>) {
        let loopback = std::net::Ipv4Addr::LOCALHOST.into();
        let (session, hub_at) = open_on_free_ports(&[loopback], &[]).expect("orchestrator session");
        self.hub = Some(ZenohHub::create(&self.run, &session).expect("hub"));
        self.session = Some(session);
        let procs: Vec<Proc> = std::iter::once(Proc::Plant).chain((1..=topo.n_agents()).map(Proc::Agent)).collect();
        // Declare every endpoint first, then wait for each to be connected: the order a real run
        // gets from its processes starting together.
        let pending: Vec<_> = procs
            .iter()
            .map(|&p| ZenohData::declare(&self.run, topo, p, &["tcp/127.0.0.1:0".into()], &hub_at).expect("declare"))
            .collect();
        let mut endpoints: Vec<Box<dyn Transport>> = pending
            .into_iter()
            .map(|p| Box::new(p.ready(Duration::from_secs(20)).expect("ready")) as Box<dyn Transport>)
            .collect();
        let agents = endpoints.split_off(1);
        (endpoints.pop().expect("the plant"), agents)
    }
    fn run_id(&self) -> u64 {
        self.run.run_id
    }
    fn request_stop(&mut self) {
        self.hub().request_stop().expect("stop");
    }
    fn grant_start(&mut self) {
        self.hub().grant_start().expect("start");
    }
    fn send_control(&mut self, c: RunControl) {
        match c.command {
            CONTROL_RESUME => self.hub().resume(c.step, c.dead, c.alive).expect("resume"),
            _ => self.hub().report_dead(c.dead).expect("dead"),
        }
    }
    fn statuses(&mut self) -> Vec<Status> {
        let mut out = Vec::new();
        self.hub().poll_status(&mut |s| out.push(*s)).expect("status");
        out
    }
}

/// A ring of four: 1–2–3–4–1, so agent 1 reads 2 and 4, and agent 3 does not read agent 1.
fn ring4() -> Topology {
    Topology { neighbours: vec![vec![2, 4], vec![1, 3], vec![2, 4], vec![3, 1]] }
}

/// Everything `t` has received by now, retried until `want` messages are in (a datagram or a
/// sample can take a moment to land) or a generous deadline passes.
fn collect(t: &mut dyn Transport, want: usize) -> Vec<Received> {
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        t.drain(&mut |m| {
            got.push(match m {
                Incoming::Measurement(m) => Received::Measurement(Box::new(*m)),
                Incoming::Share { from, share } => Received::Share(from, Box::new(*share)),
            })
        })
        .expect("drain");
        if got.len() >= want || Instant::now() > deadline {
            return got;
        }
        let _ = t.wait(Duration::from_millis(5));
    }
}

enum Received {
    Measurement(Box<Measurement>),
    Share(u32, Box<Share>),
}

fn measurement(run_id: u64, step: u64, readings: &[f64]) -> Measurement {
    Measurement::new(Header::new(run_id, PLANT_ID, step, step as f64 * 0.01), readings)
}

fn share(run_id: u64, from: u32, step: u64, values: &[f64]) -> Share {
    Share::new(Header::new(run_id, from, step, step as f64 * 0.01), &[f64::from(from), 0.5, -0.25], values)
}

/// Measurements reach only their agent, with every bit of the payload.
fn measurements_reach_only_their_agent(h: &mut dyn Harness) {
    let (mut plant, mut agents) = h.open(&ring4());
    h.grant_start();
    let odd = [f64::MIN_POSITIVE, -0.0, 1e300, std::f64::consts::PI];
    for i in 1..=4u32 {
        let readings: Vec<f64> = odd.iter().map(|x| x * f64::from(i)).collect();
        plant.send_measurement(i, &measurement(h.run_id(), 7, &readings)).unwrap();
    }
    for (i, a) in agents.iter_mut().enumerate() {
        let got = collect(a.as_mut(), 1);
        assert_eq!(got.len(), 1, "agent {}: one measurement, got {}", i + 1, got.len());
        let Received::Measurement(m) = &got[0] else { panic!("agent {}: not a measurement", i + 1) };
        assert_eq!(m.header.step, 7);
        let want: Vec<u64> = odd.iter().map(|x| (x * (i as f64 + 1.0)).to_bits()).collect();
        assert_eq!(m.readings().iter().map(|x| x.to_bits()).collect::<Vec<_>>(), want, "agent {}", i + 1);
    }
    assert!(collect(plant.as_mut(), 0).is_empty(), "the plant got its own measurements back");
}

/// A share reaches the plant and exactly its readers, in send order per sender.
fn shares_reach_the_plant_and_their_readers_in_order(h: &mut dyn Harness) {
    let topo = ring4();
    let (mut plant, mut agents) = h.open(&topo);
    h.grant_start();
    let values: Vec<f64> = (0..500).map(|k| (k as f64).sin() * 1e3).collect();
    for step in 0..3u64 {
        agents[0].send_share(&share(h.run_id(), 1, step, &values[..100 + step as usize])).unwrap();
    }
    let at_plant = collect(plant.as_mut(), 3);
    let steps: Vec<(u32, u64)> = at_plant
        .iter()
        .map(|r| match r {
            Received::Share(from, s) => (*from, s.header.step),
            Received::Measurement(_) => panic!("the plant got a measurement"),
        })
        .collect();
    assert_eq!(steps, [(1, 0), (1, 1), (1, 2)], "FIFO per sender, owner of the service as `from`");
    for reader in topo.readers_of(1) {
        let got = collect(agents[reader as usize - 1].as_mut(), 3);
        assert_eq!(got.len(), 3, "reader {reader}");
        let Received::Share(from, s) = &got[2] else { panic!("reader {reader}: not a share") };
        assert_eq!(*from, 1);
        assert_eq!(s.values().len(), 102);
        let want: Vec<u64> = values[..102].iter().map(|x| x.to_bits()).collect();
        assert_eq!(s.values().iter().map(|x| x.to_bits()).collect::<Vec<_>>(), want);
    }
    // Agent 3 is not a reader of agent 1.
    assert!(collect(agents[2].as_mut(), 0).is_empty(), "agent 3 got a share it does not read");
}

/// `drain` never blocks, and `wait` returns within its timeout when nothing comes.
fn drain_is_non_blocking_and_wait_is_bounded(h: &mut dyn Harness) {
    let (mut plant, mut agents) = h.open(&ring4());
    h.grant_start();
    let t0 = Instant::now();
    let mut n = 0;
    agents[1].drain(&mut |_| n += 1).unwrap();
    assert_eq!(n, 0);
    plant.wait(Duration::from_millis(50)).unwrap();
    let took = t0.elapsed();
    assert!(took < Duration::from_secs(5), "an empty drain and a 50 ms wait took {took:?}");
    // A message sent before the wait ends it early (or is simply there after it).
    plant.send_measurement(2, &measurement(h.run_id(), 1, &[1.0])).unwrap();
    let t1 = Instant::now();
    agents[1].wait(Duration::from_secs(5)).unwrap();
    assert!(t1.elapsed() < Duration::from_secs(5), "a pending message did not end the wait");
    assert_eq!(collect(agents[1].as_mut(), 1).len(), 1);
}

/// Stop and start requests reach every endpoint; resume and dead notices reach the plant.
fn run_control_reaches_every_process(h: &mut dyn Harness) {
    let (mut plant, mut agents) = h.open(&ring4());
    h.grant_start();
    let deadline = Instant::now() + Duration::from_secs(10);
    while !plant.start_granted() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(plant.start_granted(), "the plant never saw the start");
    assert!(!plant.stop_requested() && agents.iter_mut().all(|a| !a.stop_requested()));
    let mut dead = Roster::EMPTY;
    dead.set(3, true);
    h.send_control({
        let mut c = RunControl::new(CONTROL_DEAD, h.run_id());
        c.dead = dead;
        c
    });
    h.send_control({
        let mut c = RunControl::new(CONTROL_RESUME, h.run_id());
        (c.step, c.alive) = (42, dead);
        c
    });
    let mut events = Vec::new();
    while events.len() < 2 && Instant::now() < deadline {
        plant.control_events(&mut events);
        std::thread::sleep(Duration::from_millis(2));
    }
    let kinds: Vec<u32> = events.iter().map(|c| c.command).collect();
    assert_eq!(kinds, [CONTROL_DEAD, CONTROL_RESUME]);
    assert!(events[0].dead.contains(3) && !events[0].dead.contains(2));
    assert_eq!(events[1].step, 42);
    h.request_stop();
    while !(plant.stop_requested() && agents.iter_mut().all(|a| a.stop_requested())) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(plant.stop_requested(), "the plant never saw the stop");
    assert!(agents.iter_mut().all(|a| a.stop_requested()), "an agent never saw the stop");
}

/// A run-control notice ends the wait of a process whose data path says it is woken by run
/// control (iceoryx2: the orchestrator rings every doorbell), and `control_rung` reports it
/// before the port is read; with nothing new since, it says so. Every other data path always
/// says there may be something new, and its waits stay short.
fn a_control_notice_wakes_a_data_path_woken_by_control(h: &mut dyn Harness) {
    let (_plant, mut agents) = h.open(&ring4());
    h.grant_start();
    let a = agents[1].as_mut();
    let woken = a.woken_by_control();
    a.drain(&mut |_| {}).unwrap();
    assert!(a.control_rung(), "a fresh port has run control to read (the start)");
    assert_eq!(a.control_rung(), !woken, "nothing new since the last call");
    h.request_stop();
    let t0 = Instant::now();
    a.wait(if woken { Duration::from_secs(60) } else { Duration::from_millis(50) }).unwrap();
    assert!(t0.elapsed() < Duration::from_secs(20), "the stop did not end the wait: {:?}", t0.elapsed());
    a.drain(&mut |_| {}).unwrap();
    assert!(a.control_rung(), "the stop was not reported as new run control");
    let deadline = Instant::now() + Duration::from_secs(10);
    while !a.stop_requested() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(a.stop_requested());
}

/// Drain once each time `t` says it was rung ([`DataPath::rung`], what a spinning process looks
/// at before it drains again), never waiting (a wait that ends unrung makes iceoryx2's next drain
/// look at everything), until one message comes or a generous deadline passes.
fn drain_when_rung(t: &mut dyn Transport) -> Option<Received> {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        if t.rung() {
            let mut got = None;
            t.drain(&mut |m| {
                got.get_or_insert(match m {
                    Incoming::Measurement(m) => Received::Measurement(Box::new(*m)),
                    Incoming::Share { from, share } => Received::Share(from, Box::new(*share)),
                });
            })
            .expect("drain");
            if got.is_some() {
                return got;
            }
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    None
}

/// `rung` never hides a message: a neighbour's share, then the plant's measurement, each reach
/// an agent that drains only when it says it was rung — the measurement too, though the drain
/// before it was for a share (iceoryx2 reads its measurement subscriber only after the plant rang).
fn rung_never_hides_a_message(h: &mut dyn Harness) {
    let (mut plant, mut agents) = h.open(&ring4());
    h.grant_start();
    assert!(collect(agents[1].as_mut(), 0).is_empty());
    agents[0].send_share(&share(h.run_id(), 1, 0, &[1.0])).unwrap();
    let Some(Received::Share(1, _)) = drain_when_rung(agents[1].as_mut()) else {
        panic!("agent 2 did not get agent 1's share by draining when rung")
    };
    plant.send_measurement(2, &measurement(h.run_id(), 0, &[2.0])).unwrap();
    let Some(Received::Measurement(m)) = drain_when_rung(agents[1].as_mut()) else {
        panic!("agent 2 did not get its measurement by draining when rung")
    };
    assert_eq!(m.readings(), [2.0]);
}

/// Status reports reach the orchestrator's side.
fn status_reaches_the_orchestrator(h: &mut dyn Harness) {
    let (mut plant, _agents) = h.open(&ring4());
    let st = Status {
        version: cohort_wire::msg::SCHEMA_VERSION,
        sender: PLANT_ID,
        run_id: h.run_id(),
        kind: STATUS_PROGRESS,
        waiting_for: 0,
        step: 99,
        t_s: 0.99,
        build_hash: cohort_wire::build_id_hash(),
        detail: 0,
        _pad: 0,
        mac: [0; 2],
    };
    plant.report(&st);
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut got = Vec::new();
    while got.is_empty() && Instant::now() < deadline {
        got = h.statuses();
        std::thread::sleep(Duration::from_millis(2));
    }
    assert_eq!(got, [st]);
}

/// A share of another run and a damaged share, sent before a genuine one: the transport delivers
/// all three as they are, in order (it neither drops nor repairs, so every backend's receiver
/// counts the same), validation rejects the first two by reason and takes the third. With the
/// run's key, a share altered after sealing is rejected as `mac` (issue 18, finding 6).
fn foreign_and_damaged_messages_are_counted_and_the_genuine_one_still_arrives(h: &mut dyn Harness) {
    let (mut plant, mut agents) = h.open(&ring4());
    h.grant_start();
    let key = cohort_wire::auth::MacKey::from_bytes([9; 32]);
    let run = h.run_id();
    let mut foreign = share(run ^ 0xDEAD, 1, 3, &[1.0]);
    key.seal_share(&mut foreign);
    let mut damaged = share(run, 1, 3, &[1.0, 2.0]);
    key.seal_share(&mut damaged);
    damaged.values[1] = 866.0;
    let mut genuine = share(run, 1, 3, &[1.0, 2.0]);
    key.seal_share(&mut genuine);
    for s in [&foreign, &damaged, &genuine] {
        agents[0].send_share(s).unwrap();
    }
    let got = collect(plant.as_mut(), 3);
    assert_eq!(got.len(), 3, "every message is delivered, none is lost or merged");
    let mut counts = RejectCounts::default();
    let mut accepted = Vec::new();
    let e = Expect { run_id: run, sender: 1, step_min: 3, step_max: 3, key: Some(key) };
    for r in &got {
        let Received::Share(from, s) = r else { panic!("the plant got a measurement") };
        assert_eq!(*from, 1);
        match validate_share(s, &e) {
            Ok(()) => accepted.push(s.values().to_vec()),
            Err(r) => counts.add(r),
        }
    }
    assert_eq!((counts.get(Rejection::RunId), counts.get(Rejection::Mac), counts.total()), (1, 1, 2));
    assert_eq!(accepted, [vec![1.0, 2.0]], "the genuine share, after the bad ones");
}

macro_rules! conformance {
    ($backend:ident, $make:expr) => {
        mod $backend {
            use super::*;
            #[test]
            fn measurements_reach_only_their_agent() {
                super::measurements_reach_only_their_agent(&mut $make);
            }
            #[test]
            fn shares_reach_the_plant_and_their_readers_in_order() {
                super::shares_reach_the_plant_and_their_readers_in_order(&mut $make);
            }
            #[test]
            fn drain_is_non_blocking_and_wait_is_bounded() {
                super::drain_is_non_blocking_and_wait_is_bounded(&mut $make);
            }
            #[test]
            fn run_control_reaches_every_process() {
                super::run_control_reaches_every_process(&mut $make);
            }
            #[test]
            fn a_control_notice_wakes_a_data_path_woken_by_control() {
                super::a_control_notice_wakes_a_data_path_woken_by_control(&mut $make);
            }
            #[test]
            fn rung_never_hides_a_message() {
                super::rung_never_hides_a_message(&mut $make);
            }
            #[test]
            fn status_reaches_the_orchestrator() {
                super::status_reaches_the_orchestrator(&mut $make);
            }
            #[test]
            fn foreign_and_damaged_messages_are_counted_and_the_genuine_one_still_arrives() {
                super::foreign_and_damaged_messages_are_counted_and_the_genuine_one_still_arrives(&mut $make);
            }
        }
    };
}

conformance!(memory, Memory::new());
conformance!(iceoryx2, Iox::new(false));
conformance!(udp, Iox::new(true));
conformance!(zenoh_tcp, Zenoh::new());
