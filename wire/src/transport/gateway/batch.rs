//! What one gateway sends another: every message of one wakeup's drain for one remote host, as
//! one zenoh payload.
//!
//! Layout (little-endian, as every payload of ours is the host's `#[repr(C)]` bytes):
//! - header, 28 bytes: magic `CGW2`, [`SCHEMA_VERSION`] (u32), run id (u64), record count (u32),
//!   the plant's waiting advice (u64; `DataPath::wait_advice`, 0 for none): the plant's host's
//!   gateway sends its host's word, and a receiving gateway writes it to its own host's, so that
//!   every process of the run waits as the plant's trial chose (processes on other hosts had
//!   kept their own choice, and near a tie the hosts split: 2 of 12 fig1 runs through the lab's
//!   gateways had agents spinning beside blocking ones, 2026-12-07);
//! - each record: kind (u8: 1 measurement, 2 share), three zero bytes, sender id (u32),
//!   receiver id (u32: the agent a measurement is for; 0 for a share), payload length (u32), then
//!   the payload: the message's bytes up to its last non-zero byte. A share is 4.2 kB of which a
//!   consensus share uses a few dozen bytes; the receiving gateway fills the rest with zeros,
//!   so the message it publishes is bit for bit the one sent.
//!
//! [`decode`] checks everything before anything is delivered: header, lengths, kinds, and that
//! every sender runs on the host the batch came from, every measurement is for a process of
//! this host and only the plant's host gives advice (a host cannot speak for another's
//! processes). The receiving process's driver then
//! checks each message as it checks any (its header's sender, run, version, tag).

use super::Placement;
use crate::msg::{Measurement, PLANT_ID, SCHEMA_VERSION, Share};
use crate::transport::{Proc, bytes_of, read_payload_prefix};

const MAGIC: [u8; 4] = *b"CGW2";
/// Where the header's fields start (the magic at 0), and its length.
const VERSION_AT: usize = 4;
const RUN_AT: usize = 8;
const COUNT_AT: usize = 16;
const ADVICE_AT: usize = 20;
const HEADER_BYTES: usize = 28;
const RECORD_BYTES: usize = 16;
const KIND_MEASUREMENT: u8 = 1;
const KIND_SHARE: u8 = 2;

/// A batch being filled for one remote host.
pub struct Batch {
    buf: Vec<u8>,
    count: u32,
}

impl Batch {
    pub fn new(run_id: u64) -> Self {
        let mut buf = Vec::with_capacity(4096);
        buf.extend_from_slice(&MAGIC);
        buf.extend_from_slice(&SCHEMA_VERSION.to_le_bytes());
        buf.extend_from_slice(&run_id.to_le_bytes());
        buf.extend_from_slice(&0u32.to_le_bytes());
        buf.extend_from_slice(&0u64.to_le_bytes());
        Self { buf, count: 0 }
    }
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
    pub fn len(&self) -> u32 {
        self.count
    }
    pub fn push_measurement(&mut self, to: u32, m: &Measurement) {
        self.push(KIND_MEASUREMENT, PLANT_ID, to, bytes_of(m));
    }
    pub fn push_share(&mut self, s: &Share) {
        self.push(KIND_SHARE, s.header.sender, 0, bytes_of(s));
    }
    fn push(&mut self, kind: u8, sender: u32, to: u32, bytes: &[u8]) {
        let used = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
        self.buf.extend_from_slice(&[kind, 0, 0, 0]);
        self.buf.extend_from_slice(&sender.to_le_bytes());
        self.buf.extend_from_slice(&to.to_le_bytes());
        self.buf.extend_from_slice(&(used as u32).to_le_bytes());
        self.buf.extend_from_slice(&bytes[..used]);
        self.count += 1;
    }
    /// The payload, with the plant's waiting advice (0 from a host without the plant), leaving
    /// this batch empty for the next drain.
    pub fn take(&mut self, wait_advice: u64) -> Vec<u8> {
        self.buf[COUNT_AT..COUNT_AT + 4].copy_from_slice(&self.count.to_le_bytes());
        self.buf[ADVICE_AT..HEADER_BYTES].copy_from_slice(&wait_advice.to_le_bytes());
        let run_id = u64_at(&self.buf, RUN_AT);
        std::mem::replace(self, Batch::new(run_id)).buf
    }
}

/// One checked message of a received batch: its bytes up to the last non-zero one (at most the
/// message's size; [`Record::measurement`] and [`Record::share`] give the whole message).
#[derive(Debug, Clone, Copy)]
pub enum Record<'a> {
    Measurement { to: u32, bytes: &'a [u8] },
    Share { from: u32, bytes: &'a [u8] },
}

impl Record<'_> {
    /// The measurement a record carries (its zero tail restored).
    pub fn measurement(bytes: &[u8]) -> Measurement {
        read_payload_prefix(bytes)
    }
    /// The share a record carries (its zero tail restored).
    pub fn share(bytes: &[u8]) -> Share {
        read_payload_prefix(bytes)
    }
}

/// A received batch, checked: the plant's waiting advice it carries (0: none) and its messages.
#[derive(Debug)]
pub struct Received<'a> {
    pub wait_advice: u64,
    pub records: Vec<Record<'a>>,
}

/// Why a received batch was refused (as a whole: nothing of it is delivered).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BatchError {
    #[error("{0} bytes: shorter than a batch header")]
    Short(usize),
    #[error("not a gateway batch (magic {0:02x?})")]
    Magic([u8; 4]),
    #[error("schema version {0}, this build speaks {SCHEMA_VERSION}")]
    Version(u32),
    #[error("run {0:016x}, not this run")]
    Run(u64),
    #[error("record {index}: {reason}")]
    Record { index: u32, reason: String },
    #[error("{0} bytes after the last record")]
    Trailing(usize),
    #[error("waiting advice from host {0}, which does not run the plant")]
    Advice(u16),
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// The advice and records of a batch that host `from_host` sent to host `here`, every one checked.
pub fn decode<'a>(
    bytes: &'a [u8],
    run_id: u64,
    placement: &Placement,
    from_host: u16,
    here: u16,
) -> Result<Received<'a>, BatchError> {
    if bytes.len() < HEADER_BYTES {
        return Err(BatchError::Short(bytes.len()));
    }
    let magic: [u8; 4] = bytes[..4].try_into().expect("4 bytes");
    if magic != MAGIC {
        return Err(BatchError::Magic(magic));
    }
    let version = u32_at(bytes, VERSION_AT);
    if version != SCHEMA_VERSION {
        return Err(BatchError::Version(version));
    }
    let run = u64_at(bytes, RUN_AT);
    if run != run_id {
        return Err(BatchError::Run(run));
    }
    let count = u32_at(bytes, COUNT_AT);
    let wait_advice = u64_at(bytes, ADVICE_AT);
    if wait_advice != 0 && placement.host(Proc::Plant) != from_host {
        return Err(BatchError::Advice(from_host));
    }
    let mut at = HEADER_BYTES;
    let mut out = Vec::with_capacity((count as usize).min(2 * crate::msg::MAX_AGENTS));
    for index in 0..count {
        let bad = |reason: String| BatchError::Record { index, reason };
        if bytes.len() < at + RECORD_BYTES {
            return Err(bad("the batch ends inside it".into()));
        }
        let (kind, sender, to, len) =
            (bytes[at], u32_at(bytes, at + 4), u32_at(bytes, at + 8), u32_at(bytes, at + 12) as usize);
        at += RECORD_BYTES;
        if bytes.len() < at + len {
            return Err(bad(format!("a payload of {len} bytes runs past the batch's end")));
        }
        let payload = &bytes[at..at + len];
        at += len;
        let from = match sender {
            PLANT_ID => Proc::Plant,
            i if i as usize <= placement.n_agents() => Proc::Agent(i),
            i => return Err(bad(format!("sender {i} is no process of the run"))),
        };
        if placement.host(from) != from_host {
            return Err(bad(format!("{} does not run on host {from_host}", from.name())));
        }
        let size = match kind {
            KIND_MEASUREMENT => std::mem::size_of::<Measurement>(),
            _ => std::mem::size_of::<Share>(),
        };
        if len > size {
            return Err(bad(format!("a payload of {len} bytes, more than the message's {size}")));
        }
        let record = match kind {
            KIND_MEASUREMENT if from == Proc::Plant => {
                if to == 0 || to as usize > placement.n_agents() || placement.host(Proc::Agent(to)) != here {
                    return Err(bad(format!("a measurement for agent {to}, which does not run here")));
                }
                Record::Measurement { to, bytes: payload }
            }
            KIND_SHARE if from != Proc::Plant => Record::Share { from: sender, bytes: payload },
            k => return Err(bad(format!("kind {k} from {}", from.name()))),
        };
        out.push(record);
    }
    if at != bytes.len() {
        return Err(BatchError::Trailing(bytes.len() - at));
    }
    Ok(Received { wait_advice, records: out })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Header;
    use crate::transport::read_payload;

    fn header(sender: u32) -> Header {
        Header { version: SCHEMA_VERSION, sender, run_id: 7, step: 3, t_s: 0.3, sent_wall_ns: 11, mac: [5, 6] }
    }

    /// Plant on host 0, agents 1, 2 on host 1, agent 3 on host 2.
    fn placement() -> Placement {
        Placement::new(vec![0, 1, 1, 2])
    }

    #[test]
    fn a_batch_round_trips_bit_for_bit() {
        let share = Share::new(header(3), &[1.5], &[-0.25, 1e-300]);
        let mut b = Batch::new(7);
        b.push_share(&share);
        let bytes = b.take(0);
        assert!(bytes.len() < 200, "{} bytes: the share's unused tail is not sent", bytes.len());
        let got = decode(&bytes, 7, &placement(), 2, 0).unwrap();
        let [Record::Share { from: 3, bytes }] = got.records.as_slice() else { panic!("{got:?}") };
        assert_eq!(bytes_of(&Record::share(bytes)), bytes_of(&share));
        assert_eq!(got.wait_advice, 0);
        // The batch is empty again after take, with the same run.
        assert!(b.is_empty());
        assert_eq!(decode(&b.take(0), 7, &placement(), 2, 0).unwrap().records.len(), 0);
    }

    #[test]
    fn a_measurement_for_an_agent_of_this_host_round_trips() {
        let mut m: Measurement = read_payload(&vec![0u8; std::mem::size_of::<Measurement>()]);
        m.header = header(PLANT_ID);
        m.len = 2;
        m.readings[1] = 4.0;
        let mut b = Batch::new(7);
        b.push_measurement(2, &m);
        // The plant's host (0) passes on its advice with the measurements.
        let bytes = b.take(u64::MAX - 1);
        let got = decode(&bytes, 7, &placement(), 0, 1).unwrap();
        let [Record::Measurement { to: 2, bytes }] = got.records.as_slice() else { panic!("{got:?}") };
        assert_eq!(bytes_of(&Record::measurement(bytes)), bytes_of(&m));
        assert_eq!(got.wait_advice, u64::MAX - 1);
    }

    #[test]
    fn a_host_cannot_speak_for_another_hosts_processes() {
        let mut b = Batch::new(7);
        b.push_share(&Share::new(header(3), &[], &[1.0]));
        let bytes = b.take(0);
        // Agent 3 runs on host 2: a batch from host 1 carrying its share is refused.
        let e = decode(&bytes, 7, &placement(), 1, 0).unwrap_err();
        assert_eq!(e.to_string(), "record 0: agent-3 does not run on host 1");
        // A measurement for an agent of another host.
        let m: Measurement = read_payload(&vec![0u8; std::mem::size_of::<Measurement>()]);
        let mut b = Batch::new(7);
        b.push_measurement(3, &m);
        let e = decode(&b.take(0), 7, &placement(), 0, 1).unwrap_err();
        assert!(e.to_string().contains("agent 3, which does not run here"), "{e}");
        // Waiting advice from a host without the plant (agent 3's host 2, even an empty batch).
        let e = decode(&Batch::new(7).take(5), 7, &placement(), 2, 0).unwrap_err();
        assert_eq!(e, BatchError::Advice(2));
        assert_eq!(e.to_string(), "waiting advice from host 2, which does not run the plant");
    }

    #[test]
    fn damaged_batches_are_refused_whole() {
        let mut b = Batch::new(7);
        b.push_share(&Share::new(header(1), &[], &[1.0]));
        let good = b.take(0);
        assert_eq!(decode(&good, 8, &placement(), 1, 0).unwrap_err(), BatchError::Run(7));
        assert_eq!(decode(&good[..10], 7, &placement(), 1, 0).unwrap_err(), BatchError::Short(10));
        let mut cut = good.clone();
        cut.truncate(good.len() - 1);
        assert!(matches!(decode(&cut, 7, &placement(), 1, 0), Err(BatchError::Record { index: 0, .. })));
        let mut more = good.clone();
        more.push(0);
        assert_eq!(decode(&more, 7, &placement(), 1, 0).unwrap_err(), BatchError::Trailing(1));
        let mut kind = good.clone();
        kind[HEADER_BYTES] = 9;
        assert!(decode(&kind, 7, &placement(), 1, 0).unwrap_err().to_string().contains("kind 9"));
        let mut magic = good;
        magic[0] = b'X';
        assert!(matches!(decode(&magic, 7, &placement(), 1, 0), Err(BatchError::Magic(_))));
    }
}
