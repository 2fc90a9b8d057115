//! pandas reads the tables as a notebook user does, and FMPy's CSV reader reads the
//! time series (`pandas`, `FMPy` in `scripts/fmi-requirements.txt`, installed by
//! `scripts/fmi-venv.sh`), through `pandas_check.py` beside this file.

mod tables;
