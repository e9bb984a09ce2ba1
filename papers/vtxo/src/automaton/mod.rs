//! The mission supervisor of Sec. 8 of "Explainable AI-Enhanced Supervisory Control for
//! High-Precision Spacecraft Formation" (its timed automaton, (92) and Tables 6–8; called
//! `automaton` here so as not to read as the workspace's process supervisor): the table as data
//! with its departures from the print ([`table`]), its validation ([`check`]), its run in integer
//! ticks ([`exec`]), what it adds to the two spacecraft's messages ([`share`]), and the lockstep
//! `Algorithm` that runs it one tick per step ([`lockstep`]).

pub mod check;
pub mod exec;
pub(crate) mod lockstep;
pub(crate) mod share;
pub mod table;
