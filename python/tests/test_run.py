"""A run from Python against the command line's files: the same values, bit for bit."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tiltsim
from conftest import tiltsim_cli

# Summary keys that hold wall-clock measurements (summary.json lists them itself).
def deterministic(summary: dict) -> dict:
    out = json.loads(json.dumps(summary))
    for key in summary["wall_clock_fields"]:
        parts = key.split(".")
        nodes = [out]
        for p in parts[:-1]:
            nxt = []
            for n in nodes:
                v = n.get(p)
                nxt.extend(v if isinstance(v, list) else [v])
            nodes = [n for n in nxt if isinstance(n, dict)]
        for n in nodes:
            n.pop(parts[-1], None)
    for k in ("scenario_file", "wall_clock_fields", "ipc_prefix", "leftover_ipc_files"):
        out.pop(k, None)
    return out


def read_timeseries(path: Path) -> pd.DataFrame:
    # The shortest round-trip text of each double reads back to the same double.
    return pd.read_csv(path, float_precision="round_trip")


def test_run_arrays_equal_the_command_lines_timeseries_value_for_value(tmp_path: Path) -> None:
    setting = "controller.mpc.output_weight=5"
    tiltsim_cli("run", "scenarios/paper-mpc.toml", "--transport", "in-process", "--set",
                setting, "--out", str(tmp_path / "cli"), "--quiet")
    cli = read_timeseries(tmp_path / "cli" / "timeseries.csv")
    r = tiltsim.run("scenarios/paper-mpc.toml", set={"controller.mpc.output_weight": 5.0},
                    transport="in-process")
    assert r.out_dir is None
    assert r.status == "completed"
    assert list(r.signals) == list(cli.columns)
    assert len(r) == len(cli) == 16801
    for name in cli.columns:
        a = r[name]
        b = cli[name].to_numpy()
        assert a.dtype.kind == b.dtype.kind or (a.dtype.kind == "u" and b.dtype.kind == "i"), name
        # Bit for bit: NaN where NaN, every other value identical.
        np.testing.assert_array_equal(a, b.astype(a.dtype), err_msg=name, strict=False)
    assert r.time[9] == 0.009
    # The comfort and flags are the command line's, key for key.
    cli_summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert deterministic(r.summary) == deterministic(cli_summary)
    assert r.comfort == cli_summary["comfort"]
    assert r.flags == cli_summary["flags"]
    assert r.raised_flags == [k for k, v in cli_summary["flags"].items() if v["raised"]]
    # The frame holds the same values, indexed by time, with the units beside it.
    f = r.frame()
    pd.testing.assert_frame_equal(f, cli.set_index("time"), check_dtype=False)
    assert f.index.name == "time" and f.index[9] == 0.009
    assert f.attrs["units"]["lat_acc"] == r.units["lat_acc"] != ""
    # A notebook shows the run as a table naming its scenario and its EN 12299 comfort.
    html = r._repr_html_()
    assert "paper-mpc" in html and "EN 12299" in html and "<table>" in html
    p = r.comfort["p_ct_en12299"]["standing_pct"]
    assert f"{p:.2f} %" in html


def test_polars_reads_the_table_with_its_default_type_inference(tmp_path: Path) -> None:
    import polars as pl

    tiltsim_cli("run", "scenarios/paper-passive.toml", "--transport", "in-process",
                "--out", str(tmp_path / "run"), "--quiet")
    r = tiltsim.run("scenarios/paper-passive.toml", transport="in-process")
    # Defaults: types guessed from the first 100 rows, where many float columns are whole
    # numbers (zero before the curve); each must still come out as floats, value for value.
    table = pl.read_csv(tmp_path / "run" / "timeseries.csv")
    assert table.columns == list(r.signals)
    for name in r.signals:
        want = r[name]
        if want.dtype.kind == "f":
            assert table.schema[name] == pl.Float64, name
        np.testing.assert_array_equal(table[name].to_numpy(), want, err_msg=name, strict=False)


def test_arrays_are_read_only_views_of_the_runs_rows_not_copies() -> None:
    r = tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", duration=0.5)
    t, lat = r.time, r.lat_acc
    # One buffer for every signal: each array steps through it a whole row at a time.
    assert t.strides == lat.strides == r.step.strides
    assert t.strides[0] > 8 * 20
    assert t.base is not None and t.base is lat.base
    assert not lat.flags.writeable
    with pytest.raises(ValueError):
        lat[0] = 1.0
    # The views stay valid after the result goes (the buffer lives with them).
    kept = r.theta_v
    del r
    assert np.isfinite(kept).all() and len(kept) == 501


def test_a_run_writes_the_command_lines_files_when_given_a_directory(tmp_path: Path) -> None:
    tiltsim_cli("run", "scenarios/paper-lqg.toml", "--transport", "in-process", "--duration",
                "2", "--out", str(tmp_path / "cli"), "--quiet")
    r = tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", duration=2.0,
                    out=tmp_path / "py")
    assert r.out_dir == tmp_path / "py"
    for name in ("timeseries.csv", "events.csv", "columns.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    np.testing.assert_array_equal(r.theta_v, read_timeseries(tmp_path / "py" / "timeseries.csv")["theta_v"])


def test_ipc_transport_gives_the_in_process_values() -> None:
    a = tiltsim.run("scenarios/paper-lqg.toml", transport="ipc", duration=1.0)
    b = tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", duration=1.0)
    assert a.summary["transport"] == "ipc"
    assert [p["process"] for p in a.summary["participants"]] == [
        "plant-proc", "actuator-proc", "controller-proc"]
    for name in a.signals:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_a_scenario_as_a_dict_or_toml_text_runs_as_the_file_does(root: Path) -> None:
    import tomllib

    text = (root / "scenarios" / "paper-lqg.toml").read_text()
    from_file = tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", duration=1.0)
    from_text = tiltsim.run(text, transport="in-process", duration=1.0)
    from_dict = tiltsim.run(tomllib.loads(text), transport="in-process", duration=1.0)
    for other in (from_text, from_dict):
        for name in from_file.signals:
            np.testing.assert_array_equal(other[name], from_file[name], err_msg=name)


def test_the_gil_is_released_while_a_run_computes() -> None:
    counts: list[int] = []
    stop = threading.Event()
    counter = [0]

    def spin() -> None:
        while not stop.is_set():
            counter[0] += 1

    # Samples of the other thread's count, taken from the progress callback (which holds
    # the GIL): between two of them only the simulation ran on this thread.
    def progress(done: int, total: int) -> None:
        counts.append(counter[0])

    th = threading.Thread(target=spin)
    th.start()
    try:
        tiltsim.run("scenarios/paper-mpc.toml", transport="in-process", progress=progress)
    finally:
        stop.set()
        th.join()
    assert len(counts) >= 2, counts
    # Held, the lock would freeze the other thread for the whole run: no count between the
    # first callback and the last.
    assert counts[-1] - counts[0] > 1000, counts


def test_progress_reports_ticks_up_to_the_whole_run() -> None:
    seen: list[tuple[int, int]] = []
    tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", duration=2.0,
                progress=lambda d, n: seen.append((d, n)))
    assert seen[-1] == (2000, 2000)
    assert all(a[0] <= b[0] for a, b in zip(seen, seen[1:]))


def test_nothing_is_printed_to_standard_output(capfd: pytest.CaptureFixture[str]) -> None:
    tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", duration=0.2)
    tiltsim.sweep("scenarios/paper-lqg.toml", samples=2, seed=3, jobs=1)
    out, _ = capfd.readouterr()
    assert out == ""


def test_the_whole_car_from_python_is_the_command_lines_and_not_the_half_vehicle(
    tmp_path: Path,
) -> None:
    """`vehicle.model = "full"` set from Python steps the whole car: its summary carries the
    running safety of the four wheelsets and the comfort along the car, the command line's key
    for key; the half vehicle's run has neither and another body roll."""
    tiltsim_cli("run", "scenarios/paper-mpc.toml", "--transport", "in-process", "--set",
                "vehicle.model=full", "--set", "run.duration_s=8", "--out",
                str(tmp_path / "cli"), "--quiet")
    full = tiltsim.run("scenarios/paper-mpc.toml",
                       set={"vehicle.model": "full", "run.duration_s": 8.0},
                       transport="in-process")
    half = tiltsim.run("scenarios/paper-mpc.toml", set={"run.duration_s": 8.0},
                       transport="in-process")
    safety = full.summary["full_car"]["running_safety"]
    assert [q["quantity"] for q in safety] == ["(Y/Q)_2m", "(SumY)_2m", "dQ/Q0", "Y_qst", "Q_qst"]
    # Eight seconds reach 2.6 s into the steady curve: every wheel force is there.
    assert all(q["value"] > 0 for q in safety), safety
    assert len(full.summary["full_car"]["comfort_along_car"]) == 3
    assert "full_car" not in half.summary
    assert not np.array_equal(full["theta_v"], half["theta_v"])
    cli_summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert deterministic(full.summary) == deterministic(cli_summary)
