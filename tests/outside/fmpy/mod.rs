//! FMPy (`FMPy` in `scripts/fmi-requirements.txt`, installed by `scripts/fmi-venv.sh`) validates
//! and co-simulates tiltsim's FMUs and reads their model descriptions; pythonfmu (same file)
//! builds an FMI 2.0 controller tiltsim did not write (`tilt_pi.py`). The Python helpers live
//! beside this file.

mod fmi;
mod getting_started;
