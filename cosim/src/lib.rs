//! `cosim`: the lock-step co-simulation kernel of tiltsim.
//!
//! * [`msg`]: the samples exchanged each tick, `#[repr(C)]` and zero-copy, each carrying the
//!   step index it belongs to.
//! * [`participant`]: the [`Participant`](participant::Participant) trait a model implements: a
//!   plain struct with an explicit `step`, no IPC inside.
//! * [`endpoint`]: the orchestrator's view of a participant, one interface for both transports:
//!   [`InProcess`](endpoint::InProcess) and [`ipc::IpcEndpoint`].
//! * [`ipc`]: iceoryx2 transport (orchestrator side and participant side).
//! * [`wait`]: the wait strategy used while a port has no sample yet.
//! * [`stats`]: percentiles for timing reports.
//!
//! The kernel never reads a clock to decide what to compute: simulated time is the step index
//! times the base period, owned by the orchestrator. Wall clocks are read only to measure.

pub mod endpoint;
pub mod ipc;
pub mod msg;
pub mod participant;
pub mod realtime;
pub mod settings;
pub mod stats;
pub mod time;
pub mod wait;

pub use endpoint::{Endpoint, InProcess, LinkError, ProcessFault};
pub use msg::{Header, Kind, Message};
pub use participant::{Participant, Role};
