//! `tiltsim-master`: the co-simulation master. It reads a scenario, starts the plant, actuator
//! and controller (as processes over iceoryx2 or in this process), steps them in lock-step,
//! carries their samples through the links and the scheduled faults, and records what they
//! exchanged.
//!
//! A caller runs a scenario with:
//! * [`Scenario::load`] (the file, validated: every error names the field and what is
//!   allowed);
//! * [`engine::Run`] with [`RunOptions`], its observers (the outputs among them:
//!   [`engine::outputs`], and the caller's own: [`engine::observe`]) and its manipulators
//!   ([`engine::manipulate`]); [`engine::run`] is the short form that writes the rows to
//!   `timeseries.csv`;
//! * the [`Summary`] it returns (the schema of `summary.json`), and the recorded series read
//!   back as typed rows: [`table::each_row`], [`table::Rows`].
//!
//! Modules: [`scenario`] (the file and its validation), [`links`] (link effects),
//! [`faults`] (process faults), [`events`] (`events.csv`), [`degraded`] (stand-ins for a
//! lost participant), [`roles`] (a value per role), [`engine`] (launch, lock-step, team,
//! manipulators, algorithms, observers, summary), [`table`] (`timeseries.csv`: the rows, written and read back), [`columns`]
//! (`columns.csv`: each column's unit and description), [`float_text`] (floats as every
//! table writes them), [`free`] (free running and its exact
//! replay),
//! [`export_mcap`] (`run.mcap` from a finished run), [`budget`] (a run's outputs against the
//! disk's free space, checked before it starts), [`participant_replay`] (one participant against its
//! recorded inputs), [`outdir`] (one run per output directory), [`export_fmu`] (a scenario's
//! participant as an FMU), [`export_ssp`] (a scenario as an SSP system of FMUs), [`files`] and
//! [`signals`] (atomic writes, interrupting signals).
//! The comfort and validity results the summary carries come from `tiltsim-assessment`;
//! filling them, and drawing figures, is the caller's step (`tiltsim-report`).

pub mod budget;
pub mod columns;
pub mod degraded;
pub mod engine;
pub mod events;
pub mod export_fmu;
pub mod export_mcap;
pub mod export_ssp;
pub mod faults;
pub mod files;
pub mod float_text;
pub mod free;
pub mod links;
pub mod outdir;
pub mod participant_replay;
pub mod roles;
pub mod scenario;
pub mod signals;
pub mod table;

pub use engine::{run, RunOptions, Summary};
pub use scenario::{Master, Scenario, Transport};
