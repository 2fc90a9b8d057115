//! `tiltsim-runner`: a scenario run end to end, one way for every front end (the `tiltsim`
//! program, the studies, the Python package). [`pipeline::carry_out`] is the one entry that
//! runs a scenario (lock-step, free, or a replay of a free run's timing, through
//! `tiltsim_master`) and then reports on it with `tiltsim_report`.
//!
//! A caller uses:
//! * [`pipeline::carry_out`] with a [`pipeline::Job`]: run a scenario into a directory (or
//!   with its rows in memory), with the observers and manipulators it adds, then fill the
//!   summary's quick look, comfort and flags from its rows, write `summary.json` and
//!   `perf.json` and draw its figures (with the whole car, [`full_car`]'s running safety and
//!   comfort along the car);
//! * [`compare`]: a comparison run into a directory (`tiltsim compare`): each scenario run
//!   through the pipeline, then the Table 4 tables and figures.

pub mod compare;
pub mod full_car;
pub mod pipeline;
