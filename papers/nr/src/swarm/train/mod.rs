//! The swarm policy learned from the global solution (Sec. 7.2.1 of "Neural-Rendezvous",
//! arXiv:2208.04883): the problem as the planner sees it ([`problem`]), the centralised SCP
//! global solution ([`scp`]), the training data ([`data`]), DAgger rounds ([`dagger`]), the
//! in-process evaluation of a policy alone ([`eval`]), the training run ([`imitation`]) and the
//! trainer `orchestrator train nr-swarm` ([`command`]).

pub(crate) mod command;
pub(crate) mod dagger;
pub(crate) mod data;
pub mod eval;
pub(crate) mod imitation;
pub(crate) mod problem;
pub(crate) mod scp;
