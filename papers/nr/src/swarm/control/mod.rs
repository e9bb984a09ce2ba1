//! One swarm vehicle's algorithm, the `nr-swarm` kind (Sec. 7.2 of "Neural-Rendezvous",
//! arXiv:2208.04883): the local observation and the policy interface ([`obs`]), the learned
//! deep set ([`policy`]) and the PD baseline ([`pd`]), the own-state estimator ([`nav`]), the
//! distributed safety filter ([`safety`]) and the vehicle itself ([`agent`]).

pub(crate) mod agent;
pub(crate) mod nav;
pub(crate) mod obs;
pub(crate) mod pd;
pub mod policy;
pub(crate) mod safety;
