//! The ISO encounter in the registry and the host (Sec. 6 of "Neural-Rendezvous",
//! arXiv:2208.04883): the `iso-encounter` plant kind and the `neural-rendezvous` algorithm kind
//! ([`kinds`]), the run's analysis from its telemetry ([`analysis`]), its figures ([`figures`])
//! and its verdict ([`verdict`]).

pub(crate) mod analysis;
pub(crate) mod figures;
pub mod kinds;
pub(crate) mod verdict;
