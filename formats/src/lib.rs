//! `tiltsim-formats`: the tables a run writes, each one typed record written and read back by
//! this crate. A crate that only reads a run's rows (reports, studies) needs this crate, not the
//! engine.
//!
//! Modules: [`table`] (`timeseries.csv`: the rows, written and read back), [`columns`]
//! (`columns.csv`: each column's unit and description), [`events`] (the `EventKind`
//! vocabulary and `events.csv`), [`float_text`] (floats as every table writes them).

pub mod columns;
pub mod events;
pub mod float_text;
pub mod table;
