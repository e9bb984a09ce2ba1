//! The ISO encounter in the registry and the host (Sec. 6 of "Neural-Rendezvous",
//! arXiv:2208.04883): the `iso-encounter` plant kind and the `neural-rendezvous` algorithm kind
//! ([`kinds`]), the run's analysis from its telemetry ([`analysis`]), its figures ([`figures`])
//! and its verdict ([`verdict`]), declared to the host as the run's hooks ([`hooks`]).

#[cfg(feature = "host")]
pub(crate) mod analysis;
#[cfg(feature = "host")]
pub(crate) mod figures;
#[cfg(feature = "host")]
pub(crate) mod hooks;
pub mod kinds;
#[cfg(feature = "host")]
pub(crate) mod verdict;
