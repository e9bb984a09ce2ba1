//! The swarm in the registry and the host (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883):
//! the `swarm` plant kind and the `nr-swarm` algorithm kind ([`kinds`]), the run's analysis
//! ([`analysis`], with the neighbour rule's check [`stray`]) and figures ([`figures`]), declared to the host as the run's hooks ([`hooks`]).

#[cfg(feature = "host")]
pub(crate) mod analysis;
#[cfg(feature = "host")]
pub(crate) mod figures;
#[cfg(feature = "host")]
pub(crate) mod hooks;
pub(crate) mod kinds;
#[cfg(feature = "host")]
pub(crate) mod stray;
