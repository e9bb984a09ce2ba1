//! In-memory transport: every process of a run as a thread of one process, each with an inbox
//! (mutex + condvar). Used by the reference run (`orchestrator launch --reference`) and by unit
//! tests. Delivery order per sender is FIFO, as with iceoryx2, and the drivers never depend on the
//! order between senders, so both transports give the same telemetry bit for bit.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use super::{DataPath, Incoming, Proc, RunControlPort, Topology, TransportError, monotonic_ns};
use crate::msg::{Measurement, RunControl, Share, Status};

#[derive(Default)]
struct Inbox {
    measurements: VecDeque<Measurement>,
    shares: VecDeque<(u32, Box<Share>)>,
    woken: bool,
}

#[derive(Default)]
struct Slot {
    inbox: Mutex<Inbox>,
    cv: Condvar,
}

/// The shared "bus" of one in-memory run.
pub struct MemoryBus {
    topology: Topology,
    /// Index 0 is the plant, i is agent i.
    slots: Vec<Slot>,
    stop: AtomicBool,
    status: Mutex<VecDeque<Status>>,
    control: Mutex<Vec<RunControl>>,
}

impl MemoryBus {
    pub fn new(topology: Topology) -> Arc<Self> {
        let n = topology.n_agents() as usize;
        Arc::new(Self {
            topology,
            slots: (0..=n).map(|_| Slot::default()).collect(),
            stop: AtomicBool::new(false),
            status: Mutex::new(VecDeque::new()),
            control: Mutex::new(Vec::new()),
        })
    }
    pub fn endpoint(self: &Arc<Self>, me: Proc) -> MemoryTransport {
        let readers = match me {
            Proc::Plant => Vec::new(),
            Proc::Agent(i) => self.topology.readers_of(i),
        };
        MemoryTransport { bus: Arc::clone(self), me, readers }
    }
    /// Ask every endpoint to stop (the in-process equivalent of the orchestrator's stop request).
    pub fn request_stop(&self) {
        self.stop.store(true, Ordering::SeqCst);
        for s in &self.slots {
            s.cv.notify_all();
        }
    }
    /// Hand the plant a resume or dead-agent notice (what the orchestrator publishes on the
    /// control service in a multi-process run).
    pub fn send_control(&self, c: RunControl) {
        self.control.lock().unwrap_or_else(|p| p.into_inner()).push(c);
        self.slots[0].cv.notify_all();
    }
    /// Status reports sent so far, oldest first (drained).
    pub fn take_status(&self) -> Vec<Status> {
        self.status.lock().unwrap_or_else(|p| p.into_inner()).drain(..).collect()
    }
    fn slot(&self, p: Proc) -> &Slot {
        match p {
            Proc::Plant => &self.slots[0],
            Proc::Agent(i) => &self.slots[i as usize],
        }
    }
    fn deliver(&self, to: Proc, f: impl FnOnce(&mut Inbox)) {
        let slot = self.slot(to);
        let mut inbox = slot.inbox.lock().unwrap_or_else(|p| p.into_inner());
        f(&mut inbox);
        inbox.woken = true;
        slot.cv.notify_one();
    }
}

pub struct MemoryTransport {
    bus: Arc<MemoryBus>,
    me: Proc,
    readers: Vec<u32>,
}

impl DataPath for MemoryTransport {
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError> {
        let mut m = *m;
        m.header.sent_wall_ns = monotonic_ns();
        self.bus.deliver(Proc::Agent(to), |ib| ib.measurements.push_back(m));
        Ok(())
    }

    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        let Proc::Agent(me) = self.me else {
            return Err(TransportError::Other("the plant has no share to send".into()));
        };
        let mut s = *s;
        s.header.sent_wall_ns = monotonic_ns();
        self.bus.deliver(Proc::Plant, |ib| ib.shares.push_back((me, Box::new(s))));
        for &j in &self.readers {
            self.bus.deliver(Proc::Agent(j), |ib| ib.shares.push_back((me, Box::new(s))));
        }
        Ok(())
    }

    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        // Take everything out under the lock, hand it over outside it.
        let (ms, ss) = {
            let mut ib = self.bus.slot(self.me).inbox.lock().unwrap_or_else(|p| p.into_inner());
            (std::mem::take(&mut ib.measurements), std::mem::take(&mut ib.shares))
        };
        for m in &ms {
            f(Incoming::Measurement(m));
        }
        for (from, s) in &ss {
            f(Incoming::Share { from: *from, share: s });
        }
        Ok(())
    }

    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        let slot = self.bus.slot(self.me);
        let mut ib = slot.inbox.lock().unwrap_or_else(|p| p.into_inner());
        if !ib.woken && !self.bus.stop.load(Ordering::SeqCst) {
            ib = slot.cv.wait_timeout(ib, timeout).unwrap_or_else(|p| p.into_inner()).0;
        }
        ib.woken = false;
        Ok(())
    }
}

impl RunControlPort for MemoryTransport {
    fn report(&mut self, s: &Status) {
        let mut q = self.bus.status.lock().unwrap_or_else(|p| p.into_inner());
        if q.len() > 1024 {
            q.pop_front();
        }
        q.push_back(*s);
    }

    fn stop_requested(&mut self) -> bool {
        self.bus.stop.load(Ordering::SeqCst)
    }

    fn start_granted(&mut self) -> bool {
        true // every inbox exists from the bus's creation
    }

    fn control_events(&mut self, out: &mut Vec<RunControl>) {
        if self.me == Proc::Plant {
            out.append(&mut self.bus.control.lock().unwrap_or_else(|p| p.into_inner()));
        }
    }
}
