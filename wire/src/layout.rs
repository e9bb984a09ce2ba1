//! The byte layout of the two data payloads, [`Measurement`] and [`Share`], as a table of fields:
//! what a recording (`launch --record`) needs to describe the exact bytes it stores and what a
//! replay needs to name the field a differing byte belongs to.
//!
//! Both payloads are `#[repr(C)]` structs of `u32`, `u64` and `f64` (and fixed arrays of them)
//! with every padding made explicit (`_pad`), so their bytes on a little-endian machine are, field
//! after field with no gaps, exactly what the ROS 1 serialisation of a message with the same fields
//! in the same order would be (ROS 1 writes little-endian primitives back to back and fixed-size
//! arrays without a length). [`ros1_definition`] writes that message definition, so a tool that
//! reads ROS 1 messages (Foxglove reading an MCAP file) decodes the wire bytes as they are. The
//! tests check the table against `offset_of!` and `size_of`. ROS 1 field names cannot start with an
//! underscore: `_pad` is called `pad` there.

use crate::msg::{
    MAX_AGENTS, MAX_COMMAND, MAX_LINKS_IN, MAX_READINGS, MAX_SHARE_VALUES, Measurement, SCHEMA_VERSION, Share,
};

/// A primitive of the wire payloads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prim {
    U32,
    U64,
    F64,
}

impl Prim {
    pub const fn size(self) -> usize {
        match self {
            Prim::U32 => 4,
            Prim::U64 | Prim::F64 => 8,
        }
    }
    fn ros1(self) -> &'static str {
        match self {
            Prim::U32 => "uint32",
            Prim::U64 => "uint64",
            Prim::F64 => "float64",
        }
    }
    /// One value of this type from its little-endian bytes, in words: a float with its bits (so
    /// two that print alike but differ show it).
    pub fn show(self, b: &[u8]) -> String {
        match self {
            Prim::U32 => u32::from_le_bytes(b.try_into().expect("4 bytes")).to_string(),
            Prim::U64 => u64::from_le_bytes(b.try_into().expect("8 bytes")).to_string(),
            Prim::F64 => {
                let bits = u64::from_le_bytes(b.try_into().expect("8 bytes"));
                format!("{:?} (bits {bits:#018x})", f64::from_bits(bits))
            }
        }
    }
}

/// One field: its name (ROS 1 spelling), type and count (1: a scalar, else a fixed array).
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub name: &'static str,
    pub prim: Prim,
    pub count: usize,
    /// Whether a ROS 1 definition writes it as an array (`uint64[2] mac`), even of one.
    pub array: bool,
}

const fn scalar(name: &'static str, prim: Prim) -> Field {
    Field { name, prim, count: 1, array: false }
}

const fn array(name: &'static str, prim: Prim, count: usize) -> Field {
    Field { name, prim, count, array: true }
}

/// [`crate::msg::Header`], at the start of both payloads.
pub const HEADER: &[Field] = &[
    scalar("version", Prim::U32),
    scalar("sender", Prim::U32),
    scalar("run_id", Prim::U64),
    scalar("step", Prim::U64),
    scalar("t_s", Prim::F64),
    scalar("sent_wall_ns", Prim::U64),
    array("mac", Prim::U64, 2),
];

/// [`Measurement`] after its header (rosters are arrays of 64-bit words).
pub const MEASUREMENT: &[Field] = &[
    scalar("len", Prim::U32),
    scalar("pad", Prim::U32),
    array("readings", Prim::F64, MAX_READINGS),
    array("live", Prim::U64, MAX_AGENTS / 64),
    array("lost_at_close", Prim::U64, MAX_AGENTS / 64),
    scalar("links_len", Prim::U32),
    scalar("pad2", Prim::U32),
    array("links", Prim::U32, MAX_LINKS_IN),
];

/// [`Share`] after its header.
pub const SHARE: &[Field] = &[
    scalar("command_len", Prim::U32),
    scalar("values_len", Prim::U32),
    scalar("link", Prim::U32),
    scalar("pad", Prim::U32),
    array("command", Prim::F64, MAX_COMMAND),
    array("values", Prim::F64, MAX_SHARE_VALUES),
];

/// Which payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Payload {
    Measurement,
    Share,
}

impl Payload {
    /// Its fields after the header.
    pub fn fields(self) -> &'static [Field] {
        match self {
            Payload::Measurement => MEASUREMENT,
            Payload::Share => SHARE,
        }
    }
    /// Its size in bytes.
    pub fn size(self) -> usize {
        match self {
            Payload::Measurement => std::mem::size_of::<Measurement>(),
            Payload::Share => std::mem::size_of::<Share>(),
        }
    }
    /// The ROS 1 type name of a recording's schema.
    pub fn ros1_name(self) -> &'static str {
        match self {
            Payload::Measurement => "cohort/Measurement",
            Payload::Share => "cohort/Share",
        }
    }
}

/// Every field of `p` with its byte offset, the header's prefixed `header.`.
pub fn fields_with_offsets(p: Payload) -> Vec<(String, Field, usize)> {
    let mut out = Vec::new();
    let mut at = 0;
    for f in HEADER {
        out.push((format!("header.{}", f.name), *f, at));
        at += f.prim.size() * f.count;
    }
    for f in p.fields() {
        out.push((f.name.to_string(), *f, at));
        at += f.prim.size() * f.count;
    }
    out
}

/// Where byte `offset` of a `p` payload lies: the element's name (`values[3]`, `header.step`), the
/// element's type and the offset of its first byte.
pub fn locate(p: Payload, offset: usize) -> Option<(String, Prim, usize)> {
    fields_with_offsets(p).into_iter().find_map(|(name, f, at)| {
        let size = f.prim.size();
        (offset >= at && offset < at + size * f.count).then(|| {
            let i = (offset - at) / size;
            let name = if f.array { format!("{name}[{i}]") } else { name };
            (name, f.prim, at + i * size)
        })
    })
}

/// The byte range of the header's `mac` (a keyed tag of a per-run key that is never stored).
pub fn mac_range() -> std::ops::Range<usize> {
    let start = std::mem::offset_of!(crate::msg::Header, mac);
    start..start + 16
}

fn ros1_lines(fields: &[Field]) -> String {
    fields
        .iter()
        .map(|f| {
            if f.array {
                format!("{}[{}] {}\n", f.prim.ros1(), f.count, f.name)
            } else {
                format!("{} {}\n", f.prim.ros1(), f.name)
            }
        })
        .collect()
}

/// The ROS 1 message definition (`ros1msg`) of `p`'s wire bytes, with its header type after the
/// usual separator. The header type is `cohort/WireHeader`, not `Header`: ROS 1 reads a bare
/// `Header` as `std_msgs/Header`.
pub fn ros1_definition(p: Payload) -> String {
    format!(
        "# Cohort wire payload, schema version {SCHEMA_VERSION}: the #[repr(C)] struct's bytes as they are \
         (little-endian, no padding between fields)\ncohort/WireHeader header\n{}{}\nMSG: cohort/WireHeader\n{}",
        ros1_lines(p.fields()),
        "=".repeat(80),
        ros1_lines(HEADER)
    )
}

/// A payload's bytes as they are in memory (and on the wire).
pub fn measurement_bytes(m: &Measurement) -> &[u8] {
    crate::transport::bytes_of(m)
}

/// A payload's bytes as they are in memory (and on the wire).
pub fn share_bytes(s: &Share) -> &[u8] {
    crate::transport::bytes_of(s)
}

/// A measurement from its bytes; None when the length is not the payload's.
pub fn measurement_from_bytes(b: &[u8]) -> Option<Measurement> {
    (b.len() == Payload::Measurement.size()).then(|| crate::transport::read_payload(b))
}

/// A share from its bytes; None when the length is not the payload's.
pub fn share_from_bytes(b: &[u8]) -> Option<Share> {
    (b.len() == Payload::Share.size()).then(|| crate::transport::read_payload(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Header, Roster};
    use std::mem::offset_of;

    #[test]
    fn the_tables_describe_the_structs_byte_for_byte() {
        let at = |p, name: &str| fields_with_offsets(p).into_iter().find(|(n, _, _)| n == name).unwrap().2;
        let end = |p: Payload| {
            let (_, f, a) = fields_with_offsets(p).pop().unwrap();
            a + f.prim.size() * f.count
        };
        assert_eq!(end(Payload::Share), std::mem::size_of::<Share>());
        assert_eq!(end(Payload::Measurement), std::mem::size_of::<Measurement>());
        assert_eq!(at(Payload::Share, "header.step"), offset_of!(Header, step));
        assert_eq!(at(Payload::Share, "header.mac"), offset_of!(Header, mac));
        assert_eq!(at(Payload::Share, "link"), offset_of!(Share, link));
        assert_eq!(at(Payload::Share, "command"), offset_of!(Share, command));
        assert_eq!(at(Payload::Share, "values"), offset_of!(Share, values));
        assert_eq!(at(Payload::Measurement, "readings"), offset_of!(Measurement, readings));
        assert_eq!(at(Payload::Measurement, "live"), offset_of!(Measurement, live));
        assert_eq!(at(Payload::Measurement, "lost_at_close"), offset_of!(Measurement, lost_at_close));
        assert_eq!(mac_range().start, at(Payload::Share, "header.mac"));
    }

    #[test]
    fn a_byte_is_named_by_its_element_and_the_bytes_round_trip() {
        let mut s = Share::new(Header::new(7, 3, 12, 0.12), &[1.0, 2.0, 3.0], &[4.0, 5.0]);
        s.values[1] = -0.5;
        let b = share_bytes(&s).to_vec();
        let off = offset_of!(Share, values) + 8 + 3;
        let (name, prim, start) = locate(Payload::Share, off).unwrap();
        assert_eq!((name.as_str(), prim, start), ("values[1]", Prim::F64, offset_of!(Share, values) + 8));
        assert!(prim.show(&b[start..start + 8]).starts_with("-0.5 (bits 0xbfe0000000000000)"));
        assert_eq!(locate(Payload::Share, offset_of!(Header, step)).unwrap().0, "header.step");
        assert_eq!(locate(Payload::Share, std::mem::size_of::<Share>()), None);
        let back = share_from_bytes(&b).unwrap();
        assert_eq!(share_bytes(&back), &b[..]);
        assert!(share_from_bytes(&b[1..]).is_none());
        let mut m = Measurement::new(Header::new(7, 0, 12, 0.12), &[9.0]);
        m.live = Roster::all(6);
        let mb = measurement_bytes(&m).to_vec();
        assert_eq!(measurement_bytes(&measurement_from_bytes(&mb).unwrap()), &mb[..]);
    }

    #[test]
    fn the_ros1_definition_lists_every_field_with_its_fixed_size() {
        let d = ros1_definition(Payload::Share);
        assert!(d.contains("cohort/WireHeader header\n"), "{d}");
        assert!(d.contains(&format!("float64[{MAX_SHARE_VALUES}] values\n")), "{d}");
        assert!(d.contains("\nMSG: cohort/WireHeader\nuint32 version\n"), "{d}");
        assert!(d.contains("uint64[2] mac\n"), "{d}");
        let m = ros1_definition(Payload::Measurement);
        assert!(m.contains(&format!("uint64[{}] live\n", MAX_AGENTS / 64)), "{m}");
        // Every declared field is a line; nothing is left out.
        let fields = d.lines().filter(|l| l.starts_with("uint") || l.starts_with("float")).count();
        assert_eq!(fields, HEADER.len() + SHARE.len());
    }
}
