//! Thin binary: serves the actuator over iceoryx2 (normally started by `tiltsim`).
fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = actuator_proc::serve(&args) {
        eprintln!("{e}");
        std::process::exit(1);
    }
}
