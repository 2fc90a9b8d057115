//! Checks against tools tiltsim did not write, one module per tool. Every tool comes from
//! PyPI, pinned in `scripts/fmi-requirements.txt` and installed by `scripts/fmi-venv.sh` into
//! `target/fmi-venv` (the first test that needs it runs the script; CI runs it beforehand).
//! These checks run with the README's test command like every other: a tool that is missing
//! or does not start fails the test with a message naming it and the script that installs
//! it, never a skip.

mod fmpy;
mod libcosim;
mod mcap;
mod pandas;
mod pytest;
mod rerun;
