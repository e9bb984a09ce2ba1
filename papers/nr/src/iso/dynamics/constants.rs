//! Physical constants and the set-up values we fix where the paper's are lost (reference values
//! of Sec. 6.1 of "Neural-Rendezvous", arXiv:2208.04883; every one is also a scenario key, these
//! are the defaults).

/// The Sun's gravitational parameter (IAU 2015 nominal GM☉), m³/s².
pub const MU_SUN_M3PS2: f64 = 1.327_124_400_18e20;
/// Astronomical unit, m.
pub const AU_M: f64 = 1.495_978_707e11;
/// Standard gravity for the rocket equation, m/s².
pub const G0_MPS2: f64 = 9.806_65;

/// Terminal time of the encounter t_f (ours: one day), s.
pub const T_F_S: f64 = 86_400.0;
/// Control interval Δt (ours), s.
pub const DT_S: f64 = 600.0;
/// Wet mass at the start of terminal guidance (ours), kg.
pub const M0_KG: f64 = 500.0;
/// Per-axis thrust limit |uᵢ| ≤ u_max (ours), N.
pub const U_MAX_N: f64 = 1.0;
/// Specific impulse (ours), s.
pub const ISP_S: f64 = 220.0;
/// Δv budget (ours), m/s.
pub const DV_BUDGET_MPS: f64 = 20.0;
/// Radius of the sphere the desired terminal relative positions ρ_f are drawn on (ours), m.
pub const RHO_F_RADIUS_M: f64 = 100e3;

/// Size of the synthetic ISO set and its split (ours: 0–199 train, 200–299 test).
pub const ISO_SET_SIZE: u32 = 300;
pub const TRAIN_ISOS: std::ops::Range<u32> = 0..200;
pub const TEST_ISOS: std::ops::Range<u32> = 200..300;
/// Seed of the synthetic ISO set (a data set, fixed: training and every run use the same ISOs).
pub const ISO_SET_SEED: u64 = 3;
