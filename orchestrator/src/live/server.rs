//! The process's one Foxglove WebSocket server (`--live ADDR`), started before the first run so
//! that a port in use is an input error before anything runs, and kept for every run of the
//! command (a soak's many runs share it). Channels are made on first use and kept by topic; the
//! latest message of each is kept too, so that a client that subscribes late gets the latest
//! state at once, and only that client (see [`Server::take_subscriptions`]).

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Context, PartialMetadata, RawChannel, Schema, SinkId, WebSocketServerHandle};

/// Messages a client's queue holds before its oldest are dropped: a client that stalls loses
/// messages, it never slows the server (nor the run, which never waits for the server at all).
const BACKLOG: usize = 256;

/// `--live-rate` and where the server listens.
#[derive(Debug, Clone)]
pub struct Options {
    pub addr: String,
    /// Scene and telemetry messages per second of sim time.
    pub rate_hz: f64,
}

/// The running server.
pub struct Server {
    pub options: Options,
    ctx: Arc<Context>,
    handle: WebSocketServerHandle,
    channels: Mutex<HashMap<String, Arc<RawChannel>>>,
    subscribed: Arc<Mutex<Vec<Subscription>>>,
    /// Whether runs are followed (the bench turns it off for its rows without `--live`).
    enabled: AtomicBool,
}

static SERVER: OnceLock<Server> = OnceLock::new();
/// The latest step the run's progress hook saw (the supervisor's or the reference run's).
pub static STEP: AtomicU64 = AtomicU64::new(0);

/// A client's subscription to a topic: the client (its sink) is sent that topic's latest state.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Subscription {
    pub sink: Option<SinkId>,
    pub topic: String,
    /// How many messages had been logged to every subscriber when it subscribed: those numbered
    /// higher reached it already (it was subscribed when they were logged), so sending it the
    /// latest state skips them. (Sent after the view's next publishing instead, a subscriber got
    /// the message just logged twice.)
    pub logged: u64,
}

/// Queues every subscription for [`Server::take_subscriptions`].
struct Subscribed(Arc<Mutex<Vec<Subscription>>>);

impl ServerListener for Subscribed {
    fn on_subscribe(&self, client: Client, channel: ChannelView) {
        let mut q = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let logged = LOGGED.load(Ordering::SeqCst);
        q.push(Subscription { sink: client.sink_id(), topic: channel.topic().to_string(), logged });
    }
}

/// Why `--live` cannot start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    #[error("--live {addr}: not HOST:PORT (e.g. 127.0.0.1:8765)")]
    Address { addr: String },
    #[error(
        "--live {addr}: cannot listen there ({why}); is another run or program using the port? choose another with --live HOST:PORT"
    )]
    Bind { addr: String, why: String },
    #[error("--live-rate {rate}: must be a positive number of messages per second of sim time")]
    Rate { rate: f64 },
}

/// Start the server (once per process); nothing else of the live view exists before this.
pub fn start(options: Options) -> Result<&'static Server, StartError> {
    if !(options.rate_hz.is_finite() && options.rate_hz > 0.0) {
        return Err(StartError::Rate { rate: options.rate_hz });
    }
    let addr = options.addr.clone();
    let (host, port) = addr
        .rsplit_once(':')
        .and_then(|(h, p)| Some((h.trim_start_matches('[').trim_end_matches(']').to_string(), p.parse::<u16>().ok()?)))
        .ok_or_else(|| StartError::Address { addr: addr.clone() })?;
    let ctx = Context::new();
    let subscribed = Arc::new(Mutex::new(Vec::new()));
    let handle = ctx
        .websocket_server()
        .name(format!("cohort {}", cohort_wire::build_id()))
        .bind(host, port)
        .message_backlog_size(BACKLOG)
        .listener(Arc::new(Subscribed(Arc::clone(&subscribed))))
        .start_blocking()
        .map_err(|e| StartError::Bind { addr: addr.clone(), why: e.to_string() })?;
    let server = Server {
        options,
        ctx,
        handle,
        channels: Mutex::new(HashMap::new()),
        subscribed,
        enabled: AtomicBool::new(true),
    };
    Ok(SERVER.get_or_init(|| server))
}

/// The server, when `--live` started one and runs are followed.
pub fn get() -> Option<&'static Server> {
    SERVER.get().filter(|s| s.enabled.load(Ordering::Relaxed))
}

/// The server whether or not runs are followed now.
pub fn started() -> Option<&'static Server> {
    SERVER.get()
}

impl Server {
    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.handle.port()
    }

    /// Follow the runs that start from now on, or not.
    pub fn set_enabled(&self, on: bool) {
        self.enabled.store(on, Ordering::Relaxed);
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.handle.client_count()
    }

    /// The subscriptions made since the last call (the caller sends each subscriber, and only
    /// it, the topic's latest state, so the clients already there get no duplicates).
    pub fn take_subscriptions(&self) -> Vec<Subscription> {
        std::mem::take(&mut *self.subscribed.lock().unwrap_or_else(|p| p.into_inner()))
    }

    /// The channel `topic` if it was made.
    pub fn existing(&self, topic: &str) -> Option<Arc<RawChannel>> {
        self.channels.lock().unwrap_or_else(|p| p.into_inner()).get(topic).cloned()
    }

    /// The channel `topic` with this schema and encoding, made on first use. A topic whose
    /// schema changed (another scenario's columns, in a soak) is closed and made anew.
    pub fn channel(&self, topic: &str, encoding: &str, schema: Schema) -> Option<Arc<RawChannel>> {
        let mut channels = self.channels.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(c) = channels.get(topic) {
            if c.schema() == Some(&schema) {
                return Some(Arc::clone(c));
            }
            c.close();
        }
        let c = self.ctx.channel_builder(topic).message_encoding(encoding).schema(schema).build_raw().ok()?;
        channels.insert(topic.to_string(), Arc::clone(&c));
        Some(c)
    }
}

/// Messages logged to every subscriber so far, counted before each is logged.
static LOGGED: AtomicU64 = AtomicU64::new(0);

/// Log `bytes` on `channel` at sim time `t_ns`, to every subscriber. Returns the message's number
/// (see [`Subscription::logged`]).
pub fn log(channel: &RawChannel, bytes: &[u8], t_ns: u64) -> u64 {
    let n = LOGGED.fetch_add(1, Ordering::SeqCst) + 1;
    channel.log_with_meta(bytes, PartialMetadata::with_log_time(t_ns));
    n
}

/// Log `bytes` on `channel` at sim time `t_ns` to one subscriber only.
pub fn log_to(channel: &RawChannel, bytes: &[u8], t_ns: u64, sink: Option<SinkId>) {
    if sink.is_some() {
        channel.log_with_meta_to_sink(bytes, PartialMetadata::with_log_time(t_ns), sink);
    }
}
