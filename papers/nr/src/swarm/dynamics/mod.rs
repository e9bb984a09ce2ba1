//! The swarm's dynamics (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883): the geometry and
//! seeded reconfiguration problems with the tall-ellipsoid collision distance ([`setup`]), the
//! `swarm` plant of 3-D double integrators ([`plant`]) and what it and the vehicles say
//! ([`messages`]); who must hear whom ([`neighbours`]).

pub(crate) mod messages;
pub(crate) mod neighbours;
pub(crate) mod plant;
pub(crate) mod setup;
