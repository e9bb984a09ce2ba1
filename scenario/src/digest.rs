//! A run's scenario table in binary form (`scenario.digest` beside the run's `scenario.toml`),
//! so that each of a run's processes does not parse the TOML text again.
//!
//! Every process of a run reads the run's scenario. Parsing the text is most of that reading: a
//! thousand-agent scenario (123 kB) took ≈ 5 ms of a process's ≈ 16 ms start (`perf record` of
//! `orchestrator check`), paid by each of the thousand processes and the plant. The digest holds
//! the table the text parses to (before the command line's overrides), encoded with bincode:
//! floats as their bits, so the table decoded is the one parsed, bit for bit. Everything after
//! the table (overrides, typed sections, validation, the papers' own sections) is done as for
//! the text, so a process reading the digest ends with the same scenario.
//!
//! The digest names the text it was made from (its length and CRC-32) and carries the CRC-32 of
//! its table: a process reads the text too (problems are located in it), and a digest of another
//! text, a damaged one or one of another format is not used ([`DigestError`]); the text is
//! parsed instead.

use std::path::{Path, PathBuf};

use bincode::de::Decoder;
use bincode::enc::Encoder;
use bincode::error::{DecodeError, EncodeError};
use bincode::{Decode, Encode};
use toml::{Table, Value};

/// The first bytes of a digest, with its format's version.
const MAGIC: &[u8; 8] = b"COHDIG\x00\x01";

/// How deep tables and arrays may nest in a digest: TOML text nests far less, and a damaged
/// digest must not overflow the stack of the process reading it.
const MAX_DEPTH: u32 = 64;

/// The largest digest read, bytes (its text is at most [`crate::parse::MAX_INPUT_BYTES`]; its
/// binary form is smaller).
const MAX_DIGEST_BYTES: usize = 4 * crate::parse::MAX_INPUT_BYTES as usize;

/// Why a digest was not used.
#[derive(Debug, thiserror::Error)]
pub enum DigestError {
    #[error("{}: cannot read: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{}: not a scenario digest of this version", path.display())]
    Format { path: PathBuf },
    #[error("{}: made from another text than {} (its length or checksum differs)", path.display(), text.display())]
    OtherText { path: PathBuf, text: PathBuf },
    #[error("{}: damaged: {source}", path.display())]
    Damaged { path: PathBuf, source: DecodeError },
}

/// The digest of the scenario file `file`: beside it, `.digest` instead of its extension.
pub fn path_for(file: &Path) -> PathBuf {
    file.with_extension("digest")
}

/// The digest of scenario text: its table (as [`toml`] parses it), named by the text's length
/// and checksum. The caller writes it to [`path_for`] its file.
pub fn encode(text: &str) -> Result<Vec<u8>, toml::de::Error> {
    let table: Table = text.parse()?;
    let body = bincode::encode_to_vec(TableOut(&table), config()).expect("encoding into memory cannot fail");
    let head = (text.len() as u64, crc32fast::hash(text.as_bytes()), crc32fast::hash(&body));
    let mut out = MAGIC.to_vec();
    out.extend(bincode::encode_to_vec(head, config()).expect("encoding into memory cannot fail"));
    out.extend(body);
    Ok(out)
}

/// The table of `text` from the digest at `path`, which must have been made from `text` (the
/// contents of `file`).
pub fn read(path: &Path, file: &Path, text: &str) -> Result<Table, DigestError> {
    use std::io::Read as _;
    let f = std::fs::File::open(path).map_err(|source| DigestError::Read { path: path.into(), source })?;
    let mut bytes = Vec::new();
    f.take(MAX_DIGEST_BYTES as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|source| DigestError::Read { path: path.into(), source })?;
    decode(&bytes, text).map_err(|e| match e {
        Refused::Format => DigestError::Format { path: path.into() },
        Refused::OtherText => DigestError::OtherText { path: path.into(), text: file.into() },
        Refused::Damaged(source) => DigestError::Damaged { path: path.into(), source },
    })
}

enum Refused {
    Format,
    OtherText,
    Damaged(DecodeError),
}

fn decode(bytes: &[u8], text: &str) -> Result<Table, Refused> {
    let body =
        bytes.strip_prefix(MAGIC.as_slice()).filter(|_| bytes.len() <= MAX_DIGEST_BYTES).ok_or(Refused::Format)?;
    let ((len, crc, body_crc), used): ((u64, u32, u32), usize) =
        bincode::decode_from_slice(body, config()).map_err(Refused::Damaged)?;
    if len != text.len() as u64 || crc != crc32fast::hash(text.as_bytes()) {
        return Err(Refused::OtherText);
    }
    let body = &body[used..];
    // A damaged table could still decode, to another scenario.
    if body_crc != crc32fast::hash(body) {
        return Err(Refused::Damaged(DecodeError::Other("its checksum differs")));
    }
    let (TableIn(table), more): (TableIn, usize) =
        bincode::decode_from_slice(body, config()).map_err(Refused::Damaged)?;
    if more != body.len() {
        return Err(Refused::Damaged(DecodeError::Other("bytes after the table")));
    }
    Ok(table)
}

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_little_endian()
}

struct TableOut<'a>(&'a Table);
struct ValueOut<'a>(&'a Value);
struct TableIn(Table);

const STRING: u8 = 0;
const INTEGER: u8 = 1;
const FLOAT: u8 = 2;
const BOOLEAN: u8 = 3;
const DATETIME: u8 = 4;
const ARRAY: u8 = 5;
const TABLE: u8 = 6;

impl Encode for TableOut<'_> {
    fn encode<E: Encoder>(&self, e: &mut E) -> Result<(), EncodeError> {
        (self.0.len() as u64).encode(e)?;
        for (k, v) in self.0 {
            k.encode(e)?;
            ValueOut(v).encode(e)?;
        }
        Ok(())
    }
}

impl Encode for ValueOut<'_> {
    fn encode<E: Encoder>(&self, e: &mut E) -> Result<(), EncodeError> {
        match self.0 {
            Value::String(s) => (STRING, s).encode(e),
            Value::Integer(i) => (INTEGER, i).encode(e),
            // The bits, so that the float read back is this one.
            Value::Float(x) => (FLOAT, x.to_bits()).encode(e),
            Value::Boolean(b) => (BOOLEAN, b).encode(e),
            Value::Datetime(d) => (DATETIME, d.to_string()).encode(e),
            Value::Array(a) => {
                (ARRAY, a.len() as u64).encode(e)?;
                a.iter().try_for_each(|v| ValueOut(v).encode(e))
            }
            Value::Table(t) => (TABLE, TableOut(t)).encode(e),
        }
    }
}

impl<C> Decode<C> for TableIn {
    fn decode<D: Decoder<Context = C>>(d: &mut D) -> Result<Self, DecodeError> {
        table(d, 0).map(TableIn)
    }
}

fn table<D: Decoder>(d: &mut D, depth: u32) -> Result<Table, DecodeError> {
    let n = u64::decode(d)?;
    let mut t = Table::new();
    for _ in 0..n {
        let k = String::decode(d)?;
        let v = value(d, depth + 1)?;
        if t.insert(k, v).is_some() {
            return Err(DecodeError::Other("a key twice in one table"));
        }
    }
    Ok(t)
}

fn value<D: Decoder>(d: &mut D, depth: u32) -> Result<Value, DecodeError> {
    if depth > MAX_DEPTH {
        return Err(DecodeError::Other("tables and arrays nested too deep"));
    }
    Ok(match u8::decode(d)? {
        STRING => Value::String(String::decode(d)?),
        INTEGER => Value::Integer(i64::decode(d)?),
        FLOAT => Value::Float(f64::from_bits(u64::decode(d)?)),
        BOOLEAN => Value::Boolean(bool::decode(d)?),
        DATETIME => Value::Datetime(
            String::decode(d)?.parse().map_err(|_| DecodeError::Other("a date-time that does not parse"))?,
        ),
        ARRAY => {
            let n = u64::decode(d)?;
            // No capacity from the length read: a damaged length must not allocate.
            let mut a = Vec::new();
            for _ in 0..n {
                a.push(value(d, depth + 1)?);
            }
            Value::Array(a)
        }
        TABLE => Value::Table(table(d, depth)?),
        tag => {
            return Err(DecodeError::UnexpectedVariant {
                type_name: "toml value",
                allowed: &bincode::error::AllowedEnumVariants::Range { min: 0, max: 6 },
                found: u32::from(tag),
            });
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal, floats by their bits (so NaN, -0.0 and every last bit count).
    fn same(a: &Value, b: &Value) -> bool {
        match (a, b) {
            (Value::Float(x), Value::Float(y)) => x.to_bits() == y.to_bits(),
            (Value::Array(x), Value::Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(a, b)| same(a, b)),
            (Value::Table(x), Value::Table(y)) => same_table(x, y),
            _ => a == b,
        }
    }

    fn same_table(x: &Table, y: &Table) -> bool {
        x.len() == y.len() && x.iter().zip(y).all(|((ka, a), (kb, b))| ka == kb && same(a, b))
    }

    const EVERY_KIND: &str = r#"
s = "text with \"quotes\" and ünïcode"
i = -9223372036854775808
f = [0.1, -0.0, 1e-308, 5e-324, 2.5e300, nan, -inf]
b = true
when = 2026-12-07T15:27:53.25Z
day = 2026-12-07
nested = [[1, 2], [], [[3.5]]]
[t.u]
deep = { a = [{ b = 1 }] }
[[agents]]
id = 1
r0_m = [2600.9486782259564, 8.796401551782532, -1.0]
"#;

    #[test]
    fn the_digest_gives_the_table_the_text_parses_to_bit_for_bit() {
        let mut texts = vec![EVERY_KIND.to_string()];
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../topologies");
        for f in std::fs::read_dir(dir).unwrap() {
            let p = f.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                texts.push(std::fs::read_to_string(p).unwrap());
            }
        }
        assert!(texts.len() > 20, "the shipped scenarios are read: {}", texts.len());
        for text in &texts {
            let parsed: Table = text.parse().unwrap();
            let decoded = decode(&encode(text).unwrap(), text).ok().expect("a digest of this text");
            assert!(same_table(&parsed, &decoded), "{text}");
        }
    }

    #[test]
    fn a_digest_of_another_text_or_damaged_is_refused() {
        let d = encode(EVERY_KIND).unwrap();
        let other = EVERY_KIND.replace("b = true", "b = fals");
        assert!(matches!(decode(&d, &other), Err(Refused::OtherText)));
        assert!(matches!(decode(&d[1..], EVERY_KIND), Err(Refused::Format)));
        assert!(matches!(decode(b"", EVERY_KIND), Err(Refused::Format)));
        // Cut anywhere after the header, or with a byte more: never a panic, never a table.
        for n in MAGIC.len()..d.len() {
            assert!(decode(&d[..n], EVERY_KIND).is_err(), "cut at {n}");
        }
        let mut longer = d.clone();
        longer.push(0);
        assert!(matches!(decode(&longer, EVERY_KIND), Err(Refused::Damaged(_))));
        // Every byte flipped in turn: refused, never a panic, never another table.
        for i in 0..d.len() {
            let mut bad = d.clone();
            bad[i] ^= 0xA5;
            assert!(decode(&bad, EVERY_KIND).is_err(), "byte {i} flipped");
        }
    }

    #[test]
    fn nesting_beyond_the_limit_is_refused_not_followed() {
        let text = "x = 1\n";
        // One key whose value is an array holding an array holding … (a million deep).
        let mut body = bincode::encode_to_vec((1u64, "x"), config()).unwrap();
        for _ in 0..1_000_000 {
            body.extend([ARRAY, 1]);
        }
        let head = (text.len() as u64, crc32fast::hash(text.as_bytes()), crc32fast::hash(&body));
        let mut d = MAGIC.to_vec();
        d.extend(bincode::encode_to_vec(head, config()).unwrap());
        d.extend(body);
        assert!(matches!(decode(&d, text), Err(Refused::Damaged(DecodeError::Other(m))) if m.contains("too deep")));
    }

    #[test]
    fn a_missing_digest_is_a_read_error_naming_it() {
        let dir = std::env::temp_dir().join(format!("cohort-digest-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("scenario.toml");
        let e = read(&path_for(&file), &file, "x = 1\n").unwrap_err();
        assert!(e.to_string().contains("scenario.digest: cannot read"), "{e}");
        std::fs::write(path_for(&file), b"COHDIG\x00\x02rest").unwrap();
        let e = read(&path_for(&file), &file, "x = 1\n").unwrap_err();
        assert!(e.to_string().ends_with("scenario.digest: not a scenario digest of this version"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
