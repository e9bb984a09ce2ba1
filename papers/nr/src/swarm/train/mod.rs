//! The swarm policy learned from the global solution (Sec. 7.2.1 of "Neural-Rendezvous",
//! arXiv:2208.04883): the problem as the planner sees it ([`problem`]), the centralised SCP
//! global solution ([`scp`]), the training data ([`data`]), DAgger rounds ([`dagger`]), the
//! near-conflict oversampling and collision-aware loss ([`avoidance`]), the
//! in-process evaluation of a policy alone ([`eval`]), the training run ([`imitation`]) and the
//! trainer `orchestrator train nr-swarm` ([`command`]). All but [`problem`] (which the flown
//! policy reads too) are the host's.

#[cfg(feature = "host")]
pub(crate) mod avoidance;
#[cfg(feature = "host")]
pub(crate) mod command;
#[cfg(feature = "host")]
pub(crate) mod dagger;
#[cfg(feature = "host")]
pub(crate) mod data;
#[cfg(feature = "host")]
pub mod eval;
#[cfg(feature = "host")]
pub(crate) mod imitation;
#[cfg(feature = "host")]
pub(crate) mod problem;
#[cfg(feature = "host")]
pub(crate) mod scp;
