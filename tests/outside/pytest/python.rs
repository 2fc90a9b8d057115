//! The Python package: built as a wheel with maturin from `python/`, installed into the
//! project's Python environment (`scripts/fmi-venv.sh`), and checked by its own pytest tests
//! (`python/tests`: a run's arrays against the command line's timeseries.csv value for value,
//! a sweep's frame against samples.csv, errors, the GIL, Ctrl-C) and by running the example
//! in `examples/`. A missing tool (maturin, pytest) fails the test, naming it.

use std::path::PathBuf;
use std::process::Command;

use tiltsim_suite::{fmi_python, root, tiltsim};

/// Builds the wheel into `target/wheels` and installs it; returns the environment's Python.
fn installed() -> PathBuf {
    let py = fmi_python();
    let bin = py.parent().expect("venv/bin").to_path_buf();
    let target = tiltsim()
        .parent()
        .and_then(|p| p.parent())
        .expect("target/")
        .to_path_buf();
    let wheels = target.join("wheels");
    let _ = std::fs::remove_dir_all(&wheels);
    let out = Command::new(bin.join("maturin"))
        .args(["build", "--release", "--quiet", "--manifest-path"])
        .arg(root().join("python/Cargo.toml"))
        .arg("--out")
        .arg(&wheels)
        .arg("--interpreter")
        .arg(&py)
        .current_dir(root())
        .output()
        .unwrap_or_else(|e| panic!("maturin (from scripts/fmi-requirements.txt): {e}"));
    assert!(
        out.status.success(),
        "maturin build of python/ failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let wheel = std::fs::read_dir(&wheels)
        .expect("target/wheels")
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "whl"))
        .expect("maturin wrote a wheel");
    let out = Command::new(&py)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
        ])
        .args(["--no-deps", "--force-reinstall"])
        .arg(&wheel)
        .output()
        .expect("pip");
    assert!(
        out.status.success(),
        "pip install {} failed:\n{}",
        wheel.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    py
}

#[test]
fn the_python_package_builds_installs_and_passes_its_tests() {
    let py = installed();
    let out = Command::new(&py)
        .args([
            "-m",
            "pytest",
            "-q",
            "-rfE",
            // A deprecation (pandas' `float_precision="round_trip"` under pandas 3, say)
            // fails the test instead of passing by.
            "-W",
            "error",
            "-p",
            "no:cacheprovider",
            "python/tests",
        ])
        .env("TILTSIM_CLI", tiltsim())
        .env_remove("TILTSIM_PARTICIPANT_EXE")
        .current_dir(root())
        .output()
        .expect("pytest (from scripts/fmi-requirements.txt)");
    let text = String::from_utf8_lossy(&out.stdout);
    eprintln!("{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "pytest python/tests failed");
    // Every test ran: none skipped, none deselected.
    let last = text
        .lines()
        .rev()
        .find(|l| l.contains(" passed"))
        .unwrap_or("");
    assert!(
        !last.contains("skipped") && !last.contains("deselected"),
        "{last}"
    );
}
