//! `tiltsim-report`: what a run shows, read from what it recorded. It takes the master's
//! typed rows and summaries; [`pipeline::carry_out`] is the one entry that runs a scenario
//! (lock-step, free, or a replay of a free run's timing, through `tiltsim_master`) and then
//! reports on it, for every front end.
//!
//! A caller uses:
//! * [`pipeline::carry_out`] with a [`pipeline::Job`]: run a scenario into a directory (or
//!   with its rows in memory), then fill the summary's quick look, comfort and flags from its
//!   rows, write `summary.json` and `perf.json` and draw its figures;
//! * [`analysis::assess`] and [`analysis::write_plots`] on a finished run's directory;
//! * [`compare`]: a comparison run into a directory (`tiltsim compare`), and
//!   [`table4::entry`] and [`table4::tables`]: the paper's Table 4 from several runs;
//! * [`linearize::report`]: the controllers' linear design model and the PI loop's margins;
//! * [`plot`]: one chart layout written as SVG and rendered to PNG.

pub mod analysis;
pub mod compare;
pub mod linearize;
pub mod pipeline;
pub mod plot;
pub mod table4;
