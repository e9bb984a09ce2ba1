//! Every receiver validates what it reads before trusting a number of it. A bad message is dropped
//! and counted by [`Rejection`], never trusted and never a crash. With a run key
//! ([`crate::auth`]) the tag is checked right after the version and run id, so nothing else of a
//! forged or damaged message is believed (the reason counted is `mac`).
//!
//! Nothing read from a message is used as an index or a loop bound before it is checked here:
//! lengths against the wire bounds, steps against the window the receiver gives in [`Expect`]
//! (which never reaches past the run's last step).

use crate::auth::MacKey;
use crate::msg::{
    Header, MAX_COMMAND, MAX_LINKS_IN, MAX_READINGS, MAX_SHARE_VALUES, Measurement, SCHEMA_VERSION, Share,
};

/// Why a message was dropped. The discriminant indexes [`RejectCounts`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Rejection {
    Version,
    RunId,
    Sender,
    Step,
    Length,
    NonFinite,
    /// The keyed MAC does not match: forged, or damaged in place.
    Mac,
}

impl Rejection {
    pub const ALL: [Rejection; 7] = [
        Rejection::Version,
        Rejection::RunId,
        Rejection::Sender,
        Rejection::Step,
        Rejection::Length,
        Rejection::NonFinite,
        Rejection::Mac,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Rejection::Version => "version",
            Rejection::RunId => "run_id",
            Rejection::Sender => "sender",
            Rejection::Step => "step",
            Rejection::Length => "length",
            Rejection::NonFinite => "non_finite",
            Rejection::Mac => "mac",
        }
    }
}

/// Rejected-message counters, one per reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RejectCounts(pub [u64; 7]);

impl RejectCounts {
    pub fn add(&mut self, r: Rejection) {
        self.0[r as usize] += 1;
    }
    pub fn total(&self) -> u64 {
        self.0.iter().sum()
    }
    pub fn get(&self, r: Rejection) -> u64 {
        self.0[r as usize]
    }
}

/// What the receiver expects of a message it reads.
#[derive(Debug, Clone, Copy)]
pub struct Expect {
    pub run_id: u64,
    pub sender: u32,
    /// Accepted steps, inclusive. The plant accepts the open step (less the longest link delay);
    /// an agent accepts measurements from its current step and neighbours' shares from its
    /// step less the delays, both up to the run's last step (a returning agent cannot know how
    /// far the others are).
    pub step_min: u64,
    pub step_max: u64,
    /// The run's key when `run.authenticate` is on.
    pub key: Option<MacKey>,
}

fn check_origin(h: &Header, e: &Expect, tag_ok: impl FnOnce(&MacKey) -> bool) -> Result<(), Rejection> {
    if h.version != SCHEMA_VERSION {
        return Err(Rejection::Version);
    }
    if h.run_id != e.run_id {
        return Err(Rejection::RunId);
    }
    if e.key.as_ref().is_some_and(|k| !tag_ok(k)) {
        return Err(Rejection::Mac);
    }
    Ok(())
}

fn check_header(h: &Header, e: &Expect) -> Result<(), Rejection> {
    if h.sender != e.sender {
        return Err(Rejection::Sender);
    }
    if h.step < e.step_min || h.step > e.step_max {
        return Err(Rejection::Step);
    }
    if !h.t_s.is_finite() {
        return Err(Rejection::NonFinite);
    }
    Ok(())
}

fn all_finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

pub fn validate_measurement(m: &Measurement, e: &Expect) -> Result<(), Rejection> {
    check_origin(&m.header, e, |k| k.check_measurement(m))?;
    check_header(&m.header, e)?;
    if m.len as usize > MAX_READINGS || m.links_len as usize > MAX_LINKS_IN {
        return Err(Rejection::Length);
    }
    if !all_finite(m.readings()) {
        return Err(Rejection::NonFinite);
    }
    Ok(())
}

pub fn validate_share(s: &Share, e: &Expect) -> Result<(), Rejection> {
    check_origin(&s.header, e, |k| k.check_share(s))?;
    check_header(&s.header, e)?;
    if s.command_len as usize > MAX_COMMAND || s.values_len as usize > MAX_SHARE_VALUES || s.link > 1 {
        return Err(Rejection::Length);
    }
    if !all_finite(s.command()) || !all_finite(s.values()) {
        return Err(Rejection::NonFinite);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const RUN: u64 = 0xC0FFEE;

    fn share(sender: u32, step: u64) -> Share {
        Share::new(Header::new(RUN, sender, step, step as f64 * 0.01), &[1.0, 2.0, 3.0], &[4.0, 5.0])
    }
    fn expect(sender: u32, k: u64) -> Expect {
        Expect { run_id: RUN, sender, step_min: k, step_max: k + 1, key: None }
    }

    #[test]
    fn accepts_a_good_share_and_measurement() {
        assert_eq!(validate_share(&share(3, 10), &expect(3, 10)), Ok(()));
        assert_eq!(validate_share(&share(3, 11), &expect(3, 10)), Ok(()));
        let m = Measurement::new(Header::new(RUN, 0, 5, 0.05), &[1.0, -2.0]);
        assert_eq!(
            validate_measurement(&m, &Expect { run_id: RUN, sender: 0, step_min: 5, step_max: 5, key: None }),
            Ok(())
        );
    }

    #[test]
    fn wrong_version_is_rejected() {
        let mut s = share(3, 10);
        s.header.version = SCHEMA_VERSION + 1;
        assert_eq!(validate_share(&s, &expect(3, 10)), Err(Rejection::Version));
    }

    #[test]
    fn wrong_run_is_rejected() {
        let mut s = share(3, 10);
        s.header.run_id = RUN + 1;
        assert_eq!(validate_share(&s, &expect(3, 10)), Err(Rejection::RunId));
    }

    #[test]
    fn wrong_sender_is_rejected() {
        assert_eq!(validate_share(&share(4, 10), &expect(3, 10)), Err(Rejection::Sender));
    }

    #[test]
    fn unexpected_step_is_rejected() {
        assert_eq!(validate_share(&share(3, 9), &expect(3, 10)), Err(Rejection::Step));
        assert_eq!(validate_share(&share(3, 12), &expect(3, 10)), Err(Rejection::Step));
        let m = Measurement::new(Header::new(RUN, 0, 6, 0.06), &[1.0]);
        assert_eq!(
            validate_measurement(&m, &Expect { run_id: RUN, sender: 0, step_min: 5, step_max: 5, key: None }),
            Err(Rejection::Step)
        );
    }

    #[test]
    fn non_finite_numbers_are_rejected_wherever_they_sit() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut s = share(3, 10);
            s.values[1] = bad;
            assert_eq!(validate_share(&s, &expect(3, 10)), Err(Rejection::NonFinite));
            let mut s = share(3, 10);
            s.command[2] = bad;
            assert_eq!(validate_share(&s, &expect(3, 10)), Err(Rejection::NonFinite));
            let mut s = share(3, 10);
            s.header.t_s = bad;
            assert_eq!(validate_share(&s, &expect(3, 10)), Err(Rejection::NonFinite));
            let mut m = Measurement::new(Header::new(RUN, 0, 5, 0.05), &[1.0, 2.0]);
            m.readings[0] = bad;
            assert_eq!(
                validate_measurement(&m, &Expect { run_id: RUN, sender: 0, step_min: 5, step_max: 5, key: None }),
                Err(Rejection::NonFinite)
            );
        }
    }

    #[test]
    fn a_non_finite_value_past_len_is_not_read() {
        let mut s = share(3, 10);
        s.values[300] = f64::NAN; // beyond values_len = 2: never read, so harmless
        assert_eq!(validate_share(&s, &expect(3, 10)), Ok(()));
    }

    #[test]
    fn out_of_bound_lengths_are_rejected_not_read() {
        let mut s = share(3, 10);
        s.values_len = (MAX_SHARE_VALUES + 1) as u32;
        assert_eq!(validate_share(&s, &expect(3, 10)), Err(Rejection::Length));
        assert!(s.values().is_empty());
        let mut m = Measurement::new(Header::new(RUN, 0, 5, 0.05), &[1.0]);
        m.len = u32::MAX;
        assert_eq!(
            validate_measurement(&m, &Expect { run_id: RUN, sender: 0, step_min: 5, step_max: 5, key: None }),
            Err(Rejection::Length)
        );
    }

    #[test]
    fn with_a_key_an_altered_value_is_rejected_as_mac_and_a_sealed_one_passes() {
        // Issue 18, finding 6: a share with a valid header and altered values was accepted.
        let key = crate::auth::MacKey::from_bytes([3; 32]);
        let e = Expect { key: Some(key), ..expect(3, 10) };
        let mut s = share(3, 10);
        key.seal_share(&mut s);
        assert_eq!(validate_share(&s, &e), Ok(()));
        s.values[1] = 866.0;
        assert_eq!(validate_share(&s, &Expect { key: None, ..e }), Ok(()), "without a key it passes");
        assert_eq!(validate_share(&s, &e), Err(Rejection::Mac));
        let mut m = Measurement::new(Header::new(RUN, 0, 5, 0.05), &[1.0]);
        let em = Expect { run_id: RUN, sender: 0, step_min: 5, step_max: 5, key: Some(key) };
        assert_eq!(validate_measurement(&m, &em), Err(Rejection::Mac), "unsealed");
        key.seal_measurement(&mut m);
        assert_eq!(validate_measurement(&m, &em), Ok(()));
    }

    #[test]
    fn counts_add_up_per_reason() {
        let mut c = RejectCounts::default();
        c.add(Rejection::Step);
        c.add(Rejection::Step);
        c.add(Rejection::NonFinite);
        assert_eq!(c.get(Rejection::Step), 2);
        assert_eq!(c.total(), 3);
    }
}
