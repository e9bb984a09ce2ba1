//! The ISO encounter (Secs. 2–6 of "Neural-Rendezvous", arXiv:2208.04883): K spacecraft about
//! the Sun meeting one interstellar object at t_f.
//!
//! - [`dynamics`]: the truth and the models (two-body, the ISO's LVLH frame, the relative
//!   dynamics (1)–(2), navigation, the synthetic ISO set) and the `iso-encounter` plant;
//! - [`guidance`]: the global solution (SCP, Sec. 3.1), the SN-DNN's input (74) and the desired
//!   trajectory (21)–(24);
//! - [`control`]: the min-norm tracking control (25)–(36), the delivery-error bound (49)–(50),
//!   the baselines of Sec. 6.3 and the spacecraft's algorithm (Algorithm 1);
//! - [`train`]: the guidance policy trained by imitation (Secs. 3.2, 6.2.2–6.2.4);
//! - [`campaign`]: the in-process evaluation of Sec. 6.3 and its command;
//! - [`host`]: the kinds in the registry, the run's analysis, figures and verdict;
//! - [`config`]: the scenario sections; [`cli`]: the commands' argument parsing.

#[cfg(feature = "host")]
pub mod campaign;
#[cfg(feature = "host")]
pub(crate) mod cli;
pub mod config;
pub mod control;
pub mod dynamics;
pub mod guidance;
pub mod host;
#[cfg(feature = "host")]
pub(crate) mod train;
