//! The swarm reconfiguration (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883): N vehicles
//! as double integrators swap places without collision, each flying a learned distributed
//! policy on local observations under Neural-Rendezvous's tracking control.
//!
//! - [`dynamics`]: the geometry and random problems, the `swarm` plant and its messages;
//! - [`control`]: one vehicle's algorithm (the `nr-swarm` kind): observation, policies (deep
//!   set, PD baseline), own-state estimator and safety filter;
//! - [`train`]: the global solution (centralised SCP, Sec. 7.2.1), the training data, DAgger,
//!   the in-process evaluation and the trainer `orchestrator train nr-swarm`;
//! - [`campaign`]: `orchestrator nr swarm-campaign`, its cases and outputs;
//! - [`generate`]: `orchestrator generate swarm`, a swarm of any size with sparse neighbours;
//! - [`host`]: the kinds in the registry, the run's analysis and figures;
//! - [`config`]: the scenario sections.

#[cfg(feature = "host")]
pub(crate) mod campaign;
pub(crate) mod config;
pub mod control;
pub(crate) mod dynamics;
#[cfg(feature = "host")]
pub(crate) mod generate;
pub(crate) mod host;
pub mod train;
