//! One module per paper method, each a pure `Algorithm` (no transport inside).

pub mod coast;
pub mod consensus_formation;
pub mod dai_attitude;
pub mod lbdnn_network;
pub mod lbdnn_servicing;
pub mod null;
pub mod tsnr_aemc;
pub mod tsnr_common;
pub mod tsnr_dmpc;
pub mod tsnr_mpc;
pub mod tsnr_smc;
