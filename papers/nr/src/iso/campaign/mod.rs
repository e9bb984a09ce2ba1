//! The ISO encounter's evaluation in one process (Sec. 6.3 of "Neural-Rendezvous",
//! arXiv:2208.04883): the lockstep loop ([`sim`]), every method over the test ISOs and the
//! sweeps of Figs. 9 and 11 ([`eval`]), the command `orchestrator nr campaign` ([`command`]) and
//! what it writes ([`report`]).

pub(crate) mod command;
pub(crate) mod eval;
pub(crate) mod report;
pub mod sim;
