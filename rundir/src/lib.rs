//! `tiltsim-rundir`: a run's output directory. One run per directory (a lock, and the files of
//! an earlier run removed before a new one writes), the run's outputs checked against the
//! disk's free space before it starts, files written whole or not at all, and the signals that
//! interrupt a run.
//!
//! Modules: [`outdir`] (one run per output directory), [`budget`] (a run's outputs against the
//! disk's free space), [`files`] (atomic writes), [`signals`] (Ctrl-C, SIGTERM, SIGHUP).

pub mod budget;
pub mod files;
pub mod outdir;
pub mod signals;
