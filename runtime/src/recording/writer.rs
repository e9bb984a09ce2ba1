//! The recording side (see the module above for the file's format): [`Recording`] is a transport
//! that passes everything through to the process's own and copies each measurement and share it
//! sees into a bounded queue; a thread of its own encodes the queue into the MCAP file, so the step
//! path pays a copy and a queue push per message, never a compression or a write. A full queue
//! makes the step wait for the writer (it changes speed, never results); a writer that failed (a
//! full disk) ends the run at the next message with a transport error naming the file.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use cohort_wire::layout::{self, Payload};
use cohort_wire::msg::{Measurement, PLANT_ID, RunControl, Share, Status};
use cohort_wire::transport::{DataPath, Incoming, Proc, RunControlPort, Transport, TransportError};
use mcap::records::{MessageHeader, Metadata};

use super::walk::Attachment;
use super::{Direction, MESSAGE_ENCODING, META_FORMAT, META_NAME, SCHEMA_ENCODING, path_for, proc_of};

/// Messages the queue holds before the step path waits for the writer (≈ 4 MiB of shares).
const QUEUE: usize = 1024;

/// What the file's `cohort` metadata record says, besides what the writer knows itself.
#[derive(Debug, Clone)]
pub struct RecordMeta {
    pub me: Proc,
    pub run_id: u64,
    pub dt_s: f64,
    /// The agents whose shares this process reads (an agent's neighbours).
    pub neighbours: Vec<u32>,
    /// The agents that read this process's shares (the plant reads them too).
    pub readers: Vec<u32>,
    pub scenario: String,
    pub seed: u64,
    /// Files the recording carries, written before the first message (a relaunched agent's: the
    /// checkpoint it resumes from, [`super::RESTORED_FROM`]).
    pub attachments: Vec<Attachment>,
}

impl RecordMeta {
    /// The metadata of process `me` of a configured run.
    pub fn from_setup(setup: &crate::paper::Setup, run_id: u64, me: Proc) -> Self {
        let topo = setup.topology();
        let (neighbours, readers) = match me {
            Proc::Plant => ((1..=setup.n_agents()).collect(), Vec::new()),
            Proc::Agent(i) => (topo.neighbours_of(i).to_vec(), topo.readers_of(i)),
        };
        Self {
            me,
            run_id,
            dt_s: setup.scenario.dt_s,
            neighbours,
            readers,
            scenario: setup.scenario.name.clone(),
            seed: setup.scenario.seed,
            attachments: Vec::new(),
        }
    }

    fn record(&self) -> Metadata {
        let ids = |v: &[u32]| v.iter().map(u32::to_string).collect::<Vec<_>>().join(",");
        let mut m = BTreeMap::new();
        m.insert("format".into(), META_FORMAT.into());
        m.insert("process".into(), self.me.name());
        m.insert("id".into(), self.me.sender_id().to_string());
        m.insert("neighbours".into(), ids(&self.neighbours));
        m.insert("readers".into(), ids(&self.readers));
        m.insert("run_id".into(), format!("{:016x}", self.run_id));
        m.insert("wire_schema_version".into(), cohort_wire::msg::SCHEMA_VERSION.to_string());
        m.insert("build_id".into(), cohort_wire::build_id().into());
        m.insert("scenario".into(), self.scenario.clone());
        m.insert("seed".into(), self.seed.to_string());
        // Shortest round-trip form: a reader gets the same f64 back.
        m.insert("dt_s".into(), format!("{:?}", self.dt_s));
        m.insert("byte_order".into(), "little-endian".into());
        Metadata { name: META_NAME.into(), metadata: m }
    }
}

/// One message for the writer thread.
enum Item {
    Measurement { dir: Direction, other: u32, m: Box<Measurement> },
    Share { dir: Direction, from: u32, s: Box<Share> },
}

/// Why a recording could not be started ([`Recording::start`]): its file, and what failed.
#[derive(Debug, thiserror::Error)]
pub enum OpenRecordingError {
    /// `record/` or the file cannot be created.
    #[error("{}: {source}", path.display())]
    Create { path: PathBuf, source: std::io::Error },
    /// The MCAP header cannot be written.
    #[error("{}: {source}", path.display())]
    Mcap { path: PathBuf, source: mcap::McapError },
    #[error("{}: cannot start its writer thread: {source}", path.display())]
    Thread { path: PathBuf, source: std::io::Error },
}

/// Why a recording did not close cleanly ([`Recording::finish`]).
#[derive(Debug, Clone, thiserror::Error)]
pub enum FinishRecordingError {
    /// The writer failed; the message names the file.
    #[error("{0}")]
    Write(String),
    #[error("{}: its writer thread panicked", path.display())]
    Panicked { path: PathBuf },
}

/// A transport that records what passes through it (see the module doc).
pub struct Recording<'a> {
    inner: &'a mut dyn Transport,
    me: Proc,
    tx: Option<SyncSender<Item>>,
    thread: Option<JoinHandle<Result<u64, String>>>,
    /// The writer's error, once it failed.
    failed: Arc<Mutex<Option<String>>>,
    path: PathBuf,
}

impl<'a> Recording<'a> {
    /// Create `record/<proc>.mcap` in `run_dir` (a relaunched process, finding its predecessor's
    /// file, writes `<proc>.<n>.mcap` beside it) and start its writer thread.
    pub fn start(inner: &'a mut dyn Transport, run_dir: &Path, meta: RecordMeta) -> Result<Self, OpenRecordingError> {
        let path = free_path(&path_for(run_dir, meta.me));
        let in_dir = |source: std::io::Error| OpenRecordingError::Create { path: path.clone(), source };
        std::fs::create_dir_all(path.parent().expect("a file in record/")).map_err(in_dir)?;
        let file = File::create(&path).map_err(in_dir)?;
        let in_file = |source: mcap::McapError| OpenRecordingError::Mcap { path: path.clone(), source };
        let w = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            // Level 1 and no zstd worker threads: the machine's cores belong to the run.
            .compression_level(1)
            .compression_threads(0)
            .library(format!("cohort {}", cohort_wire::build_id()))
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(in_file)?;
        let failed = Arc::new(Mutex::new(None));
        let (tx, rx) = sync_channel(QUEUE);
        let me = meta.me;
        let (failed_w, path_w) = (Arc::clone(&failed), path.clone());
        let thread = std::thread::Builder::new()
            .name(format!("record-{}", me.name()))
            .spawn(move || {
                let r = write_all(w, rx, &meta).map_err(|e| format!("{}: {e}", path_w.display()));
                if let Err(e) = &r {
                    *failed_w.lock().unwrap_or_else(|p| p.into_inner()) = Some(e.clone());
                }
                r
            })
            .map_err(|source| OpenRecordingError::Thread { path: path.clone(), source })?;
        Ok(Self { inner, me, tx: Some(tx), thread: Some(thread), failed, path })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Close the file: the writer drains the queue, writes the summary and footer. Returns the
    /// number of messages recorded.
    pub fn finish(mut self) -> Result<u64, FinishRecordingError> {
        self.close()
    }

    fn close(&mut self) -> Result<u64, FinishRecordingError> {
        drop(self.tx.take());
        match self.thread.take() {
            Some(t) => match t.join() {
                Ok(written) => written.map_err(FinishRecordingError::Write),
                Err(_) => Err(FinishRecordingError::Panicked { path: self.path.clone() }),
            },
            None => Ok(0),
        }
    }

    fn push(&mut self, item: Item) -> Result<(), TransportError> {
        let Some(tx) = &self.tx else { return Ok(()) };
        let item = match tx.try_send(item) {
            Ok(()) => return Ok(()),
            Err(TrySendError::Full(item)) => item,
            Err(TrySendError::Disconnected(_)) => return Err(self.error()),
        };
        // The writer is behind: wait for it (speed, never results).
        tx.send(item).map_err(|_| self.error())
    }

    fn error(&self) -> TransportError {
        let why = self.failed.lock().unwrap_or_else(|p| p.into_inner()).clone();
        TransportError::Other(format!(
            "recording {}: {}",
            self.path.display(),
            why.unwrap_or_else(|| "its writer stopped".into())
        ))
    }
}

impl Drop for Recording<'_> {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

/// `path`, or the first `<stem>.<n>.mcap` beside it that does not exist yet.
fn free_path(path: &Path) -> PathBuf {
    if !path.exists() {
        return path.to_path_buf();
    }
    let stem = path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    (1..).map(|n| path.with_file_name(format!("{stem}.{n}.mcap"))).find(|p| !p.exists()).expect("a free name")
}

impl DataPath for Recording<'_> {
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError> {
        self.push(Item::Measurement { dir: Direction::Sent, other: to, m: Box::new(*m) })?;
        self.inner.send_measurement(to, m)
    }
    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        let from = self.me.sender_id();
        self.push(Item::Share { dir: Direction::Sent, from, s: Box::new(*s) })?;
        self.inner.send_share(s)
    }
    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        let mut got = Vec::new();
        self.inner.drain(&mut |inc| {
            got.push(match &inc {
                Incoming::Measurement(m) => {
                    Item::Measurement { dir: Direction::Received, other: PLANT_ID, m: Box::new(**m) }
                }
                Incoming::Share { from, share } => {
                    Item::Share { dir: Direction::Received, from: *from, s: Box::new(**share) }
                }
            });
            f(inc);
        })?;
        for item in got {
            self.push(item)?;
        }
        Ok(())
    }
    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        self.inner.wait(timeout)
    }
    fn rung(&self) -> bool {
        self.inner.rung()
    }
    fn keeps_ports_until_stopped(&self) -> bool {
        self.inner.keeps_ports_until_stopped()
    }
    fn woken_by_control(&self) -> bool {
        self.inner.woken_by_control()
    }
    fn control_rung(&mut self) -> bool {
        self.inner.control_rung()
    }
    fn wait_advice(&self) -> u64 {
        self.inner.wait_advice()
    }
    fn set_wait_advice(&self, advice: u64) {
        self.inner.set_wait_advice(advice);
    }
}

impl RunControlPort for Recording<'_> {
    fn report(&mut self, s: &Status) {
        self.inner.report(s);
    }
    fn stop_requested(&mut self) -> bool {
        self.inner.stop_requested()
    }
    fn start_granted(&mut self) -> bool {
        self.inner.start_granted()
    }
    fn control_events(&mut self, out: &mut Vec<RunControl>) {
        self.inner.control_events(out);
    }
}

/// The writer thread: every queued message into the file, then the summary and footer.
fn write_all(mut w: mcap::Writer<BufWriter<File>>, rx: Receiver<Item>, meta: &RecordMeta) -> Result<u64, String> {
    let e = |e: mcap::McapError| e.to_string();
    w.write_metadata(&meta.record()).map_err(e)?;
    for a in &meta.attachments {
        let data = std::borrow::Cow::Borrowed(a.data.as_slice());
        let (name, media_type) = (a.name.clone(), a.media_type.clone());
        w.attach(&mcap::Attachment { log_time: 0, create_time: 0, name, media_type, data }).map_err(e)?;
    }
    let mut schema = HashMap::new();
    for p in [Payload::Measurement, Payload::Share] {
        let id = w.add_schema(p.ros1_name(), SCHEMA_ENCODING, layout::ros1_definition(p).as_bytes()).map_err(e)?;
        schema.insert(p, id);
    }
    let dt_ns = meta.dt_s * 1e9;
    // (kind, sender, direction, receiver of a sent measurement: the plant's one per agent).
    let mut channels: HashMap<(Payload, u32, Direction, u32), u16> = HashMap::new();
    let mut sequence = 0u32;
    let mut n = 0u64;
    for item in rx {
        let (payload, sender, dir, other, step, bytes) = match &item {
            Item::Measurement { dir, other, m } => {
                (Payload::Measurement, PLANT_ID, *dir, *other, m.header.step, layout::measurement_bytes(m))
            }
            Item::Share { dir, from, s } => (Payload::Share, *from, *dir, 0, s.header.step, layout::share_bytes(s)),
        };
        let key = (payload, sender, dir, if dir == Direction::Sent { other } else { 0 });
        let channel_id = match channels.get(&key) {
            Some(id) => *id,
            None => {
                let md = channel_metadata(meta, payload, sender, dir, other);
                let topic = topic(payload, sender, dir, other);
                let id = w.add_channel(schema[&payload], &topic, MESSAGE_ENCODING, &md).map_err(e)?;
                channels.insert(key, id);
                id
            }
        };
        // Sim time of the step the message names (saturating: a garbled step is recorded too).
        let log_time = (step as f64 * dt_ns).round().min(u64::MAX as f64) as u64;
        let header = MessageHeader { channel_id, sequence, log_time, publish_time: log_time };
        w.write_to_known_channel(&header, bytes).map_err(e)?;
        sequence = sequence.wrapping_add(1);
        n += 1;
    }
    w.finish().map_err(e)?;
    w.into_inner().flush().map_err(|e| e.to_string())?;
    Ok(n)
}

/// A channel's topic: one per (kind, sender); the plant's measurements it sends, one per agent.
fn topic(p: Payload, sender: u32, dir: Direction, other: u32) -> String {
    match (p, dir) {
        (Payload::Measurement, Direction::Received) => "/measurement/plant".into(),
        (Payload::Measurement, Direction::Sent) => format!("/measurement/plant/{}", proc_of(other).name()),
        (Payload::Share, _) => format!("/share/{}", proc_of(sender).name()),
    }
}

fn channel_metadata(
    meta: &RecordMeta,
    p: Payload,
    sender: u32,
    dir: Direction,
    other: u32,
) -> BTreeMap<String, String> {
    let receiver = match (p, dir) {
        (_, Direction::Received) => meta.me.name(),
        (Payload::Measurement, Direction::Sent) => proc_of(other).name(),
        (Payload::Share, Direction::Sent) => std::iter::once("plant".to_string())
            .chain(meta.readers.iter().map(|&j| Proc::Agent(j).name()))
            .collect::<Vec<_>>()
            .join(","),
    };
    let kind = match p {
        Payload::Measurement => "measurement",
        Payload::Share => "share",
    };
    BTreeMap::from([
        ("kind".to_string(), kind.to_string()),
        ("sender".to_string(), proc_of(sender).name()),
        ("receiver".to_string(), receiver),
        ("direction".to_string(), dir.name().to_string()),
    ])
}
