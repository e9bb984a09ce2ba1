//! One module per paper method, each a pure `Algorithm` (no transport inside).

pub mod consensus_formation;
