//! Reading a recording back, for replay (Foxglove reads the file without this): its `cohort`
//! metadata and every message in file order, each checked to be a whole payload of its kind. A
//! damaged file (chunk CRCs are checked, every length is bounded) or one that is not a Cohort
//! recording of this wire version is refused with what is wrong and where; a file cut short by a
//! killed process is read up to its last complete chunk, saying so.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cohort_wire::layout;
use cohort_wire::msg::{Measurement, PLANT_ID, SCHEMA_VERSION, Share};

use super::{Direction, META_FORMAT, META_NAME, walk};

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
    /// A file without its footer: where it stops, in words (its messages are those before).
    pub cut_short: Option<String>,
    /// The file's attachments (a relaunched agent's: the checkpoint it resumed from).
    pub attachments: Vec<walk::Attachment>,
}

#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    #[error("{}: no recording here (was the run launched with --record?)", path.display())]
    Missing { path: PathBuf },
    #[error("{}: cannot read: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: damaged MCAP file: {detail}", path.display())]
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
    /// The attachment named `name`, if the file has one.
    pub fn attachment(&self, name: &str) -> Option<&walk::Attachment> {
        self.attachments.iter().find(|a| a.name == name)
    }
    fn foreign(&self, detail: String) -> ReadError {
        ReadError::Foreign { path: self.path.clone(), detail }
    }
}

/// Read the recording at `path`: walked record by record ([`super::walk`]), so damage anywhere is
/// a [`ReadError::Corrupt`] naming the offset, and a file without its footer gives the messages of
/// its complete chunks with [`RecordingFile::cut_short`] saying where it stops.
pub fn read(path: &Path) -> Result<RecordingFile, ReadError> {
    let buf = std::fs::read(path).map_err(|source| match source.kind() {
        std::io::ErrorKind::NotFound => ReadError::Missing { path: path.to_path_buf() },
        _ => ReadError::Io { path: path.to_path_buf(), source },
    })?;
    let foreign = |detail: String| ReadError::Foreign { path: path.to_path_buf(), detail };
    let walked =
        walk::walk(&buf).map_err(|d| ReadError::Corrupt { path: path.to_path_buf(), detail: d.to_string() })?;
    let meta = walked
        .metadata
        .iter()
        .find(|(name, _)| name == META_NAME)
        .map(|(_, m)| m.clone())
        .ok_or_else(|| foreign(format!("no {META_NAME:?} metadata record: not a Cohort recording")))?;
    let format = meta.get("format").map(String::as_str).unwrap_or("");
    if format != META_FORMAT {
        return Err(foreign(format!("format {format:?}, this build reads {META_FORMAT:?}")));
    }
    let version = meta.get("wire_schema_version").map(String::as_str).unwrap_or("");
    if version != SCHEMA_VERSION.to_string() {
        return Err(foreign(format!("wire schema version {version:?}, this build speaks {SCHEMA_VERSION}")));
    }
    let messages = messages(&walked, path)?;
    let cut_short = walked.cut_short.map(|(at, why)| {
        format!(
            "{}: no footer (its process was killed?): read up to offset {at}, the end of its last complete \
             record ({} messages); after it, {why}",
            path.display(),
            messages.len()
        )
    });
    Ok(RecordingFile { path: path.to_path_buf(), meta, messages, cut_short, attachments: walked.attachments })
}

/// Every message of the walk, decoded.
fn messages(walked: &walk::Walk, path: &Path) -> Result<Vec<Recorded>, ReadError> {
    let mut messages = Vec::with_capacity(walked.messages.len());
    for (n, m) in walked.messages.iter().enumerate() {
        let channel = &walked.channels[&m.channel];
        let at = |what: &str| ReadError::Foreign {
            path: path.to_path_buf(),
            detail: format!("message {n} on {} (record at offset {}): {what}", channel.topic, m.offset),
        };
        let md = &channel.metadata;
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
