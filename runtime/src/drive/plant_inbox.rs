//! The plant's inbox (a step token and the newest data share from every live agent) and its
//! roster.

use std::sync::Arc;
use std::time::Instant;

use cohort_scenario::faults::{Fate, FaultPlan};
use cohort_wire::auth::MacKey;
use cohort_wire::msg::{CONTROL_DEAD, LINK_DATA, LINK_LOST, PLANT_ID, Roster, RunControl, STATUS_ALIVE, STATUS_DEAD};
use cohort_wire::transport::{Incoming, Transport, monotonic_ns};
use cohort_wire::validate::{Expect, RejectCounts, Rejection, validate_share};

use super::params::DriveParams;
use super::status::status;
use super::wait::{Inbox, rejected_note};
use crate::record::{LatencyHist, RosterChange};

/// The plant's inbox for step k: a step token from every live agent (its share of k, or a
/// `LINK_LOST` token when the link lost or delayed it), and the newest data share due by k (its
/// own share of k, or one delayed to arrive now).
pub(super) struct PlantInbox {
    pub(super) run_id: u64,
    pub(super) k: u64,
    /// Oldest step accepted (k minus the longest link delay, or one more in real time).
    pub(super) back: u64,
    pub(super) plan: Arc<FaultPlan>,
    /// Per agent: step k's token still awaited.
    pub(super) want: Vec<bool>,
    /// Per agent: the step of the newest data share taken, and its command (buffers reused:
    /// this is every share of every step).
    pub(super) newest_step: Vec<Option<u64>>,
    pub(super) newest_cmd: Vec<Vec<f64>>,
    /// Per agent: the size of its latest data share, bits (the link model's share size).
    pub(super) share_bits: Vec<u64>,
    /// Agents the orchestrator reported dead while the plant waited.
    pub(super) died: Roster,
    pub(super) latency_max_ns: u64,
    pub(super) received: u64,
    /// Per agent: messages received (valid or not), and the latency of the valid ones.
    pub(super) from: Vec<u64>,
    pub(super) latency: Vec<LatencyHist>,
    /// Per agent: the newest step of a token, and tokens lost to a full queue (a gap in steps).
    pub(super) last_token: Vec<Option<u64>>,
    pub(super) overrun: Vec<u64>,
    pub(super) late: u64,
    pub(super) rejects: RejectCounts,
    /// Per agent: why its latest share was rejected, if it was.
    pub(super) rejected: Vec<Option<Rejection>>,
    pub(super) key: Option<MacKey>,
}

impl PlantInbox {
    /// The inbox for `n` agents.
    pub(super) fn new(p: &DriveParams, n: usize) -> Self {
        PlantInbox {
            run_id: p.run_id,
            k: 0,
            back: u64::from(p.faults.max_delay()) + u64::from(p.realtime_rate.is_some()),
            plan: Arc::clone(&p.faults),
            want: vec![false; n],
            newest_step: vec![None; n],
            newest_cmd: vec![Vec::new(); n],
            share_bits: vec![0; n],
            died: Roster::EMPTY,
            latency_max_ns: 0,
            received: 0,
            from: vec![0; n],
            latency: (0..n).map(|_| LatencyHist::default()).collect(),
            last_token: vec![None; n],
            overrun: vec![0; n],
            late: 0,
            rejects: RejectCounts::default(),
            rejected: vec![None; n],
            key: p.key,
        }
    }
}

impl Inbox for PlantInbox {
    fn take(&mut self, inc: Incoming<'_>) {
        self.received += 1;
        let Incoming::Share { from, share } = inc else {
            self.rejects.add(Rejection::Sender); // the plant reads no measurements
            return;
        };
        // `from` names the service (or socket) it came by; anything else is no agent of ours.
        if from == 0 || from as usize > self.want.len() {
            self.rejects.add(Rejection::Sender);
            return;
        }
        let idx = (from - 1) as usize;
        let e = Expect {
            run_id: self.run_id,
            sender: from,
            step_min: self.k.saturating_sub(self.back),
            step_max: self.k,
            key: self.key,
        };
        self.from[idx] += 1;
        match validate_share(share, &e) {
            Ok(()) => {
                self.rejected[idx] = None;
                self.latency[idx].record(monotonic_ns().saturating_sub(share.header.sent_wall_ns));
                let step = share.header.step;
                let on_time = share.link == LINK_LOST || self.plan.fate(from, step) == Fate::Deliver;
                if on_time {
                    if let Some(last) = self.last_token[idx]
                        && step > last + 1
                    {
                        self.overrun[idx] += step - last - 1;
                    }
                    self.last_token[idx] = Some(self.last_token[idx].map_or(step, |l| l.max(step)));
                }
                if step == self.k && on_time {
                    self.want[idx] = false;
                } else if on_time && share.link == LINK_DATA {
                    self.late += 1; // its step closed without it (real time)
                }
                if share.link == LINK_DATA {
                    self.share_bits[idx] = share_bits(share);
                }
                if share.link == LINK_DATA && self.newest_step[idx].is_none_or(|s| s < step) {
                    self.newest_step[idx] = Some(step);
                    self.newest_cmd[idx].clear();
                    self.newest_cmd[idx].extend_from_slice(share.command());
                    let latency = monotonic_ns().saturating_sub(share.header.sent_wall_ns);
                    self.latency_max_ns = self.latency_max_ns.max(latency);
                }
            }
            Err(r) => {
                self.rejects.add(r);
                self.rejected[idx] = Some(r);
            }
        }
    }
    fn complete(&self) -> bool {
        self.want.iter().all(|w| !w)
    }
    fn missing(&self) -> (u32, String) {
        let id = self.want.iter().position(|w| *w).map_or(0, |i| i as u32 + 1);
        (id, format!("agent {id}{}", rejected_note(self.rejected_from(id))))
    }
    fn rejected_from(&self, id: u32) -> Option<Rejection> {
        self.rejected.get((id as usize).wrapping_sub(1)).copied().flatten()
    }
    fn control(&mut self, c: &RunControl) {
        if c.command == CONTROL_DEAD {
            let n = self.want.len();
            for id in c.dead.ids().filter(|&id| id as usize <= n) {
                self.died.set(id, true);
                self.want[id as usize - 1] = false;
            }
        }
    }
}

/// A share's size on a link, bits: its header, lengths and the values it carries (a link sends
/// what is used, not the fixed-size buffer).
fn share_bits(s: &cohort_wire::msg::Share) -> u64 {
    let header = std::mem::size_of::<cohort_wire::msg::Header>() + 16;
    8 * (header as u64 + 8 * (u64::from(s.command_len) + u64::from(s.values_len)))
}

/// The plant's roster: who is live, and what changed (reported to the orchestrator and kept for
/// the report).
pub(super) struct PlantRoster {
    pub(super) live: Roster,
    pub(super) lost_at_close: Roster,
    pub(super) changes: Vec<RosterChange>,
    pub(super) since: Instant,
}

impl PlantRoster {
    pub(super) fn set<T: Transport + ?Sized>(
        &mut self,
        t: &mut T,
        p: &DriveParams,
        id: u32,
        live: bool,
        step: u64,
        why: &str,
    ) {
        if self.live.contains(id) == live {
            return;
        }
        self.live.set(id, live);
        let wall_s = self.since.elapsed().as_secs_f64();
        tracing::debug!("step {step}: agent {id} {} the roster ({why})", if live { "joins" } else { "leaves" });
        self.changes.push(RosterChange { step, agent: id, live, reason: why.into(), wall_s });
        t.report(&status(p, PLANT_ID, if live { STATUS_ALIVE } else { STATUS_DEAD }, step, id));
    }
}
