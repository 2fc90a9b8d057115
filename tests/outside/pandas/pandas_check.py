"""Reads a run's and a sweep's tables as a notebook user would, with pandas and FMPy, and
prints what it found as JSON: the columns that clash with a pandas DataFrame attribute, the
units columns.csv gives, the first time and the time step, and whether FMPy's own CSV reader
takes timeseries.csv (it needs a `time` column).

With a compare's directory too, its tidy table.csv: the type pandas and polars give each
numeric column with their defaults, the table.csv columns and metrics columns.csv does not
describe, and the text of any `value` that is not a number.

    python pandas_check.py RUN_DIR SWEEP_DIR [COMPARE_DIR]
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
    found = {}
    if len(sys.argv) > 3:
        found = compare_table(Path(sys.argv[3]))
    print(json.dumps({
        **found,
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


def compare_table(cmp: Path) -> dict:
    import polars as pl

    table = cmp / "table.csv"
    df = pd.read_csv(table)
    pl_df = pl.read_csv(table)
    raw = pd.read_csv(table, dtype=str, keep_default_na=False)
    not_numbers = []
    for v in raw["value"]:
        try:
            float(v)
        except ValueError:
            not_numbers.append(v)
    units = pd.read_csv(cmp / "columns.csv", dtype=str, keep_default_na=False)
    described = set(units[units["file"] == "table.csv"]["column"])
    return {
        "compare_pandas_types": {c: str(df[c].dtype) for c in ("value", "paper", "difference")},
        "compare_polars_value": str(pl_df["value"].dtype),
        "compare_undescribed": sorted(
            (set(df.columns) | set(df["metric"])) - described
        ),
        "compare_not_numbers": not_numbers,
        "compare_rows": int(len(df)),
    }


if __name__ == "__main__":
    main()
