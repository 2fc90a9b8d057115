//! With the `embed-fmu` feature (`cargo install --path orchestrator --features embed-fmu`),
//! builds the FMU library (`tiltsim-fmu`, a cdylib that `cargo install` would not install)
//! with the same cargo into `OUT_DIR`, for `tiltsim export-fmu` to carry inside the
//! executable. Without the feature it does nothing.

use std::path::PathBuf;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_EMBED_FMU").is_none() {
        return;
    }
    let here = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let root = here
        .parent()
        .expect("the orchestrator sits in the workspace")
        .to_path_buf();
    // What the library is built from.
    for d in [
        "fmu-export",
        "cosim",
        "plant-proc",
        "actuator-proc",
        "controller-proc",
        "vehicle-model",
    ] {
        println!(
            "cargo:rerun-if-changed={}",
            root.join(d).join("src").display()
        );
    }
    println!(
        "cargo:rerun-if-changed={}",
        root.join("Cargo.lock").display()
    );
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo"));
    let target = out.join("fmu-target");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .args([
            "build",
            "--release",
            "--lib",
            "-p",
            "tiltsim-fmu",
            "--target-dir",
        ])
        .arg(&target)
        .current_dir(&root)
        // The outer build's settings for this package are not the library's.
        .env_remove("CARGO_FEATURE_EMBED_FMU")
        .env_remove("CARGO_TARGET_DIR")
        .status()
        .expect("cargo runs");
    assert!(status.success(), "building the FMU library failed");
    let lib = target.join("release").join("libtiltsim_fmu.so");
    std::fs::copy(&lib, out.join("libtiltsim_fmu.so"))
        .unwrap_or_else(|e| panic!("{}: {e}", lib.display()));
}
