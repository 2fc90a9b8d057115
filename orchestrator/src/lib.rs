//! `orchestrator`: scenario, lock-step scheduling, recording and reporting, and the `tiltsim`
//! command-line program.

pub mod analysis;
pub mod bench;
pub mod budget;
pub mod cli;
pub mod comfort;
pub mod compare;
pub mod degraded;
pub mod engine;
pub mod events;
pub mod export_fmu;
pub mod export_mcap;
pub mod faults;
pub mod files;
pub mod linearize;
pub mod links;
pub mod outdir;
pub mod plot;
pub mod record;
pub mod replay;
pub mod roles;
pub mod scenario;
pub mod signals;
pub mod sweep;
pub mod validity;

pub use engine::{run, RunOptions, Summary};
pub use scenario::{Master, Scenario, Transport};
