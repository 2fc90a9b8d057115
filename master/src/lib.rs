//! `tiltsim-master`: the co-simulation master. It starts the plant, actuator and controller
//! (as processes over iceoryx2 or in this process), steps them in lock-step or lets them run
//! free, carries their samples through the links and the scheduled faults, and records what
//! they exchanged.
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
//! Modules: [`engine`] (launch, lock-step, team, manipulators, algorithms, observers,
//! summary), [`free`] (free running and its exact replay), [`links`] (link effects on the
//! values in flight), [`degraded`] (stand-ins for a lost participant), [`participant_replay`]
//! (one participant against its recorded inputs), [`export_mcap`] (`run.mcap` from a finished
//! run), [`export_fmu`] (a scenario's participant as an FMU), [`export_ssp`] (a scenario as an
//! SSP system of FMUs).
//!
//! Re-exported from the crates below, so that their paths under `tiltsim_master::` keep
//! working: from `tiltsim-scenario`, [`scenario`] (the file and its validation), [`faults`]
//! (process-fault settings) and [`roles`] (a value per role); from `tiltsim-formats`,
//! [`table`] (`timeseries.csv`), [`columns`] (`columns.csv`), [`events`] (`events.csv`) and
//! [`float_text`] (floats as every table writes them); from `tiltsim-rundir`, [`outdir`] (one
//! run per output directory), [`budget`] (a run's outputs against the disk's free space),
//! [`files`] and [`signals`] (atomic writes, interrupting signals).
//! The comfort and validity results the summary carries come from `tiltsim-assessment`;
//! filling them, and drawing figures, is the caller's step (`tiltsim-report`).

pub mod degraded;
pub mod engine;
pub mod export_fmu;
pub mod export_mcap;
pub mod export_ssp;
pub mod free;
pub mod links;
pub mod participant_replay;

pub use tiltsim_formats::{columns, events, float_text, table};
pub use tiltsim_rundir::{budget, files, outdir, signals};
pub use tiltsim_scenario::{faults, roles, scenario};

pub use engine::{run, RunOptions, Summary};
pub use scenario::{Master, Scenario, Transport};

#[cfg(test)]
mod tests {
    use crate::engine::Status;

    #[test]
    fn a_status_prints_as_summary_json_spells_it() {
        for v in [
            Status::Completed,
            Status::Failed,
            Status::Degraded,
            Status::Interrupted,
        ] {
            assert_eq!(serde_json::to_string(&v).unwrap(), format!("\"{v}\""));
        }
    }
}
