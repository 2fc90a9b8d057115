"""Reads a run's and a sweep's tables as a notebook user would, with pandas and FMPy, and
prints what it found as JSON: the columns that clash with a pandas DataFrame attribute, the
units columns.csv gives, the first time and the time step, and whether FMPy's own CSV reader
takes timeseries.csv (it needs a `time` column).

    python pandas_check.py RUN_DIR SWEEP_DIR
"""

import json
import sys
from pathlib import Path

import pandas as pd
from fmpy.util import read_csv


def main():
    run, sweep = Path(sys.argv[1]), Path(sys.argv[2])
    reserved = set(dir(pd.DataFrame))
    clashes = []
    tables = {
        "timeseries.csv": run / "timeseries.csv",
        "events.csv": run / "events.csv",
        "samples.csv": sweep / "samples.csv",
        "series.csv": sweep / "series.csv",
        "table.csv": sweep / "table.csv",
    }
    frames = {name: pd.read_csv(path) for name, path in tables.items()}
    for name, df in frames.items():
        clashes += [f"{name}:{c}" for c in df.columns if c in reserved]
    ts = frames["timeseries.csv"]
    units = pd.concat([pd.read_csv(run / "columns.csv"), pd.read_csv(sweep / "columns.csv")])
    unit = units.set_index(["file", "column"])["unit"]
    missing = [
        f"{name}:{c}"
        for name, df in frames.items()
        if name != "table.csv"
        for c in df.columns
        if (name, c) not in unit.index
    ]
    series = frames["series.csv"]
    first = series[series["sample_id"] == series["sample_id"].iloc[0]]
    fmpy_rows = read_csv(str(tables["timeseries.csv"]))
    print(json.dumps({
        "clashes": clashes,
        "missing_units": missing,
        "first_column": list(ts.columns[:2]),
        "time0": float(ts["time"].iloc[0]),
        "time_at_9ms": repr(float(ts["time"].iloc[9])),
        "lat_acc_unit": unit[("timeseries.csv", "lat_acc")],
        "time_unit": unit[("timeseries.csv", "time")],
        "p_ct_unit": unit[("samples.csv", "p_ct_en12299_standing_pct")],
        "series_columns": list(series.columns),
        "series_times": [repr(float(t)) for t in first["time"].iloc[:4]],
        "series_points": int(len(first)),
        "fmpy_rows": int(len(fmpy_rows)),
        "fmpy_time0": float(fmpy_rows["time"][0]),
    }))


if __name__ == "__main__":
    main()
