//! The spectrally-normalised neural network both sub-systems fly (Sec. 3.2 of
//! "Neural-Rendezvous", arXiv:2208.04883): [`sn_dnn`] evaluates it in flight from a
//! safetensors weights file (the ISO encounter's guidance policy, the swarm's deep set),
//! [`sn_mlp`] is its trainable twin on candle that the trainers of [`crate::iso::train`] and
//! [`crate::swarm::train`] fit and write.

pub mod sn_dnn;
#[cfg(feature = "host")]
pub(crate) mod sn_mlp;
