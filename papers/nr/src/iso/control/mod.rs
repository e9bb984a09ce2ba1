//! The ISO encounter's control (Sec. 4 and 6.3 of "Neural-Rendezvous", arXiv:2208.04883): the
//! pointwise min-norm control (27)–(36) ([`min_norm`]) on the tracking quantities (25)–(31)
//! ([`tracking`]), the delivery-error bound (49)–(50), (72)–(73) ([`bound`]), the baselines of
//! Sec. 6.3 ([`baselines`]) and the spacecraft's algorithm, Algorithm 1 ([`agent`]).

pub mod agent;
pub(crate) mod baselines;
pub mod bound;
pub(crate) mod min_norm;
pub(crate) mod tracking;
