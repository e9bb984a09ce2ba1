//! Column names to quantities: `[a<i>_]<name>[_<axis>][_<unit>]` (see the crate docs).

use std::collections::HashMap;

use crate::table::Table;

/// Display form of a unit suffix, or `None` if `suffix` is not a unit we know (it is then taken
/// as part of the quantity's name). The table is the runtime's, the one the telemetry writer uses.
pub fn unit_label(suffix: &str) -> Option<&'static str> {
    cohort_runtime::units::UNITS.iter().find(|(s, _)| *s == suffix).map(|(_, label)| *label)
}

/// A column name split into its parts; see the module documentation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct ColumnName {
    pub(crate) owner: Option<u32>,
    pub(crate) name: String,
    pub(crate) axis: Option<char>,
    pub(crate) unit: Option<String>,
}

pub(crate) fn parse_column_name(column: &str, allow_owner: bool) -> ColumnName {
    let owner_prefix = column.split_once('_').filter(|_| allow_owner).and_then(|(prefix, tail)| {
        let digits = prefix.strip_prefix('a')?;
        let is_id = !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit());
        if !is_id || tail.is_empty() {
            return None;
        }
        Some((digits.parse::<u32>().ok()?, tail))
    });
    let (owner, rest) = match owner_prefix {
        Some((id, tail)) => (Some(id), tail),
        None => (None, column),
    };
    let (stem, unit) = cohort_runtime::units::split_unit(rest);
    let unit = unit.map(|(suffix, _)| suffix.to_string());
    let mut tokens: Vec<&str> = stem.split('_').collect();
    let mut axis = None;
    if let [_, .., a @ ("x" | "y" | "z")] = tokens[..] {
        axis = a.chars().next();
        tokens.pop();
    }
    ColumnName { owner, name: tokens.join("_"), axis, unit }
}

/// A plotted quantity of one table: a scalar column, or a vector of axis columns.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Quantity {
    pub(crate) owner: Option<u32>,
    pub(crate) name: String,
    pub(crate) unit: Option<String>,
    /// `(axis, column index)`; exactly one entry with axis `None` for a scalar.
    pub(crate) components: Vec<(Option<char>, usize)>,
}

impl Quantity {
    pub(crate) fn is_vector(&self) -> bool {
        self.components.len() >= 2
    }

    /// Per-row values: the column itself for a scalar, the Euclidean norm for a vector.
    pub(crate) fn values(&self, table: &Table) -> Vec<f64> {
        if let [(_, col)] = self.components[..] {
            return table.columns[col].values.clone();
        }
        let rows = self.components.iter().map(|&(_, col)| table.columns[col].values.len()).min().unwrap_or(0);
        (0..rows)
            .map(|row| {
                self.components.iter().map(|&(_, col)| table.columns[col].values[row].powi(2)).sum::<f64>().sqrt()
            })
            .collect()
    }

    pub(crate) fn column<'t>(&self, table: &'t Table, axis: char) -> Option<&'t [f64]> {
        self.components.iter().find(|(a, _)| *a == Some(axis)).map(|&(_, col)| table.columns[col].values.as_slice())
    }
}

/// Groups a table's columns into quantities, in order of first appearance. `file_owner` is the
/// agent id of an agent file (whose columns carry no `a<i>_` prefix).
pub(crate) fn classify_columns(table: &Table, file_owner: Option<u32>) -> Vec<Quantity> {
    let mut quantities: Vec<Quantity> = Vec::new();
    let mut vector_index: HashMap<(Option<u32>, String, Option<String>), usize> = HashMap::new();
    for (col, column) in table.columns.iter().enumerate() {
        let parsed = parse_column_name(&column.name, file_owner.is_none());
        let owner = file_owner.or(parsed.owner);
        match parsed.axis {
            Some(axis) => {
                let key = (owner, parsed.name.clone(), parsed.unit.clone());
                if let Some(&q) = vector_index.get(&key) {
                    quantities[q].components.push((Some(axis), col));
                } else {
                    vector_index.insert(key, quantities.len());
                    quantities.push(Quantity {
                        owner,
                        name: parsed.name,
                        unit: parsed.unit,
                        components: vec![(Some(axis), col)],
                    });
                }
            }
            None => {
                quantities.push(Quantity { owner, name: parsed.name, unit: parsed.unit, components: vec![(None, col)] })
            }
        }
    }
    // A lone axis column (say `r_x_m` without `r_y_m`) is a scalar named `r_x`.
    for q in &mut quantities {
        if let [(Some(axis), _)] = q.components[..] {
            q.name = format!("{}_{axis}", q.name);
            q.components[0].0 = None;
        }
    }
    quantities
}
