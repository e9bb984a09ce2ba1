//! The swarm campaign (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883): one case flown by
//! every method ([`case`]), the command `orchestrator nr swarm-campaign` ([`command`]) and its
//! outputs ([`report`]).

pub(crate) mod case;
pub(crate) mod command;
pub(crate) mod report;
