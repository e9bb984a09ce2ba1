//! Cohort's astrodynamics, shared by every paper that flies orbits: force models behind a trait,
//! fixed-step RK4, Kepler propagation and the LVLH frame ([`orbit`]).

pub mod orbit;
