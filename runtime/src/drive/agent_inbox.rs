//! An agent's inbox: the plant's measurements and its neighbours' shares, validated, with the
//! roster history each measurement carries; and how the algorithm steps from what arrived.

use std::sync::Arc;

use cohort_scenario::faults::{Fate, FaultPlan};
use cohort_wire::auth::MacKey;
use cohort_wire::msg::{LINK_DATA, LINK_LOST, Measurement, PLANT_ID};
use cohort_wire::transport::{Incoming, Proc, monotonic_ns};
use cohort_wire::validate::{Expect, RejectCounts, Rejection, validate_measurement, validate_share};

use super::params::DriveParams;
use super::wait::{Inbox, rejected_note};
use crate::model::{Algorithm, Neighbour};
use crate::record::{LatencyHist, ProcessReport};

/// Whether a roster history (first step, live) says live at step `u` (live before any entry).
pub(super) fn live_at(hist: &[(u64, bool)], u: u64) -> bool {
    hist.iter().rev().find(|(s, _)| *s <= u).is_none_or(|e| e.1)
}

/// What a neighbour's link did with its share of step `s`, as of step `u`.
enum LinkVerdict {
    /// Ideal links (no code for the step): as sent.
    Ideal,
    /// Delivered by step `u`.
    Delivered,
    /// Delivered later than `u`.
    InFlight,
    /// Never delivered (out of range, blocked, lost, or not sent while the link was busy).
    Undelivered,
}

fn link_verdict(link: &[(u64, u32)], s: u64, u: u64) -> LinkVerdict {
    match link.iter().find(|(step, _)| *step == s) {
        None => LinkVerdict::Ideal,
        Some((_, code)) => match crate::links::delay_of(*code) {
            Some(d) if s + d <= u => LinkVerdict::Delivered,
            Some(_) => LinkVerdict::InFlight,
            None => LinkVerdict::Undelivered,
        },
    }
}

/// Fold measurement `m`'s roster into the history of agent `id`.
fn note_roster(hist: &mut Vec<(u64, bool)>, m: &Measurement, id: u32) {
    let step = m.header.step;
    let mut live = hist.last().is_none_or(|e| e.1);
    if live && m.lost_at_close.contains(id) {
        hist.push((step.saturating_sub(1), false));
        live = false;
    }
    let now = m.live.contains(id);
    if now != live {
        hist.push((step, now));
    }
}

/// An agent's view of one neighbour.
pub(super) struct Peer {
    pub(super) id: u32,
    /// Valid shares not yet used: (step, values).
    pub(super) arrived: Vec<(u64, Vec<f64>)>,
    /// Value buffers to reuse for the next shares (a share arrives every step).
    pub(super) spare: Vec<Vec<f64>>,
    /// The last share used (step, values): it stands in for one that does not arrive.
    pub(super) held: Option<(u64, Vec<f64>)>,
    /// Roster history: (first step, live).
    pub(super) hist: Vec<(u64, bool)>,
    /// Steps whose token (an on-time share, or a `LINK_LOST` token) has arrived.
    pub(super) tokens: Vec<u64>,
    /// Geometric links: (step, link code) of its shares, from this agent's measurements (see
    /// `cohort_wire::msg::Measurement::links`); empty on ideal links.
    pub(super) link: Vec<(u64, u32)>,
    /// Messages received from it (valid or not), and the latency of the valid ones.
    pub(super) received: u64,
    pub(super) latency: LatencyHist,
    /// The newest step of a token from it, and tokens lost to a full queue (a gap in steps).
    pub(super) last_token: Option<u64>,
    pub(super) overrun: u64,
    /// Why its latest share was rejected, if it was.
    pub(super) rejected: Option<Rejection>,
}

/// An agent's inbox: the plant's measurement, then the neighbours' shares.
pub(super) struct AgentInbox {
    pub(super) run_id: u64,
    pub(super) me: u32,
    pub(super) k: u64,
    /// Waiting for the measurement of step k (true), or past it (false).
    pub(super) want_measurement: bool,
    /// The step whose neighbours' shares complete this wait, if any.
    pub(super) need_shares: Option<u64>,
    /// Oldest share step accepted, behind k.
    pub(super) back: u64,
    pub(super) realtime: bool,
    /// The newest measurement of step ≥ k.
    pub(super) meas: Option<Box<Measurement>>,
    pub(super) meas_latency_ns: u64,
    pub(super) from_plant: u64,
    pub(super) latency_plant: LatencyHist,
    /// Measurements lost to a full queue (a gap in their steps).
    pub(super) overrun_plant: u64,
    pub(super) last_meas_step: Option<u64>,
    pub(super) me_hist: Vec<(u64, bool)>,
    pub(super) peers: Vec<Peer>,
    pub(super) plan: Arc<FaultPlan>,
    pub(super) fresh: bool,
    pub(super) received: u64,
    pub(super) rejects: RejectCounts,
    /// Why the plant's latest measurement was rejected, if it was.
    pub(super) rejected_plant: Option<Rejection>,
    /// The run's last step: no message names a later one (a step read from a message is never
    /// trusted as a loop bound beyond it).
    pub(super) last_step: u64,
    pub(super) key: Option<MacKey>,
}

impl AgentInbox {
    /// The inbox of agent `me` with these neighbours; `back`: the oldest share step accepted,
    /// behind k.
    pub(super) fn new(p: &DriveParams, me: u32, neighbours: &[u32], back: u64) -> Self {
        AgentInbox {
            run_id: p.run_id,
            me,
            k: 0,
            want_measurement: true,
            need_shares: None,
            back,
            realtime: p.realtime_rate.is_some(),
            meas: None,
            meas_latency_ns: 0,
            from_plant: 0,
            latency_plant: LatencyHist::default(),
            overrun_plant: 0,
            last_meas_step: None,
            me_hist: Vec::new(),
            peers: neighbours
                .iter()
                .map(|&j| Peer {
                    id: j,
                    arrived: Vec::new(),
                    spare: Vec::new(),
                    held: None,
                    hist: Vec::new(),
                    tokens: Vec::new(),
                    link: Vec::new(),
                    received: 0,
                    latency: LatencyHist::default(),
                    last_token: None,
                    overrun: 0,
                    rejected: None,
                })
                .collect(),
            plan: Arc::clone(&p.faults),
            fresh: false,
            received: 0,
            rejects: RejectCounts::default(),
            rejected_plant: None,
            last_step: p.n_steps.saturating_sub(1),
            key: p.key,
        }
    }

    /// Step `algo` from `u`'s shares: for each neighbour live at u, the newest share that has
    /// arrived by u, else its last valid one (held, its age recorded); a dead one is left out.
    pub(super) fn advance(&mut self, algo: &mut dyn Algorithm, u: Option<u64>, dt_s: f64, report: &mut ProcessReport) {
        let Some(u) = u else {
            algo.step(dt_s, &[]); // link delay, step 0: nothing heard yet
            return;
        };
        let plan = &*self.plan;
        let back = self.back;
        for peer in &mut self.peers {
            let live = live_at(&peer.hist, u);
            let Peer { id, arrived, spare, held, tokens, link, .. } = peer;
            let mut newest: Option<(u64, Vec<f64>)> = None;
            tokens.retain(|s| *s > u);
            arrived.retain_mut(|(s, v)| {
                let sent = plan.arrival(*id, *s).is_some_and(|a| a <= u) || *s <= u.saturating_sub(back);
                let (due, undelivered) = match link_verdict(link, *s, u) {
                    LinkVerdict::Ideal | LinkVerdict::Delivered => (sent, false),
                    LinkVerdict::InFlight => (false, false),
                    LinkVerdict::Undelivered => (true, true),
                };
                if undelivered {
                    report.faults.link_undelivered += 1;
                    spare.push(std::mem::take(v));
                } else if due {
                    let taken = (*s, std::mem::take(v));
                    let replaced = if live && newest.as_ref().is_none_or(|(n, _)| *n < *s) {
                        newest.replace(taken)
                    } else {
                        Some(taken)
                    };
                    spare.extend(replaced.map(|(_, v)| v));
                }
                !due
            });
            link.retain(|&(s, code)| s > u || crate::links::delay_of(code).is_some_and(|d| s + d > u));
            if !live {
                spare.extend(newest.map(|(_, v)| v));
                continue;
            }
            match newest {
                Some(n) if held.as_ref().is_none_or(|(h, _)| *h < n.0) => spare.extend(held.replace(n).map(|(_, v)| v)),
                other => {
                    spare.extend(other.map(|(_, v)| v));
                    *report.faults.held.entry(Proc::Agent(*id).name()).or_default() += 1;
                }
            }
            if let Some((s, _)) = &peer.held {
                report.faults.max_age_steps = report.faults.max_age_steps.max(u.saturating_sub(*s));
            }
        }
        let nb: Vec<Neighbour<'_>> = self
            .peers
            .iter()
            .filter(|peer| live_at(&peer.hist, u))
            .filter_map(|peer| peer.held.as_ref().map(|(s, v)| Neighbour { id: peer.id, values: v, age_steps: u - *s }))
            .collect();
        algo.step(dt_s, &nb);
    }

    fn i_am_live(&self) -> bool {
        self.last_meas_step.is_none_or(|s| live_at(&self.me_hist, s))
    }
}

impl Inbox for AgentInbox {
    fn take(&mut self, inc: Incoming<'_>) {
        self.received += 1;
        match inc {
            Incoming::Measurement(m) => {
                // Once every share of step k is in, the plant may already send step k+1's
                // measurement while this agent still waits for a neighbour: keep it.
                let want = if self.want_measurement { self.k } else { self.k + 1 };
                let e = Expect {
                    run_id: self.run_id,
                    sender: PLANT_ID,
                    step_min: want,
                    step_max: self.last_step,
                    key: self.key,
                };
                self.from_plant += 1;
                match validate_measurement(m, &e) {
                    Ok(()) => {
                        self.rejected_plant = None;
                        self.latency_plant.record(monotonic_ns().saturating_sub(m.header.sent_wall_ns));
                        let step = m.header.step;
                        if self.last_meas_step.is_some_and(|s| s >= step) {
                            return; // a duplicate or an older one: the first, newest, counts
                        }
                        if let Some(last) = self.last_meas_step {
                            self.overrun_plant += step - last - 1;
                        }
                        self.last_meas_step = Some(step);
                        self.fresh = true;
                        note_roster(&mut self.me_hist, m, self.me);
                        let links = m.links();
                        let geometric = links.len() == self.peers.len() && !links.is_empty();
                        for (n, peer) in self.peers.iter_mut().enumerate() {
                            note_roster(&mut peer.hist, m, peer.id);
                            if geometric {
                                peer.link.push((step, links[n]));
                            }
                        }
                        self.meas_latency_ns = monotonic_ns().saturating_sub(m.header.sent_wall_ns);
                        self.meas = Some(Box::new(*m));
                    }
                    Err(r) => {
                        self.rejects.add(r);
                        self.rejected_plant = Some(r);
                    }
                }
            }
            Incoming::Share { from, share } => {
                let Some(peer) = self.peers.iter_mut().find(|p| p.id == from) else {
                    self.rejects.add(Rejection::Sender);
                    return;
                };
                peer.received += 1;
                // A delayed share may be `back` steps old. Ahead, any step of the run: this agent
                // cannot know how far the others are. In lockstep a neighbour is at most one step
                // ahead of the newest measurement, but an agent that was frozen or relaunched
                // learns where the run is only from what it drains, and a drain the freeze cut
                // between the plant's queue and a neighbour's meets that neighbour's shares of
                // the return step before the measurement that names it. Rejected there, their
                // tokens were lost and the returning agent waited for them until the plant
                // declared it dead one step after its return (seen in CI under load).
                let e = Expect {
                    run_id: self.run_id,
                    sender: from,
                    step_min: self.k.saturating_sub(self.back),
                    step_max: self.last_step,
                    key: self.key,
                };
                match validate_share(share, &e) {
                    Ok(()) => {
                        peer.rejected = None;
                        peer.latency.record(monotonic_ns().saturating_sub(share.header.sent_wall_ns));
                        let step = share.header.step;
                        if share.link == LINK_LOST || self.plan.fate(from, step) == Fate::Deliver {
                            peer.tokens.push(step);
                            if let Some(last) = peer.last_token
                                && step > last + 1
                                && live_at(&peer.hist, step)
                            {
                                peer.overrun += step - last - 1;
                            }
                            peer.last_token = Some(peer.last_token.map_or(step, |l| l.max(step)));
                        }
                        if share.link == LINK_DATA && !peer.arrived.iter().any(|(s, _)| *s == step) {
                            let mut values = peer.spare.pop().unwrap_or_default();
                            values.clear();
                            values.extend_from_slice(share.values());
                            peer.arrived.push((step, values));
                        }
                    }
                    Err(r) => {
                        self.rejects.add(r);
                        peer.rejected = Some(r);
                    }
                }
            }
        }
    }
    fn complete(&self) -> bool {
        if self.want_measurement {
            // Off the roster (frozen, or relaunched before its return step): wait on.
            let Some(m) = &self.meas else { return false };
            if !live_at(&self.me_hist, m.header.step) {
                return false;
            }
        }
        let Some(u) = self.need_shares else { return true };
        // Declared dead while waiting (a late return from a freeze), or the step closed
        // without the share (real time): go on with what arrived.
        if !self.i_am_live() || (self.realtime && self.last_meas_step.is_some_and(|s| s > u)) {
            return true;
        }
        self.peers.iter().all(|p| !live_at(&p.hist, u) || p.tokens.contains(&u))
    }
    fn missing(&self) -> (u32, String) {
        if self.want_measurement && self.meas.is_none() {
            return (PLANT_ID, format!("the plant{}", rejected_note(self.rejected_plant)));
        }
        if self.want_measurement && !self.i_am_live() {
            return (PLANT_ID, "the plant (to be back on the roster)".into());
        }
        let u = self.need_shares.unwrap_or(self.k);
        let j = self.peers.iter().find(|p| live_at(&p.hist, u) && !p.tokens.contains(&u)).map_or(0, |p| p.id);
        (j, format!("neighbour agent {j}{}", rejected_note(self.rejected_from(j))))
    }
    fn rejected_from(&self, id: u32) -> Option<Rejection> {
        if id == PLANT_ID {
            return self.rejected_plant;
        }
        self.peers.iter().find(|p| p.id == id).and_then(|p| p.rejected)
    }
    fn fresh(&mut self) -> bool {
        std::mem::take(&mut self.fresh)
    }
}
