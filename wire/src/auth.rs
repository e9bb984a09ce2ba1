//! Message authentication (`run.authenticate = true`): a keyed MAC over every message, with a
//! per-run random key. Shared memory and loopback sockets of a run are owner-only, so the MAC is
//! what stands between the run and a process of the same user that writes into them (a buggy or
//! hostile program, or bytes damaged in place): such a message fails [`MacKey::check_share`] and
//! friends, is counted as rejected (`mac`) and never used.
//!
//! The tag is the first 128 bits of keyed BLAKE3 over every field a receiver reads, in a fixed
//! little-endian encoding: the header but for `sent_wall_ns` (the transport stamps it when it
//! sends, after the sender sealed the message; a forged stamp can only distort the latency
//! histograms, which are diagnostic), the lengths, and the values up to those lengths (what lies
//! past a length is never read). Lengths beyond their bound are clamped here; validation rejects
//! them anyway.
//!
//! The key never appears in argv or the environment: the orchestrator writes it into a pipe and
//! the child inherits the pipe's read end as a file descriptor ([`MacKey::read_from_fd`]).

use std::io::Read;
use std::os::fd::FromRawFd;

use crate::msg::{Header, MAX_COMMAND, MAX_READINGS, MAX_SHARE_VALUES, Measurement, Roster, RunControl, Share, Status};

/// Bytes of a run's key.
pub const KEY_LEN: usize = 32;

/// A run's MAC key.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct MacKey([u8; KEY_LEN]);

impl std::fmt::Debug for MacKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("MacKey(..)") // never print a key
    }
}

/// A message's tag: 128 bits.
pub type Tag = [u64; 2];

impl MacKey {
    pub fn from_bytes(b: [u8; KEY_LEN]) -> Self {
        Self(b)
    }

    /// A fresh random key from the kernel's generator.
    pub fn generate() -> std::io::Result<Self> {
        let mut b = [0u8; KEY_LEN];
        std::fs::File::open("/dev/urandom")?.read_exact(&mut b)?;
        Ok(Self(b))
    }

    /// Read the key from an inherited descriptor (the read end of the orchestrator's pipe) and
    /// close it.
    pub fn read_from_fd(fd: i32) -> std::io::Result<Self> {
        // SAFETY: `fd` is a descriptor this process inherited for this purpose and nothing else
        // owns; the File closes it once read. fcntl first, so a bad number is an error, not UB.
        if unsafe { libc::fcntl(fd, libc::F_GETFD) } < 0 {
            return Err(std::io::Error::last_os_error());
        }
        let mut f = unsafe { std::fs::File::from_raw_fd(fd) };
        let mut b = [0u8; KEY_LEN];
        f.read_exact(&mut b)?;
        Ok(Self(b))
    }

    /// The bytes to hand a child (the orchestrator writes them into the child's key pipe).
    pub fn bytes(&self) -> &[u8; KEY_LEN] {
        &self.0
    }

    fn tag(&self, feed: impl FnOnce(&mut Feed)) -> Tag {
        let mut f = Feed(blake3::Hasher::new_keyed(&self.0));
        feed(&mut f);
        let out = f.0.finalize();
        let b = out.as_bytes();
        [u64::from_le_bytes(b[..8].try_into().expect("8 bytes")), u64::from_le_bytes(b[8..16].try_into().expect("8"))]
    }

    pub fn seal_measurement(&self, m: &mut Measurement) {
        m.header.mac = self.measurement_tag(m);
    }
    pub fn check_measurement(&self, m: &Measurement) -> bool {
        tags_equal(&m.header.mac, &self.measurement_tag(m))
    }
    fn measurement_tag(&self, m: &Measurement) -> Tag {
        self.tag(|f| {
            f.header(b'M', &m.header);
            f.u32(m.len);
            f.f64s(&m.readings[..(m.len as usize).min(MAX_READINGS)]);
            f.roster(&m.live);
            f.roster(&m.lost_at_close);
            f.u32(m.links_len);
            for code in m.links() {
                f.u32(*code);
            }
        })
    }

    pub fn seal_share(&self, s: &mut Share) {
        s.header.mac = self.share_tag(s);
    }
    pub fn check_share(&self, s: &Share) -> bool {
        tags_equal(&s.header.mac, &self.share_tag(s))
    }
    fn share_tag(&self, s: &Share) -> Tag {
        self.tag(|f| {
            f.header(b'S', &s.header);
            f.u32(s.command_len);
            f.u32(s.values_len);
            f.u32(s.link);
            f.f64s(&s.command[..(s.command_len as usize).min(MAX_COMMAND)]);
            f.f64s(&s.values[..(s.values_len as usize).min(MAX_SHARE_VALUES)]);
        })
    }

    pub fn seal_control(&self, c: &mut RunControl) {
        c.mac = self.control_tag(c);
    }
    pub fn check_control(&self, c: &RunControl) -> bool {
        tags_equal(&c.mac, &self.control_tag(c))
    }
    fn control_tag(&self, c: &RunControl) -> Tag {
        self.tag(|f| {
            f.0.update(b"C");
            f.u32(c.version);
            f.u32(c.command);
            f.u64(c.run_id);
            f.u64(c.step);
            f.roster(&c.dead);
            f.roster(&c.alive);
        })
    }

    pub fn seal_status(&self, s: &mut Status) {
        s.mac = self.status_tag(s);
    }
    pub fn check_status(&self, s: &Status) -> bool {
        tags_equal(&s.mac, &self.status_tag(s))
    }
    fn status_tag(&self, s: &Status) -> Tag {
        self.tag(|f| {
            f.0.update(b"T");
            f.u32(s.version);
            f.u32(s.sender);
            f.u64(s.run_id);
            f.u32(s.kind);
            f.u32(s.waiting_for);
            f.u64(s.step);
            f.f64s(&[s.t_s]);
            f.u64(s.build_hash);
            f.u32(s.detail);
        })
    }
}

/// Constant-time comparison (no early exit that would time how much of a forged tag is right).
fn tags_equal(a: &Tag, b: &Tag) -> bool {
    ((a[0] ^ b[0]) | (a[1] ^ b[1])) == 0
}

struct Feed(blake3::Hasher);

impl Feed {
    fn u32(&mut self, x: u32) {
        self.0.update(&x.to_le_bytes());
    }
    fn u64(&mut self, x: u64) {
        self.0.update(&x.to_le_bytes());
    }
    fn f64s(&mut self, xs: &[f64]) {
        for x in xs {
            self.0.update(&x.to_bits().to_le_bytes());
        }
    }
    fn roster(&mut self, r: &Roster) {
        for w in r.0 {
            self.u64(w);
        }
    }
    /// The header but for `sent_wall_ns` and the tag itself; `kind` keeps a measurement's tag
    /// from ever passing as a share's.
    fn header(&mut self, kind: u8, h: &Header) {
        self.0.update(&[kind]);
        self.u32(h.version);
        self.u32(h.sender);
        self.u64(h.run_id);
        self.u64(h.step);
        self.f64s(&[h.t_s]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(b: u8) -> MacKey {
        MacKey::from_bytes([b; KEY_LEN])
    }

    #[test]
    fn a_sealed_message_checks_and_any_altered_field_does_not() {
        let k = key(7);
        let mut s = Share::new(Header::new(9, 2, 40, 0.4), &[1.0, 2.0], &[3.0, 4.0, 5.0]);
        k.seal_share(&mut s);
        assert!(k.check_share(&s));
        let mut stamped = s;
        stamped.header.sent_wall_ns = 12345; // the transport's stamp is not covered
        assert!(k.check_share(&stamped));
        let alter: [&dyn Fn(&mut Share); 7] = [
            &|s| s.values[1] = 866.0,
            &|s| s.command[0] = -1.0,
            &|s| s.header.step += 1,
            &|s| s.header.sender = 3,
            &|s| s.header.run_id ^= 1,
            &|s| s.values_len = 2,
            &|s| s.link = 1,
        ];
        for (i, f) in alter.iter().enumerate() {
            let mut t = s;
            f(&mut t);
            assert!(!k.check_share(&t), "alteration {i} passed");
        }
        assert!(!key(8).check_share(&s), "another run's key");
        let mut m = Measurement::new(Header::new(9, 0, 40, 0.4), &[1.5, -2.5]);
        k.seal_measurement(&mut m);
        assert!(k.check_measurement(&m));
        m.readings[1] = 0.0;
        assert!(!k.check_measurement(&m));
        m.readings[1] = -2.5;
        m.live.set(5, true);
        assert!(!k.check_measurement(&m));
    }

    #[test]
    fn control_and_status_are_sealed_too() {
        let k = key(1);
        let mut c = RunControl::new(crate::msg::CONTROL_STOP, 5);
        k.seal_control(&mut c);
        assert!(k.check_control(&c));
        c.command = crate::msg::CONTROL_START;
        assert!(!k.check_control(&c));
        let mut st = Status {
            version: crate::msg::SCHEMA_VERSION,
            sender: 1,
            run_id: 5,
            kind: crate::msg::STATUS_READY,
            waiting_for: 0,
            step: 0,
            t_s: 0.0,
            build_hash: 3,
            detail: 0,
            _pad: 0,
            mac: [0; 2],
        };
        k.seal_status(&mut st);
        assert!(k.check_status(&st));
        st.waiting_for = 200;
        assert!(!k.check_status(&st));
    }

    #[test]
    fn the_key_travels_through_a_descriptor() {
        let mut fds = [0i32; 2];
        // SAFETY: pipe(2) into an array we own.
        assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
        let k = key(42);
        // SAFETY: the write end is ours; the File closes it.
        let mut w = unsafe { std::fs::File::from_raw_fd(fds[1]) };
        std::io::Write::write_all(&mut w, k.bytes()).unwrap();
        drop(w);
        assert_eq!(MacKey::read_from_fd(fds[0]).unwrap(), k);
        assert!(MacKey::read_from_fd(-1).is_err());
    }
}
