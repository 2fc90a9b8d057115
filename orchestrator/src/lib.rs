//! `tiltsim`, the command-line program: [`cli`] parses the arguments, calls the libraries
//! (`tiltsim-master` runs a scenario, `tiltsim-report` reports on it, `tiltsim-studies`
//! sweeps and benchmarks) and maps their errors to exit codes in one place.

pub mod cli;
