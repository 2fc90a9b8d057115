//! `tiltsim`: thin main. `tiltsim participant ROLE ...` is how the orchestrator starts its
//! participant processes from this same executable.
fn main() {
    #[cfg(feature = "embed-fmu")]
    tiltsim_master::export_fmu::embed_library(include_bytes!(concat!(
        env!("OUT_DIR"),
        "/libtiltsim_fmu.so"
    )));
    std::process::exit(orchestrator::cli::main());
}
