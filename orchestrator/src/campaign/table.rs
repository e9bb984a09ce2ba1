//! `campaign.parquet`: a row per case — `case`, `seed`, `status`, `error`, every drawn value
//! (named by its key path), every summary metric, and per verdict line `verdict: <line>` and
//! `ours: <line>`, then `verdict_overall`. Units (from the names' suffixes, or the verdict line's)
//! are in each field's metadata under `unit`, as in the telemetry files. Doubles as they were
//! computed (bit-exact); a metric a case did not produce is null.

use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::sync::Arc;

use arrow_array::builder::{BooleanBuilder, Float64Builder, Int64Builder, StringBuilder};
use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::{DataType, Field, Schema};
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::properties::WriterProperties;

use super::row::{CaseRow, Cell};

pub const FILE: &str = "campaign.parquet";

/// The metric columns of `rows`: every name any case produced, sorted.
pub fn metric_names(rows: &[CaseRow]) -> Vec<String> {
    rows.iter().flat_map(|r| r.outcome.metrics.keys().cloned()).collect::<BTreeSet<_>>().into_iter().collect()
}

/// The verdict lines of `rows`, in order of first appearance, with their units.
pub fn verdict_names(rows: &[CaseRow]) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = Vec::new();
    for v in rows.iter().flat_map(|r| &r.outcome.verdict) {
        if !out.iter().any(|(n, _)| *n == v.name) {
            out.push((v.name.clone(), v.unit.clone()));
        }
    }
    out
}

fn field(name: &str, t: DataType, nullable: bool, unit: Option<&str>) -> Field {
    let f = Field::new(name, t, nullable);
    match unit.filter(|u| !u.is_empty()) {
        Some(u) => f.with_metadata(HashMap::from([(cohort_runtime::parquet_out::UNIT_KEY.to_string(), u.to_string())])),
        None => f,
    }
}

/// A drawn column: Float64 (any float among its values), Int64, Boolean or Utf8.
fn drawn_column(name: &str, rows: &[CaseRow], k: usize) -> (Field, ArrayRef) {
    let cells: Vec<&Cell> = rows.iter().map(|r| &r.values[k]).collect();
    let unit = cohort_runtime::units::unit_of(name);
    let all = |f: fn(&Cell) -> bool| cells.iter().all(|c| f(c));
    if all(|c| matches!(c, Cell::Int(_))) {
        let mut b = Int64Builder::new();
        cells.iter().for_each(|c| b.append_option(if let Cell::Int(i) = c { Some(*i) } else { None }));
        (field(name, DataType::Int64, false, unit), Arc::new(b.finish()))
    } else if all(|c| c.as_f64().is_some()) {
        let mut b = Float64Builder::new();
        cells.iter().for_each(|c| b.append_option(c.as_f64()));
        (field(name, DataType::Float64, false, unit), Arc::new(b.finish()))
    } else if all(|c| matches!(c, Cell::Bool(_))) {
        let mut b = BooleanBuilder::new();
        cells.iter().for_each(|c| b.append_option(if let Cell::Bool(x) = c { Some(*x) } else { None }));
        (field(name, DataType::Boolean, false, None), Arc::new(b.finish()))
    } else {
        let mut b = StringBuilder::new();
        for c in cells {
            match c {
                Cell::Text(s) => b.append_value(s),
                Cell::Bool(x) => b.append_value(x.to_string()),
                other => b.append_value(other.as_f64().map_or(String::new(), |x| x.to_string())),
            }
        }
        (field(name, DataType::Utf8, false, None), Arc::new(b.finish()))
    }
}

/// The table of `rows` (in case order); `columns` names the drawn values.
pub fn batch(rows: &[CaseRow], columns: &[String]) -> Result<RecordBatch, String> {
    let mut fields = Vec::new();
    let mut arrays: Vec<ArrayRef> = Vec::new();
    let mut push = |f: Field, a: ArrayRef| {
        fields.push(f);
        arrays.push(a);
    };
    let u64s = |f: fn(&CaseRow) -> u64| Arc::new(rows.iter().map(f).collect::<arrow_array::UInt64Array>()) as ArrayRef;
    push(field("case", DataType::UInt64, false, None), u64s(|r| r.case));
    push(field("seed", DataType::UInt64, false, None), u64s(|r| r.seed));
    let strings = |f: &dyn Fn(&CaseRow) -> Option<String>| {
        let mut b = StringBuilder::new();
        rows.iter().for_each(|r| b.append_option(f(r)));
        Arc::new(b.finish()) as ArrayRef
    };
    push(field("status", DataType::Utf8, false, None), strings(&|r| Some(r.outcome.status.clone())));
    push(field("error", DataType::Utf8, true, None), strings(&|r| r.outcome.error.clone()));
    for (k, name) in columns.iter().enumerate() {
        let (f, a) = drawn_column(name, rows, k);
        push(f, a);
    }
    for name in metric_names(rows) {
        let mut b = Float64Builder::new();
        rows.iter().for_each(|r| b.append_option(r.metric(&name)));
        push(field(&name, DataType::Float64, true, cohort_runtime::units::unit_of(&name)), Arc::new(b.finish()));
    }
    for (name, unit) in verdict_names(rows) {
        let line = |r: &CaseRow| r.outcome.verdict.iter().find(|v| v.name == name).cloned();
        push(field(&format!("verdict: {name}"), DataType::Utf8, true, None), strings(&|r| line(r).map(|v| v.verdict)));
        let mut b = Float64Builder::new();
        rows.iter().for_each(|r| b.append_option(line(r).and_then(|v| v.ours).map(f64::from_bits)));
        push(field(&format!("ours: {name}"), DataType::Float64, true, Some(&unit)), Arc::new(b.finish()));
    }
    push(field("verdict_overall", DataType::Utf8, false, None), strings(&|r| Some(r.outcome.verdict_overall.clone())));
    let schema = Arc::new(Schema::new(fields));
    RecordBatch::try_new(schema, arrays).map_err(|e| e.to_string())
}

/// Write the table to `root/campaign.parquet` (whole, then renamed into place), `meta` in the
/// file's key-value metadata and in its Arrow schema's.
pub fn write(root: &Path, rows: &[CaseRow], columns: &[String], meta: &[(&str, String)]) -> Result<(), String> {
    let path = root.join(FILE);
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let batch = batch(rows, columns).map_err(|e| err(&e))?;
    // In the Arrow schema too, where Arrow readers (pyarrow's `schema.metadata`) look.
    let schema = batch
        .schema()
        .as_ref()
        .clone()
        .with_metadata(meta.iter().map(|(k, v)| (k.to_string(), v.clone())).collect::<HashMap<_, _>>());
    let batch = batch.with_schema(Arc::new(schema)).map_err(|e| err(&e))?;
    let kv = meta.iter().map(|(k, v)| parquet::file::metadata::KeyValue::new(k.to_string(), v.clone())).collect();
    let props = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::try_new(3).expect("zstd level 3 exists")))
        .set_key_value_metadata(Some(kv))
        .build();
    let tmp = root.join(format!(".{FILE}.tmp"));
    let file = std::fs::File::create(&tmp).map_err(|e| err(&e))?;
    let mut w = ArrowWriter::try_new(file, batch.schema(), Some(props)).map_err(|e| err(&e))?;
    w.write(&batch).map_err(|e| err(&e))?;
    w.close().map_err(|e| err(&e))?;
    std::fs::rename(&tmp, &path).map_err(|e| err(&e))
}
