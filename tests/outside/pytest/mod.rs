//! The Python package, built with maturin and tested with pytest (`maturin`, `pytest` in
//! `scripts/fmi-requirements.txt`, installed by `scripts/fmi-venv.sh`), and its example run.

mod python;
