//! Gateways (`run.zenoh_links = "gateway"`, the default of zenoh runs): inside each host the
//! run's processes talk iceoryx2 as on one machine, and one gateway process per host carries
//! everything that crosses hosts over one zenoh session, one zenoh message per destination host
//! for all that one wakeup found.
//!
//! - **Domains.** Each host's processes use their own iceoryx2 domain of the run
//!   ([`super::iox::Domain`]: prefix `cohort_<run>_<k>_`, root `<run>-<k>`; network namespaces
//!   on one machine share /dev/shm, so the host's index is in the names). The gateway creates the
//!   domain's services, as the orchestrator does for a one-host run, and holds them.
//! - **Out.** A process that sends to a process of another host publishes on its own service as
//!   always and rings the gateway's doorbell (with its sender id; [`super::doorbell`]) instead
//!   of the reader's. The gateway's out thread subscribes to every local service read elsewhere,
//!   drains the senders that rang, and puts one [`batch`] per destination host on
//!   `cohort/<run>/g/<destination>/<source>`.
//! - **In.** A callback subscriber on `cohort/<run>/g/<here>/*`, run by zenoh's receiving
//!   thread, checks each batch ([`batch::decode`]: every sender must run on the source host),
//!   publishes each message on the local service of its sender (as that sender's stand-in) and
//!   rings the local readers' doorbells with the sender's id — so a reader cannot tell a remote
//!   sender from a local one, and the driver checks the message as it checks any. Its ports are
//!   iceoryx2's thread-safe variant (`ipc_threadsafe`, the same resources as `ipc`); a thread of
//!   our own fed by a zenoh channel cost one more wake-up on every hop between hosts.
//! - **Control.** The gateway is its host's run-control hub: it relays the orchestrator's
//!   requests (zenoh `control`) onto the domain's `control` service as they were sealed, and the
//!   local processes' statuses (checked as the orchestrator checks them) onto zenoh `status`. It
//!   holds statuses back until each of its batch publishers reaches the gateway it serves, so
//!   a process reported ready means its host is linked, and the orchestrator's start grant still
//!   means step 0's first message finds its reader.
//!
//! Why not `iceoryx2-tunnel`: its newest release (0.8) depends on iceoryx2 ^0.8 (we are on
//! 0.10), and it relays each service on a zenoh key of its own with no notion of which messages
//! belong together, so it cannot put a step's messages for one host into one zenoh message.
//! Why batches per wakeup rather than per step: a gateway does not know how many messages a step
//! will bring when agents die or are frozen; what one wakeup finds is what has arrived together,
//! and lockstep makes that most of a step on a loaded host.

pub mod batch;
mod carry;
mod hold;
mod hub;

pub use hub::{GatewayEnd, GatewaySpec, READY_MARKER, ready_marker, run};

use super::Proc;

/// Where every process of a run runs: a host index per process (0: the orchestrator's machine,
/// k: the scenario's `hosts[k-1]`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Placement {
    /// The plant's at index 0, agent i's at index i.
    host_of: Vec<u16>,
}

impl Placement {
    pub fn new(host_of: Vec<u16>) -> Self {
        Self { host_of }
    }
    pub fn n_agents(&self) -> usize {
        self.host_of.len().saturating_sub(1)
    }
    pub fn host(&self, p: Proc) -> u16 {
        let k = match p {
            Proc::Plant => 0,
            Proc::Agent(i) => i as usize,
        };
        self.host_of.get(k).copied().unwrap_or(0)
    }
    /// The hosts that run a process, each once, ascending.
    pub fn hosts(&self) -> Vec<u16> {
        let mut h = self.host_of.clone();
        h.sort_unstable();
        h.dedup();
        h
    }
    /// Every process, the plant first.
    pub fn procs(&self) -> impl Iterator<Item = Proc> + '_ {
        std::iter::once(Proc::Plant).chain((1..=self.n_agents() as u32).map(Proc::Agent))
    }
}

/// `cohort/<run>/g/<to>/<from>`: batches from host `from` to host `to`.
fn batch_key(prefix: &str, to: u16, from: u16) -> String {
    format!("{prefix}/g/{to:x}/{from:x}")
}

/// The source host a batch key names in its last chunk.
fn source_of(key: &str) -> Option<u16> {
    key.rsplit('/').next().and_then(|k| u16::from_str_radix(k, 16).ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batch_keys_name_both_hosts() {
        let k = batch_key("cohort/00ff", 2, 10);
        assert_eq!(k, "cohort/00ff/g/2/a");
        assert_eq!(source_of(&k), Some(10));
        assert_eq!(source_of("cohort/00ff/g/2/zz"), None);
    }

    #[test]
    fn placement_lists_hosts_once() {
        let p = Placement::new(vec![1, 2, 2, 0]);
        assert_eq!(p.hosts(), vec![0, 1, 2]);
        assert_eq!(p.host(Proc::Agent(3)), 0);
        assert_eq!(p.host(Proc::Agent(9)), 0);
        assert_eq!(p.procs().count(), 4);
    }
}
