//! The ISO encounter's guidance policy trained by imitation of the global solution (Secs. 3.2
//! and 6.2.2–6.2.4 of "Neural-Rendezvous", arXiv:2208.04883): the SCP data ([`data`]), the loss
//! (10)–(12) ([`loss`]), the training run ([`imitation`]), the terms of Lemma 1 ([`lemma1`]) and
//! the trainer `orchestrator train nr-iso` ([`command`]).

pub(crate) mod command;
pub(crate) mod data;
pub(crate) mod imitation;
pub(crate) mod lemma1;
pub(crate) mod loss;
