//! Telemetry as Apache Parquet (`run.telemetry = "parquet"`, the default): one file per process,
//! `k` (UInt64) then one Float64 column per value, each column's unit (from [`crate::units`]) in
//! its Arrow field metadata under `unit`. Doubles are stored as they are (bit-exact). The same
//! writer writes a process's wall-clock timing (`timing/<proc>.parquet`), whose value columns are
//! UInt64 (nanoseconds): [`ParquetWriter`] is generic over the value type ([`Value`]).
//!
//! A Parquet file is readable only once its footer is written, so a process killed with SIGKILL
//! would lose every row of an open file. Never lose telemetry: rows go to disk twice, both off the
//! step path, on a writer thread:
//! * every [`ParquetWriter::batch_rows`] rows (the first batch shorter by the file's `phase`, so
//!   that a lockstep's processes do not all write at the same step; at most [`JOURNAL_BATCH_BYTES`] of numbers: fewer
//!   rows than the CSV writer's 64 KiB text buffer holds, so no more rows are at risk than with
//!   CSV) are appended, as raw little-endian numbers, to a journal `telemetry/<proc>.rows` (one
//!   `write`: no encoding, so it costs next to nothing; see [`read_journal`] for the format);
//! * the same rows go to the final file, written in row groups of [`rows_per_group`] rows into a
//!   hidden temporary file, closed and renamed to `telemetry/<proc>.parquet` by
//!   [`ParquetWriter::finish`], which then removes the journal. The encoding waits for `finish`
//!   (the rows wait in memory, up to a budget, [`defer_budget`], then are encoded as they come): on 2 cores the
//!   lockstep leaves no core idle, and encoding during the run slowed fig1's step loop by 16 %
//!   against CSV (9 % with the writer thread at nice 19); deferred, the loop runs as fast as with
//!   CSV or faster, and the run's end takes ≈ 0.1–0.3 s longer.
//!
//! So a clean exit leaves one file per process; a killed process leaves its journal, whose
//! complete rows [`seal_dir`] (the orchestrator, after every run) turns into the same one file.
//! [`ParquetWriter::flush`] (before a planned process fault) appends the buffered rows to the
//! journal and waits until they are written; it does not close the final file, so it costs one
//! small `write`, never a rewrite of the rows so far. (Closing and reopening the file at every
//! flush, as a first version did, made every fault hold slow enough in real time to expose a
//! plant bug: see `drive.rs`, `last_heard`.)
//!
//! Bytes are deterministic: the final file's row groups fall every [`rows_per_group`] rows (a
//! function of the file's width) whatever the flushes, with no time stamps (`created_by` is
//! fixed by the crate version).

use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel, sync_channel};
use std::thread::JoinHandle;

use arrow_array::cast::AsArray;
use arrow_array::types::{ArrowPrimitiveType, Float64Type, UInt64Type};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch, UInt64Array};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::properties::WriterProperties;
use parquet::schema::types::ColumnPath;

/// Rows per row group of a file of at most [`GROUP_BYTES`]` / 32 kB` = 1 024 columns: 4096
/// rows of a 107-column file (the widest shipped plant) are 3.5 MB before compression.
pub const ROWS_PER_GROUP: usize = 4096;

/// At most this many bytes of numbers per row group: a wider file's groups have fewer rows
/// ([`rows_per_group`]). The writer holds a whole group in memory (each column's values, then
/// its compressed pages) until the group closes: a 1 000-agent ring's plant file has 9 003
/// columns, and 4096 of its rows held 295 MB in the plant (a 300-agent plant's resident set
/// was 341 MB against 65 MB writing CSV). Each group also adds its columns' metadata to the
/// footer (≈ 100 bytes a column), so groups must not get small: at 32 MiB and 9 003 columns
/// (465 rows a group) that is ≈ 3 % of a group's numbers.
pub const GROUP_BYTES: usize = 32 << 20;

/// Fewest rows per row group, whatever the width.
const MIN_GROUP_ROWS: usize = 64;

/// Rows per row group of a file of `columns` columns (the step column included): a function of
/// the schema alone, so the bytes of a file do not depend on when it was flushed or sealed.
pub fn rows_per_group(columns: usize) -> usize {
    (GROUP_BYTES / (8 * columns.max(1))).clamp(MIN_GROUP_ROWS, ROWS_PER_GROUP)
}

/// At most this many bytes of numbers per journal write: 2048 numbers. The CSV writer buffers
/// 64 KiB of text, at 17 to 25 characters per double about 2600 to 3800 numbers, all lost with
/// the process.
pub const JOURNAL_BATCH_BYTES: usize = 16 * 1024;

/// Fewest rows per journal write.
const MIN_BATCH_ROWS: usize = 8;

/// The first line of a journal.
const JOURNAL_MAGIC: &[u8] = b"COHORT-ROWS 2\n";

/// The type of a file's value columns (those after `k`): `f64` (telemetry) or `u64` (timing).
pub trait Value: arrow_array::ArrowNativeTypeOp + Send + Sync + 'static {
    type Arrow: ArrowPrimitiveType<Native = Self>;
    /// Its name in a journal's header.
    const NAME: &'static str;
    fn data_type() -> DataType {
        Self::Arrow::DATA_TYPE
    }
    /// The 64-bit word a journal holds for it (a double's bits, or the whole number).
    fn word(self) -> u64;
}

impl Value for f64 {
    type Arrow = Float64Type;
    const NAME: &'static str = "f64";
    fn word(self) -> u64 {
        self.to_bits()
    }
}

impl Value for u64 {
    type Arrow = UInt64Type;
    const NAME: &'static str = "u64";
    fn word(self) -> u64 {
        self
    }
}

/// The value type a journal names.
fn value_type(name: &str) -> Option<DataType> {
    [(f64::NAME, f64::data_type()), (u64::NAME, u64::data_type())].into_iter().find(|(n, _)| *n == name).map(|x| x.1)
}

/// The metadata key of a field's unit.
pub const UNIT_KEY: &str = "unit";

/// The journal of the telemetry file `path` (`agent-2.parquet` → `agent-2.rows`).
pub fn journal_path(path: &Path) -> PathBuf {
    path.with_extension("rows")
}

/// The Arrow schema of a file with these columns (`k` first, then the value columns, of type
/// `value`: Float64 for telemetry, UInt64 for timing).
pub fn schema(columns: &[String], value: DataType) -> SchemaRef {
    let fields: Vec<Field> = columns
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let field =
                if i == 0 { Field::new(name, DataType::UInt64, false) } else { Field::new(name, value.clone(), false) };
            match crate::units::unit_of(name) {
                Some(unit) => field.with_metadata(HashMap::from([(UNIT_KEY.to_string(), unit.to_string())])),
                None => field,
            }
        })
        .collect();
    Arc::new(Schema::new(fields))
}

/// The final file's encoding.
fn properties(schema: &Schema) -> WriterProperties {
    // Byte-stream split puts the bytes of equal significance of every double together, which
    // zstd then compresses far better than plain doubles (the widest shipped plant file:
    // 23.5 MB against 28.3 MB plain); the steps are a delta-coded count. Measured on that run: zstd levels 6
    // and 9 and row groups of 16384 or all rows gain under 1 %, level 12 6 % at three times
    // the CPU; dictionaries do not fit noisy doubles. Whole numbers (the steps, and timing's
    // nanoseconds) are delta-coded: bit-packed differences, which zstd shrinks further.
    //
    // A file wider than 1 024 columns (whose groups the width cuts short, `rows_per_group`) is
    // compressed with LZ4 (raw blocks) instead: the parquet crate gives every column writer of
    // the open row group its own zstd compression and decompression contexts (≈ 100 kB a
    // column, held until the group closes), which made most of a 300-agent plant's 300 MB
    // (2 703 columns). LZ4 keeps no context; on the ring's plant
    // files it wrote 1.5 % more bytes (2 703 columns, 3 000 rows: 54.5 MB against 53.7 MB).
    let rows = rows_per_group(schema.fields().len());
    let compression = if rows < ROWS_PER_GROUP {
        Compression::LZ4_RAW
    } else {
        Compression::ZSTD(ZstdLevel::try_new(3).expect("zstd level 3 exists"))
    };
    let mut b = WriterProperties::builder()
        .set_compression(compression)
        .set_dictionary_enabled(false)
        .set_encoding(Encoding::BYTE_STREAM_SPLIT)
        .set_max_row_group_row_count(Some(rows));
    for f in schema.fields().iter().filter(|f| *f.data_type() == DataType::UInt64) {
        b = b.set_column_encoding(ColumnPath::from(f.name().as_str()), Encoding::DELTA_BINARY_PACKED);
    }
    b.build()
}

/// How many rows the first journal batch of the file at `path` is short of `batch_rows`: a
/// function of the file's name, spread over `0..batch_rows`. A lockstep's processes write rows
/// at the same steps, so without it every agent's writer thread woke at the same step (and every
/// 186th step of a 100-agent ring): a hundred threads at once, which the scheduler runs before
/// the spinning processes of the lockstep, made those steps the run's slowest (see the README,
/// "Where a 100-agent step's worst cases come from"). Only when the journal is written changes;
/// the final file's bytes do not depend on it.
fn phase(path: &Path, batch_rows: usize) -> usize {
    // A digest of the name: `agent-17.parquet` and `agent-18.parquet` land far apart.
    let name = path.file_name().map_or(&[][..], |n| n.as_encoded_bytes());
    (cohort_wire::fnv1a(name) % batch_rows.max(1) as u64) as usize
}

type Ack = Sender<std::io::Result<()>>;

enum Cmd {
    /// Rows to write (to the journal, then into the final file), as the journal holds them (each
    /// row `k` then every value, one word each); answer once they are in the journal if asked.
    Rows(Vec<u64>, Option<Ack>),
    /// Close the final file, rename it into place, remove the journal; answer with the outcome.
    Finish(Ack),
}

/// Buffers rows and has a thread write them; see the module docs. `V` is the type of the value
/// columns (f64 for telemetry, u64 for timing).
///
/// The rows' buffers go to the writer thread and come back to be filled again, so that neither
/// thread frees what the other allocated. glibc's `free` of another thread's allocation takes that
/// thread's arena lock, and the writer thread runs at nice 19: preempted while it held the lock
/// of the process's main arena (freeing the columns it had been sent), it stalled the step
/// thread's next `malloc` for as long as the lockstep's spinning processes kept it off a core. A
/// 1 000-agent ring's plant slept there 40–220 ms at a time, five times in four seconds, and the
/// whole lockstep with it.
pub struct ParquetWriter<V: Value = f64> {
    /// The rows being buffered, in journal order (see [`Cmd::Rows`]).
    rows: Vec<u64>,
    /// Words per row: `k` and the values.
    width: usize,
    /// Emptied buffers the writer thread handed back.
    spare: Receiver<Vec<u64>>,
    value: std::marker::PhantomData<V>,
    batch_rows: usize,
    /// Rows of the batch being buffered: [`Self::batch_rows`], but the first batch is shorter by
    /// this file's [`phase`].
    this_batch: usize,
    tx: Option<Sender<Cmd>>,
    thread: Option<JoinHandle<()>>,
    path: PathBuf,
    finished: bool,
}

impl<V: Value> ParquetWriter<V> {
    /// A new file at `path` (replacing any, and any journal of one), `columns[0]` the step column.
    pub fn create(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        if path.exists() {
            std::fs::remove_file(path)?;
        }
        Self::open(path, columns)
    }
    /// Go on with an existing file (a relaunched agent continues its predecessor's rows); a
    /// journal a killed predecessor left is sealed into it first.
    pub fn append(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        if journal_path(path).exists() {
            seal(path)?;
        }
        Self::open(path, columns)
    }
    fn open(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        let schema = schema(columns, V::data_type());
        let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        // The journal now, with its header: a run directory that cannot be written fails here.
        let journal = new_journal(&journal_path(path), V::NAME, columns)?;
        let mut state = FileState {
            path: path.to_path_buf(),
            tmp: path.with_file_name(format!(".{name}.tmp")),
            journal: Some(journal),
            schema: schema.clone(),
            writer: None,
            error: None,
            bytes: Vec::new(),
            deferred: Vec::new(),
            deferred_bytes: 0,
        };
        let (tx, rx) = channel::<Cmd>();
        // Two places: a batch's buffer is back before the next batch is sent; a fixed ring, so
        // handing one back allocates nothing.
        let (back, spare) = sync_channel::<Vec<u64>>(2);
        let thread = std::thread::Builder::new().name(format!("telemetry {name}")).spawn(move || {
            // What this thread does during the run (journal writes; encoding beyond its budget)
            // competes for the cores with the lockstep's processes (on 2 cores, seven spinning
            // processes leave none idle): at the lowest priority it takes the time they leave.
            lower_this_threads_priority();
            // The final file starts with the predecessor's rows (a relaunched agent), copied
            // here, off the step path.
            if let Err(e) = state.start() {
                state.error = Some(e);
            }
            for cmd in rx {
                match cmd {
                    Cmd::Rows(mut rows, ack) => {
                        let r = state.write(&rows);
                        rows.clear();
                        // Full only if the step thread stopped taking them: then it is freed here.
                        let _ = back.try_send(rows);
                        if let Some(ack) = ack {
                            let _ = ack.send(r);
                        }
                    }
                    Cmd::Finish(ack) => {
                        let _ = ack.send(state.finish());
                        return;
                    }
                }
            }
        })?;
        let width = columns.len().max(1);
        let batch_rows = (JOURNAL_BATCH_BYTES / (8 * width)).clamp(MIN_BATCH_ROWS, ROWS_PER_GROUP);
        Ok(Self {
            rows: Vec::with_capacity(batch_rows * width),
            width,
            spare,
            value: std::marker::PhantomData,
            batch_rows,
            this_batch: batch_rows - phase(path, batch_rows),
            tx: Some(tx),
            thread: Some(thread),
            path: path.to_path_buf(),
            finished: false,
        })
    }
    /// Rows per journal write: the most rows a killed process can lose (with those of the
    /// batches still queued for the writer thread, which keeps up).
    pub fn batch_rows(&self) -> usize {
        self.batch_rows
    }
    /// Buffer one row: step `k`, then the values (one per column after `k`).
    pub fn row(&mut self, k: u64, values: &[V]) -> std::io::Result<()> {
        debug_assert_eq!(values.len() + 1, self.width, "{}", self.path.display());
        self.rows.push(k);
        self.rows.extend(values.iter().map(|v| v.word()));
        if self.rows.len() >= self.this_batch * self.width { self.send_rows(None) } else { Ok(()) }
    }
    /// Hand the buffered rows to the writer thread (always, when `ack` is given).
    fn send_rows(&mut self, ack: Option<Ack>) -> std::io::Result<()> {
        if self.rows.is_empty() && ack.is_none() {
            return Ok(());
        }
        self.this_batch = self.batch_rows;
        let next = self.spare.try_recv().unwrap_or_else(|_| Vec::with_capacity(self.batch_rows * self.width));
        let rows = std::mem::replace(&mut self.rows, next);
        self.send(Cmd::Rows(rows, ack))
    }
    fn gone(&self) -> std::io::Error {
        std::io::Error::other(format!("{}: the telemetry writer thread ended", self.path.display()))
    }
    fn send(&self, cmd: Cmd) -> std::io::Result<()> {
        self.tx.as_ref().ok_or_else(|| self.gone())?.send(cmd).map_err(|_| self.gone())
    }
    /// Put every buffered row in the journal and wait until it is there; the final file stays
    /// open. Before a planned process fault, which may end the process.
    pub fn flush(&mut self) -> std::io::Result<()> {
        if self.finished {
            return Ok(());
        }
        let (ack, answer) = channel();
        self.send_rows(Some(ack))?;
        answer.recv().map_err(|_| self.gone())?
    }
    /// Write every row into the final file, close it, rename it into place and remove the
    /// journal. The writer takes no rows after this.
    pub fn finish(&mut self) -> std::io::Result<()> {
        if self.finished {
            return Ok(());
        }
        self.finished = true;
        let sent = self.send_rows(None);
        let (ack, answer) = channel();
        let finished = self.send(Cmd::Finish(ack)).and_then(|_| answer.recv().map_err(|_| self.gone())?);
        drop(self.tx.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        sent.and(finished)
    }
}

impl<V: Value> Drop for ParquetWriter<V> {
    fn drop(&mut self) {
        // Rows not written yet (an unwinding panic) still reach the file.
        let _ = self.finish();
    }
}

/// A new journal at `path` with the header of these columns: the magic line, the value type's
/// name ([`Value::NAME`]) and a newline, then the column names joined by commas and a newline.
fn new_journal(path: &Path, value: &str, columns: &[String]) -> std::io::Result<File> {
    let mut f = File::create(path)?;
    f.write_all(JOURNAL_MAGIC)?;
    f.write_all(value.as_bytes())?;
    f.write_all(b"\n")?;
    f.write_all(columns.join(",").as_bytes())?;
    f.write_all(b"\n")?;
    Ok(f)
}

/// A journal's header (see [`new_journal`]): its value type, its column names (`k` first) and
/// its length in bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct JournalHeader {
    pub value: DataType,
    pub columns: Vec<String>,
    pub len: usize,
}

impl JournalHeader {
    /// Whether its values are f64 telemetry (not u64 timing).
    pub fn holds_f64(&self) -> bool {
        self.value == DataType::Float64
    }
}

/// The header at the start of `bytes`, `Ok(None)` while it is not whole yet (a journal still
/// being written, read by `launch --live`), or why these bytes are not a journal's.
pub fn journal_header(bytes: &[u8]) -> Result<Option<JournalHeader>, &'static str> {
    let Some(rest) = bytes.strip_prefix(JOURNAL_MAGIC) else {
        return if JOURNAL_MAGIC.starts_with(bytes) { Ok(None) } else { Err("no header") };
    };
    let mut lines = rest.splitn(3, |&b| b == b'\n');
    let (Some(value), Some(names), Some(_)) = (lines.next(), lines.next(), lines.next()) else { return Ok(None) };
    let len = JOURNAL_MAGIC.len() + value.len() + names.len() + 2;
    let value = std::str::from_utf8(value).ok().and_then(value_type).ok_or("unknown value type")?;
    let columns: Vec<String> =
        std::str::from_utf8(names).map_err(|_| "column names are not UTF-8")?.split(',').map(str::to_string).collect();
    if columns.len() < 2 {
        return Err("fewer than two columns");
    }
    Ok(Some(JournalHeader { value, columns, len }))
}

/// The columns and the complete rows of a journal: after the header (see [`new_journal`]),
/// each row is `k` (u64) and then every value (f64 bits or u64), 8 bytes each, little-endian. A
/// row cut short by the end of the file (the process died while writing it) is left out.
pub fn read_journal(path: &Path) -> std::io::Result<(Vec<String>, RecordBatch)> {
    let bad = |why: &str| std::io::Error::other(format!("{}: not a telemetry journal: {why}", path.display()));
    let mut bytes = Vec::new();
    File::open(path)?.read_to_end(&mut bytes)?;
    let JournalHeader { value, columns, len } =
        journal_header(&bytes).map_err(bad)?.ok_or_else(|| bad("header cut short"))?;
    let schema = schema(&columns, value);
    let batch = batch_from_words(&bytes[len..], &schema).map_err(std::io::Error::other)?;
    Ok((columns, batch))
}

/// The whole rows of journal-format `data` (each row `k`, then every value, 8 little-endian bytes
/// each) as a batch of `schema` (its value columns Float64 or UInt64); a cut-short last row is
/// left out.
fn batch_from_words(data: &[u8], schema: &SchemaRef) -> Result<RecordBatch, arrow_schema::ArrowError> {
    let width = schema.fields().len();
    let rows = data.len() / (8 * width);
    let word = |r: usize, c: usize| {
        let at = 8 * (r * width + c);
        u64::from_le_bytes(data[at..at + 8].try_into().expect("8 bytes"))
    };
    let mut arrays: Vec<ArrayRef> =
        vec![Arc::new(UInt64Array::from((0..rows).map(|r| word(r, 0)).collect::<Vec<_>>()))];
    for (c, field) in schema.fields().iter().enumerate().skip(1) {
        let words = (0..rows).map(|r| word(r, c));
        arrays.push(if field.data_type() == &DataType::Float64 {
            Arc::new(Float64Array::from(words.map(f64::from_bits).collect::<Vec<_>>()))
        } else {
            Arc::new(UInt64Array::from(words.collect::<Vec<_>>()))
        });
    }
    RecordBatch::try_new(schema.clone(), arrays)
}

/// One UInt64 column of a Parquet file (a timing file's nanoseconds, or any file's `k`).
pub fn read_u64_column(path: &Path, column: &str) -> std::io::Result<Vec<u64>> {
    let bad = |e: &dyn std::fmt::Display| std::io::Error::other(format!("{}: {e}", path.display()));
    let builder =
        ParquetRecordBatchReaderBuilder::try_new(File::open(path).map_err(|e| bad(&e))?).map_err(|e| bad(&e))?;
    let Some(i) = builder.schema().fields().iter().position(|f| f.name() == column) else {
        return Err(bad(&format!("no column `{column}`")));
    };
    let mask = parquet::arrow::ProjectionMask::roots(builder.parquet_schema(), [i]);
    let mut out = Vec::new();
    for batch in builder.with_projection(mask).build().map_err(|e| bad(&e))? {
        let batch = batch.map_err(|e| bad(&e))?;
        let c = batch.column(0);
        let values =
            c.as_primitive_opt::<UInt64Type>().ok_or_else(|| bad(&format!("column `{column}` is not UInt64")))?;
        if values.null_count() > 0 {
            return Err(bad(&format!("column `{column}` has missing values")));
        }
        out.extend_from_slice(values.values());
    }
    Ok(out)
}

/// Each column's name and unit (the `unit` of its field metadata, if any), in file order.
pub fn units(path: &Path) -> std::io::Result<Vec<(String, Option<String>)>> {
    let bad = |e: &dyn std::fmt::Display| std::io::Error::other(format!("{}: {e}", path.display()));
    let builder =
        ParquetRecordBatchReaderBuilder::try_new(File::open(path).map_err(|e| bad(&e))?).map_err(|e| bad(&e))?;
    Ok(builder.schema().fields().iter().map(|f| (f.name().clone(), f.metadata().get(UNIT_KEY).cloned())).collect())
}

/// Every batch of a Parquet file.
fn read_parquet(path: &Path) -> std::io::Result<Vec<RecordBatch>> {
    let bad = |e: &dyn std::fmt::Display| std::io::Error::other(format!("{}: {e}", path.display()));
    let reader = ParquetRecordBatchReaderBuilder::try_new(File::open(path).map_err(|e| bad(&e))?)
        .and_then(|b| b.with_batch_size(ROWS_PER_GROUP).build())
        .map_err(|e| bad(&e))?;
    reader.map(|b| b.map_err(|e| bad(&e))).collect()
}

/// The writer thread's side: the final file being written and the journal.
struct FileState {
    path: PathBuf,
    tmp: PathBuf,
    journal: Option<File>,
    schema: SchemaRef,
    writer: Option<ArrowWriter<File>>,
    /// The first error writing the final file (reported by `finish`; the journal goes on).
    error: Option<std::io::Error>,
    /// Scratch for a batch's journal bytes.
    bytes: Vec<u8>,
    /// Batches in the journal, not yet encoded into the final file (as their journal bytes,
    /// 8 bytes a number: a batch of a few rows of a wide file held as Arrow arrays took four
    /// times its numbers, 128 MB of a 100-agent plant's 211 MB), and their size in memory.
    /// Encoding waits for `finish` (up to [`defer_budget`]): on a 2-core machine every core is busy
    /// with the lockstep while it runs, and encoding then slowed fig1's step loop by 9–16 % against
    /// CSV even at the lowest priority. Each batch is encoded as it came (the same rows per
    /// `write`), so the file's bytes are those of encoding at once.
    deferred: Vec<Vec<u8>>,
    deferred_bytes: usize,
}

/// Rows held back from encoding until the process ends, at most, by one writer (beyond: encoded
/// as they come), and by all the writers of a run together ([`defer_budget`]).
const DEFER_BYTES: usize = 256 << 20;
const RUN_DEFER_BYTES: usize = 1 << 30;
/// The least a writer may hold back: a few journal batches of the widest file.
const MIN_DEFER_BYTES: usize = 1 << 20;
/// This process's budget, set by [`defer_budget`] (the largest until then).
static DEFER_LIMIT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(DEFER_BYTES);

/// Share the rows held back by a run of `processes` processes: each writer of this process holds
/// back at most 1 GiB / `processes`, between 1 MiB and 256 MiB. Deferred rows are 8 bytes a
/// number: a 1 000-agent ring's agents would otherwise hold 16 MB each after 100 000 steps (16 GB
/// together) where 1 MiB each costs them some encoding during the run. The file's bytes do not
/// depend on it (row groups fall every [`rows_per_group`] rows).
pub fn defer_budget(processes: u32) {
    let each = (RUN_DEFER_BYTES / processes.max(1) as usize).clamp(MIN_DEFER_BYTES, DEFER_BYTES);
    DEFER_LIMIT.store(each, std::sync::atomic::Ordering::Relaxed);
}

impl FileState {
    fn err(&self, e: impl std::fmt::Display) -> std::io::Error {
        std::io::Error::other(format!("{}: {e}", self.path.display()))
    }
    /// Open the final file's temporary file, with the rows of the file in place first (if any).
    fn start(&mut self) -> std::io::Result<()> {
        let props = properties(&self.schema);
        let out = File::create(&self.tmp).map_err(|e| self.err(e))?;
        let mut w = ArrowWriter::try_new(out, self.schema.clone(), Some(props)).map_err(|e| self.err(e))?;
        if self.path.exists() {
            for batch in read_parquet(&self.path)? {
                if batch.schema().fields() != self.schema.fields() {
                    return Err(self.err("the existing file has other columns"));
                }
                w.write(&batch).map_err(|e| self.err(e))?;
            }
        }
        self.writer = Some(w);
        Ok(())
    }
    /// Append `rows` (journal order, see [`Cmd::Rows`]) to the journal (one write), then to the
    /// final file.
    fn write(&mut self, rows: &[u64]) -> std::io::Result<()> {
        // In this thread's own buffer: the rows' buffer goes back to the step thread.
        self.bytes.clear();
        self.bytes.reserve(8 * rows.len());
        for w in rows {
            self.bytes.extend_from_slice(&w.to_le_bytes());
        }
        let journal = self.journal.as_mut().ok_or_else(|| std::io::Error::other("the journal is closed"))?;
        journal
            .write_all(&self.bytes)
            .map_err(|e| std::io::Error::other(format!("{}: journal: {e}", self.path.display())))?;
        self.deferred_bytes += self.bytes.len();
        self.deferred.push(std::mem::take(&mut self.bytes));
        if self.deferred_bytes > DEFER_LIMIT.load(std::sync::atomic::Ordering::Relaxed) {
            self.encode_deferred();
        }
        Ok(())
    }
    /// Encode the batches held back into the final file (row groups fall every
    /// [`rows_per_group`] rows whenever this runs, so the bytes do not depend on it).
    fn encode_deferred(&mut self) {
        self.deferred_bytes = 0;
        for bytes in std::mem::take(&mut self.deferred) {
            if self.error.is_some() {
                break;
            }
            let written = match (batch_from_words(&bytes, &self.schema), self.writer.as_mut()) {
                (Ok(batch), Some(w)) => w.write(&batch).map_err(|e| e.to_string()),
                (Err(e), _) => Err(e.to_string()),
                (Ok(_), None) => Ok(()),
            };
            if let Err(e) = written {
                self.error = Some(self.err(e));
            }
        }
    }
    fn finish(&mut self) -> std::io::Result<()> {
        self.encode_deferred();
        let writer = self.writer.take();
        if let Some(e) = self.error.take() {
            // The journal stays: it holds every row, for `seal_dir`.
            let _ = std::fs::remove_file(&self.tmp);
            return Err(e);
        }
        let Some(w) = writer else { return Err(self.err("the final file was never opened")) };
        w.close().map_err(|e| self.err(e))?;
        std::fs::rename(&self.tmp, &self.path).map_err(|e| self.err(e))?;
        self.journal = None;
        std::fs::remove_file(journal_path(&self.path)).map_err(|e| self.err(e))
    }
}

/// Turn the journal of the telemetry file `path` into `path`, as the process's clean exit would
/// have: the rows of `path` if it exists (a relaunched agent's predecessor), then those of the
/// journal after them (a process killed between renaming its file and removing its journal has
/// them in both), then remove the journal.
pub fn seal(path: &Path) -> std::io::Result<()> {
    let (_, rows) = read_journal(&journal_path(path))?;
    let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let mut state = FileState {
        path: path.to_path_buf(),
        tmp: path.with_file_name(format!(".{name}.tmp")),
        journal: None,
        schema: rows.schema(),
        writer: None,
        error: None,
        bytes: Vec::new(),
        deferred: Vec::new(),
        deferred_bytes: 0,
    };
    state.start()?;
    let before = if path.exists() { read_parquet(path)?.last().and_then(last_k) } else { None };
    let k = rows.column(0).as_primitive::<UInt64Type>().values();
    let from = before.map_or(0, |last| k.iter().position(|&k| k > last).unwrap_or(k.len()));
    let w = state.writer.as_mut().expect("started");
    w.write(&rows.slice(from, rows.num_rows() - from)).map_err(|e| state.err(e))?;
    state.finish()
}

fn last_k(b: &RecordBatch) -> Option<u64> {
    b.column(0).as_primitive::<UInt64Type>().values().last().copied()
}

/// What [`seal_dir`] did: the files written, and each journal it could not turn into its file.
#[derive(Debug, Default)]
pub struct Sealed {
    pub files: Vec<PathBuf>,
    /// "`<journal>`: why", one per journal left as it was.
    pub failures: Vec<String>,
}

/// Seal every journal in a telemetry directory (see [`seal`]): what processes killed before
/// their clean exit left. A journal that cannot be sealed (damaged, a full disk) is reported and
/// left in place, and the others are sealed all the same.
pub fn seal_dir(telemetry: &Path) -> Sealed {
    let mut out = Sealed::default();
    let Ok(entries) = std::fs::read_dir(telemetry) else { return out };
    let mut journals: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "rows"))
        .collect();
    journals.sort();
    for j in journals {
        let path = j.with_extension("parquet");
        match seal(&path) {
            Ok(()) => out.files.push(path),
            Err(e) => out.failures.push(format!("{}: {e}", j.display())),
        }
    }
    out
}

/// nice 19 for the calling thread only (Linux: `setpriority` on a thread id is per thread). A
/// refusal changes nothing but the speed, so it is ignored.
pub(crate) fn lower_this_threads_priority() {
    // SAFETY: gettid has no preconditions; setpriority on our own thread id with a valid value.
    unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
        let _ = libc::setpriority(libc::PRIO_PROCESS, tid, 19);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_back(path: &Path) -> (SchemaRef, Vec<u64>, Vec<Vec<u64>>) {
        let reader = ParquetRecordBatchReaderBuilder::try_new(File::open(path).unwrap()).unwrap();
        let schema = reader.schema().clone();
        let (mut k, mut cols) = (Vec::new(), vec![Vec::new(); schema.fields().len() - 1]);
        for batch in reader.build().unwrap() {
            let batch = batch.unwrap();
            k.extend_from_slice(batch.column(0).as_primitive::<UInt64Type>().values());
            for (j, c) in cols.iter_mut().enumerate() {
                c.extend(batch.column(j + 1).as_primitive::<Float64Type>().values().iter().map(|v| v.to_bits()));
            }
        }
        (schema, k, cols)
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("cohort-parquet-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn columns() -> Vec<String> {
        ["k", "t_s", "omega_x_rad_s", "q_w"].iter().map(|s| s.to_string()).collect()
    }

    fn row(k: u64) -> [f64; 3] {
        let tricky = [0.1 + 0.2, -0.0, f64::MIN_POSITIVE, 5e-324, f64::MAX, -1.0 / 3.0, f64::NAN, f64::INFINITY];
        [k as f64 * 0.01, tricky[k as usize % tricky.len()], (k as f64).sqrt()]
    }

    /// Values come back bit for bit (across row groups and flushes), units are in the field
    /// metadata, the same rows give the same bytes whatever the flushes, and a clean finish
    /// leaves one file and no journal.
    #[test]
    fn rows_round_trip_bit_for_bit_with_units_and_deterministic_bytes() {
        let dir = scratch("rt");
        let n = ROWS_PER_GROUP as u64 + 10;
        let write = |name: &str, flush_at: &[u64]| {
            let path = dir.join(name);
            let mut w = ParquetWriter::create(&path, &columns()).unwrap();
            for k in 0..n {
                if flush_at.contains(&k) {
                    w.flush().unwrap(); // as before a planned process fault; the rows go on after it
                }
                w.row(k, &row(k)).unwrap();
            }
            w.finish().unwrap();
            drop(w);
            assert!(!journal_path(&path).exists(), "a journal left after a clean finish");
            path
        };
        let (a, b) = (write("a.parquet", &[]), write("b.parquet", &[100, 101, 3000]));
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "same rows, different bytes");
        let meta = ParquetRecordBatchReaderBuilder::try_new(File::open(&a).unwrap()).unwrap().metadata().clone();
        assert!(matches!(meta.row_group(0).column(1).compression(), Compression::ZSTD(_)), "a narrow file is zstd");
        let (schema, k, cols) = read_back(&a);
        assert_eq!(k, (0..n).collect::<Vec<_>>());
        for (j, c) in cols.iter().enumerate() {
            let want: Vec<u64> = (0..n).map(|k| row(k)[j].to_bits()).collect();
            assert_eq!(c, &want, "column {}", columns()[j + 1]);
        }
        let unit = |i: usize| schema.field(i).metadata().get(UNIT_KEY).cloned();
        assert_eq!((unit(1), unit(2), unit(3)), (Some("s".into()), Some("rad/s".into()), None));
        // A relaunched process goes on with the file.
        let mut w = ParquetWriter::append(&a, &columns()).unwrap();
        w.row(n, &row(n)).unwrap();
        w.finish().unwrap();
        assert_eq!(read_back(&a).1, (0..=n).collect::<Vec<_>>());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A file wider than 1 024 columns (a large formation's plant) gets row groups of fewer rows,
    /// at most [`GROUP_BYTES`] of numbers each, compressed with LZ4: the same rows whether
    /// finished or sealed from the journal of a killed writer, bit for bit the same bytes.
    #[test]
    fn a_wide_file_has_row_groups_of_fewer_rows_and_the_same_bytes_sealed() {
        assert_eq!(rows_per_group(4), ROWS_PER_GROUP);
        assert_eq!(rows_per_group(1024), ROWS_PER_GROUP);
        assert_eq!(rows_per_group(9003), GROUP_BYTES / (8 * 9003));
        assert_eq!(rows_per_group(usize::MAX / 16), MIN_GROUP_ROWS);
        let dir = scratch("wide");
        let cols: Vec<String> = std::iter::once("k".to_string()).chain((0..4095).map(|j| format!("x{j}_m"))).collect();
        let per = rows_per_group(cols.len());
        assert_eq!(per, 1024);
        let n = per as u64 + 3;
        let value = |k: u64, j: usize| (k as f64 + 1.0) * (j as f64 + 0.5).sqrt();
        let write = |path: &Path, finish: bool| {
            let mut w = ParquetWriter::create(path, &cols).unwrap();
            for k in 0..n {
                w.row(k, &(0..cols.len() - 1).map(|j| value(k, j)).collect::<Vec<_>>()).unwrap();
            }
            if finish {
                w.finish().unwrap();
            } else {
                w.flush().unwrap();
                std::mem::forget(w); // as a SIGKILL
            }
        };
        let (a, b) = (dir.join("a").join("plant.parquet"), dir.join("b").join("plant.parquet"));
        std::fs::create_dir_all(a.parent().unwrap()).unwrap();
        std::fs::create_dir_all(b.parent().unwrap()).unwrap();
        write(&a, true);
        write(&b, false);
        assert_eq!(seal_dir(b.parent().unwrap()).files, vec![b.clone()]);
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "sealed bytes differ");
        let meta = ParquetRecordBatchReaderBuilder::try_new(File::open(&a).unwrap()).unwrap().metadata().clone();
        let groups: Vec<i64> = meta.row_groups().iter().map(|g| g.num_rows()).collect();
        assert_eq!(groups, vec![per as i64, 3]);
        assert_eq!(meta.row_group(0).column(1).compression(), Compression::LZ4_RAW);
        let (_, k, back) = read_back(&a);
        assert_eq!(k, (0..n).collect::<Vec<_>>());
        assert_eq!(back[4094][n as usize - 1], value(n - 1, 4094).to_bits());
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The step thread fills the buffers the writer thread hands back instead of allocating new
    /// ones (and so never has one freed by the writer thread; see [`ParquetWriter`]).
    #[test]
    fn the_rows_buffers_come_back_to_the_step_thread() {
        let dir = scratch("recycled");
        let path = dir.join("a.parquet");
        let mut w = ParquetWriter::<f64>::create(&path, &columns()).unwrap();
        let first = w.rows.as_ptr();
        w.row(0, &row(0)).unwrap();
        w.flush().unwrap();
        assert_ne!(w.rows.as_ptr(), first, "the first buffer went to the writer thread");
        w.row(1, &row(1)).unwrap();
        w.flush().unwrap();
        assert_eq!(w.rows.as_ptr(), first, "the first buffer came back and is filled again");
        w.finish().unwrap();
        let (_, k, _) = read_back(&path);
        assert_eq!(k, [0, 1]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The processes of a run write their first journal batch at steps spread over a whole batch
    /// (so later ones too), each at the same steps every run; a first batch is never empty.
    #[test]
    fn journal_batches_of_a_runs_processes_fall_at_spread_steps() {
        let per = 186; // an 11-column agent file
        let phases: Vec<usize> = (1..=100).map(|i| phase(Path::new(&format!("agent-{i}.parquet")), per)).collect();
        assert!(phases.iter().all(|&p| p < per));
        let mut distinct = phases.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert!(distinct.len() >= 50, "100 agents' first batches at only {} distinct steps", distinct.len());
        assert!(phases.iter().filter(|&&p| p < per / 2).count() >= 25, "{phases:?}");
        assert!(phases.iter().filter(|&&p| p >= per / 2).count() >= 25, "{phases:?}");
        assert_eq!(phase(Path::new("telemetry/agent-7.parquet"), per), phase(Path::new("agent-7.parquet"), per));
        assert_eq!(phase(Path::new("agent-7.parquet"), 1), 0);
    }

    /// A writer that never finishes (its process killed) leaves a journal with every row but
    /// those of its last, unfilled batch (and a row cut short is dropped); `seal_dir` turns it
    /// into the file a clean finish writes, bit for bit the same rows.
    #[test]
    fn an_unfinished_writer_loses_at_most_one_batch_and_its_journal_seals_into_the_file() {
        let dir = scratch("kill");
        let path = dir.join("agent-2.parquet");
        let n = 3 * ROWS_PER_GROUP as u64 + 7;
        let mut w = ParquetWriter::create(&path, &columns()).unwrap();
        let per = w.batch_rows() as u64;
        assert_eq!(per, (JOURNAL_BATCH_BYTES / 32) as u64);
        for k in 0..n {
            w.row(k, &row(k)).unwrap();
        }
        w.flush().unwrap();
        for k in n..n + per - 1 {
            w.row(k, &row(k)).unwrap(); // buffered only: lost with the process
        }
        // As a SIGKILL: the thread stops where it is, nothing is finished.
        std::mem::forget(w);
        assert!(!path.exists());
        // A row half written when the process died.
        let mut j = std::fs::OpenOptions::new().append(true).open(journal_path(&path)).unwrap();
        j.write_all(&[7u8; 13]).unwrap();
        drop(j);
        let (cols, rows) = read_journal(&journal_path(&path)).unwrap();
        assert_eq!((cols, rows.num_rows() as u64), (columns(), n));
        assert_eq!(seal_dir(&dir).files, vec![path.clone()]);
        assert!(!journal_path(&path).exists());
        let (schema, k, cols) = read_back(&path);
        assert_eq!(k, (0..n).collect::<Vec<_>>());
        for (j, c) in cols.iter().enumerate() {
            assert_eq!(c, &(0..n).map(|k| row(k)[j].to_bits()).collect::<Vec<_>>());
        }
        assert_eq!(schema.field(2).metadata().get(UNIT_KEY).map(String::as_str), Some("rad/s"));
        assert!(seal_dir(&dir).files.is_empty(), "sealed twice");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Timing's whole numbers: UInt64 columns with their units, back exactly, also from the
    /// journal of a writer that never finished.
    #[test]
    fn whole_number_columns_round_trip_with_units_also_through_a_journal() {
        let dir = scratch("u64");
        let cols: Vec<String> = ["k", "round_ns", "share_latency_max_ns"].iter().map(|s| s.to_string()).collect();
        let value = |k: u64, j: u64| k.wrapping_mul(2_654_435_761).rotate_left(j as u32 * 7) >> (j * 5);
        let n = ROWS_PER_GROUP as u64 + 123;
        let write = |path: &Path, finish: bool| {
            let mut w = ParquetWriter::<u64>::create(path, &cols).unwrap();
            for k in 0..n {
                w.row(k, &[value(k, 1), value(k, 2)]).unwrap();
            }
            if finish {
                w.finish().unwrap();
            } else {
                w.flush().unwrap();
                std::mem::forget(w);
            }
        };
        let (a, b) = (dir.join("plant.parquet"), dir.join("agent-1.parquet"));
        write(&a, true);
        write(&b, false);
        assert!(!b.exists() && journal_path(&b).exists());
        assert_eq!(seal_dir(&dir).files, vec![b.clone()]);
        for path in [&a, &b] {
            assert_eq!(read_u64_column(path, "k").unwrap(), (0..n).collect::<Vec<_>>());
            for (j, c) in [(1, "round_ns"), (2, "share_latency_max_ns")] {
                let want: Vec<u64> = (0..n).map(|k| value(k, j)).collect();
                assert_eq!(read_u64_column(path, c).unwrap(), want, "{c}");
            }
            let u = units(path).unwrap();
            assert_eq!(u[1], ("round_ns".to_string(), Some("ns".to_string())));
        }
        let e = read_u64_column(&a, "compute_ns").unwrap_err().to_string();
        assert!(e.contains("plant.parquet") && e.contains("compute_ns"), "{e}");
        let e = read_u64_column(&dir.join("other.parquet"), "k").unwrap_err().to_string();
        assert!(e.contains("other.parquet"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A relaunched writer goes on after a killed one's journal; a journal whose rows are
    /// already in the file (killed between the rename and the removal) adds none twice.
    #[test]
    fn a_relaunched_writer_goes_on_after_a_killed_ones_journal() {
        let dir = scratch("relaunch");
        let path = dir.join("agent-3.parquet");
        let mut w = ParquetWriter::create(&path, &columns()).unwrap();
        for k in 0..1000 {
            w.row(k, &row(k)).unwrap();
        }
        w.flush().unwrap();
        std::mem::forget(w);
        let mut w = ParquetWriter::append(&path, &columns()).unwrap();
        for k in 1200..1300 {
            w.row(k, &row(k)).unwrap();
        }
        w.flush().unwrap();
        let journal = std::fs::read(journal_path(&path)).unwrap();
        w.finish().unwrap();
        let want: Vec<u64> = (0..1000).chain(1200..1300).collect();
        assert_eq!(read_back(&path).1, want);
        assert!(!journal_path(&path).exists());
        std::fs::write(journal_path(&path), journal).unwrap();
        seal(&path).unwrap();
        assert_eq!(read_back(&path).1, want);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Issue 36, defect 5: a damaged journal is reported and left, and the others are sealed all
    /// the same (before, the first failure ended the directory's sealing).
    #[test]
    fn one_bad_journal_does_not_stop_the_others() {
        let dir = scratch("one-bad");
        let cols: Vec<String> = ["k", "x_m"].iter().map(|s| s.to_string()).collect();
        let paths: Vec<PathBuf> =
            ["agent-1", "agent-2", "agent-3"].iter().map(|n| dir.join(format!("{n}.parquet"))).collect();
        for p in &paths {
            let mut w = ParquetWriter::<f64>::create(p, &cols).unwrap();
            for k in 0..10 {
                w.row(k, &[k as f64]).unwrap();
            }
            w.flush().unwrap();
            std::mem::forget(w);
        }
        std::fs::write(journal_path(&paths[0]), b"not a journal").unwrap();
        let sealed = seal_dir(&dir);
        assert_eq!(sealed.files, paths[1..].to_vec());
        assert_eq!(sealed.failures.len(), 1, "{:?}", sealed.failures);
        assert!(
            sealed.failures[0].contains("agent-1.rows") && sealed.failures[0].contains("no header"),
            "{:?}",
            sealed.failures
        );
        assert!(journal_path(&paths[0]).exists(), "the bad journal is left as it was");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
