#!/usr/bin/env python3
"""Writes a finished tiltsim run as a Rerun recording (.rrd) whose signals plot over
simulated time: every column of DIR/timeseries.csv as a Rerun `Scalars` series on the
`sim_time` timeline, grouped by participant (/plant, /actuator, /controller, /links), and the
run's events (DIR/events.csv) as text logs at their ticks. Simulated time is exact: a row's
`sim_time` is its `step` times the base tick `run.dt_s` (DIR/scenario.toml) in whole
nanoseconds, integer arithmetic throughout, never seconds multiplied by 1e9 and truncated.

    python scripts/to-rerun.py DIR [--out FILE.rrd]     # default DIR/run.rrd
    rerun DIR/run.rrd

Needs the `rerun-sdk` and `numpy` packages (scripts/fmi-requirements.txt pins the versions
the tests use). Rerun reads MCAP files too, but keeps JSON messages such as run.mcap's as
opaque bytes; this route gives it plottable scalars.
"""

import argparse
import csv
import sys
import tomllib
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


def tick_ns(run_dir: Path, header, data) -> int:
    """The base tick in whole ns: `run.dt_s` of DIR/scenario.toml, else the table's first step."""
    sc = run_dir / "scenario.toml"
    dt_s = None
    if sc.is_file():
        try:
            with open(sc, "rb") as f:
                dt_s = tomllib.load(f).get("run", {}).get("dt_s")
        except (OSError, tomllib.TOMLDecodeError) as e:
            fail(f"{sc}: {e}")
    if dt_s is None:
        if len(data) < 2:
            fail(f"{run_dir}: no scenario.toml and a single row: the tick is unknown")
        t = data[:, header.index(next(c for c in TIME_COLUMNS if c in header))]
        dt_s = float(t[1] - t[0])
    # dt_s is the double nearest a decimal number of seconds; its whole ns are the nearest.
    return round(float(dt_s) * 1e9)


def sim_time_ns(header, data, dt_ns: int):
    """Each row's simulated time in ns, step·dt as integers (int64). Tables of tiltsim 0.1
    (`step,t,...`) held the outputs after tick `step`, at (step + 1)·dt."""
    steps = data[:, header.index("step")].astype(np.int64)
    if "time" not in header:
        steps = steps + 1
    return steps * np.int64(dt_ns)


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
    if "step" not in header:
        fail(f"{ts}: no step column")
    dt_ns = tick_ns(a.dir, header, data)
    ns = sim_time_ns(header, data, dt_ns)
    out = a.out or a.dir / "run.rrd"
    name = a.dir.resolve().name
    rec = rr.RecordingStream("tiltsim", recording_id=f"tiltsim-{name}")
    rec.save(str(out))
    times = [rr.TimeColumn("sim_time", duration=ns.astype("timedelta64[ns]"))]
    for i, col in enumerate(header):
        if col in TIME_COLUMNS or col == "step":
            continue
        path = f"/{GROUP_OF.get(col, 'run')}/{col}"
        rec.send_columns(path, indexes=times, columns=rr.Scalars.columns(scalars=data[:, i]))
    ev = a.dir / "events.csv"
    if ev.is_file():
        with open(ev, newline="") as f:
            for e in csv.DictReader(f):
                if "step" not in e:
                    fail(f"{ev}: no step column")
                # An event is at the start of its tick: step·dt, as events.csv's time.
                when = np.timedelta64(int(e["step"]) * dt_ns, "ns")
                rec.set_time("sim_time", duration=when)
                text = f"{e['source']} {e['event']}: {e['detail']}".strip()
                rec.log("/events", rr.TextLog(text))
    rec.flush()
    print(f"wrote {out} ({len(ns)} rows, {len(header) - 2} signals on the sim_time timeline)")


if __name__ == "__main__":
    main()
