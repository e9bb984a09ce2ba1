//! Recording and replay over the in-memory transport with toy models: the recording holds every
//! message each agent saw, byte for byte; recording changes no telemetry; the same algorithm
//! replays bit-identically, an edited one is caught at its first differing share with the field
//! named; a damaged, cut-short or missing file is refused by reason.

use std::path::{Path, PathBuf};
use std::time::Duration;

use cohort_wire::transport::memory::MemoryBus;
use cohort_wire::transport::{Proc, Topology};

use super::reader::{self, Msg, ReadError};
use super::replay::replay_with;
use super::writer::{RecordMeta, Recording};
use super::{Direction, path_for};
use crate::drive::{DriveParams, run_agent, run_plant};
use crate::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use crate::record::RunDirs;
use crate::rng::process_rng;

const STEPS: u64 = 40;
const RUN_ID: u64 = 0x5eed;

/// The drive tests' 1-D integrators.
use crate::drive::tests::ToyPlant as Plant;

/// Consensus u = gain · Σ (yⱼ − y); shares y.
struct Agent {
    gain: f64,
    y: f64,
    nbr: Vec<f64>,
}
impl Agent {
    fn new(gain: f64) -> Self {
        Self { gain, y: 0.0, nbr: vec![] }
    }
    fn u(&self) -> f64 {
        self.nbr.iter().map(|x| x - self.y).sum::<f64>() * self.gain
    }
}
impl Algorithm for Agent {
    fn columns(&self) -> Vec<String> {
        vec!["y".into(), "u".into()]
    }
    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        self.y = input.readings[0];
        out.command.push(self.u());
        out.values.push(self.y);
    }
    fn step(&mut self, _dt_s: f64, neighbours: &[Neighbour<'_>]) {
        self.nbr = neighbours.iter().map(|n| n.values[0]).collect();
    }
    fn row(&self, out: &mut Vec<f64>) {
        out.extend([self.y, self.u()]);
    }
    fn save_state(&self) -> Vec<u8> {
        crate::checkpoint::encode_state(&(self.y, &self.nbr))
    }
    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        (self.y, self.nbr) = crate::checkpoint::decode_state(bytes)?;
        Ok(())
    }
}

fn topo() -> Topology {
    Topology { neighbours: vec![vec![2, 4], vec![1, 3], vec![2, 4], vec![3, 1]] }
}

fn params(dir: &Path) -> DriveParams {
    let dirs = RunDirs::new(dir);
    dirs.create_all().unwrap();
    // CSV: the checks below read agent 1's rows as text (recording is format-blind).
    let mut p = DriveParams::basic(RUN_ID, STEPS, 0.1, Duration::from_secs(20), dirs);
    p.telemetry = cohort_scenario::TelemetryFormat::Csv;
    p
}

fn meta(me: Proc) -> RecordMeta {
    let t = topo();
    let Proc::Agent(i) = me else { unreachable!() };
    RecordMeta {
        me,
        run_id: RUN_ID,
        dt_s: 0.1,
        neighbours: t.neighbours_of(i).to_vec(),
        readers: t.readers_of(i),
        scenario: "toy".into(),
        seed: 5,
        attachments: Vec::new(),
    }
}

/// A 4-agent ring run into `dir`, every agent recording when `record`.
fn run(dir: &Path, record: bool) {
    let bus = MemoryBus::new(topo());
    let p = params(dir);
    std::thread::scope(|sc| {
        let plant = sc.spawn(|| {
            let mut t = bus.endpoint(Proc::Plant);
            let mut m = Plant { x: vec![1.0, -2.0, 3.5, 0.25], u: vec![0.0; 4] };
            run_plant(&mut t, &mut m, &mut process_rng(5, Proc::Plant), 4, &p)
        });
        let agents: Vec<_> = (1..=4u32)
            .map(|i| {
                let (bus, p) = (&bus, &p);
                sc.spawn(move || {
                    let mut t = bus.endpoint(Proc::Agent(i));
                    let mut a = Agent::new(0.7);
                    let nb = topo().neighbours_of(i).to_vec();
                    if record {
                        let mut rec = Recording::start(&mut t, &p.dirs.root, meta(Proc::Agent(i))).unwrap();
                        let r = run_agent(&mut rec, &mut a, i, &nb, p, None);
                        rec.finish().unwrap();
                        r
                    } else {
                        run_agent(&mut t, &mut a, i, &nb, p, None)
                    }
                })
            })
            .collect();
        assert!(plant.join().unwrap().error.is_none());
        for a in agents {
            assert!(a.join().unwrap().error.is_none());
        }
    });
}

fn scratch(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cohort-recording-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Every telemetry file of a run (Parquet or CSV, whichever the run wrote), by name, with its
/// bytes: the plant's and the four agents'.
fn telemetry(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir.join("telemetry"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "parquet" || x == "csv"))
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()))
        .collect();
    files.sort();
    assert_eq!(
        files.len(),
        5,
        "expected the plant's and 4 agents' telemetry: {:?}",
        files.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    files
}

#[test]
fn a_recording_holds_every_message_and_replays_bit_for_bit_and_an_edit_is_named() {
    let (with, without) = (scratch("with"), scratch("without"));
    run(&with, true);
    run(&without, false);
    // Recording changes no telemetry.
    assert_eq!(telemetry(&with), telemetry(&without));

    let rec = reader::read(&path_for(&with, Proc::Agent(1))).unwrap();
    assert_eq!(rec.run_id().unwrap(), RUN_ID);
    assert_eq!(rec.id().unwrap(), 1);
    assert_eq!(rec.meta("neighbours").unwrap(), "2,4");
    let count = |dir: Direction, pick: &dyn Fn(&Msg) -> bool| {
        rec.messages.iter().filter(|m| m.dir == dir && pick(&m.msg)).count() as u64
    };
    assert_eq!(count(Direction::Received, &|m| matches!(m, Msg::Measurement(_))), STEPS);
    for j in [2, 4] {
        assert_eq!(count(Direction::Received, &|m| matches!(m, Msg::Share { from, .. } if *from == j)), STEPS);
    }
    assert_eq!(count(Direction::Sent, &|m| matches!(m, Msg::Share { from: 1, .. })), STEPS);
    // Each sent share carries what agent 1's telemetry says it computed (y, and u in its command).
    let tel = std::fs::read_to_string(with.join("telemetry/agent-1.csv")).unwrap();
    let sent: Vec<_> = rec
        .messages
        .iter()
        .filter_map(|m| match (&m.msg, m.dir) {
            (Msg::Share { share, .. }, Direction::Sent) => Some(share),
            _ => None,
        })
        .collect();
    for (line, s) in tel.lines().skip(1).zip(&sent) {
        let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(
            (f[0] as u64, f[2].to_bits(), f[3].to_bits()),
            (s.header.step, s.values[0].to_bits(), s.command[0].to_bits())
        );
        assert_eq!(s.header.sent_wall_ns, 0, "sent shares are recorded before the transport stamps them");
    }

    // The same algorithm replays identically; its telemetry is the run's.
    let out = with.join("replay");
    let same = replay_with(&mut Agent::new(0.7), 1, &[2, 4], params(&out), &rec, None);
    assert!(same.identical(), "{same:?}");
    assert_eq!((same.steps, same.identical), (STEPS, STEPS as usize));
    assert_eq!(std::fs::read(out.join("telemetry/agent-1.csv")).unwrap(), tel.as_bytes());

    // An edited gain departs at the first step whose command uses a neighbour (step 1), in command[0].
    let edited = replay_with(&mut Agent::new(0.8), 1, &[2, 4], params(&scratch("edited")), &rec, None);
    let m = edited.first.clone().expect("a mismatch");
    assert_eq!((m.step, m.index), (1, 1), "{m}");
    assert_eq!(m.field, "command[0]");
    let at = std::mem::offset_of!(cohort_wire::msg::Share, command);
    assert!((at..at + 8).contains(&m.offset), "{m}");
    assert!(!edited.identical() && edited.identical == 1, "{edited:?}");
    assert!(m.recorded.contains("bits 0x") && m.recorded != m.replayed, "{m}");
    for d in [with, without, scratch("edited")] {
        let _ = std::fs::remove_dir_all(d);
    }
}

#[test]
fn a_damaged_cut_short_missing_or_foreign_file_is_refused_by_reason() {
    let dir = scratch("damaged");
    run(&dir, true);
    let path = path_for(&dir, Proc::Agent(2));
    let good = std::fs::read(&path).unwrap();
    assert!(good.len() > 1000, "{} bytes", good.len());

    // One bit flipped in the first chunk's CRC of its decompressed records (chunk record: opcode,
    // length, start and end time, decompressed size, CRC, …).
    let summary = mcap::Summary::read(&good).unwrap().expect("a summary");
    let chunk = &summary.chunk_indexes[0];
    let mut bad = good.clone();
    bad[usize::try_from(chunk.chunk_start_offset).unwrap() + 1 + 8 + 24] ^= 0x40;
    std::fs::write(&path, &bad).unwrap();
    let e = reader::read(&path).err().expect("refused");
    assert!(matches!(e, ReadError::Corrupt { .. } | ReadError::Foreign { .. }), "{e}");
    assert!(e.to_string().contains("agent-2.mcap"), "{e}");

    // A chunk whose header claims an absurd decompressed size (the mcap crate would reserve it
    // first and panic on "capacity overflow"): refused, naming the chunk.
    let at = usize::try_from(chunk.chunk_start_offset).unwrap() + 1 + 8 + 16;
    let mut huge = good.clone();
    huge[at..at + 8].copy_from_slice(&(u64::MAX / 3).to_le_bytes());
    std::fs::write(&path, &huge).unwrap();
    let e = reader::read(&path).err().expect("refused");
    assert!(matches!(e, ReadError::Corrupt { .. }) && e.to_string().contains("decompressed size"), "{e}");

    // Cut short, as a killed process leaves it: read up to its last complete chunk, saying so.
    std::fs::write(&path, &good).unwrap();
    let whole = reader::read(&path).unwrap();
    assert!(whole.cut_short.is_none());
    // Cut one byte into the record after the first chunk: that chunk's messages are read.
    let first_end = usize::try_from(chunk.chunk_start_offset + chunk.chunk_length).unwrap();
    std::fs::write(&path, &good[..first_end + 1]).unwrap();
    let part = reader::read(&path).expect("read up to the cut");
    let says = part.cut_short.clone().expect("says it is cut short");
    assert!(says.contains("no footer") && says.contains("agent-2.mcap"), "{says}");
    assert!(says.contains(&format!("read up to offset {first_end}")), "{says}");
    assert!(!part.messages.is_empty() && part.messages.len() <= whole.messages.len(), "{says}");
    // Cut inside the first chunk: nothing complete to read, said so.
    std::fs::write(&path, &good[..first_end - 10]).unwrap();
    let none = reader::read(&path).expect("read up to the cut");
    assert!(none.messages.is_empty() && none.cut_short.is_some());

    // Not an MCAP at all, and no file.
    std::fs::write(&path, b"telemetry, not a recording").unwrap();
    assert!(matches!(reader::read(&path), Err(ReadError::Corrupt { .. })));
    let e = reader::read(&dir.join("record/agent-9.mcap")).err().expect("refused");
    assert!(matches!(e, ReadError::Missing { .. }) && e.to_string().contains("--record"), "{e}");

    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 36, defect 4: seeded one-byte flips anywhere in a recording, and many in its chunks'
/// headers and zstd frame headers (where the mcap crate allocated from a damaged length and the
/// process aborted), are each read or refused naming the file: never a panic or an abort.
#[test]
fn seeded_byte_flips_are_read_or_refused_never_an_abort() {
    let dir = scratch("flips");
    run(&dir, true);
    let path = path_for(&dir, Proc::Agent(2));
    let good = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&good).unwrap().expect("a summary");
    let chunks: Vec<usize> = summary.chunk_indexes.iter().map(|c| c.chunk_start_offset as usize).collect();
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let (mut read, mut refused) = (0, 0);
    for n in 0..2000 {
        let at = if n % 2 == 0 {
            (next() % good.len() as u64) as usize
        } else {
            // The chunk record's header and the start of its zstd frame (byte +59 among them).
            (chunks[(next() % chunks.len() as u64) as usize] + (next() % 96) as usize).min(good.len() - 1)
        };
        let mut bad = good.clone();
        bad[at] ^= 1 << (next() % 8);
        std::fs::write(&path, &bad).unwrap();
        match reader::read(&path) {
            Ok(_) => read += 1,
            Err(e) => {
                assert!(e.to_string().contains("agent-2.mcap"), "flip at {at}: {e}");
                refused += 1;
            }
        }
    }
    assert!(refused > 500, "{read} read, {refused} refused");
    let _ = std::fs::remove_dir_all(&dir);
}

/// An MCAP file with one attachment of `data`, as the writer's mcap crate writes it.
fn file_with_attachment(data: &[u8]) -> Vec<u8> {
    let mut buf = std::io::Cursor::new(Vec::new());
    let mut w = mcap::WriteOptions::new().create(&mut buf).unwrap();
    let a = mcap::Attachment {
        log_time: 0,
        create_time: 0,
        name: super::RESTORED_FROM.into(),
        media_type: super::CHECKPOINT_MEDIA_TYPE.into(),
        data: std::borrow::Cow::Borrowed(data),
    };
    w.attach(&a).unwrap();
    w.finish().unwrap();
    drop(w);
    buf.into_inner()
}

#[test]
fn an_attachment_is_read_back_whole_and_a_flipped_byte_of_it_is_damage() {
    let data: Vec<u8> = (0..=255u8).cycle().take(3000).collect();
    let good = file_with_attachment(&data);
    let w = super::walk::walk(&good).unwrap();
    assert_eq!(w.attachments.len(), 1);
    assert_eq!((w.attachments[0].name.as_str(), &w.attachments[0].data), (super::RESTORED_FROM, &data));
    let at = good.windows(16).position(|win| win == &data[..16]).expect("the data in the file");
    let mut bad = good.clone();
    bad[at + 100] ^= 0x01;
    let e = super::walk::walk(&bad).expect_err("refused");
    assert!(e.reason.contains("CRC mismatch") && e.reason.contains(super::RESTORED_FROM), "{e}");
}
