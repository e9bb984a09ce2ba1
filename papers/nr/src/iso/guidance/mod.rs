//! The ISO encounter's guidance (Secs. 3.1–3.2 and 6.2.2–6.2.3 of "Neural-Rendezvous",
//! arXiv:2208.04883): the global solution by sequential convex programming ([`scp`], on the
//! condensed QP [`qp`]), the SN-DNN's input (74) ([`features`]) and the desired trajectory
//! (21)–(24) rolled out from the guidance policy ([`desired`]).

pub mod desired;
pub mod features;
pub(crate) mod qp;
pub mod scp;
