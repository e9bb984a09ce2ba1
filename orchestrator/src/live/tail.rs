//! Reading a process's telemetry journal (`telemetry/<proc>.rows`, see
//! `cohort_runtime::parquet_out`) while the process still appends to it: the header once, then
//! whatever complete rows arrived since the last read. A journal the process replaced (a
//! relaunched agent starts a new one at the same path) is reopened from its header; one the
//! process removed (its clean end: the rows are in the Parquet file) is read to its end through
//! the open handle.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// The journal's first line (`parquet_out::new_journal`).
const MAGIC: &[u8] = b"COHORT-ROWS 2\n";

/// One journal being followed.
pub struct Journal {
    path: PathBuf,
    file: Option<(File, u64)>,
    /// Column names, `k` first, once the header has been read.
    columns: Vec<String>,
    /// Bytes read but not yet a whole row.
    pending: Vec<u8>,
}

impl Journal {
    pub fn new(path: &Path) -> Self {
        Self { path: path.to_path_buf(), file: None, columns: Vec::new(), pending: Vec::new() }
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

    /// Parse the header out of `pending` (magic, `f64`, the column line); false until it is
    /// complete or when it is not an f64 journal.
    fn read_header(&mut self) -> bool {
        let Some(rest) = self.pending.strip_prefix(MAGIC) else { return false };
        let mut lines = rest.splitn(3, |&b| b == b'\n');
        let (Some(value), Some(names), Some(_)) = (lines.next(), lines.next(), lines.next()) else { return false };
        if value != b"f64" {
            return false;
        }
        let Ok(names) = std::str::from_utf8(names) else { return false };
        let columns: Vec<String> = names.split(',').map(str::to_string).collect();
        let header = MAGIC.len() + value.len() + names.len() + 2;
        self.columns = columns;
        self.pending.drain(..header);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cohort_runtime::parquet_out::ParquetWriter;

    #[test]
    fn reads_the_rows_a_writer_flushed_bit_for_bit() {
        let dir = std::env::temp_dir().join(format!("cohort-live-tail-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plant.parquet");
        let columns: Vec<String> = ["k", "t_s", "x_m"].map(String::from).to_vec();
        let mut w = ParquetWriter::<f64>::create(&path, &columns).unwrap();
        let mut j = Journal::new(&cohort_runtime::parquet_out::journal_path(&path));
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
}
