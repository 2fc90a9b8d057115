//! `tiltsim-report`: what a run shows, read from what it recorded. It takes the master's
//! typed rows and summaries and starts no process of its own; [`analysis::run`] is the one
//! entry that runs a scenario (through `tiltsim_master::engine`) and then reports on it.
//!
//! A caller uses:
//! * [`analysis::run`] / [`analysis::run_then`]: run a scenario, then fill the summary's
//!   quick look, comfort and flags from its rows and draw its figures;
//! * [`analysis::analyse`] and [`analysis::write_plots`] on a finished run's directory;
//! * [`compare::entry`] and [`compare::tables`]: the paper's Table 4 from several runs;
//! * [`linearize::report`]: the controllers' linear design model and the PI loop's margins;
//! * [`plot`]: one chart layout written as SVG and rendered to PNG.

pub mod analysis;
pub mod compare;
pub mod comparison;
pub mod linearize;
pub mod plot;
