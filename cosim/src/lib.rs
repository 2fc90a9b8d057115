//! `cosim`: the transports of tiltsim's co-simulation, beside the protocol they carry.
//!
//! The samples, their header and the [`Participant`] trait are in `tiltsim-protocol`
//! (re-exported here as [`msg`], [`participant`], [`settings`], [`time`] and [`wait`]); this
//! crate moves them:
//!
//! * [`endpoint`]: the orchestrator's view of a participant, one interface for both transports:
//!   [`InProcess`](endpoint::InProcess) and [`ipc::IpcEndpoint`].
//! * [`ipc`]: iceoryx2 transport (orchestrator side and participant side).
//! * [`realtime`]: `SCHED_FIFO` and locked memory for paced runs.
//! * [`stats`]: percentiles for timing reports.
//!
//! The kernel never reads a clock to decide what to compute: simulated time is the step index
//! times the base period, owned by the orchestrator. Wall clocks are read only to measure.

pub mod endpoint;
pub mod ipc;
pub mod realtime;
pub mod stats;

pub use tiltsim_protocol::{msg, participant, settings, time, wait};

pub use endpoint::{Endpoint, InProcess, LinkError, ProcessFault};
pub use msg::{Header, Kind, Message};
pub use participant::{Participant, Role};
