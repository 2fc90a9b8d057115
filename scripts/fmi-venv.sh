#!/usr/bin/env bash
# Makes the Python environment of the outside checks (FMI and its masters, MCAP, Rerun) in DIR (default target/fmi-venv) from
# scripts/fmi-requirements.txt; does nothing when it is there and complete. The tests call
# it themselves, so `cargo test --release --workspace` needs nothing else.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="${1:-$here/../target/fmi-venv}"
if [ -x "$venv/bin/python" ] && [ "$venv/.requirements" -nt "$here/fmi-requirements.txt" ] \
    && "$venv/bin/python" -c "import fmpy, libcosimpy, pythonfmu, mcap, rerun, pandas, polars, pytest" 2>/dev/null \
    && "$venv/bin/maturin" --version >/dev/null 2>&1; then
    exit 0
fi
rm -rf "$venv"
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/fmi-requirements.txt"
touch "$venv/.requirements"
echo "made the FMI check environment in $venv" >&2
