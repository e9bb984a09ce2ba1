//! Reading a telemetry Parquet file (as `cohort_runtime::parquet_out` writes it: `k` UInt64,
//! then Float64 columns, `t_s` first) into a [`Table`]. A damaged or foreign file is an error
//! naming the file, never a panic.

use std::collections::HashSet;
use std::fs::File;
use std::path::Path;

use arrow_array::cast::AsArray;
use arrow_array::types::{Float64Type, UInt64Type};
use arrow_array::{Array, RecordBatch};
use arrow_schema::DataType;
use parquet::arrow::ProjectionMask;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

use crate::ReportError;
use crate::table::{Column, Table};

/// The columns after `k` and `t_s` whose name passes `keep`, with `k` and `t_s`.
pub(crate) fn read(path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<Table, ReportError> {
    // The decoders check what they read, but a damaged file must never take the reader down:
    // a panic inside them is reported as the file's damage.
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| read_checked(path, keep))).unwrap_or_else(|_| {
        Err(ReportError::BadParquet { path: path.to_path_buf(), reason: "its data cannot be decoded".into() })
    })
}

fn read_checked(path: &Path, keep: &dyn Fn(&str) -> bool) -> Result<Table, ReportError> {
    let bad = |reason: String| ReportError::BadParquet { path: path.to_path_buf(), reason };
    let bad_header = |reason: String| ReportError::BadHeader { path: path.to_path_buf(), reason };
    let file = File::open(path).map_err(|error| ReportError::Io { path: path.to_path_buf(), error })?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(|e| bad(e.to_string()))?;
    let schema = builder.schema().clone();
    let names: Vec<&str> = schema.fields().iter().map(|f| f.name().as_str()).collect();
    if names.len() < 2 || names[0] != "k" || names[1] != "t_s" {
        return Err(bad_header(format!(
            "the first two columns must be `k,t_s`, found `{}`",
            names.iter().take(2).copied().collect::<Vec<_>>().join(",")
        )));
    }
    let mut seen = HashSet::new();
    for (i, field) in schema.fields().iter().enumerate() {
        if !seen.insert(field.name().as_str()) {
            return Err(bad_header(format!("duplicate column `{}`", field.name())));
        }
        let want = if i == 0 { DataType::UInt64 } else { DataType::Float64 };
        if *field.data_type() != want {
            return Err(bad_header(format!("column `{}` is {}, not {want}", field.name(), field.data_type())));
        }
    }
    let kept: Vec<usize> = (0..names.len()).filter(|&i| i < 2 || keep(names[i])).collect();
    let mask = ProjectionMask::roots(builder.parquet_schema(), kept.iter().copied());
    let reader = builder.with_projection(mask).build().map_err(|e| bad(e.to_string()))?;
    let mut table = Table {
        k: Vec::new(),
        t: Vec::new(),
        columns: kept[2..].iter().map(|&i| Column { name: names[i].to_string(), values: Vec::new() }).collect(),
    };
    for batch in reader {
        let batch = batch.map_err(|e| bad(e.to_string()))?;
        append(&mut table, &batch).map_err(bad)?;
    }
    Ok(table)
}

fn append(table: &mut Table, batch: &RecordBatch) -> Result<(), String> {
    if let Some(c) = batch.columns().iter().position(|c| c.null_count() > 0) {
        return Err(format!("column `{}` has missing values", batch.schema().field(c).name()));
    }
    let k = batch.column(0).as_primitive_opt::<UInt64Type>().ok_or("column `k` is not UInt64")?;
    table.k.extend_from_slice(k.values());
    let f64s = |j: usize| batch.column(j).as_primitive_opt::<Float64Type>().ok_or("a column is not Float64");
    table.t.extend_from_slice(f64s(1)?.values());
    for (j, column) in table.columns.iter_mut().enumerate() {
        column.values.extend_from_slice(f64s(j + 2)?.values());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cohort_runtime::parquet_out::ParquetWriter;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("cohort-pq-in-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn parquet_reads_back_bit_for_bit_and_a_csv_path_finds_it() {
        let dir = scratch("rt");
        let cols: Vec<String> = ["k", "t_s", "a_m", "b_mps"].iter().map(|s| s.to_string()).collect();
        let mut w = ParquetWriter::create(&dir.join("plant.parquet"), &cols).unwrap();
        let rows: Vec<[f64; 3]> =
            (0..5000).map(|k| [k as f64 * 0.01, (k as f64).sin() * 1e-300, -(k as f64) / 3.0]).collect();
        for (k, r) in rows.iter().enumerate() {
            w.row(k as u64, r).unwrap();
        }
        w.finish().unwrap();
        drop(w);
        // Asked for by its CSV name, as every analysis does.
        let t = Table::read_columns(&dir.join("plant.csv"), &["b_mps"]).unwrap();
        assert_eq!(t.k, (0..5000).collect::<Vec<u64>>());
        assert_eq!(t.columns.len(), 1);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&t.t), bits(&rows.iter().map(|r| r[0]).collect::<Vec<_>>()));
        assert_eq!(bits(t.col("b_mps")), bits(&rows.iter().map(|r| r[2]).collect::<Vec<_>>()));
        let all = Table::read(&dir.join("plant.parquet")).unwrap();
        assert_eq!(bits(all.col("a_m")), bits(&rows.iter().map(|r| r[1]).collect::<Vec<_>>()));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_damaged_parquet_file_is_an_error_naming_it() {
        let dir = scratch("bad");
        let cols: Vec<String> = ["k", "t_s", "a_m"].iter().map(|s| s.to_string()).collect();
        let path = dir.join("agent-2.parquet");
        let mut w = ParquetWriter::create(&path, &cols).unwrap();
        for k in 0..100 {
            w.row(k, &[k as f64, 1.0]).unwrap();
        }
        w.finish().unwrap();
        drop(w);
        let good = std::fs::read(&path).unwrap();
        for damaged in [good[..good.len() / 2].to_vec(), b"PAR1 not really".to_vec(), Vec::new()] {
            std::fs::write(&path, &damaged).unwrap();
            let e = Table::read(&path).unwrap_err().to_string();
            assert!(e.contains("agent-2.parquet") && e.contains("not a readable telemetry Parquet file"), "{e}");
        }
        // Flipped bytes in the middle of the data: an error or the same shape, never a panic.
        let mut flipped = good.clone();
        for b in flipped.iter_mut().skip(8).take(200) {
            *b ^= 0x5a;
        }
        std::fs::write(&path, &flipped).unwrap();
        if let Err(e) = Table::read(&path) {
            assert!(e.to_string().contains("agent-2.parquet"), "{e}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
