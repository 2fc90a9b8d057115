//! Rerun's SDK and its `rerun` command (`rerun-sdk` in `scripts/fmi-requirements.txt`,
//! installed by `scripts/fmi-venv.sh`) write and read back the `.rrd` of `scripts/to-rerun.py`.

mod record;
