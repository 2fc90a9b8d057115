//! `tiltsim`: thin main. `tiltsim participant ROLE ...` is how the orchestrator starts its
//! participant processes from this same executable.
fn main() {
    std::process::exit(orchestrator::cli::main());
}
