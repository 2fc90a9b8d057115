//! `tiltsim-master`: the co-simulation master. It starts the plant, actuator and controller
//! (as processes over iceoryx2 or in this process), steps them in lock-step or lets them run
//! free, carries their samples through the links and the scheduled faults, and records what
//! they exchanged.
//!
//! A caller runs a scenario with:
//! * `tiltsim_scenario::scenario::Scenario::load` (the file, validated: every error names the
//!   field and what is allowed);
//! * [`engine::Run`] with [`RunOptions`], its observers (the outputs among them:
//!   [`engine::outputs`], and the caller's own: [`engine::observe`]) and its manipulators
//!   ([`engine::manipulate`]); [`engine::run`] is the short form that writes the rows to
//!   `timeseries.csv`;
//! * the [`Summary`] it returns (the schema of `summary.json`), and the recorded series read
//!   back as typed rows: `tiltsim_formats::table::each_row`, `tiltsim_formats::table::Rows`.
//!
//! Modules: [`engine`] (launch, lock-step, team, manipulators, algorithms, observers,
//! summary), [`free`] (free running and its exact replay), [`links`] (link effects on the
//! values in flight), [`degraded`] (stand-ins for a lost participant), [`participant_replay`]
//! (one participant against its recorded inputs), [`export_mcap`] (`run.mcap` from a finished
//! run), [`export_fmu`] (a scenario's participant as an FMU), [`export_ssp`] (a scenario as an
//! SSP system of FMUs).
//!
//! The crates below hold what the master reads and writes, each at its own path:
//! `tiltsim-scenario` (the scenario file and its validation, fault and link settings, a value
//! per role), `tiltsim-formats` (`timeseries.csv`, `columns.csv`, `events.csv`, floats as every
//! table writes them) and `tiltsim-rundir` (one run per output directory, the disk budget,
//! atomic writes, interrupting signals). The comfort and validity results the summary carries
//! come from `tiltsim-assessment`; filling them, and drawing figures, is the caller's step
//! (`tiltsim-runner`'s pipeline, with `tiltsim-report`).

pub mod degraded;
pub mod engine;
pub mod export_fmu;
pub mod export_mcap;
pub mod export_ssp;
pub mod free;
pub mod links;
pub mod participant_replay;

pub use engine::{run, RunOptions, Summary};

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
