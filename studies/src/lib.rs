//! `tiltsim-studies`: studies over many runs of one scenario.
//!
//! * [`sweep`]: Monte Carlo and grid plans ([`sweep::Plan`], [`sweep::parse_grid`]), the
//!   samples run in parallel ([`sweep::run`]), shards and their merge ([`sweep::merge`]), and
//!   what the comfort metrics do across them ([`sweep::write_outputs`]);
//! * [`bench`]: the machine's numbers for the co-simulation, measured in one run
//!   ([`bench::run`], [`bench_table::table`]).
//!
//! What a run will write against the disk's free space (the disk budget) is
//! `tiltsim_rundir::budget`.

pub mod bench;
pub mod bench_floor;
pub mod bench_fmu;
pub mod bench_table;
pub mod falsify;
pub mod parallel;
pub mod route;
pub mod sweep;
