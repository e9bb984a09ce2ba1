//! The scenario sections: the `tsnr-net` plant ([`net_plant`]) and the `tsnr-formation`
//! algorithm ([`formation`]).

pub mod formation;
pub mod net_plant;
