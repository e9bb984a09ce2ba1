//! Key paths into a scenario's TOML table: `plant.mass_kg`, `agents[3].r0_m`,
//! `agents[0].output_matrix[1][2]` — the form every problem of a scenario is reported in
//! (indices from 0, as in those reports).

use std::fmt;

/// One step of a key path: a table key or an array index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Seg {
    Key(String),
    Index(usize),
}

/// A parsed key path (at least one key; it starts with one).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeyPath(pub Vec<Seg>);

impl KeyPath {
    /// Parse `a.b[2].c`; the reason when the text is not a key path.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut segs = Vec::new();
        if text.is_empty() {
            return Err("empty key path".into());
        }
        for part in text.split('.') {
            let (name, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
            let ok_name = !name.is_empty() && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-');
            if !ok_name {
                return Err(format!("{part:?} is not a key (letters, digits, _ and -, then [index]s)"));
            }
            segs.push(Seg::Key(name.to_string()));
            while !rest.is_empty() {
                let close = rest.find(']').ok_or_else(|| format!("{part:?}: unclosed ["))?;
                let idx =
                    rest[1..close].parse::<usize>().map_err(|_| format!("{part:?}: an index is a whole number ≥ 0"))?;
                segs.push(Seg::Index(idx));
                rest = &rest[close + 1..];
                if !rest.is_empty() && !rest.starts_with('[') {
                    return Err(format!("{part:?}: text after an index"));
                }
            }
        }
        Ok(Self(segs))
    }

    /// The value at this path, if every step exists.
    pub fn get<'a>(&self, table: &'a toml::Table) -> Option<&'a toml::Value> {
        let (Seg::Key(first), rest) = self.0.split_first()? else { return None };
        let mut cur = table.get(first)?;
        for seg in rest {
            cur = match seg {
                Seg::Key(k) => cur.as_table()?.get(k)?,
                Seg::Index(i) => cur.as_array()?.get(*i)?,
            };
        }
        Some(cur)
    }

    /// The value at this path, mutable, if every step exists.
    pub fn get_mut<'a>(&self, table: &'a mut toml::Table) -> Option<&'a mut toml::Value> {
        let (Seg::Key(first), rest) = self.0.split_first()? else { return None };
        let mut cur = table.get_mut(first)?;
        for seg in rest {
            cur = match seg {
                Seg::Key(k) => cur.as_table_mut()?.get_mut(k)?,
                Seg::Index(i) => cur.as_array_mut()?.get_mut(*i)?,
            };
        }
        Some(cur)
    }

    /// Why the path finds nothing in `table`: the first step that is missing, with what is there
    /// instead (the keys of that table, with a "did you mean", or the array's length).
    pub fn why_missing(&self, table: &toml::Table) -> String {
        let mut cur: Option<&toml::Value> = None;
        for (k, seg) in self.0.iter().enumerate() {
            let here = KeyPath(self.0[..k].to_vec());
            let next = match (seg, cur) {
                (Seg::Key(key), None) => table.get(key).ok_or_else(|| missing_key(key, &here, table)),
                (Seg::Key(key), Some(toml::Value::Table(t))) => t.get(key).ok_or_else(|| missing_key(key, &here, t)),
                (Seg::Index(i), Some(toml::Value::Array(a))) => {
                    a.get(*i).ok_or_else(|| format!("{here} has {} element(s), no index {i}", a.len()))
                }
                (Seg::Key(_), Some(v)) => Err(format!("{here} is a {}, not a table", v.type_str())),
                (Seg::Index(_), Some(v)) => Err(format!("{here} is a {}, not an array", v.type_str())),
                (Seg::Index(_), None) => Err("a key path starts with a key".into()),
            };
            match next {
                Ok(v) => cur = Some(v),
                Err(why) => return why,
            }
        }
        "present".into()
    }
}

fn missing_key(key: &str, at: &KeyPath, t: &toml::Table) -> String {
    let options: Vec<&str> = t.keys().map(String::as_str).collect();
    let hint = crate::parse::did_you_mean(key, &options);
    let place = if at.0.is_empty() { "the scenario".to_string() } else { at.to_string() };
    format!("{place} has no key {key:?}{hint}")
}

impl fmt::Display for KeyPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (k, seg) in self.0.iter().enumerate() {
            match seg {
                Seg::Key(key) if k == 0 => write!(f, "{key}")?,
                Seg::Key(key) => write!(f, ".{key}")?,
                Seg::Index(i) => write!(f, "[{i}]")?,
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_parse_print_and_find() {
        let t: toml::Table = "[plant]\nmass_kg = 3.0\n[[agents]]\nm = [[1, 2], [3, 4]]\n".parse().unwrap();
        for text in ["plant.mass_kg", "agents[0].m[1][0]"] {
            let p = KeyPath::parse(text).unwrap();
            assert_eq!(p.to_string(), text);
            assert!(p.get(&t).is_some(), "{text}");
        }
        assert_eq!(KeyPath::parse("agents[0].m[1][0]").unwrap().get(&t), Some(&toml::Value::Integer(3)));
        for bad in ["", "a..b", "a[x]", "a[1", "a[1]b", "[1]", "a b"] {
            assert!(KeyPath::parse(bad).is_err(), "{bad}");
        }
        let why = |p: &str| KeyPath::parse(p).unwrap().why_missing(&t);
        assert_eq!(why("plant.mass_k"), "plant has no key \"mass_k\" (did you mean \"mass_kg\"?)");
        assert_eq!(why("agents[2].m"), "agents has 1 element(s), no index 2");
        assert_eq!(why("plant.mass_kg.x"), "plant.mass_kg is a float, not a table");
        assert_eq!(why("algorithm.k1"), "the scenario has no key \"algorithm\"");
    }
}
