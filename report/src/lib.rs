//! `tiltsim-report`: what a run shows, read from what it recorded. It takes the master's
//! typed rows and summaries and runs nothing: running a scenario and then reporting on it is
//! `tiltsim-runner`'s pipeline, which calls [`analysis`] after the engine.
//!
//! A caller uses:
//! * [`analysis::assess`] and [`analysis::write_plots`] on a finished run's directory (or its
//!   rows in memory);
//! * [`table4::entry`] and [`table4::tables`]: the paper's Table 4 from several runs;
//! * [`linearize::report`]: the controllers' linear design model and the PI loop's margins;
//! * [`plot`]: one chart layout written as SVG and rendered to PNG.

pub mod analysis;
pub mod linearize;
pub mod plot;
pub mod table4;
