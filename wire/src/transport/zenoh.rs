//! zenoh transport (`run.transport = "zenoh"`): the same messages and validation as iceoryx2,
//! carried by zenoh publish–subscribe over TCP, so the processes of one run may sit on several
//! machines (multi-host runs, see the README's "Multi-host" section).
//!
//! Key expressions of one run, all under `cohort/<run id>/`, so concurrent runs never see each
//! other's messages:
//! - `d/<receiver>/<sender>`: the data path, one key per (receiver, sender) pair (`d/agent-3/plant`
//!   carries agent 3's measurements, `d/plant/agent-3` its shares to the plant, `d/agent-2/agent-3`
//!   to its reader 2). A process subscribes once to `d/<me>/*`; the last chunk of a sample's key
//!   names its sender, which the driver checks against the header (as the UDP baseline checks
//!   the source address). One key per receiver also makes readiness exact: a publisher with a
//!   matching subscriber has a route to exactly the process it serves.
//! - `control`: [`RunControl`], orchestrator → every process.
//! - `status`: [`Status`], every process → orchestrator.
//! - `orchestrator`: the orchestrator's liveliness token (host daemons kill a run's processes
//!   when it disappears).
//!
//! Sessions are zenoh peers with multicast scouting off: the orchestrator's session listens on an
//! explicit endpoint, every plant and agent connects to it and listens on its own host's address,
//! and zenoh's gossip (one hop, through the orchestrator) makes them connect to each other
//! directly. Peers do not route for others, so data always travels on a direct TCP connection
//! between the two processes. A process reports ready only once each of its publishers has a
//! matching subscriber ([`ZenohPending::ready`]); the orchestrator grants the start only after
//! every process has, so step 0's first message always finds its reader.
//!
//! Sessions use zenoh's default unicast transport (QoS on, a TX task that batches), not its
//! `lowlatency` transport. With `lowlatency` a session writes on the socket from the thread that
//! sends, and zenoh 1.10.2 then deadlocks under start-up churn: an RX thread handling a gossip
//! link-state message holds the routing locks while it blocks writing to another peer, and the
//! network runtime's worker that would let that write finish waits for the same locks (thread
//! dumps of hung agents and of the orchestrator itself, stuck in `put`). A 20-agent ring on one
//! host failed to start in 3 of 6 launches that way; with the default transport 8 of 8 started.
//! The default transport costs a hand-off to the TX task: a 256-byte round trip on one host was
//! 45–69 µs p50 against 35–36 µs with `lowlatency` (two interleaved `orchestrator bench` runs).
//!
//! Payloads are the `#[repr(C)]` bytes of the messages, as with UDP. Publishers block rather than
//! drop when zenoh's queue is full (`CongestionControl::Block`): lockstep never loses a message
//! to congestion, only to a lost process.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use ::zenoh::handlers::FifoChannelHandler;
use ::zenoh::liveliness::LivelinessToken;
use ::zenoh::pubsub::{Publisher, Subscriber};
use ::zenoh::qos::CongestionControl;
use ::zenoh::sample::Sample;
use ::zenoh::{Config, Session, Wait};

use super::{
    ControlHub, DataPath, Incoming, Proc, RunControlPort, Split, Topology, TransportError, bytes_of, monotonic_ns,
    read_payload,
};
use crate::msg::{
    CONTROL_DEAD, CONTROL_RESUME, CONTROL_START, CONTROL_STOP, Measurement, PLANT_ID, Roster, RunControl,
    SCHEMA_VERSION, Share, Status,
};

/// Depth of a process's inbox channel (samples zenoh has received and the driver not yet
/// drained). In lockstep a process has at most one message per peer per step in flight.
const INBOX_DEPTH: usize = 1024;
/// Largest payload Cohort puts in one zenoh message (file pieces of the host daemon are cut
/// well below it; every step message is far smaller).
pub const MAX_MESSAGE_BYTES: usize = 60 * 1024;

pub(crate) fn err(what: impl std::fmt::Display) -> impl FnOnce(::zenoh::Error) -> TransportError {
    move |e| TransportError::Other(format!("zenoh {what}: {e}"))
}

/// The configuration every session of Cohort uses: a peer, no multicast scouting (endpoints are
/// explicit), the default transport (not `lowlatency`: see the module docs). `listen` and
/// `connect` are zenoh endpoints (`tcp/192.0.2.2:7447`).
pub fn session_config(listen: &[String], connect: &[String]) -> Result<Config, TransportError> {
    let mut c = Config::default();
    let json = |v: &[String]| serde_like_list(v);
    for (key, value) in [
        ("mode", "\"peer\"".to_string()),
        ("scouting/multicast/enabled", "false".to_string()),
        ("listen/endpoints", json(listen)),
        ("connect/endpoints", json(connect)),
        ("transport/unicast/lowlatency", "false".to_string()),
        // Of two peers that learn of each other by gossip, only the one with the greater id
        // connects: with both connecting at once ("always"), a pair was seen to end up with no
        // link at all now and then (start-up timed out with a publisher unmatched).
        (
            "scouting/gossip/autoconnect_strategy",
            "{ peer: { to_router: \"always\", to_peer: \"greater-zid\" } }".to_string(),
        ),
    ] {
        c.insert_json5(key, &value).map_err(|e| TransportError::Other(format!("zenoh config {key} = {value}: {e}")))?;
    }
    // TLS and user/password authentication, the same for every session of the run.
    let security = super::zenoh_security::current().map_err(|e| TransportError::Other(e.to_string()))?;
    for (key, value) in security.config_entries() {
        c.insert_json5(key, &value).map_err(|e| TransportError::Other(format!("zenoh config {key}: {e}")))?;
    }
    Ok(c)
}

/// A JSON list of strings (endpoints hold no quotes or backslashes; any that would are escaped).
fn serde_like_list(v: &[String]) -> String {
    let items: Vec<String> =
        v.iter().map(|s| format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))).collect();
    format!("[{}]", items.join(","))
}

/// Open a session with [`session_config`].
pub fn open_session(listen: &[String], connect: &[String]) -> Result<Session, TransportError> {
    ::zenoh::open(session_config(listen, connect)?).wait().map_err(err("open session"))
}

/// `tcp/<ip>:<port>` (IPv6 in brackets), or `tls/…` when this process's sessions use TLS
/// ([`super::zenoh_security`]).
pub fn tcp_endpoint(ip: std::net::IpAddr, port: u16) -> String {
    let scheme = super::zenoh_security::current().map(|s| s.scheme()).unwrap_or("tcp");
    match ip {
        std::net::IpAddr::V4(a) => format!("{scheme}/{a}:{port}"),
        std::net::IpAddr::V6(a) => format!("{scheme}/[{a}]:{port}"),
    }
}

/// Open a session listening on a free TCP port of each address in `ips`, connecting to
/// `connect`; the session and the endpoints it listens on. zenoh's stable API does not say which
/// port a `:0` endpoint got, so the ports are picked here (bound and released by the kernel's
/// choice) and the open retried should another process take one in between.
pub fn open_on_free_ports(
    ips: &[std::net::IpAddr],
    connect: &[String],
) -> Result<(Session, Vec<String>), TransportError> {
    let mut last = None;
    for _ in 0..8 {
        let listen = ips
            .iter()
            .map(|&ip| {
                let l = std::net::TcpListener::bind((ip, 0))
                    .map_err(|e| TransportError::Other(format!("zenoh: no free port on {ip}: {e}")))?;
                let port = l.local_addr().map_err(|e| TransportError::Other(format!("zenoh: {ip}: {e}")))?.port();
                Ok(tcp_endpoint(ip, port))
            })
            .collect::<Result<Vec<_>, TransportError>>()?;
        match open_session(&listen, connect) {
            Ok(s) => return Ok((s, listen)),
            Err(e) => last = Some(e),
        }
    }
    Err(last.unwrap_or_else(|| TransportError::Other("zenoh: cannot open a session".into())))
}

/// The names of one run's key expressions, and its MAC key when `run.authenticate` is on.
#[derive(Debug, Clone)]
pub struct ZenohRun {
    pub run_id: u64,
    pub key: Option<crate::auth::MacKey>,
}

impl ZenohRun {
    pub fn new(run_id: u64) -> Self {
        Self { run_id, key: None }
    }
    pub fn with_key(mut self, key: Option<crate::auth::MacKey>) -> Self {
        self.key = key;
        self
    }
    /// `cohort/<run id>`: every key of the run starts with it.
    pub fn prefix(&self) -> String {
        format!("cohort/{:016x}", self.run_id)
    }
    fn data_key(&self, to: Proc, from: Proc) -> String {
        format!("{}/d/{}/{}", self.prefix(), to.name(), from.name())
    }
    fn inbox_key(&self, me: Proc) -> String {
        format!("{}/d/{}/*", self.prefix(), me.name())
    }
    pub(crate) fn control_key(&self) -> String {
        format!("{}/control", self.prefix())
    }
    pub(crate) fn status_key(&self) -> String {
        format!("{}/status", self.prefix())
    }
    /// The orchestrator's liveliness token of this run.
    pub fn orchestrator_token(&self) -> String {
        format!("{}/orchestrator", self.prefix())
    }
}

/// The sender a data key names in its last chunk: `plant` or `agent-<id>`; anything else is no
/// process of ours (an id no agent has, which the driver rejects and counts).
fn sender_of(key: &str) -> u32 {
    match key.rsplit('/').next() {
        Some("plant") => PLANT_ID,
        Some(last) => {
            last.strip_prefix("agent-").and_then(|i| i.parse::<u32>().ok()).filter(|&i| i > 0).unwrap_or(u32::MAX)
        }
        None => u32::MAX,
    }
}

pub(crate) fn publisher(session: &Session, key: String) -> Result<Publisher<'static>, TransportError> {
    session
        .declare_publisher(key.clone())
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(err(format!("publisher {key}")))
}

pub(crate) fn subscriber(
    session: &Session,
    key: String,
) -> Result<Subscriber<FifoChannelHandler<Sample>>, TransportError> {
    session
        .declare_subscriber(key.clone())
        .with(::zenoh::handlers::FifoChannel::new(INBOX_DEPTH))
        .wait()
        .map_err(err(format!("subscriber {key}")))
}

/// Whether `p` has a matching subscriber now (a failed query counts as not yet).
pub fn matched(p: &Publisher<'_>) -> bool {
    p.matching_status().wait().is_ok_and(|m| m.matching())
}

fn put<T: Copy>(p: &Publisher<'static>, msg: &T) -> Result<(), TransportError> {
    p.put(bytes_of(msg).to_vec()).wait().map_err(err(format!("put {}", p.key_expr())))
}

/// The data path of one plant or agent process over zenoh.
pub struct ZenohData {
    me: Proc,
    /// Plant: agent i's publisher at index i − 1. Agent: the plant's first, then each reader's.
    pubs: Vec<Publisher<'static>>,
    inbox: Subscriber<FifoChannelHandler<Sample>>,
    /// Samples taken off the channel by `wait`, not yet drained.
    pending: VecDeque<Sample>,
}

/// A process's run-control ports over zenoh; it owns the session, so it is dropped last.
pub struct ZenohControl {
    control: Subscriber<FifoChannelHandler<Sample>>,
    status: Publisher<'static>,
    run_id: u64,
    key: Option<crate::auth::MacKey>,
    stop: bool,
    started: bool,
    events: Vec<RunControl>,
    session: Session,
}

/// One plant or agent process's zenoh endpoint.
pub type ZenohTransport = Split<ZenohData, ZenohControl>;

/// An endpoint whose publishers and subscribers are declared but whose peers may not be
/// connected yet (see [`ZenohPending::ready`]).
pub struct ZenohPending {
    t: ZenohTransport,
}

impl ZenohData {
    /// Open a session (listening on `listen`, connecting to `connect`, the orchestrator's
    /// endpoint) and declare this process's publishers and subscribers.
    pub fn declare(
        run: &ZenohRun,
        topo: &Topology,
        me: Proc,
        listen: &[String],
        connect: &[String],
    ) -> Result<ZenohPending, TransportError> {
        let session = open_session(listen, connect)?;
        Self::declare_on(run, topo, me, session)
    }

    /// [`ZenohData::declare`] on a session already open.
    pub fn declare_on(
        run: &ZenohRun,
        topo: &Topology,
        me: Proc,
        session: Session,
    ) -> Result<ZenohPending, TransportError> {
        let targets: Vec<Proc> = match me {
            Proc::Plant => (1..=topo.n_agents()).map(Proc::Agent).collect(),
            Proc::Agent(i) => {
                std::iter::once(Proc::Plant).chain(topo.readers_of(i).into_iter().map(Proc::Agent)).collect()
            }
        };
        let pubs =
            targets.iter().map(|&to| publisher(&session, run.data_key(to, me))).collect::<Result<Vec<_>, _>>()?;
        let inbox = subscriber(&session, run.inbox_key(me))?;
        let control = ZenohControl {
            control: subscriber(&session, run.control_key())?,
            status: publisher(&session, run.status_key())?,
            run_id: run.run_id,
            key: run.key,
            stop: false,
            started: false,
            events: Vec::new(),
            session,
        };
        Ok(ZenohPending { t: Split { data: Self { me, pubs, inbox, pending: VecDeque::new() }, control } })
    }
}

impl ZenohPending {
    /// Wait (up to `timeout`) until every publisher of this process has a matching subscriber —
    /// its reader's, reached over a direct connection — and the status publisher the
    /// orchestrator's.
    pub fn ready(self, timeout: Duration) -> Result<ZenohTransport, TransportError> {
        self.ready_unless(timeout, &std::sync::atomic::AtomicBool::new(false))
    }

    /// [`Self::ready`], or [`TransportError::Stopped`] as soon as `stop` is set (a SIGTERM's
    /// flag): a process whose peers never come must still end at once when told to.
    pub fn ready_unless(
        self,
        timeout: Duration,
        stop: &std::sync::atomic::AtomicBool,
    ) -> Result<ZenohTransport, TransportError> {
        let started = Instant::now();
        loop {
            if stop.load(std::sync::atomic::Ordering::SeqCst) {
                return Err(TransportError::Stopped(format!("{} waited for its zenoh peers", self.t.data.me.name())));
            }
            let unmatched: Vec<String> = self
                .t
                .data
                .pubs
                .iter()
                .chain(std::iter::once(&self.t.control.status))
                .filter(|p| !matched(p))
                .map(|p| p.key_expr().to_string())
                .collect();
            if unmatched.is_empty() {
                return Ok(self.t);
            }
            if started.elapsed() > timeout {
                return Err(TransportError::Other(format!(
                    "zenoh: {} not connected after {:.0} s: no subscriber reached for {}",
                    self.t.data.me.name(),
                    timeout.as_secs_f64(),
                    unmatched.join(", ")
                )));
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

impl DataPath for ZenohData {
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError> {
        let p = match self.me {
            Proc::Plant => (to as usize).checked_sub(1).and_then(|i| self.pubs.get(i)),
            Proc::Agent(_) => None,
        };
        let Some(p) = p else {
            return Err(TransportError::Other(format!("{} cannot send a measurement to agent {to}", self.me.name())));
        };
        let mut m = *m;
        m.header.sent_wall_ns = monotonic_ns();
        put(p, &m)
    }

    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        if self.me == Proc::Plant {
            return Err(TransportError::Other("the plant has no share to send".into()));
        }
        let mut s = *s;
        s.header.sent_wall_ns = monotonic_ns();
        // One encoding, handed to every reader's publisher (zenoh shares the buffer).
        let bytes = ::zenoh::bytes::ZBytes::from(bytes_of(&s).to_vec());
        for p in &self.pubs {
            p.put(bytes.clone()).wait().map_err(err(format!("put {}", p.key_expr())))?;
        }
        Ok(())
    }

    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        while let Ok(Some(s)) = self.inbox.try_recv() {
            self.pending.push_back(s);
        }
        for sample in self.pending.drain(..) {
            let from = sender_of(sample.key_expr().as_str());
            let bytes = sample.payload().to_bytes();
            if bytes.len() == std::mem::size_of::<Measurement>() && from == PLANT_ID {
                let m: Measurement = read_payload(&bytes);
                f(Incoming::Measurement(&m));
            } else if bytes.len() == std::mem::size_of::<Share>() {
                let s: Share = read_payload(&bytes);
                f(Incoming::Share { from, share: &s });
            }
            // Any other size is not one of our payloads: there is nothing to count it as.
        }
        Ok(())
    }

    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        if !self.pending.is_empty() {
            return Ok(());
        }
        match self.inbox.recv_timeout(timeout) {
            Ok(Some(s)) => self.pending.push_back(s),
            Ok(None) => {}
            Err(e) => return Err(TransportError::Other(format!("zenoh inbox: {e}"))),
        }
        Ok(())
    }
}

impl ZenohControl {
    fn poll(&mut self) {
        while let Ok(Some(sample)) = self.control.try_recv() {
            let bytes = sample.payload().to_bytes();
            if bytes.len() != std::mem::size_of::<RunControl>() {
                continue;
            }
            let c: RunControl = read_payload(&bytes);
            let tag_ok = self.key.as_ref().is_none_or(|k| k.check_control(&c));
            if c.version == SCHEMA_VERSION && c.run_id == self.run_id && tag_ok {
                match c.command {
                    CONTROL_STOP => self.stop = true,
                    CONTROL_START => self.started = true,
                    CONTROL_RESUME | CONTROL_DEAD => self.events.push(c),
                    _ => {}
                }
            }
        }
    }
}

impl RunControlPort for ZenohControl {
    /// Best effort, like every transport's status.
    fn report(&mut self, s: &Status) {
        let mut s = *s;
        if let Some(k) = &self.key {
            k.seal_status(&mut s);
        }
        let _ = put(&self.status, &s);
    }
    fn stop_requested(&mut self) -> bool {
        if !self.stop {
            self.poll();
        }
        self.stop
    }
    fn start_granted(&mut self) -> bool {
        if !self.started {
            self.poll();
        }
        self.started
    }
    fn control_events(&mut self, out: &mut Vec<RunControl>) {
        self.poll();
        out.append(&mut self.events);
    }
}

impl Drop for ZenohControl {
    fn drop(&mut self) {
        // Undeclare before the session goes, so peers learn it at once.
        let _ = self.session.close().wait();
    }
}

/// The orchestrator's side of run control over zenoh, on the run's session: the control
/// publisher, the status subscriber and the orchestrator's liveliness token.
pub struct ZenohHub {
    control: Publisher<'static>,
    _status: Subscriber<()>,
    statuses: std::sync::mpsc::Receiver<Sample>,
    _token: LivelinessToken,
    run: ZenohRun,
    rejected: std::cell::Cell<u64>,
}

impl ZenohHub {
    pub fn create(run: &ZenohRun, session: &Session) -> Result<Self, TransportError> {
        let control = publisher(session, run.control_key())?;
        // Statuses queue without bound. Zenoh blocks its receiving thread on a full bounded
        // queue, and that thread also brings the host daemons' answers: while the orchestrator
        // asked daemons to start a thousand processes, one request at a time, their "ready"
        // statuses filled a queue of 1 024, and every later request timed out unanswered (the
        // N = 1 000 ring across three namespaces stalled at agent 515). A status is ~100 bytes and
        // a process sends a handful, except the waits it reports while stuck.
        let (tx, statuses) = std::sync::mpsc::channel();
        let status_key = run.status_key();
        let status = session
            .declare_subscriber(status_key.clone())
            .callback(move |s| {
                let _ = tx.send(s);
            })
            .wait()
            .map_err(err(format!("subscriber {status_key}")))?;
        let token = session
            .liveliness()
            .declare_token(run.orchestrator_token())
            .wait()
            .map_err(err("orchestrator liveliness token"))?;
        Ok(Self {
            control,
            _status: status,
            statuses,
            _token: token,
            run: run.clone(),
            rejected: std::cell::Cell::new(0),
        })
    }

    fn send(&self, command: u32, edit: impl FnOnce(&mut RunControl)) -> Result<(), TransportError> {
        let mut msg = RunControl::new(command, self.run.run_id);
        edit(&mut msg);
        if let Some(k) = &self.run.key {
            k.seal_control(&mut msg);
        }
        put(&self.control, &msg)
    }
}

impl ControlHub for ZenohHub {
    fn request_stop(&self) -> Result<(), TransportError> {
        self.send(CONTROL_STOP, |_| {})
    }
    fn grant_start(&self) -> Result<(), TransportError> {
        self.send(CONTROL_START, |_| {})
    }
    fn resume(&self, step: u64, dead: Roster, alive: Roster) -> Result<(), TransportError> {
        self.send(CONTROL_RESUME, |m| (m.step, m.dead, m.alive) = (step, dead, alive))
    }
    fn report_dead(&self, dead: Roster) -> Result<(), TransportError> {
        self.send(CONTROL_DEAD, |m| m.dead = dead)
    }
    fn poll_status(&self, f: &mut dyn FnMut(&Status)) -> Result<(), TransportError> {
        while let Ok(sample) = self.statuses.try_recv() {
            let bytes = sample.payload().to_bytes();
            if bytes.len() != std::mem::size_of::<Status>() {
                self.rejected.set(self.rejected.get() + 1);
                continue;
            }
            let st: Status = read_payload(&bytes);
            let tag_ok = self.run.key.as_ref().is_none_or(|k| k.check_status(&st));
            if st.version == SCHEMA_VERSION && st.run_id == self.run.run_id && tag_ok {
                f(&st);
            } else {
                self.rejected.set(self.rejected.get() + 1);
            }
        }
        Ok(())
    }
    fn rejected(&self) -> u64 {
        self.rejected.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn senders_are_read_from_the_last_chunk_of_the_key() {
        assert_eq!(sender_of("cohort/00/d/agent-2/plant"), PLANT_ID);
        assert_eq!(sender_of("cohort/00/d/plant/agent-17"), 17);
        for bad in ["cohort/00/d/plant/agent-0", "cohort/00/d/plant/agent-x", "cohort/00/d/plant/someone", ""] {
            assert_eq!(sender_of(bad), u32::MAX, "{bad}");
        }
    }

    /// Wait until `p` has a subscriber, within 20 s.
    fn until_matched(p: &Publisher<'static>) {
        let until = Instant::now() + Duration::from_secs(20);
        while !matched(p) {
            assert!(Instant::now() < until, "{} never matched", p.key_expr());
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// An orchestrator busy elsewhere (starting processes through host daemons) does not poll
    /// statuses: three queues' worth of them must not stop its session reading what else comes
    /// in (there, the daemons' answers; here, a put on another key). With a bounded status queue
    /// zenoh blocked its receiving thread and every later answer timed out.
    #[test]
    fn unpolled_statuses_do_not_stop_the_session_reading() {
        let loopback = std::net::Ipv4Addr::LOCALHOST.into();
        let (hub_session, hub_at) = open_on_free_ports(&[loopback], &[]).expect("hub session");
        let run = ZenohRun::new(0x5ca1_ab1e);
        let hub = ZenohHub::create(&run, &hub_session).expect("hub");
        let later_key = format!("{}/test/later", run.prefix());
        let (got, later_rx) = std::sync::mpsc::channel();
        let _later_sub = hub_session
            .declare_subscriber(later_key.clone())
            .callback(move |_| {
                let _ = got.send(());
            })
            .wait()
            .expect("later subscriber");
        let (other, _) = open_on_free_ports(&[loopback], &hub_at).expect("process session");
        let (status_pub, later_pub) =
            (publisher(&other, run.status_key()).expect("status"), publisher(&other, later_key).expect("later"));
        until_matched(&status_pub);
        until_matched(&later_pub);
        let n = 3 * INBOX_DEPTH;
        let st = Status {
            version: SCHEMA_VERSION,
            sender: 1,
            run_id: run.run_id,
            kind: crate::msg::STATUS_READY,
            waiting_for: 0,
            step: 0,
            t_s: 0.0,
            build_hash: 0,
            detail: 0,
            _pad: 0,
            mac: [0; 2],
        };
        // Puts block on a stalled reader (congestion control Block): from a thread, so that a
        // stall fails the test instead of hanging it.
        std::thread::spawn(move || {
            for _ in 0..n {
                put(&status_pub, &st).expect("status put");
            }
            put(&later_pub, &1u64).expect("later put");
            (status_pub, later_pub, other)
        });
        assert!(
            later_rx.recv_timeout(Duration::from_secs(60)).is_ok(),
            "the hub's session stopped reading after {n} unpolled statuses"
        );
        let mut seen = 0;
        let until = Instant::now() + Duration::from_secs(20);
        while seen < n && Instant::now() < until {
            hub.poll_status(&mut |_| seen += 1).expect("poll");
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(seen, n, "statuses lost");
        assert_eq!(hub.rejected(), 0);
    }

    #[test]
    fn endpoint_lists_are_json() {
        assert_eq!(serde_like_list(&["tcp/127.0.0.1:0".into()]), "[\"tcp/127.0.0.1:0\"]");
        assert_eq!(serde_like_list(&[]), "[]");
    }
}
