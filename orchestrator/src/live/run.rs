//! One run's live view: a thread of the orchestrator that, every [`POLL`] of wall time, reads what
//! the run's processes appended to their telemetry journals (decimated to `--live-rate` messages
//! per second of sim time), the supervisor's timeline events and the progress hook's step, and
//! publishes them on the server. It only reads: the lockstep processes never wait for it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cohort_host::SceneBody;
use cohort_runtime::paper::Setup;
use cohort_runtime::record::{RunDirs, TimelineEvent};
use foxglove::messages::{Log, SceneUpdate, Timestamp, log};
use foxglove::{Encode, RawChannel, Schema};

use super::scene::{self, Frame};
use super::server::{self, STEP, Server, Subscription};
use cohort_runtime::tail::{Journal, journals_in};

/// How often the thread looks for new rows, events and progress (wall time).
const POLL: Duration = Duration::from_millis(50);
/// How often the thread asks the other hosts' daemons for their processes' rows (wall time), and
/// how long it waits for an answer.
const REMOTE_POLL: Duration = Duration::from_millis(200);
const REMOTE_TIMEOUT: Duration = Duration::from_secs(1);
/// Decimated rows kept per process for the scene (the agents' rows of a step may come a journal
/// batch later than the plant's).
const KEEP_ROWS: usize = 64;

/// The live view of a run, until [`LiveRun::stop`].
pub struct LiveRun {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// A message logged to every subscriber: (step, bytes, its number from [`server::log`], 0 when
/// its channel was not made).
type Sent = (u64, Vec<u8>, u64);

/// Rows of one process: (step, the values after `k`).
type Rows = Vec<(u64, Vec<f64>)>;

/// A followed process: its journal (none for a process on another host, whose rows its daemon
/// sends), columns, channel, latest message and decimated rows by step.
struct Proc {
    journal: Option<Journal>,
    columns: Vec<String>,
    channel: Option<Arc<RawChannel>>,
    latest: Option<Sent>,
    rows: BTreeMap<u64, Vec<f64>>,
    /// Rows it may still publish now, and when that was reckoned (see [`View::read_rows`]).
    allowance: f64,
    refilled: Instant,
}

/// The state the thread keeps between polls.
struct View {
    server: &'static Server,
    setup: Setup,
    telemetry: PathBuf,
    every: u64,
    dt_ns: f64,
    bodies: Vec<SceneBody>,
    procs: BTreeMap<String, Proc>,
    events: Receiver<TimelineEvent>,
    dead: BTreeSet<u32>,
    log: Vec<Sent>,
    scene: Option<Sent>,
    progress: Option<Sent>,
    last_step: u64,
    started: Instant,
    last_remote: Option<Instant>,
}

impl LiveRun {
    /// Start the live view of the run of `setup` in `dirs`, when `--live` started a server.
    pub fn start(setup: &Setup, dirs: &RunDirs) -> Option<LiveRun> {
        let server = server::get()?;
        let setup = setup.clone();
        let (tx, events) = channel();
        cohort_supervisor::observe::watch(Some(tx));
        STEP.store(0, Ordering::Relaxed);
        let dt_s = setup.scenario.dt_s;
        let every = ((1.0 / (server.options.rate_hz * dt_s)).round() as u64).max(1);
        let bodies = cohort_registry::hooks_of(&setup).iter().flat_map(|(_, h)| h.scene(&setup)).collect();
        let mut view = View {
            server,
            telemetry: dirs.telemetry(),
            every,
            dt_ns: dt_s * 1e9,
            bodies,
            procs: BTreeMap::new(),
            events,
            dead: BTreeSet::new(),
            log: Vec::new(),
            scene: None,
            progress: None,
            last_step: u64::MAX,
            started: Instant::now(),
            last_remote: None,
            setup,
        };
        let stop = Arc::new(AtomicBool::new(false));
        let stopping = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("live".into())
            .spawn(move || {
                view.roster_start();
                loop {
                    let last = stopping.load(Ordering::Relaxed);
                    view.poll();
                    if last {
                        return;
                    }
                    std::thread::sleep(POLL);
                }
            })
            .ok();
        Some(LiveRun { stop, thread })
    }

    /// Publish what the run wrote last, then end the thread.
    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        cohort_supervisor::observe::watch(None);
    }
}

/// A JSON schema of a telemetry row: `k`, then every column as a number with its unit. A NaN or
/// infinite value is sent as `null`; the field is still typed `number`, not `["number", "null"]`,
/// because Lichtblick (the open-source Foxglove fork) refuses a schema with a type list and then
/// plots none of the topic's fields.
fn row_schema(process: &str, columns: &[String]) -> Schema {
    let mut props = serde_json::Map::new();
    props.insert("k".into(), serde_json::json!({"type": "integer", "description": "step"}));
    for c in &columns[1..] {
        let mut p = serde_json::json!({"type": "number"});
        if let Some(u) = cohort_runtime::units::unit_of(c) {
            p["description"] = u.into();
        }
        props.insert(c.clone(), p);
    }
    let schema = serde_json::json!({
        "title": format!("cohort telemetry {process}"),
        "type": "object",
        "properties": props,
    });
    Schema::new(format!("cohort.telemetry.{process}"), "jsonschema", serde_json::to_vec(&schema).unwrap_or_default())
}

fn row_json(columns: &[String], k: u64, values: &[f64]) -> Vec<u8> {
    let mut m = serde_json::Map::new();
    m.insert("k".into(), k.into());
    for (c, v) in columns[1..].iter().zip(values) {
        // A non-finite value is null (JSON has no NaN).
        m.insert(c.clone(), serde_json::Number::from_f64(*v).map_or(serde_json::Value::Null, Into::into));
    }
    serde_json::to_vec(&m).unwrap_or_default()
}

fn encode<T: Encode>(msg: &T) -> Vec<u8> {
    let mut buf = Vec::new();
    let _ = msg.encode(&mut buf);
    buf
}

fn typed_channel<T: Encode>(server: &Server, topic: &str) -> Option<Arc<RawChannel>> {
    server.channel(topic, &T::get_message_encoding(), T::get_schema()?)
}

fn json_channel(server: &Server, topic: &str, title: &str, properties: serde_json::Value) -> Option<Arc<RawChannel>> {
    let schema = serde_json::json!({"title": title, "type": "object", "properties": properties});
    server.channel(topic, "json", Schema::new(title, "jsonschema", serde_json::to_vec(&schema).unwrap_or_default()))
}

impl View {
    fn t_ns(&self, step: u64) -> u64 {
        (step as f64 * self.dt_ns).round() as u64
    }

    fn poll(&mut self) {
        // A new subscriber gets the latest state it has not had (`Subscription::logged`), before
        // this poll publishes more, which reaches it anyway.
        for s in &self.server.take_subscriptions() {
            self.send_latest(s);
        }
        self.follow_new_journals();
        self.read_rows();
        self.timeline();
        self.progress();
    }

    /// A client that just subscribed to a topic gets its latest state (the whole log for
    /// `/roster`), and no other client gets it again.
    fn send_latest(&self, s: &Subscription) {
        let latest = |m: &Option<Sent>| m.iter().cloned().collect::<Vec<_>>();
        let (channel, messages) = match s.topic.as_str() {
            "/scene" => (typed_channel::<SceneUpdate>(self.server, "/scene"), latest(&self.scene)),
            "/roster" => (typed_channel::<Log>(self.server, "/roster"), self.log.clone()),
            "/progress" => (self.server.existing("/progress"), latest(&self.progress)),
            topic => {
                let p = topic.strip_prefix("/telemetry/").and_then(|name| self.procs.get(name));
                (p.and_then(|p| p.channel.clone()), p.map(|p| latest(&p.latest)).unwrap_or_default())
            }
        };
        if let Some(c) = channel {
            for (k, bytes, _) in messages.iter().filter(|m| m.2 <= s.logged) {
                server::log_to(&c, bytes, self.t_ns(*k), s.sink);
            }
        }
    }

    /// Start following every journal that appeared in `telemetry/` (one per process), but for a
    /// process of another host (its journal arrives here only when the run ends).
    fn follow_new_journals(&mut self) {
        for (name, path) in journals_in(&self.telemetry) {
            let p = self.procs.entry(name).or_insert_with(Proc::new);
            if p.journal.is_none() && p.columns.is_empty() {
                p.journal = Some(Journal::new(&path));
            }
        }
    }

    /// The rows every process appended since the last poll (decimated): a local one's from its
    /// journal, another host's from its daemon (every [`REMOTE_POLL`]).
    fn new_rows(&mut self) -> Vec<(String, Rows)> {
        let every = self.every;
        let mut out: Vec<(String, Rows)> = Vec::new();
        for (name, p) in &mut self.procs {
            if let Some(j) = p.journal.as_mut() {
                let rows = j.poll(|k| k % every == 0);
                if p.columns.is_empty() {
                    p.columns = j.columns().to_vec();
                }
                out.push((name.clone(), rows));
            }
        }
        if self.last_remote.is_none_or(|t| t.elapsed() >= REMOTE_POLL) {
            self.last_remote = Some(Instant::now());
            let max_rows = self.server.options.rate_hz.max(1.0).ceil() as usize;
            let remote = cohort_supervisor::observe::remote_rows(every, max_rows, REMOTE_TIMEOUT);
            for r in remote {
                let p = self.procs.entry(r.proc_name.clone()).or_insert_with(Proc::new);
                // Its rows come from its daemon: a journal of the same name here is the copy
                // fetched at the end, already shown.
                p.journal = None;
                p.columns.clone_from(&r.columns);
                out.push((r.proc_name.clone(), r.values()));
            }
        }
        out
    }

    /// New decimated rows of every process, each published as `/telemetry/<proc>`; a scene for
    /// each new plant row.
    fn read_rows(&mut self) {
        let rate_hz = self.server.options.rate_hz;
        let mut plant_steps = Vec::new();
        let dt_ns = self.dt_ns;
        let t = move |k: u64| (k as f64 * dt_ns).round() as u64;
        for (name, mut rows) in self.new_rows() {
            let p = self.procs.get_mut(&name).expect("listed");
            // At most `rate_hz` rows per second of wall time (a token bucket holding one second's
            // worth, so a real-time run's journal bursts pass whole): a fast run shows its newest
            // rows at wall speed instead of flooding the clients and the cores the lockstep uses.
            // Per process: a remote one's rows come every REMOTE_POLL, a local one's every POLL.
            p.allowance = (p.allowance + p.refilled.elapsed().as_secs_f64() * rate_hz).min(rate_hz.max(1.0));
            p.refilled = Instant::now();
            let n = rows.len().min(p.allowance as usize);
            p.allowance -= n as f64;
            let rows = rows.split_off(rows.len() - n);
            if p.channel.is_none() && !p.columns.is_empty() {
                p.channel = self.server.channel(&format!("/telemetry/{name}"), "json", row_schema(&name, &p.columns));
            }
            for (k, values) in rows {
                // Rows of a step already shown (a remote process's, asked again) are not sent twice.
                if p.latest.as_ref().is_some_and(|(last, _, _)| k <= *last) {
                    continue;
                }
                let bytes = row_json(&p.columns, k, &values);
                let n = p.channel.as_ref().map_or(0, |c| server::log(c, &bytes, t(k)));
                p.latest = Some((k, bytes, n));
                p.rows.insert(k, values);
                if name == "plant" {
                    plant_steps.push(k);
                }
            }
            while p.rows.len() > KEEP_ROWS {
                p.rows.pop_first();
            }
        }
        for k in plant_steps {
            self.publish_scene(k);
        }
    }

    /// The scene at step `k`: the plant's row of `k`, each other process's row of `k` or its
    /// latest before it.
    fn publish_scene(&mut self, k: u64) {
        if self.bodies.is_empty() {
            return;
        }
        let row = |proc: &str| {
            let p = self.procs.get(proc)?;
            let (_, values) = p.rows.range(..=k).next_back()?;
            Some((p.columns.as_slice(), values.as_slice()))
        };
        let truth = self.bodies.iter().map(|b| scene::position(&b.truth, &row)).collect();
        let estimate = self
            .bodies
            .iter()
            .map(|b| {
                (!b.estimate.is_empty())
                    .then(|| b.estimate.iter().map(|p| scene::position(p, &row)))
                    .and_then(|ps| ps.sum_positions())
            })
            .collect();
        let t_s = k as f64 * self.setup.scenario.dt_s;
        let topo = self.setup.topology();
        let links = (1..=self.setup.n_agents())
            .flat_map(|to| topo.neighbours_of(to).iter().map(move |&from| (from, to)))
            .map(|(from, to)| (from, to, scene::link_state(&self.setup, &self.dead, from, to, t_s)))
            .collect();
        let frame = Frame { t_ns: self.t_ns(k), bodies: &self.bodies, truth, estimate, links, dead: &self.dead };
        let bytes = encode(&scene::update(&frame));
        let n =
            typed_channel::<SceneUpdate>(self.server, "/scene").map_or(0, |c| server::log(&c, &bytes, self.t_ns(k)));
        self.scene = Some((k, bytes, n));
    }

    /// The roster at the start, on `/roster`.
    fn roster_start(&mut self) {
        let n = self.setup.n_agents();
        let text = format!(
            "run of {} started: plant and {n} agents, all on the roster; {} fault(s) planned",
            self.setup.scenario.name,
            self.setup.faults.len()
        );
        self.log_line(0, log::Level::Info, "roster", text);
    }

    fn log_line(&mut self, step: u64, level: log::Level, name: &str, message: String) {
        let t = self.t_ns(step);
        let msg = Log {
            timestamp: Some(Timestamp::new((t / 1_000_000_000) as u32, (t % 1_000_000_000) as u32)),
            level: level as i32,
            message,
            name: name.into(),
            file: String::new(),
            line: 0,
        };
        let bytes = encode(&msg);
        let n = typed_channel::<Log>(self.server, "/roster").map_or(0, |c| server::log(&c, &bytes, t));
        self.log.push((step, bytes, n));
    }

    /// Every timeline event since the last poll on `/roster` (and the roster the links show).
    fn timeline(&mut self) {
        let events: Vec<TimelineEvent> = self.events.try_iter().collect();
        for e in events {
            match e.event.as_str() {
                "dead" | "died" | "kill" => {
                    self.dead.insert(e.agent);
                }
                "alive" | "relaunch" | "thaw" => {
                    self.dead.remove(&e.agent);
                }
                _ => {}
            }
            let level = if matches!(e.event.as_str(), "died" | "restore-failed") {
                log::Level::Error
            } else {
                log::Level::Warning
            };
            let text = format!("t = {:.2} s, step {}: agent {} {}: {}", e.t_s, e.step, e.agent, e.event, e.detail);
            self.log_line(e.step, level, &format!("agent-{}", e.agent), text);
        }
    }

    /// `/progress`: step, steps of the run, sim time, steps/s since the start, clients.
    fn progress(&mut self) {
        let step = STEP.load(Ordering::Relaxed);
        if step == self.last_step {
            return;
        }
        self.last_step = step;
        let wall_s = self.started.elapsed().as_secs_f64();
        let props = serde_json::json!({
            "step": {"type": "integer"}, "n_steps": {"type": "integer"},
            "t_s": {"type": "number", "description": "s"}, "wall_s": {"type": "number", "description": "s"},
            "steps_per_s": {"type": "number"}, "clients": {"type": "integer"},
        });
        let msg = serde_json::json!({
            "step": step,
            "n_steps": self.setup.n_steps(),
            "t_s": step as f64 * self.setup.scenario.dt_s,
            "wall_s": wall_s,
            "steps_per_s": step as f64 / wall_s.max(1e-9),
            "clients": self.server.clients(),
        });
        let bytes = serde_json::to_vec(&msg).unwrap_or_default();
        let n = json_channel(self.server, "/progress", "cohort.progress", props)
            .map_or(0, |c| server::log(&c, &bytes, self.t_ns(step)));
        self.progress = Some((step, bytes, n));
    }
}

impl Proc {
    fn new() -> Self {
        Proc {
            journal: None,
            columns: Vec::new(),
            channel: None,
            latest: None,
            rows: BTreeMap::new(),
            allowance: 1.0,
            refilled: Instant::now(),
        }
    }
}

/// Sum of positions, none when any is missing.
trait SumPositions {
    fn sum_positions(self) -> Option<[f64; 3]>;
}

impl<I: Iterator<Item = Option<[f64; 3]>>> SumPositions for I {
    fn sum_positions(mut self) -> Option<[f64; 3]> {
        self.try_fold([0.0; 3], |a, p| {
            let p = p?;
            Some([a[0] + p[0], a[1] + p[1], a[2] + p[2]])
        })
    }
}
