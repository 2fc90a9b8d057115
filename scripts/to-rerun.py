#!/usr/bin/env python3
"""Writes a finished tiltsim run as a Rerun recording (.rrd) whose signals plot over
simulated time: every column of DIR/timeseries.csv as a Rerun `Scalars` series on the
`sim_time` timeline, grouped by participant (/plant, /actuator, /controller, /links), and the
run's events (DIR/events.csv) as text logs at their ticks.

    python scripts/to-rerun.py DIR [--out FILE.rrd]     # default DIR/run.rrd
    rerun DIR/run.rrd

Needs the `rerun-sdk` and `numpy` packages (scripts/fmi-requirements.txt pins the versions
the tests use). Rerun reads MCAP files too, but keeps JSON messages such as run.mcap's as
opaque bytes; this route gives it plottable scalars.
"""

import argparse
import csv
import sys
from pathlib import Path

import numpy as np
import rerun as rr

# Where each column of timeseries.csv belongs; a column not named here goes under /run.
GROUPS = {
    "plant": [
        "s", "curvature", "cant", "y_v", "theta_v", "y_b", "theta_b", "dy_v", "dtheta_v",
        "dy_b", "dtheta_b", "theta_r", "psi", "lat_acc", "theta_v_meas",
    ],
    "controller": ["theta_v_hat", "theta_ref", "delta_a_cmd", "solver_status"],
    "actuator": [
        "delta_a", "delta_a_ref", "motor_torque", "motor_speed", "motor_current", "dc_power",
        "phase_current_peak", "v_dc", "chopper_power", "actuator_limits",
    ],
    "links": ["rx_actuator_command", "rx_bar_angle", "rx_measurement", "rx_bar_twist"],
}
GROUP_OF = {c: g for g, cols in GROUPS.items() for c in cols}
TIME_COLUMNS = ("time", "t")


def fail(msg: str) -> None:
    print(f"to-rerun: {msg}", file=sys.stderr)
    sys.exit(2)


def read_table(path: Path):
    """The header and the rows of timeseries.csv as floats ('NaN' stays NaN)."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        fail(f"{path}: {e}")
    if len(rows) < 2:
        fail(f"{path}: no rows (a run's timeseries.csv has a header and one row per tick)")
    header, body = rows[0], rows[1:]
    for i, r in enumerate(body):
        if len(r) != len(header):
            fail(f"{path}: line {i + 2}: {len(r)} fields, the header has {len(header)}")
    try:
        data = np.array(body, dtype=np.float64)
    except ValueError as e:
        fail(f"{path}: a field that is not a number ({e})")
    return header, data


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", type=Path, help="a finished run's output directory")
    ap.add_argument("--out", type=Path, help="the .rrd to write (default DIR/run.rrd)")
    a = ap.parse_args()
    ts = a.dir / "timeseries.csv"
    header, data = read_table(ts)
    time_col = next((c for c in TIME_COLUMNS if c in header), None)
    if time_col is None:
        fail(f"{ts}: no time column (one of {', '.join(TIME_COLUMNS)})")
    time = data[:, header.index(time_col)]
    out = a.out or a.dir / "run.rrd"
    name = a.dir.resolve().name
    rec = rr.RecordingStream("tiltsim", recording_id=f"tiltsim-{name}")
    rec.save(str(out))
    times = [rr.TimeColumn("sim_time", duration=time)]
    for i, col in enumerate(header):
        if col in TIME_COLUMNS or col == "step":
            continue
        path = f"/{GROUP_OF.get(col, 'run')}/{col}"
        rec.send_columns(path, indexes=times, columns=rr.Scalars.columns(scalars=data[:, i]))
    ev = a.dir / "events.csv"
    if ev.is_file():
        with open(ev, newline="") as f:
            for e in csv.DictReader(f):
                when = next((e[c] for c in TIME_COLUMNS if c in e), None)
                if when is None:
                    fail(f"{ev}: no time column (one of {', '.join(TIME_COLUMNS)})")
                rec.set_time("sim_time", duration=float(when))
                text = f"{e['source']} {e['event']}: {e['detail']}".strip()
                rec.log("/events", rr.TextLog(text))
    rec.flush()
    print(f"wrote {out} ({len(time)} rows, {len(header) - 2} signals on the sim_time timeline)")


if __name__ == "__main__":
    main()
