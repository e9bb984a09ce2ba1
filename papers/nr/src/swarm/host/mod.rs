//! The swarm in the registry and the host (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883):
//! the `swarm` plant kind and the `nr-swarm` algorithm kind ([`kinds`]), the run's analysis
//! ([`analysis`]) and figures ([`figures`]).

pub(crate) mod analysis;
pub(crate) mod figures;
pub(crate) mod kinds;
