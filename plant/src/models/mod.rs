//! Truth models behind the `PlantModel` trait, one file each.

pub mod double_integrator;
pub mod null;
pub mod orbit;
pub mod rigid_body;
pub mod servicing;
pub mod tsnr_net;
