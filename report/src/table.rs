//! The one reader of telemetry files (`k,t_s,<columns…>`), Parquet or CSV (numbers that
//! round-trip exactly): for the figures, every paper's analysis, and the tests. A path is read by
//! its extension; a `.csv` or `.parquet` path that does not exist is read from the same file
//! in the other format, so `telemetry/plant.csv` names a run's plant telemetry either way.

use std::collections::HashSet;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

use crate::ReportError;

/// One telemetry file (or any CSV of the same shape: `k,t_s,…`), column-major.
#[derive(Debug, Clone, Default)]
pub struct Table {
    /// The `k` column (steps).
    pub k: Vec<u64>,
    /// The `t_s` column.
    pub t: Vec<f64>,
    /// The columns after `k` and `t_s`, in header order.
    pub columns: Vec<Column>,
}

#[derive(Debug, Clone)]
pub struct Column {
    pub name: String,
    pub values: Vec<f64>,
}

impl Table {
    /// Every column of a telemetry file.
    pub fn read(path: &Path) -> Result<Table, ReportError> {
        read_table_with(path, &|_| true)
    }
    /// Only the named columns (besides `k` and `t_s`, always read); a name the file lacks is an
    /// error naming the file and the column.
    pub fn read_columns<S: AsRef<str>>(path: &Path, wanted: &[S]) -> Result<Table, ReportError> {
        let wanted: Vec<&str> = wanted.iter().map(AsRef::as_ref).filter(|w| *w != "k" && *w != "t_s").collect();
        let table = read_table_with(path, &|name| wanted.contains(&name))?;
        if let Some(missing) = wanted.iter().find(|w| table.get(w).is_none()) {
            return Err(ReportError::MissingColumn { path: path.to_path_buf(), column: missing.to_string() });
        }
        Ok(table)
    }
    /// Parse CSV text of the same shape (`what` names it in errors).
    pub fn parse(text: &str, what: &Path) -> Result<Table, ReportError> {
        read_lines(std::io::Cursor::new(text), what, &|_| true)
    }
    /// A column by name (`t_s` included), if the table has it.
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        if name == "t_s" {
            return Some(&self.t);
        }
        self.columns.iter().find(|c| c.name == name).map(|c| c.values.as_slice())
    }
    /// A column by name (`t_s` included). Panics if absent: for columns asked for at read time
    /// ([`Table::read_columns`]).
    pub fn col(&self, name: &str) -> &[f64] {
        self.get(name).unwrap_or_else(|| panic!("column {name:?} was not read"))
    }
    /// The steps (`k`) of the rows.
    pub fn steps(&self) -> &[u64] {
        &self.k
    }
    pub fn rows(&self) -> usize {
        self.t.len()
    }
}

/// Like [`Table::read`], but keeps (and parses) only the columns after `k` and `t_s` whose name
/// passes `keep`; the other fields are counted but not checked.
pub fn read_table_with(path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<Table, ReportError> {
    let resolved = resolve(path);
    let path = resolved.as_path();
    let telemetry = path.extension().is_some_and(|e| e == "parquet" || e == "csv");
    if telemetry && !path.exists() {
        // Neither format is there: name both, not only the one asked for (a Parquet run's missing
        // file was reported as a missing `.csv`).
        return Err(ReportError::MissingTelemetryFile { path: path.with_extension("") });
    }
    if path.extension().is_some_and(|e| e == "parquet") {
        return crate::parquet_in::read(path, keep);
    }
    let file = File::open(path).map_err(|error| ReportError::Io { path: path.to_path_buf(), error })?;
    read_lines(BufReader::new(file), path, keep)
}

/// The file to read for `path`: itself if it exists, else the same stem in the other format if
/// that exists (else `path`, whose absence the reader reports).
pub fn resolve(path: &Path) -> PathBuf {
    let other = match path.extension().and_then(|e| e.to_str()) {
        Some("csv") => "parquet",
        Some("parquet") => "csv",
        _ => return path.to_path_buf(),
    };
    if path.exists() {
        return path.to_path_buf();
    }
    let alt = path.with_extension(other);
    if alt.exists() { alt } else { path.to_path_buf() }
}

fn read_lines(reader: impl BufRead, path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<Table, ReportError> {
    let io_err = |error| ReportError::Io { path: path.to_path_buf(), error };
    let bad_header = |reason: String| ReportError::BadHeader { path: path.to_path_buf(), reason };
    let mut lines = reader.lines();
    let header = match lines.next() {
        None => return Err(bad_header("the file is empty".to_string())),
        Some(line) => line.map_err(io_err)?,
    };
    let names: Vec<&str> = header.trim_end_matches('\r').split(',').map(str::trim).collect();
    if names.len() < 2 || names[0] != "k" || names[1] != "t_s" {
        return Err(bad_header(format!(
            "the first two columns must be `k,t_s`, found `{}`",
            names.iter().take(2).copied().collect::<Vec<_>>().join(",")
        )));
    }
    let mut seen = HashSet::new();
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            return Err(bad_header(format!("column {} has an empty name", i + 1)));
        }
        if !seen.insert(*name) {
            return Err(bad_header(format!("duplicate column `{name}`")));
        }
    }

    let mut t = Vec::new();
    let mut steps = Vec::new();
    // For each field after `k,t_s`, the index of its column in `columns`, if kept.
    let mut slots: Vec<Option<usize>> = Vec::with_capacity(names.len() - 2);
    let mut columns: Vec<Column> = Vec::new();
    for name in &names[2..] {
        if keep(name) {
            slots.push(Some(columns.len()));
            columns.push(Column { name: (*name).to_string(), values: Vec::new() });
        } else {
            slots.push(None);
        }
    }
    for (index, line) in lines.enumerate() {
        let line_no = index + 2; // 1-based, after the header
        let line = line.map_err(io_err)?;
        let line = line.trim_end_matches('\r');
        if line.trim().is_empty() {
            continue;
        }
        let found = line.split(',').count();
        if found != names.len() {
            return Err(ReportError::ColumnCount {
                path: path.to_path_buf(),
                line: line_no,
                expected: names.len(),
                found,
            });
        }
        let bad_number = |column: &str, value: &str| ReportError::BadNumber {
            path: path.to_path_buf(),
            line: line_no,
            column: column.to_string(),
            value: value.to_string(),
        };
        let mut fields = line.split(',').map(str::trim);
        let (Some(k), Some(t_s)) = (fields.next(), fields.next()) else {
            unreachable!("the row has as many fields as the header, which has at least two");
        };
        steps.push(k.parse::<u64>().map_err(|_| bad_number("k", k))?);
        t.push(t_s.parse::<f64>().map_err(|_| bad_number("t_s", t_s))?);
        for (slot, field) in slots.iter().zip(fields) {
            if let Some(index) = *slot {
                let column = &mut columns[index];
                let value = field.parse::<f64>().map_err(|_| bad_number(&column.name, field))?;
                column.values.push(value);
            }
        }
    }
    Ok(Table { k: steps, t, columns })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 36, defect 8: a file missing in both formats is reported as such, not as a missing
    /// `.csv` when the run writes Parquet.
    #[test]
    fn a_file_missing_in_both_formats_names_both() {
        let dir = std::env::temp_dir().join(format!("cohort-table-missing-{}", std::process::id()));
        let e = Table::read(&dir.join("telemetry/plant.csv")).unwrap_err().to_string();
        assert!(e.contains("telemetry/plant.parquet or .csv: neither exists"), "{e}");
    }
}
