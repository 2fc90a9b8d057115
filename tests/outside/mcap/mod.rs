//! The Python registry's MCAP reader (`mcap` in `scripts/fmi-requirements.txt`, installed by
//! `scripts/fmi-venv.sh`) reads tiltsim's recordings through `mcap_check.py`, beside this file.
//! The free-run recording check (`cli`'s `freerun` module) runs the same reader.

mod record;
