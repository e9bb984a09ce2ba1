//! Markdown (GitHub-flavoured) tables for the reports Cohort writes (`sweep.md`, campaign and
//! comparison tables): a header, rows of cells, and a check that every row has the header's width,
//! instead of `|` and `---|` pasted by hand at every table.

use std::fmt;

/// Column alignment, as the separator row writes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Align {
    #[default]
    Left,
    Right,
    Center,
}

/// A Markdown table being built; [`fmt::Display`] writes it, one line per row, ending in a newline.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MdTable {
    header: Vec<String>,
    align: Vec<Align>,
    rows: Vec<Vec<String>>,
}

impl MdTable {
    /// A table with these column headers, every column left-aligned.
    pub fn new<S: Into<String>>(header: impl IntoIterator<Item = S>) -> Self {
        let header: Vec<String> = header.into_iter().map(Into::into).collect();
        let align = vec![Align::Left; header.len()];
        Self { header, align, rows: Vec::new() }
    }

    /// Align column `col` (ignored past the last column).
    pub fn align(mut self, col: usize, a: Align) -> Self {
        if let Some(slot) = self.align.get_mut(col) {
            *slot = a;
        }
        self
    }

    /// Append a row. A row shorter than the header is padded with empty cells; a longer one is a
    /// bug of the caller and panics, naming both widths.
    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) -> &mut Self {
        let mut r: Vec<String> = cells.into_iter().map(Into::into).collect();
        assert!(r.len() <= self.header.len(), "a row of {} cells in a table of {} columns", r.len(), self.header.len());
        r.resize(self.header.len(), String::new());
        self.rows.push(r);
        self
    }

    /// Number of rows (the header not counted).
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when no row was added.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

/// A cell's text with its `|` escaped and line breaks folded, so it cannot break the table.
fn cell(s: &str) -> String {
    s.replace('|', "\\|").replace('\n', " ")
}

impl fmt::Display for MdTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let line = |f: &mut fmt::Formatter<'_>, cells: &[String]| -> fmt::Result {
            write!(f, "|")?;
            for c in cells {
                write!(f, " {} |", cell(c))?;
            }
            writeln!(f)
        };
        line(f, &self.header)?;
        write!(f, "|")?;
        for a in &self.align {
            f.write_str(match a {
                Align::Left => "---|",
                Align::Right => "---:|",
                Align::Center => ":---:|",
            })?;
        }
        writeln!(f)?;
        for r in &self.rows {
            line(f, r)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_writes_its_header_separator_and_padded_rows() {
        let mut t = MdTable::new(["metric", "p99"]).align(1, Align::Right);
        t.row(["e_m", "1.5"]).row(["a|b"]);
        assert_eq!(t.to_string(), "| metric | p99 |\n|---|---:|\n| e_m | 1.5 |\n| a\\|b |  |\n");
        assert_eq!(t.len(), 2);
    }

    #[test]
    #[should_panic(expected = "a row of 3 cells in a table of 2 columns")]
    fn a_row_wider_than_the_header_is_a_bug() {
        MdTable::new(["a", "b"]).row(["1", "2", "3"]);
    }
}
