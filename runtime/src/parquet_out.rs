//! Telemetry as Apache Parquet (`run.telemetry = "parquet"`, the default): one file per process,
//! `k` (UInt64) then one Float64 column per value, each column's unit (from [`crate::units`]) in
//! its Arrow field metadata under `unit`. Doubles are stored as they are (bit-exact).
//!
//! Rows are buffered in memory and handed, [`ROWS_PER_GROUP`] at a time, to a writer thread that
//! encodes and compresses them as one row group, so the step loop only copies numbers. A Parquet
//! file is readable only once its footer is written; so every [`ParquetWriter::flush`] (at the
//! end, on every error path, and before a planned process fault may end the process) closes the
//! file and renames it into place. A process that goes on after a flush reopens it: the rows
//! already written are read back and written again ahead of the new ones, so the file is always
//! one complete Parquet file. Between flushes the rows go to a hidden temporary file beside it.
//!
//! Bytes are deterministic: the same rows flushed at the same steps give the same file (no time
//! stamps; `created_by` is fixed by the crate version).

use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use arrow_array::{ArrayRef, Float64Array, RecordBatch, UInt64Array};
use arrow_schema::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::ArrowWriter;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::basic::{Compression, Encoding, ZstdLevel};
use parquet::file::properties::WriterProperties;
use parquet::schema::types::ColumnPath;

/// Rows per row group: 4096 rows of fig1's 107-column plant file are 3.5 MB before compression.
pub const ROWS_PER_GROUP: usize = 4096;

/// The metadata key of a field's unit.
pub const UNIT_KEY: &str = "unit";

/// The Arrow schema of a telemetry file with these columns (`k` first, then the f64 columns).
pub fn schema(columns: &[String]) -> SchemaRef {
    let fields: Vec<Field> = columns
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let field = if i == 0 {
                Field::new(name, DataType::UInt64, false)
            } else {
                Field::new(name, DataType::Float64, false)
            };
            match crate::units::unit_of(name) {
                Some(unit) => field.with_metadata(HashMap::from([(UNIT_KEY.to_string(), unit.to_string())])),
                None => field,
            }
        })
        .collect();
    Arc::new(Schema::new(fields))
}

fn properties(first_column: &str) -> WriterProperties {
    // Byte-stream split puts the bytes of equal significance of every double together, which
    // zstd then compresses far better than plain doubles; the steps are a delta-coded count.
    WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::try_new(3).expect("zstd level 3 exists")))
        .set_dictionary_enabled(false)
        .set_encoding(Encoding::BYTE_STREAM_SPLIT)
        .set_column_encoding(ColumnPath::from(first_column), Encoding::DELTA_BINARY_PACKED)
        .set_max_row_group_row_count(Some(ROWS_PER_GROUP))
        .build()
}

enum Cmd {
    Rows(RecordBatch),
    /// Close the file (footer, rename into place) and answer with the outcome.
    Flush,
}

/// Buffers rows and has a thread write them as row groups; see the module docs.
pub struct ParquetWriter {
    schema: SchemaRef,
    k: Vec<u64>,
    values: Vec<Vec<f64>>,
    tx: Option<Sender<Cmd>>,
    done: Receiver<std::io::Result<()>>,
    thread: Option<JoinHandle<()>>,
    path: PathBuf,
}

impl ParquetWriter {
    /// A new file at `path` (replacing any), `columns[0]` the step column.
    pub fn create(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        if path.exists() {
            std::fs::remove_file(path)?;
        }
        Self::open(path, columns)
    }
    /// Go on with an existing file (a relaunched agent continues its predecessor's rows).
    pub fn append(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        Self::open(path, columns)
    }
    fn open(path: &Path, columns: &[String]) -> std::io::Result<Self> {
        let schema = schema(columns);
        let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        let tmp = path.with_file_name(format!(".{name}.tmp"));
        // Probe now that the directory is writable, so a bad run directory fails at start.
        File::create(&tmp)?;
        std::fs::remove_file(&tmp)?;
        let (tx, rx) = channel();
        let (done_tx, done) = channel();
        let mut file = FileState { path: path.to_path_buf(), tmp, schema: schema.clone(), writer: None, error: None };
        let thread = std::thread::Builder::new().name(format!("telemetry {name}")).spawn(move || {
            for cmd in rx {
                match cmd {
                    Cmd::Rows(batch) => file.write(&batch),
                    Cmd::Flush => {
                        if done_tx.send(file.close()).is_err() {
                            return;
                        }
                    }
                }
            }
        })?;
        let width = columns.len().saturating_sub(1);
        Ok(Self {
            schema,
            k: Vec::with_capacity(ROWS_PER_GROUP),
            values: (0..width).map(|_| Vec::with_capacity(ROWS_PER_GROUP)).collect(),
            tx: Some(tx),
            done,
            thread: Some(thread),
            path: path.to_path_buf(),
        })
    }
    /// Buffer one row: step `k`, then the values (one per column after `k`).
    pub fn row(&mut self, k: u64, values: &[f64]) -> std::io::Result<()> {
        debug_assert_eq!(values.len(), self.values.len(), "{}", self.path.display());
        self.k.push(k);
        for (column, v) in self.values.iter_mut().zip(values) {
            column.push(*v);
        }
        if self.k.len() >= ROWS_PER_GROUP { self.send_rows() } else { Ok(()) }
    }
    fn send_rows(&mut self) -> std::io::Result<()> {
        if self.k.is_empty() {
            return Ok(());
        }
        let k = std::mem::replace(&mut self.k, Vec::with_capacity(ROWS_PER_GROUP));
        let mut arrays: Vec<ArrayRef> = Vec::with_capacity(self.values.len() + 1);
        arrays.push(Arc::new(UInt64Array::from(k)));
        for column in &mut self.values {
            let v = std::mem::replace(column, Vec::with_capacity(ROWS_PER_GROUP));
            arrays.push(Arc::new(Float64Array::from(v)));
        }
        let batch = RecordBatch::try_new(self.schema.clone(), arrays).map_err(std::io::Error::other)?;
        self.send(Cmd::Rows(batch))
    }
    fn send(&self, cmd: Cmd) -> std::io::Result<()> {
        let gone = || std::io::Error::other(format!("{}: the telemetry writer thread ended", self.path.display()));
        self.tx.as_ref().ok_or_else(gone)?.send(cmd).map_err(|_| gone())
    }
    /// Write every buffered row and close the file, so that it is complete on disk (the rows
    /// that follow reopen it).
    pub fn flush(&mut self) -> std::io::Result<()> {
        self.send_rows()?;
        self.send(Cmd::Flush)?;
        self.done
            .recv()
            .map_err(|_| std::io::Error::other(format!("{}: the telemetry writer thread ended", self.path.display())))?
    }
}

impl Drop for ParquetWriter {
    fn drop(&mut self) {
        // Rows not flushed yet (an unwinding panic) are still written.
        let _ = self.flush();
        drop(self.tx.take());
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The writer thread's side: the open temporary file, if any, and the first error.
struct FileState {
    path: PathBuf,
    tmp: PathBuf,
    schema: SchemaRef,
    writer: Option<ArrowWriter<File>>,
    error: Option<std::io::Error>,
}

impl FileState {
    fn err(&self, e: impl std::fmt::Display) -> std::io::Error {
        std::io::Error::other(format!("{}: {e}", self.path.display()))
    }
    fn write(&mut self, batch: &RecordBatch) {
        if self.error.is_some() {
            return;
        }
        if let Err(e) = self.try_write(batch) {
            self.error = Some(e);
        }
    }
    fn try_write(&mut self, batch: &RecordBatch) -> std::io::Result<()> {
        if self.writer.is_none() {
            self.reopen()?;
        }
        let w = self.writer.as_mut().expect("opened above");
        w.write(batch).map_err(|e| self.err(e))
    }
    /// Start the temporary file, with the rows of the file in place first (if there is one).
    fn reopen(&mut self) -> std::io::Result<()> {
        let props = properties(self.schema.field(0).name());
        let out = File::create(&self.tmp)?;
        let mut w = ArrowWriter::try_new(out, self.schema.clone(), Some(props)).map_err(|e| self.err(e))?;
        if self.path.exists() {
            let old = File::open(&self.path)?;
            let reader = ParquetRecordBatchReaderBuilder::try_new(old)
                .and_then(|b| b.with_batch_size(ROWS_PER_GROUP).build())
                .map_err(|e| self.err(e))?;
            for batch in reader {
                let batch = batch.map_err(|e| self.err(e))?;
                if batch.schema().fields() != self.schema.fields() {
                    return Err(self.err("the existing file has other columns"));
                }
                w.write(&batch).map_err(|e| self.err(e))?;
            }
        }
        self.writer = Some(w);
        Ok(())
    }
    fn close(&mut self) -> std::io::Result<()> {
        if let Some(e) = self.error.take() {
            let _ = std::fs::remove_file(&self.tmp);
            self.writer = None;
            return Err(e);
        }
        if self.writer.is_none() && !self.path.exists() {
            // Not a row yet: an empty file with the columns, so readers find the schema.
            self.reopen()?;
        }
        let Some(w) = self.writer.take() else { return Ok(()) };
        w.close().map_err(|e| self.err(e))?;
        std::fs::rename(&self.tmp, &self.path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Float64Type, UInt64Type};

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

    /// Values come back bit for bit (across row groups and a flush-and-reopen), units are in the
    /// field metadata, and the same rows flushed at the same rows give the same bytes.
    #[test]
    fn rows_round_trip_bit_for_bit_with_units_and_deterministic_bytes() {
        let dir = std::env::temp_dir().join(format!("cohort-parquet-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let columns: Vec<String> = ["k", "t_s", "omega_x_rad_s", "q_w"].iter().map(|s| s.to_string()).collect();
        let tricky = [0.1 + 0.2, -0.0, f64::MIN_POSITIVE, 5e-324, f64::MAX, -1.0 / 3.0, f64::NAN, f64::INFINITY];
        let n = ROWS_PER_GROUP as u64 + 10;
        let row = |k: u64| [k as f64 * 0.01, tricky[k as usize % tricky.len()], (k as f64).sqrt()];
        let write = |name: &str| {
            let path = dir.join(name);
            let mut w = ParquetWriter::create(&path, &columns).unwrap();
            for k in 0..n {
                if k == 100 {
                    w.flush().unwrap(); // as before a planned process fault; the rows go on after it
                }
                w.row(k, &row(k)).unwrap();
            }
            w.flush().unwrap();
            drop(w);
            path
        };
        let (a, b) = (write("a.parquet"), write("b.parquet"));
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "same rows, different bytes");
        let (schema, k, cols) = read_back(&a);
        assert_eq!(k, (0..n).collect::<Vec<_>>());
        for (j, c) in cols.iter().enumerate() {
            let want: Vec<u64> = (0..n).map(|k| row(k)[j].to_bits()).collect();
            assert_eq!(c, &want, "column {}", columns[j + 1]);
        }
        let unit = |i: usize| schema.field(i).metadata().get(UNIT_KEY).cloned();
        assert_eq!((unit(1), unit(2), unit(3)), (Some("s".into()), Some("rad/s".into()), None));
        // A relaunched process goes on with the file.
        let mut w = ParquetWriter::append(&a, &columns).unwrap();
        w.row(n, &row(n)).unwrap();
        w.flush().unwrap();
        assert_eq!(read_back(&a).1.len() as u64, n + 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
