//! The gateway's two data paths: out, a thread (local iceoryx2 services → one zenoh batch per
//! remote host), and in, the zenoh subscriber's callback (batches → local services, waking the
//! readers). Each owns an iceoryx2 node of its own: the out thread's ports stay on the thread that
//! made them; the in side's are thread-safe, as zenoh calls it from its own threads.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use ::zenoh::Wait;
use ::zenoh::pubsub::Publisher;
use ::zenoh::sample::Sample;
use iceoryx2::port::publisher::Publisher as IoxPublisher;
use iceoryx2::port::subscriber::Subscriber as IoxSubscriber;
use iceoryx2::prelude::*;

use super::batch::{Batch, Record, decode};
use super::hold::StepHold;
use super::source_of;
use crate::msg::{Measurement, PLANT_ID, Share};
use crate::transport::doorbell::Doorbells;
use crate::transport::iox::{Domain, IoxRun, MEAS_BUFFER, SHARE_BUFFER, SharedSvc, Svc};
use crate::transport::{Proc, Topology, TransportError};

/// A wait with no ring ends after this and the out thread looks at every subscriber (a sender
/// that died between its sample and its ring leaves one unrung).
const SWEEP_EVERY: Duration = Duration::from_millis(10);
/// The shortest wait: a hold about to run out is not worth a spin.
const MIN_NAP: Duration = Duration::from_micros(20);

/// What the out thread and the in callback counted, for the gateway's end line.
#[derive(Debug, Default)]
pub struct Counts {
    pub batches_out: AtomicU64,
    pub messages_out: AtomicU64,
    pub batches_in: AtomicU64,
    pub messages_in: AtomicU64,
    pub rejected: AtomicU64,
}

/// What both threads are given.
pub(super) struct Shared {
    pub run: IoxRun,
    pub topo: Topology,
    pub quit: Arc<AtomicBool>,
    pub counts: Arc<Counts>,
    /// The first failure of the out thread or the in callback (it then sets `quit`).
    pub failure: Arc<std::sync::Mutex<Option<String>>>,
}

impl Shared {
    fn domain(&self) -> &Domain {
        self.run.domain.as_ref().expect("a gateway's run has a domain")
    }
    fn fail(&self, e: impl std::fmt::Display) {
        let mut f = self.failure.lock().unwrap_or_else(|p| p.into_inner());
        f.get_or_insert_with(|| e.to_string());
        self.quit.store(true, Ordering::SeqCst);
    }
}

/// The hosts other than this one that this host's processes send to, ascending.
pub(super) fn destinations(d: &Domain, topo: &Topology) -> Vec<u16> {
    let mut out: Vec<u16> = Vec::new();
    let mut add = |p: Proc| {
        let h = d.placement.host(p);
        if h != d.here && !out.contains(&h) {
            out.push(h);
        }
    };
    for p in d.placement.procs().filter(|&p| d.is_local(p)) {
        match p {
            Proc::Plant => (1..=topo.n_agents()).for_each(|i| add(Proc::Agent(i))),
            Proc::Agent(j) => {
                add(Proc::Plant);
                topo.readers_of(j).into_iter().for_each(|r| add(Proc::Agent(r)));
            }
        }
    }
    out.sort_unstable();
    out
}

/// A local agent's share subscriber and the destinations (indices) that read it.
type ShareOut = (IoxSubscriber<Svc, Share, ()>, Vec<usize>);

/// The out thread's ports: what it reads and where each goes.
struct OutPorts {
    /// The domain's doorbells (the gateway's slot is rung for everything bound elsewhere).
    bells: Doorbells,
    /// (agent, destination index, subscriber) for each remote agent's measurements.
    meas: Vec<(u32, usize, IoxSubscriber<Svc, Measurement, ()>)>,
    /// Indexed by agent id: the subscriber and destination indices of a local agent read elsewhere.
    share: Vec<Option<ShareOut>>,
    batches: Vec<Batch>,
    pubs: Vec<Arc<Publisher<'static>>>,
    /// The plant runs on this host: its waiting advice goes out with every batch.
    plant_here: bool,
    /// Shares, and measurements, held until their step's last ([`StepHold`]).
    hold: StepHold,
    meas_hold: StepHold,
    _node: Node<Svc>,
}

impl OutPorts {
    fn open(sh: &Shared, pubs: Vec<(u16, Arc<Publisher<'static>>)>) -> Result<Self, TransportError> {
        let (run, d, topo) = (&sh.run, sh.domain(), &sh.topo);
        let node = run.node("gateway-out")?;
        let dest = |p: Proc| pubs.iter().position(|(h, _)| *h == d.placement.host(p));
        let bells = Doorbells::open(&run.root_dir(), topo.n_agents() as usize)?;
        let mut meas = Vec::new();
        let mut share: Vec<Option<_>> = (0..=topo.n_agents()).map(|_| None).collect();
        for p in d.placement.procs().filter(|&p| d.is_local(p)) {
            match p {
                Proc::Plant => {
                    for i in (1..=topo.n_agents()).filter(|&i| !d.is_local(Proc::Agent(i))) {
                        let sub = node
                            .service_builder(&run.service(&format!("meas/{i}"))?)
                            .publish_subscribe::<Measurement>()
                            .open()
                            .map_err(|e| TransportError::iox(format!("open meas {i}"), e))?
                            .subscriber_builder()
                            .buffer_size(MEAS_BUFFER)
                            .create()
                            .map_err(|e| TransportError::iox(format!("meas subscriber {i}"), e))?;
                        meas.push((i, dest(Proc::Agent(i)).expect("a remote agent's host is a destination"), sub));
                    }
                }
                Proc::Agent(j) => {
                    let mut to: Vec<usize> = std::iter::once(Proc::Plant)
                        .chain(topo.readers_of(j).into_iter().map(Proc::Agent))
                        .filter(|&r| !d.is_local(r))
                        .filter_map(dest)
                        .collect();
                    to.sort_unstable();
                    to.dedup();
                    if to.is_empty() {
                        continue;
                    }
                    let sub = node
                        .service_builder(&run.service(&format!("share/{j}"))?)
                        .publish_subscribe::<Share>()
                        .open()
                        .map_err(|e| TransportError::iox(format!("open share {j}"), e))?
                        .subscriber_builder()
                        .buffer_size(SHARE_BUFFER)
                        .create()
                        .map_err(|e| TransportError::iox(format!("share subscriber {j}"), e))?;
                    share[j as usize] = Some((sub, to));
                }
            }
        }
        let batches = pubs.iter().map(|_| Batch::new(run.run_id)).collect();
        let mut senders = vec![Vec::new(); pubs.len()];
        for (j, (_, to)) in share.iter().enumerate().filter_map(|(j, s)| Some((j, s.as_ref()?))) {
            to.iter().for_each(|&d| senders[d].push(j as u32));
        }
        let hold = StepHold::new(topo.n_agents() as usize, senders);
        let mut for_agents = vec![Vec::new(); pubs.len()];
        meas.iter().for_each(|&(i, d, _)| for_agents[d].push(i));
        let meas_hold = StepHold::new(topo.n_agents() as usize, for_agents);
        let pubs = pubs.into_iter().map(|(_, p)| p).collect();
        let plant_here = d.is_local(Proc::Plant);
        Ok(Self { bells, meas, share, batches, pubs, plant_here, hold, meas_hold, _node: node })
    }

    fn drain_meas(&mut self, now: Instant) -> Result<(), String> {
        for (i, to, sub) in &self.meas {
            while let Some(s) = sub.receive().map_err(|e| format!("receive meas/{i}: {e:?}"))? {
                self.batches[*to].push_measurement(*i, s.payload());
                self.meas_hold.shared(*i, s.payload().header.step, &[*to], now);
            }
        }
        Ok(())
    }

    fn drain_share(&mut self, j: usize, now: Instant) -> Result<(), String> {
        let Some(Some((sub, to))) = self.share.get(j) else { return Ok(()) };
        while let Some(s) = sub.receive().map_err(|e| format!("receive share/{j}: {e:?}"))? {
            for &d in to {
                self.batches[d].push_share(s.payload());
            }
            self.hold.shared(j as u32, s.payload().header.step, to, now);
        }
        Ok(())
    }

    /// One wait and what it brought: drain the senders that woke it (every one after a wait
    /// without wakeups), then one put per destination with anything for it that may go (shares
    /// and measurements are held for the rest of their step's, [`StepHold`]).
    fn once(&mut self, ids: &mut Vec<usize>, counts: &Counts) -> Result<(), String> {
        ids.clear();
        let slot = self.bells.gateway_slot();
        // A hold running out ends the wait; its end needs no ring.
        let now = Instant::now();
        let due = [self.hold.until_due(now), self.meas_hold.until_due(now)].into_iter().flatten().min();
        let nap = due.map_or(SWEEP_EVERY, |d| d.min(SWEEP_EVERY));
        self.bells.wait(slot, nap.max(MIN_NAP));
        self.bells.take(slot, |id| ids.push(id));
        // One clock read a wake: what it drains is held from now, and the holds are judged now.
        let now = Instant::now();
        let woke = !ids.is_empty();
        if woke {
            for &id in ids.iter() {
                if id == PLANT_ID as usize { self.drain_meas(now)? } else { self.drain_share(id, now)? }
            }
        } else {
            self.drain_meas(now)?;
            for j in 1..self.share.len() {
                self.drain_share(j, now)?;
            }
        }
        let advice = if self.plant_here { self.bells.advice() } else { 0 };
        for (d, (b, p)) in self.batches.iter_mut().zip(&self.pubs).enumerate() {
            if b.is_empty() || !(self.hold.ready(d, now) && self.meas_hold.ready(d, now)) {
                continue;
            }
            self.hold.sent(d);
            self.meas_hold.sent(d);
            counts.messages_out.fetch_add(u64::from(b.len()), Ordering::Relaxed);
            counts.batches_out.fetch_add(1, Ordering::Relaxed);
            p.put(b.take(advice)).wait().map_err(|e| format!("zenoh put {}: {e}", p.key_expr()))?;
        }
        Ok(())
    }
}

/// The out thread: open its ports, say so on `ready`, carry until `quit`.
pub(super) fn carry_out(
    sh: Shared,
    pubs: Vec<(u16, Arc<Publisher<'static>>)>,
    ready: std::sync::mpsc::Sender<Result<(), TransportError>>,
) {
    let mut ports = match OutPorts::open(&sh, pubs) {
        Ok(p) => {
            let _ = ready.send(Ok(()));
            p
        }
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    let mut ids = Vec::new();
    while !sh.quit.load(Ordering::SeqCst) {
        if let Err(e) = ports.once(&mut ids, &sh.counts) {
            sh.fail(e);
        }
    }
}

/// The in side's ports: stand-in publishers of remote senders, and the local readers' doorbells.
/// They live on a thread-safe node, so that zenoh's receiving thread delivers each batch itself
/// (a hand-off to a thread of our own cost a wake-up per batch, on every one-way hop of a step).
struct InPorts {
    /// Indexed by agent id: the measurement publisher of a local agent whose plant is remote.
    meas: Vec<Option<IoxPublisher<SharedSvc, Measurement, ()>>>,
    /// Indexed by agent id: the share publisher of a remote agent read here, and who reads it here
    /// (their doorbell slots: 0 the plant, i agent i).
    share: Vec<Option<ShareIn>>,
    bells: Doorbells,
    // Last: the ports above are dropped before their node (behind a mutex only to be `Sync`;
    // nothing uses it).
    _node: std::sync::Mutex<Node<SharedSvc>>,
}

/// A remote agent's stand-in share publisher and its readers here (doorbell slots).
type ShareIn = (IoxPublisher<SharedSvc, Share, ()>, Vec<usize>);

impl InPorts {
    fn open(sh: &Shared) -> Result<Self, TransportError> {
        let (run, d, topo) = (&sh.run, sh.domain(), &sh.topo);
        let node = run.shared_node("gateway-in")?;
        let n = topo.n_agents() as usize;
        let bells = Doorbells::open(&run.root_dir(), n)?;
        let mut meas: Vec<Option<_>> = (0..=n).map(|_| None).collect();
        let mut share: Vec<Option<_>> = (0..=n).map(|_| None).collect();
        let plant_here = d.is_local(Proc::Plant);
        for i in 1..=topo.n_agents() {
            let local = d.is_local(Proc::Agent(i));
            if local && !plant_here {
                let p = node
                    .service_builder(&run.service(&format!("meas/{i}"))?)
                    .publish_subscribe::<Measurement>()
                    .open()
                    .map_err(|e| TransportError::iox(format!("open meas {i}"), e))?
                    .publisher_builder()
                    .create()
                    .map_err(|e| TransportError::iox(format!("meas publisher {i}"), e))?;
                meas[i as usize] = Some(p);
            }
            if local {
                continue;
            }
            let mut readers: Vec<Proc> =
                topo.readers_of(i).into_iter().map(Proc::Agent).filter(|&r| d.is_local(r)).collect();
            if plant_here {
                readers.insert(0, Proc::Plant);
            }
            if readers.is_empty() {
                continue;
            }
            let p = node
                .service_builder(&run.service(&format!("share/{i}"))?)
                .publish_subscribe::<Share>()
                .open()
                .map_err(|e| TransportError::iox(format!("open share {i}"), e))?
                .publisher_builder()
                .create()
                .map_err(|e| TransportError::iox(format!("share publisher {i}"), e))?;
            let woken = readers.into_iter().map(|r| r.sender_id() as usize).collect();
            share[i as usize] = Some((p, woken));
        }
        Ok(Self { meas, share, bells, _node: std::sync::Mutex::new(node) })
    }

    /// Publish one checked message as its sender's stand-in and wake its readers here.
    fn deliver(&self, r: &Record<'_>) -> Result<(), String> {
        match *r {
            Record::Measurement { to, bytes } => {
                let Some(Some(p)) = self.meas.get(to as usize) else { return Ok(()) };
                let sample = p.loan_uninit().map_err(|e| format!("loan measurement: {e:?}"))?;
                let m = Record::measurement(bytes);
                sample.write_payload(m).send().map_err(|e| format!("send measurement: {e:?}"))?;
                self.bells.ring(to as usize, PLANT_ID as usize);
                Ok(())
            }
            Record::Share { from, bytes } => {
                let Some(Some((p, readers))) = self.share.get(from as usize) else { return Ok(()) };
                let sample = p.loan_uninit().map_err(|e| format!("loan share: {e:?}"))?;
                sample.write_payload(Record::share(bytes)).send().map_err(|e| format!("send share: {e:?}"))?;
                readers.iter().for_each(|&k| self.bells.ring(k, from as usize));
                Ok(())
            }
        }
    }
}

/// The in side: what the zenoh subscriber's callback does with each batch that arrives (on
/// zenoh's receiving thread; batches from different hosts may arrive on different threads at
/// once, and each stand-in publisher has one source host).
pub(super) struct Inbound {
    ports: InPorts,
    sh: Shared,
}

impl Inbound {
    /// Open the in side's ports.
    pub(super) fn open(sh: Shared) -> Result<Self, TransportError> {
        Ok(Self { ports: InPorts::open(&sh)?, sh })
    }

    /// Check one batch and deliver its messages; a batch that fails the check is refused whole
    /// (counted, the first ten logged), a failure to deliver ends the gateway.
    pub(super) fn on_batch(&self, sample: &Sample) {
        if self.sh.quit.load(Ordering::SeqCst) {
            return;
        }
        let (run_id, d) = (self.sh.run.run_id, self.sh.domain());
        let key = sample.key_expr().as_str();
        let payload = sample.payload().to_bytes();
        let checked = source_of(key)
            .ok_or_else(|| format!("a batch on {key}, which names no host"))
            .and_then(|from| decode(&payload, run_id, &d.placement, from, d.here).map_err(|e| format!("{key}: {e}")));
        let received = match checked {
            Ok(r) => r,
            Err(e) => {
                if self.sh.counts.rejected.fetch_add(1, Ordering::Relaxed) < 10 {
                    tracing::warn!("gateway: refused a batch: {e}");
                }
                return;
            }
        };
        self.sh.counts.batches_in.fetch_add(1, Ordering::Relaxed);
        self.sh.counts.messages_in.fetch_add(received.records.len() as u64, Ordering::Relaxed);
        // The plant's advice first: a process woken by this batch's messages reads it.
        if received.wait_advice != 0 {
            self.ports.bells.set_advice(received.wait_advice);
        }
        if let Err(e) = received.records.iter().try_for_each(|r| self.ports.deliver(r)) {
            self.sh.fail(e);
        }
    }
}
