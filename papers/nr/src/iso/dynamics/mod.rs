//! The ISO encounter's dynamics (Secs. 2 and 6.1–6.2.1 of "Neural-Rendezvous",
//! arXiv:2208.04883): the constants we fix, heliocentric two-body motion ([`two_body`]), the
//! ISO's LVLH frame ([`lvlh`]), the relative dynamics (1)–(2) ([`relative`]), navigation
//! (Example 1, [`navigation`]), the synthetic ISO set ([`iso_set`]), the plant's messages
//! ([`messages`]) and the `iso-encounter` plant ([`plant`]).

pub mod constants;
pub mod iso_set;
pub mod lvlh;
pub mod messages;
pub mod navigation;
pub mod plant;
pub mod relative;
pub mod two_body;
