//! Co-simulation masters tiltsim did not write: libcosim through `libcosimpy`, and FMPy's
//! container FMU (`FMPy`), both in `scripts/fmi-requirements.txt`, installed by
//! `scripts/fmi-venv.sh`. The Python helpers (`libcosim_run.py`, `fmpy_container.py`) live
//! beside this file.

mod fmi_masters;
