//! Reading a recording back, for replay (Foxglove reads the file without this): its `cohort`
//! metadata and every message in file order, each checked to be a whole payload of its kind. A
//! file that is not a finished MCAP (cut short by a killed process, or damaged: chunk CRCs are
//! checked) or not a Cohort recording of this wire version is refused with what is wrong.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cohort_wire::layout;
use cohort_wire::msg::{Measurement, PLANT_ID, SCHEMA_VERSION, Share};
use mcap::read::Options;

use super::{Direction, META_FORMAT, META_NAME};

/// A recorded payload.
pub enum Msg {
    Measurement(Box<Measurement>),
    Share { from: u32, share: Box<Share> },
}

impl Msg {
    /// The step its header names.
    pub fn step(&self) -> u64 {
        match self {
            Msg::Measurement(m) => m.header.step,
            Msg::Share { share, .. } => share.header.step,
        }
    }
}

/// One recorded message.
pub struct Recorded {
    pub dir: Direction,
    pub msg: Msg,
}

/// A recording read back.
pub struct RecordingFile {
    pub path: PathBuf,
    /// The `cohort` metadata record.
    pub meta: BTreeMap<String, String>,
    /// Every message, in the order the process saw them.
    pub messages: Vec<Recorded>,
}

#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("{}: no recording here (was the run launched with --record?)", path.display())]
    Missing { path: PathBuf },
    #[error("{}: cannot read: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: not a readable MCAP file ({detail}): damaged, or cut short by a process that was killed", path.display())]
    Corrupt { path: PathBuf, detail: String },
    #[error("{}: {detail}", path.display())]
    Foreign { path: PathBuf, detail: String },
}

impl RecordingFile {
    /// A metadata value, or an error naming the key.
    pub fn meta(&self, key: &str) -> Result<&str, ReadError> {
        self.meta.get(key).map(String::as_str).ok_or_else(|| self.foreign(format!("its metadata lacks {key:?}")))
    }
    /// The run id the messages carry.
    pub fn run_id(&self) -> Result<u64, ReadError> {
        let v = self.meta("run_id")?;
        u64::from_str_radix(v, 16).map_err(|_| self.foreign(format!("run_id {v:?} is not hexadecimal")))
    }
    /// The id of the process that wrote it (0: the plant).
    pub fn id(&self) -> Result<u32, ReadError> {
        let v = self.meta("id")?;
        v.parse().map_err(|_| self.foreign(format!("id {v:?} is not a process id")))
    }
    fn foreign(&self, detail: String) -> ReadError {
        ReadError::Foreign { path: self.path.clone(), detail }
    }
}

/// Read the recording at `path`.
pub fn read(path: &Path) -> Result<RecordingFile, ReadError> {
    let buf = std::fs::read(path).map_err(|source| match source.kind() {
        std::io::ErrorKind::NotFound => ReadError::Missing { path: path.to_path_buf() },
        _ => ReadError::Io { path: path.to_path_buf(), source },
    })?;
    let corrupt = |e: mcap::McapError| ReadError::Corrupt { path: path.to_path_buf(), detail: e.to_string() };
    let foreign = |detail: String| ReadError::Foreign { path: path.to_path_buf(), detail };
    let summary = mcap::Summary::read(&buf)
        .map_err(corrupt)?
        .ok_or_else(|| ReadError::Corrupt { path: path.to_path_buf(), detail: "it has no summary section".into() })?;
    let index = summary
        .metadata_indexes
        .iter()
        .find(|m| m.name == META_NAME)
        .ok_or_else(|| foreign(format!("no {META_NAME:?} metadata record: not a Cohort recording")))?;
    let meta = mcap::read::metadata(&buf, index).map_err(corrupt)?.metadata;
    let format = meta.get("format").map(String::as_str).unwrap_or("");
    if format != META_FORMAT {
        return Err(foreign(format!("format {format:?}, this build reads {META_FORMAT:?}")));
    }
    let version = meta.get("wire_schema_version").map(String::as_str).unwrap_or("");
    if version != SCHEMA_VERSION.to_string() {
        return Err(foreign(format!("wire schema version {version:?}, this build speaks {SCHEMA_VERSION}")));
    }
    check_chunk_headers(&buf, &summary).map_err(|detail| ReadError::Corrupt { path: path.to_path_buf(), detail })?;
    // The mcap crate panics on some damage the checks above cannot see (it trusts the lengths it
    // reads): such a panic is this file's corruption, not a crash of the caller. Known gap: damage
    // inside a chunk's compressed records can also make it allocate from a garbage length, and a
    // failed allocation aborts the process (seen in about 1 of 10 random flips there); closing it
    // needs a structural walk of the decompressed records before mcap parses them.
    std::panic::catch_unwind(|| messages(&buf, path))
        .unwrap_or_else(|_| {
            Err(ReadError::Corrupt {
                path: path.to_path_buf(),
                detail: "the mcap reader gave up on a damaged record".into(),
            })
        })
        .map(|messages| RecordingFile { path: path.to_path_buf(), meta, messages })
}

/// Largest chunk we accept, decompressed (the writer's chunks are well under 1 MiB).
const MAX_CHUNK_BYTES: u64 = 256 << 20;

/// Every indexed chunk's own header agrees with its index entry on where it is and how big it
/// decompresses, within [`MAX_CHUNK_BYTES`]. The mcap crate reserves a chunk's stated
/// decompressed size before it checks anything, so a flipped bit there would ask for exabytes.
/// Chunk record (MCAP spec): opcode 0x06, record length u64, start and end time u64, decompressed
/// size u64, …, all little-endian.
fn check_chunk_headers(buf: &[u8], summary: &mcap::Summary) -> Result<(), String> {
    let u64_at = |at: usize| buf.get(at..at + 8).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")));
    for (n, c) in summary.chunk_indexes.iter().enumerate() {
        let at = usize::try_from(c.chunk_start_offset).map_err(|_| format!("chunk {n}: offset out of range"))?;
        if buf.get(at) != Some(&0x06) {
            return Err(format!("chunk {n}: no chunk record at offset {at}"));
        }
        let record_len = u64_at(at + 1).ok_or_else(|| format!("chunk {n}: cut short at offset {at}"))?;
        let size = u64_at(at + 1 + 8 + 16).ok_or_else(|| format!("chunk {n}: cut short at offset {at}"))?;
        if record_len.checked_add(9) != Some(c.chunk_length) {
            return Err(format!("chunk {n}: record length {record_len}, its index says {}", c.chunk_length - 9));
        }
        if size != c.uncompressed_size || size > MAX_CHUNK_BYTES {
            return Err(format!("chunk {n}: decompressed size {size} B, its index says {} B", c.uncompressed_size));
        }
    }
    Ok(())
}

/// Every message of the file, decoded.
fn messages(buf: &[u8], path: &Path) -> Result<Vec<Recorded>, ReadError> {
    let corrupt = |e: mcap::McapError| ReadError::Corrupt { path: path.to_path_buf(), detail: e.to_string() };
    let foreign = |detail: String| ReadError::Foreign { path: path.to_path_buf(), detail };
    let mut messages = Vec::new();
    let stream = mcap::MessageStream::new_with_options(buf, Options::ValidateChunkCrcs.into()).map_err(corrupt)?;
    for (n, m) in stream.enumerate() {
        let m = m.map_err(corrupt)?;
        let at = |what: &str| foreign(format!("message {n} on {}: {what}", m.channel.topic));
        let md = &m.channel.metadata;
        let dir = match md.get("direction").map(String::as_str) {
            Some("received") => Direction::Received,
            Some("sent") => Direction::Sent,
            other => return Err(at(&format!("channel direction {other:?}"))),
        };
        let msg = match md.get("kind").map(String::as_str) {
            Some("measurement") => {
                layout::measurement_from_bytes(&m.data).map(|x| Msg::Measurement(Box::new(x))).ok_or_else(|| {
                    at(&format!("{} bytes, a measurement has {}", m.data.len(), layout::Payload::Measurement.size()))
                })?
            }
            Some("share") => {
                let from = sender_id(md.get("sender").map(String::as_str).unwrap_or(""))
                    .ok_or_else(|| at("channel sender is not an agent"))?;
                layout::share_from_bytes(&m.data).map(|x| Msg::Share { from, share: Box::new(x) }).ok_or_else(|| {
                    at(&format!("{} bytes, a share has {}", m.data.len(), layout::Payload::Share.size()))
                })?
            }
            other => return Err(at(&format!("channel kind {other:?}"))),
        };
        messages.push(Recorded { dir, msg });
    }
    Ok(messages)
}

/// `agent-<i>` → i.
fn sender_id(name: &str) -> Option<u32> {
    name.strip_prefix("agent-")?.parse().ok().filter(|&i| i != PLANT_ID)
}
