//! A bounded walk over an MCAP file's records, for the reader: the file is read front to back
//! (MCAP spec: magic, then records `opcode u8 · length u64 · body`, a footer, the magic again),
//! every length is checked against what holds it before anything is allocated, and a chunk is
//! decompressed into at most its declared size (itself at most [`MAX_CHUNK_BYTES`]) and checked
//! against its CRC. So a damaged file is an error naming the offset and the reason, never an abort
//! (the mcap crate reserved whatever a damaged length said: "memory allocation of
//! 7668058320836127347 bytes failed"). A file without its closing magic (its process was killed)
//! gives every record up to its last complete chunk, and says where it stops.

use std::collections::{BTreeMap, HashMap};

/// The MCAP magic, at the start and at the end of a finished file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";
/// Largest chunk accepted, decompressed (the writer's chunks are well under 1 MiB).
pub const MAX_CHUNK_BYTES: u64 = 64 << 20;

const OP_FOOTER: u8 = 0x02;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;
const OP_ATTACHMENT: u8 = 0x09;
const OP_METADATA: u8 = 0x0C;
/// Header, schema, message index, chunk index, attachment index, statistics, metadata index,
/// summary offset, data end: checked for length only.
const SKIPPED: &[u8] = &[0x01, 0x03, 0x07, 0x08, 0x0A, 0x0B, 0x0D, 0x0E, 0x0F];

/// A channel record: its topic and metadata.
#[derive(Debug, Clone)]
pub struct Channel {
    pub topic: String,
    pub metadata: BTreeMap<String, String>,
}

/// A message record: its channel id, and its data.
#[derive(Debug, Clone)]
pub struct Message {
    pub channel: u16,
    /// Offset of the message in the file (of its chunk, for a message inside one).
    pub offset: u64,
    pub data: Vec<u8>,
}

/// An attachment record: its name, media type and data (its CRC checked).
#[derive(Debug, Clone)]
pub struct Attachment {
    pub name: String,
    pub media_type: String,
    pub data: Vec<u8>,
}

/// What a walk found.
#[derive(Debug, Default)]
pub struct Walk {
    /// Metadata records: name and map.
    pub metadata: Vec<(String, BTreeMap<String, String>)>,
    /// Attachment records, in file order.
    pub attachments: Vec<Attachment>,
    pub channels: HashMap<u16, Channel>,
    /// Every message, in file order.
    pub messages: Vec<Message>,
    /// A file without its footer: the offset its last complete record ends at, and what follows.
    pub cut_short: Option<(u64, String)>,
}

/// A damaged file: where, and what is wrong there.
#[derive(Debug, Clone, PartialEq)]
pub struct Damage {
    pub offset: u64,
    pub reason: String,
}

impl std::fmt::Display for Damage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "offset {}: {}", self.offset, self.reason)
    }
}

/// Walk `buf`, a whole MCAP file.
pub fn walk(buf: &[u8]) -> Result<Walk, Damage> {
    if buf.get(..8) != Some(MAGIC.as_slice()) {
        return Err(Damage { offset: 0, reason: "not an MCAP file (no MCAP magic)".into() });
    }
    let finished = buf.len() >= 16 && buf.ends_with(MAGIC);
    let mut w = Walk::default();
    let mut at = 8usize;
    loop {
        let rest = buf.len() - at;
        let cut = |why: String| -> Result<(), Damage> {
            if finished { Err(Damage { offset: at as u64, reason: why }) } else { Ok(()) }
        };
        if rest < 9 {
            let why = format!("{rest} bytes where a record or the footer should be");
            cut(why.clone())?;
            w.cut_short = Some((at as u64, why));
            return Ok(w);
        }
        let op = buf[at];
        let len = u64::from_le_bytes(buf[at + 1..at + 9].try_into().expect("8 bytes"));
        if len > (rest - 9) as u64 {
            let why = format!("a record (opcode 0x{op:02x}) of {len} bytes, with {} bytes left in the file", rest - 9);
            cut(why.clone())?;
            w.cut_short = Some((at as u64, why));
            return Ok(w);
        }
        let body = &buf[at + 9..at + 9 + len as usize];
        let damage = |reason: String| Damage { offset: at as u64, reason };
        match op {
            OP_FOOTER => {
                if !finished || at + 9 + len as usize + 8 != buf.len() {
                    return Err(damage("a footer that is not the file's last record".into()));
                }
                return Ok(w);
            }
            OP_CHUNK => chunk(body, at as u64, &mut w).map_err(damage)?,
            OP_METADATA => {
                let mut r = Fields::new(body);
                let name = r.string().map_err(damage)?;
                let map = r.map().map_err(damage)?;
                w.metadata.push((name, map));
            }
            OP_ATTACHMENT => w.attachments.push(attachment(body).map_err(damage)?),
            OP_CHANNEL | OP_MESSAGE => record(op, body, at as u64, &mut w).map_err(damage)?,
            op if SKIPPED.contains(&op) => {}
            op => return Err(damage(format!("unknown record opcode 0x{op:02x}"))),
        }
        at += 9 + len as usize;
    }
}

/// A chunk record's body (at file offset `at`): its header checked, its records decompressed into
/// at most their declared size, their CRC checked, then walked.
fn chunk(body: &[u8], at: u64, w: &mut Walk) -> Result<(), String> {
    let mut r = Fields::new(body);
    let _start_ns = r.u64()?;
    let _end_ns = r.u64()?;
    let size = r.u64()?;
    let crc = r.u32()?;
    let compression = r.string()?;
    let records_len = r.u64()?;
    let records = r.take(records_len)?;
    if !r.rest().is_empty() {
        return Err(format!("chunk: {} bytes after its records", r.rest().len()));
    }
    if size > MAX_CHUNK_BYTES {
        return Err(format!("chunk: decompressed size {size} B, more than the {MAX_CHUNK_BYTES} B accepted"));
    }
    let owned;
    let plain: &[u8] = match compression.as_str() {
        "" => records,
        "zstd" => {
            owned = zstd::bulk::decompress(records, size as usize).map_err(|e| format!("chunk: zstd: {e}"))?;
            &owned
        }
        other => return Err(format!("chunk: compression {other:?}, this reader knows zstd and none")),
    };
    if plain.len() as u64 != size {
        return Err(format!("chunk: {} B decompressed, its header says {size} B", plain.len()));
    }
    if crc != 0 && crc32fast::hash(plain) != crc {
        return Err(format!("chunk: CRC mismatch (stored {crc:08x}, computed {:08x})", crc32fast::hash(plain)));
    }
    let mut i = 0usize;
    while i < plain.len() {
        let head = plain.get(i..i + 9).ok_or_else(|| format!("chunk: a record cut short at its byte {i}"))?;
        let (op, len) = (head[0], u64::from_le_bytes(head[1..].try_into().expect("8 bytes")));
        let body = usize::try_from(len)
            .ok()
            .and_then(|n| plain.get(i + 9..(i + 9).checked_add(n)?))
            .ok_or_else(|| format!("chunk: the record at its byte {i} claims {len} bytes, past the chunk's end"))?;
        match op {
            OP_CHANNEL | OP_MESSAGE => record(op, body, at, w).map_err(|e| format!("chunk, its byte {i}: {e}"))?,
            0x03 => {}
            op => return Err(format!("chunk: record opcode 0x{op:02x} at its byte {i} cannot be in a chunk")),
        }
        i += 9 + body.len();
    }
    Ok(())
}

/// An attachment record's body: log and create time, name, media type, data, and a CRC-32 of all
/// that precedes it (0: none computed).
fn attachment(body: &[u8]) -> Result<Attachment, String> {
    let mut r = Fields::new(body);
    let _log_ns = r.u64()?;
    let _create_ns = r.u64()?;
    let name = r.string()?;
    let media_type = r.string()?;
    let n = r.u64()?;
    let data = r.take(n)?.to_vec();
    let covered = body.len() - r.rest().len();
    let crc = r.u32()?;
    if !r.rest().is_empty() {
        return Err(format!("attachment {name:?}: {} bytes after its CRC", r.rest().len()));
    }
    let computed = crc32fast::hash(&body[..covered]);
    if crc != 0 && crc != computed {
        return Err(format!("attachment {name:?}: CRC mismatch (stored {crc:08x}, computed {computed:08x})"));
    }
    Ok(Attachment { name, media_type, data })
}

/// A channel or message record.
fn record(op: u8, body: &[u8], at: u64, w: &mut Walk) -> Result<(), String> {
    let mut r = Fields::new(body);
    if op == OP_CHANNEL {
        let id = r.u16()?;
        let _schema = r.u16()?;
        let topic = r.string()?;
        let _encoding = r.string()?;
        let metadata = r.map()?;
        w.channels.insert(id, Channel { topic, metadata });
    } else {
        let channel = r.u16()?;
        let _sequence = r.u32()?;
        let _log_ns = r.u64()?;
        let _publish_ns = r.u64()?;
        if !w.channels.contains_key(&channel) {
            return Err(format!("a message on channel {channel}, which no channel record defines"));
        }
        w.messages.push(Message { channel, offset: at, data: r.rest().to_vec() });
    }
    Ok(())
}

/// The fields of one record's body, each bounded by what is left of it.
struct Fields<'a> {
    b: &'a [u8],
}

impl<'a> Fields<'a> {
    fn new(b: &'a [u8]) -> Self {
        Self { b }
    }
    fn take(&mut self, n: u64) -> Result<&'a [u8], String> {
        let n = usize::try_from(n)
            .ok()
            .filter(|&n| n <= self.b.len())
            .ok_or_else(|| format!("a field of {n} bytes in a record with {} bytes left", self.b.len()))?;
        let (head, rest) = self.b.split_at(n);
        self.b = rest;
        Ok(head)
    }
    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2)?.try_into().expect("2 bytes")))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn string(&mut self) -> Result<String, String> {
        let n = self.u32()?;
        String::from_utf8(self.take(u64::from(n))?.to_vec()).map_err(|_| "a string that is not UTF-8".to_string())
    }
    /// `map<string, string>`: its byte length (u32), then key–value pairs.
    fn map(&mut self) -> Result<BTreeMap<String, String>, String> {
        let n = self.u32()?;
        let mut inner = Fields::new(self.take(u64::from(n))?);
        let mut out = BTreeMap::new();
        while !inner.b.is_empty() {
            let k = inner.string()?;
            let v = inner.string()?;
            out.insert(k, v);
        }
        Ok(out)
    }
    fn rest(&self) -> &'a [u8] {
        self.b
    }
}
