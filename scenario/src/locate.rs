//! Where a key path sits in the file: `agents[2].neighbours[0]` → line and column, so every
//! problem can be shown as `file:line:column` (as a compiler would). A path to a missing key
//! points at the nearest table that exists; a path no part of which exists (`(file)`, a
//! command-line argument) has no location.

use toml_edit::{ImDocument, Item, Value};

/// One step of a key path.
#[derive(Debug, PartialEq)]
enum Step<'a> {
    Key(&'a str),
    Index(usize),
}

/// `a.b[2].c` → [a, b, 2, c]; `agents[].x` (every agent) stops before the empty index.
fn steps(path: &str) -> Vec<Step<'_>> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let (key, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if !key.is_empty() {
            out.push(Step::Key(key));
        }
        while let Some(inner) = rest.strip_prefix('[') {
            let Some(end) = inner.find(']') else { return out };
            match inner[..end].parse() {
                Ok(i) => out.push(Step::Index(i)),
                Err(_) => return out,
            }
            rest = &inner[end + 1..];
        }
    }
    out
}

/// Where the walk along a path is: a table-like item, a table of an array of tables, or a value.
#[derive(Clone, Copy)]
enum Node<'a> {
    Item(&'a Item),
    Table(&'a toml_edit::Table),
    Value(&'a Value),
}

impl<'a> Node<'a> {
    /// The child `k` and the span of its key (or of its value).
    fn key(self, k: &str) -> Option<(Node<'a>, Option<std::ops::Range<usize>>)> {
        let table: &'a dyn toml_edit::TableLike = match self {
            Node::Item(i) => i.as_table_like()?,
            Node::Table(t) => t,
            Node::Value(v) => v.as_inline_table()?,
        };
        let (key, item) = table.get_key_value(k)?;
        let child = match item.as_value() {
            Some(v) => Node::Value(v),
            None => Node::Item(item),
        };
        Some((child, key.span().or_else(|| item.span())))
    }
    /// Element `i` and its span.
    fn index(self, i: usize) -> Option<(Node<'a>, Option<std::ops::Range<usize>>)> {
        match self {
            Node::Item(Item::ArrayOfTables(a)) => a.get(i).map(|t| (Node::Table(t), t.span())),
            Node::Value(v) => v.as_array()?.get(i).map(|e| (Node::Value(e), e.span())),
            _ => None,
        }
    }
}

/// The byte span of the deepest part of `path` present in `doc`.
fn span(doc: &ImDocument<&str>, path: &str) -> Option<std::ops::Range<usize>> {
    let mut node = Node::Item(doc.as_item());
    let mut found = None;
    for step in steps(path) {
        let next = match step {
            Step::Key(k) => node.key(k),
            Step::Index(i) => node.index(i),
        };
        let Some((child, span)) = next else { break };
        node = child;
        found = span.or(found);
    }
    found
}

/// 1-based (line, column) of byte offset `at` in `text`.
pub fn line_col(text: &str, at: usize) -> (usize, usize) {
    let before = &text[..at.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Line and column of `path` in the TOML `text`, when the file parses and some part of the path
/// is in it.
pub fn locate(text: &str, path: &str) -> Option<(usize, usize)> {
    let doc = ImDocument::parse(text).ok()?;
    span(&doc, path).map(|s| line_col(text, s.start))
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "[scenario]\nname = \"x\"\ndt_s = 0.01\n\n[plant]\nkind = \"orbital\"\n[plant.defunct]\nmass_kg = 3.0\n\n[[agents]]\nid = 1\nneighbours = [2, 3]\n\n[[agents]]\nid = 2\nneighbours = [1]\nr0_m = [1.0, { a = 2 }, 3.0]\n";

    #[test]
    fn paths_are_found_where_they_are_written() {
        assert_eq!(locate(TEXT, "scenario.dt_s"), Some((3, 1)));
        assert_eq!(locate(TEXT, "plant.defunct.mass_kg"), Some((8, 1)));
        assert_eq!(locate(TEXT, "agents[0].neighbours[1]"), Some((12, 18)));
        assert_eq!(locate(TEXT, "agents[1].id"), Some((15, 1)));
        assert_eq!(locate(TEXT, "agents[1].r0_m[2]"), Some((17, 25)));
    }

    #[test]
    fn a_missing_key_points_at_its_nearest_existing_parent() {
        assert_eq!(locate(TEXT, "scenario.duration_s"), Some((1, 2)));
        assert_eq!(locate(TEXT, "plant.defunct.area_m2"), Some((7, 8)));
        assert_eq!(locate(TEXT, "(file)"), None);
        assert_eq!(locate("not toml [", "scenario"), None);
        // Every agent: the first `[[agents]]` header.
        assert_eq!(locate(TEXT, "agents[].neighbours"), Some((10, 3)));
    }
}
