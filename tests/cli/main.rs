//! The `tiltsim` program as a user runs it, in-process and over iceoryx2: templates and
//! `--set`, output directories and figures, sweeps, the bench, the lock-step runtime over both
//! transports, the endpoint contract, free runs and their replay, recordings, and the pinned
//! outputs of `tests/pinned.txt`. One check here also reads a recording with the Python
//! registry's `mcap` reader, from the environment the `outside` tests use
//! (`freerun::link_effects_and_a_stall_act_in_a_free_run_and_its_replay_repeats_them`).

mod bench;
mod contract;
mod falsify;
mod falsify_requirements;
mod falsify_shards;
mod freerun;
mod getting_started;
mod network;
mod outputs;
mod pinned;
mod record;
mod report;
mod route;
mod sweep;
mod sweep_merge;
mod transport;
