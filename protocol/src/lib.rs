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
//! * [`process`]: a process of one boot told apart from a later one with its pid (the owner of
//!   a run's shared-memory files, the holder of an output directory's lock).
//! * [`wait`]: how a waiter spends the time while a port has no sample yet (the strategy a
//!   scenario names, and the spin, yield and nap every transport shares).
//! * [`wire`]: the samples as bytes on a network (little-endian fields at their pinned
//!   offsets, padding zero), for transports that cannot share memory.
//!
//! `layout_tests` pins the wire layout (sizes and offsets) against the protocol version.
//!
//! Transports live beside this crate (`cosim`: in-process and iceoryx2; it enables the `ipc`
//! feature, which makes every sample an iceoryx2 zero-copy payload); model, assessment,
//! scenario, run-directory and table crates depend on this crate only and build no iceoryx2.

pub mod address;
pub mod msg;
pub mod participant;
pub mod process;
pub mod settings;
pub mod time;
pub mod wait;
pub mod wire;

#[cfg(test)]
mod layout_tests;

pub use msg::{FreeClock, Header, Kind, Message, PROTOCOL_VERSION};
pub use participant::{Participant, Role};
