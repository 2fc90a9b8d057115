//! `tiltsim-protocol`: what the orchestrator and the participants say to each other, apart
//! from how it travels.
//!
//! * [`msg`]: the samples exchanged each tick, `#[repr(C)]` plain data, each starting with a
//!   [`Header`] that carries the step index, the kind, the protocol version and the timing of
//!   the exchange. Their layout is pinned by tests against [`PROTOCOL_VERSION`].
//! * [`participant`]: the [`Participant`] trait a model implements (a plain struct with an
//!   explicit `step`, no transport inside), its [`Role`], and [`Served`](participant::Served),
//!   the request checking every transport shares.
//! * [`time`]: simulated time on the tick grid, computed one way everywhere.
//! * [`settings`]: the field checker every crate's settings use, so that a rejected setting
//!   names its field, its value and what is allowed.
//! * [`address`]: where a participant on another host reaches the run, checked before any
//!   transport sees it.
//! * [`wire`]: the samples as bytes on a network (little-endian fields at their pinned
//!   offsets, padding zero), for transports that cannot share memory.
//!
//! `layout_tests` pins the wire layout (sizes and offsets) against the protocol version.
//!
//! Transports live beside this crate (`cosim`: in-process and iceoryx2); model and
//! assessment crates depend on this crate only.

pub mod address;
pub mod msg;
pub mod participant;
pub mod settings;
pub mod time;
pub mod wire;

#[cfg(test)]
mod layout_tests;

pub use msg::{FreeClock, Header, Kind, Message, PROTOCOL_VERSION};
pub use participant::{Participant, Role};
