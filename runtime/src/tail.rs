//! Reading a process's telemetry journal (`telemetry/<proc>.rows`, see
//! `cohort_runtime::parquet_out`), or its CSV file when the run writes CSV
//! (`telemetry/<proc>.csv`, numbers in shortest round-trip form, so read back bit for bit), while
//! the process still appends to it: the header once, then whatever complete rows arrived since
//! the last read (a CSV writer's buffer reaches the file every 64 KiB). A journal the process replaced (a
//! relaunched agent starts a new one at the same path) is reopened from its header; one the
//! process removed (its clean end: the rows are in the Parquet file) is read to its end through
//! the open handle.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// How the followed file holds its rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    /// A Parquet writer's journal: a header, then rows of little-endian 8-byte words.
    Rows,
    /// A CSV file: a header line of names, then a line per row.
    Csv,
}

/// One journal being followed.
pub struct Journal {
    path: PathBuf,
    format: Format,
    file: Option<(File, u64)>,
    /// Column names, `k` first, once the header has been read.
    columns: Vec<String>,
    /// Bytes read but not yet a whole row.
    pending: Vec<u8>,
}

impl Journal {
    /// Follow `path`: a `.csv` file as CSV, any other as a Parquet writer's journal.
    pub fn new(path: &Path) -> Self {
        let format = if path.extension().is_some_and(|e| e == "csv") { Format::Csv } else { Format::Rows };
        Self { path: path.to_path_buf(), format, file: None, columns: Vec::new(), pending: Vec::new() }
    }

    /// Its columns (`k` first); empty until the header was read.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// The complete rows appended since the last call whose step `keep(k)` accepts, as (k, values
    /// after `k`). A timing journal (u64 values) or a damaged header yields nothing.
    pub fn poll(&mut self, keep: impl Fn(u64) -> bool) -> Vec<(u64, Vec<f64>)> {
        self.reopen_if_replaced();
        let Some((file, _)) = self.file.as_mut() else { return Vec::new() };
        let mut fresh = Vec::new();
        if file.read_to_end(&mut fresh).is_err() {
            return Vec::new();
        }
        self.pending.extend_from_slice(&fresh);
        if self.format == Format::Csv {
            return self.csv_rows(keep);
        }
        if self.columns.is_empty() && !self.read_header() {
            return Vec::new();
        }
        let width = 8 * self.columns.len();
        let whole = self.pending.len() / width * width;
        let word = |row: &[u8], c: usize| u64::from_le_bytes(row[8 * c..8 * c + 8].try_into().expect("8 bytes"));
        let rows = self.pending[..whole]
            .chunks_exact(width)
            .filter(|row| keep(word(row, 0)))
            .map(|row| (word(row, 0), (1..self.columns.len()).map(|c| f64::from_bits(word(row, c))).collect()))
            .collect();
        self.pending.drain(..whole);
        rows
    }

    /// The complete lines of a CSV file read so far (the first is its header); a line that is not
    /// `k` and numbers is skipped.
    fn csv_rows(&mut self, keep: impl Fn(u64) -> bool) -> Vec<(u64, Vec<f64>)> {
        let Some(end) = self.pending.iter().rposition(|&b| b == b'\n') else { return Vec::new() };
        let text = String::from_utf8_lossy(&self.pending[..=end]).into_owned();
        self.pending.drain(..=end);
        let mut lines = text.lines();
        if self.columns.is_empty() {
            let Some(header) = lines.next() else { return Vec::new() };
            self.columns = header.split(',').map(str::to_string).collect();
        }
        lines
            .filter_map(|line| {
                let mut fields = line.split(',');
                let k = fields.next()?.parse::<u64>().ok().filter(|&k| keep(k))?;
                let values: Vec<f64> = fields.map(|f| f.parse::<f64>().ok()).collect::<Option<_>>()?;
                (values.len() + 1 == self.columns.len()).then_some((k, values))
            })
            .collect()
    }

    /// Open the journal, or reopen it when the path now names another file (its inode changed).
    fn reopen_if_replaced(&mut self) {
        let Ok(meta) = std::fs::metadata(&self.path) else { return };
        if self.file.as_ref().is_some_and(|(_, ino)| *ino == meta.ino()) {
            return;
        }
        if let Ok(mut f) = File::open(&self.path) {
            let _ = f.seek(SeekFrom::Start(0));
            self.file = Some((f, meta.ino()));
            self.columns.clear();
            self.pending.clear();
        }
    }

    /// Parse the header out of `pending` (`parquet_out::journal_header`); false until it is
    /// whole, and for a journal of other values than f64 or a damaged one.
    fn read_header(&mut self) -> bool {
        let Ok(Some(h)) = crate::parquet_out::journal_header(&self.pending) else { return false };
        if !h.holds_f64() {
            return false;
        }
        self.columns = h.columns;
        self.pending.drain(..h.len);
        true
    }
}

/// `telemetry/agent-3.rows` (a Parquet writer's journal) or `telemetry/agent-3.csv` → `agent-3`
/// (a hidden or other file → none).
pub fn journal_process(path: &Path) -> Option<String> {
    let name = path.file_name()?.to_str()?;
    let stem = name.strip_suffix(".rows").or_else(|| name.strip_suffix(".csv"))?;
    (!stem.starts_with('.')).then(|| stem.to_string())
}

/// The journals in a telemetry directory, by process name, in name order.
pub fn journals_in(telemetry: &Path) -> Vec<(String, PathBuf)> {
    let Ok(dir) = std::fs::read_dir(telemetry) else { return Vec::new() };
    let mut found: Vec<(String, PathBuf)> =
        dir.flatten().filter_map(|e| journal_process(&e.path()).map(|n| (n, e.path()))).collect();
    found.sort();
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parquet_out::ParquetWriter;
    use std::io::Write as _;

    #[test]
    fn reads_the_rows_a_writer_flushed_bit_for_bit() {
        let dir = std::env::temp_dir().join(format!("cohort-live-tail-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plant.parquet");
        let columns: Vec<String> = ["k", "t_s", "x_m"].map(String::from).to_vec();
        let mut w = ParquetWriter::<f64>::create(&path, &columns).unwrap();
        let mut j = Journal::new(&crate::parquet_out::journal_path(&path));
        for k in 0..10u64 {
            w.row(k, &[k as f64 * 0.01, (k as f64).sqrt() * -1.0e-7]).unwrap();
        }
        w.flush().unwrap();
        let rows = j.poll(|k| k % 3 == 0);
        assert_eq!(j.columns(), columns.as_slice());
        assert_eq!(rows.iter().map(|r| r.0).collect::<Vec<_>>(), [0, 3, 6, 9]);
        assert_eq!(rows[3].1[1].to_bits(), (9f64.sqrt() * -1.0e-7).to_bits());
        assert!(j.poll(|_| true).is_empty(), "nothing new");
        w.row(10, &[0.1, f64::NAN]).unwrap();
        w.flush().unwrap();
        let rows = j.poll(|_| true);
        assert_eq!(rows.len(), 1);
        assert!(rows[0].1[1].is_nan());
        w.finish().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn reads_a_csv_file_bit_for_bit_as_its_lines_arrive() {
        let dir = std::env::temp_dir().join(format!("cohort-live-tail-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("agent-1.csv");
        let columns: Vec<String> = ["k", "t_s", "x_m"].map(String::from).to_vec();
        let mut w = crate::record::CsvWriter::create(&path, &columns).unwrap();
        let mut j = Journal::new(&path);
        for k in 0..4u64 {
            w.row(k, &[k as f64 * 0.01, 1.0 / 3.0 * k as f64]).unwrap();
        }
        w.flush().unwrap();
        // Half a line more: not read until it is whole.
        std::fs::OpenOptions::new().append(true).open(&path).unwrap().write_all(b"4,0.04,0.").unwrap();
        let rows = j.poll(|_| true);
        assert_eq!(j.columns(), columns.as_slice());
        assert_eq!(rows.iter().map(|r| r.0).collect::<Vec<_>>(), [0, 1, 2, 3]);
        assert_eq!(rows[3].1[1].to_bits(), (1.0f64 / 3.0 * 3.0).to_bits());
        std::fs::OpenOptions::new().append(true).open(&path).unwrap().write_all(b"5\nnot,a,row\n").unwrap();
        let rows = j.poll(|_| true);
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].1[1].to_bits(), 0.5f64.to_bits());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
