"""Sweeps, comparisons and the linear design from Python against the command line."""

from __future__ import annotations

import json
import os
import signal
import threading
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import tiltsim
from conftest import tiltsim_cli


def read(path: Path) -> pd.DataFrame:
    return pd.read_csv(path, float_precision="round_trip", keep_default_na=False,
                       na_values=["NaN", "nan"])


def test_a_monte_carlo_sweep_is_the_command_lines_byte_for_byte(tmp_path: Path) -> None:
    tiltsim_cli("sweep", "scenarios/paper-lqg.toml", "--samples", "4", "--seed", "3",
                "--jobs", "2", "--out", str(tmp_path / "cli"), "--quiet")
    df, series = tiltsim.sweep("scenarios/paper-lqg.toml", samples=4, seed=3, jobs=2,
                               out=tmp_path / "py", series=True)
    for name in ("samples.csv", "series.csv", "table.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    cli = read(tmp_path / "cli" / "samples.csv")
    assert list(df.columns) == list(cli.columns)
    pd.testing.assert_frame_equal(df, cli, check_dtype=False)
    cli_series = read(tmp_path / "cli" / "series.csv")
    pd.testing.assert_frame_equal(series, cli_series, check_dtype=False)
    # The factors spread the masses: the samples differ.
    assert df["p_ct_en12299_standing_pct"].nunique() == 4


def test_a_grid_sweep_without_a_directory_leaves_no_file(tmp_path: Path) -> None:
    before = set(os.listdir(os.environ.get("TMPDIR", "/tmp")))
    df = tiltsim.sweep("scenarios/paper-lqg.toml", grid="links.actuator_command.delay_ticks=0,20")
    assert list(df["links.actuator_command.delay_ticks"]) == [0.0, 20.0]
    assert list(df["status"]) == ["completed", "completed"]
    # A delay on the command makes the ride worse.
    assert df["p_ct_en12299_standing_pct"][1] > df["p_ct_en12299_standing_pct"][0]
    after = set(os.listdir(os.environ.get("TMPDIR", "/tmp")))
    assert not [n for n in after - before if n.startswith("tiltsim-py-")]
    # The same grid as a pair and as a dict.
    df2 = tiltsim.sweep("scenarios/paper-lqg.toml",
                        grid=("links.actuator_command.delay_ticks", [0, 20]))
    pd.testing.assert_frame_equal(df, df2)


def test_an_interrupted_sweep_stops_and_keeps_the_samples_that_finished() -> None:
    def progress(done: int, total: int) -> None:
        if done >= 1:
            # What Ctrl-C does in a notebook: SIGINT, through Python's handler. Raised in this
            # thread, the handler runs before the call returns: the KeyboardInterrupt comes out
            # of this callback while the sweep runs, whichever thread the kernel would have
            # chosen for a signal sent to the process.
            signal.raise_signal(signal.SIGINT)

    # Python's handler even where the interpreter started with SIGINT ignored (a background
    # job), which leaves it ignored.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(tiltsim.Interrupted) as e:
            tiltsim.sweep("scenarios/paper-lqg.toml", samples=200, seed=3, jobs=2,
                          progress=progress)
    finally:
        signal.signal(signal.SIGINT, previous)
    partial = e.value.result
    assert isinstance(e.value, KeyboardInterrupt)
    assert 1 <= len(partial) < 200
    assert (partial["status"] == "completed").all()


def test_a_callback_that_raises_interrupts_a_run_and_keeps_its_rows() -> None:
    def progress(done: int, total: int) -> None:
        if done > 3000:
            raise KeyboardInterrupt

    with pytest.raises(tiltsim.Interrupted) as e:
        tiltsim.run("scenarios/paper-lqg.toml", transport="in-process", progress=progress)
    r = e.value.result
    assert r.status == "interrupted"
    assert 3000 < len(r) < 16801


def test_compare_gives_the_command_lines_table(tmp_path: Path) -> None:
    files = ["scenarios/paper-passive.toml", "scenarios/paper-lqg.toml"]
    tiltsim_cli("compare", *files, "--transport", "in-process", "--out", str(tmp_path / "cli"))
    df = tiltsim.compare(files, transport="in-process", out=tmp_path / "py")
    for name in ("table.csv", "columns.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()
    # Tidy and exact: every number of the table, parsed by Python's float, is in the frame.
    table = tmp_path / "cli" / "table.csv"
    cli = pd.read_csv(table, dtype=str, keep_default_na=False)
    for c in ("value", "paper", "difference"):
        cli[c] = [float(v) if v else float("nan") for v in cli[c]]
    pd.testing.assert_frame_equal(df, cli)
    assert df["value"].dtype == np.float64
    # What a notebook user gets with the readers' defaults: `value` is a float column.
    assert pd.read_csv(table)["value"].dtype == np.float64
    import polars as pl

    assert pl.read_csv(table)["value"].dtype == pl.Float64
    # Every metric has a unit and a meaning beside the table.
    units = pd.read_csv(tmp_path / "cli" / "columns.csv", dtype=str, keep_default_na=False)
    described = set(units[units["file"] == "table.csv"]["column"])
    assert set(df.columns) <= described
    assert set(df["metric"]) <= described
    lqg = df[(df["run"] == "paper-lqg") & (df["metric"] == "lat_acc_peak_pct_g")]
    assert lqg["paper"].iloc[0] == 9.796
    assert lqg["difference"].iloc[0] == lqg["value"].iloc[0] - 9.796
    assert (tmp_path / "py" / "paper-lqg" / "timeseries.csv").exists()
    # Without a directory: the same table, no files.
    pd.testing.assert_frame_equal(tiltsim.compare(files, transport="in-process"), cli)
    # One path is not a list of scenarios (it would be taken letter by letter).
    with pytest.raises(TypeError, match="compare: scenarios: a list of scenarios"):
        tiltsim.compare(files[0])


def expm(a: np.ndarray) -> np.ndarray:
    """exp(a) by scaling and squaring of its Taylor series (independent of tiltsim's)."""
    s = max(0, int(np.ceil(np.log2(max(np.linalg.norm(a, 1), 1e-300)))) + 1)
    b = a / 2.0**s
    out, term = np.eye(len(a)), np.eye(len(a))
    for k in range(1, 30):
        term = term @ b / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def test_linearize_gives_the_design_model_and_gains_as_arrays(tmp_path: Path) -> None:
    lin = tiltsim.linearize("scenarios/paper-lqg.toml")
    assert lin.A.shape == (9, 9) and lin.B.shape == (9, 1) and lin.Gamma.shape == (9, 6)
    assert lin.K.shape == (1, 10) and lin.L.shape == (9, 1)
    tiltsim_cli("linearize", "scenarios/paper-lqg.toml", "--out", str(tmp_path / "lin.json"))
    cli = json.loads((tmp_path / "lin.json").read_text())
    np.testing.assert_array_equal(lin.A, np.array(cli["continuous"]["A"]))
    np.testing.assert_array_equal(lin.K, np.array(cli["lqg"]["K_op"]))
    # The zero-order hold: Ad = exp(A T), checked against an independent matrix exponential
    # (the series' rounding is far below 1e-9 of the entries).
    np.testing.assert_allclose(lin.Ad, expm(lin.A * lin.period_s), rtol=1e-9, atol=1e-12)
    # The passive vehicle is stable; the Kalman filter's error dynamics A - L C are too.
    assert np.linalg.eigvals(lin.A).real.max() < 0
    assert np.linalg.eigvals(lin.A - lin.L @ lin.C).real.max() < 0
    mpc = tiltsim.linearize("scenarios/paper-mpc.toml")
    assert mpc.K is None and mpc.L is not None and mpc.period_s == 0.05


def test_falsify_gives_the_command_lines_worst_trace_and_progress(tmp_path: Path) -> None:
    bounds = tmp_path / "b.toml"
    bounds.write_text("[actuator_command]\ndelay_ms = [0, 40]\njitter_ms = 10\n")
    tiltsim_cli("falsify", "scenarios/paper-lqg.toml", "--bounds", str(bounds),
                "--set", "run.duration_s=2", "--budget", "4", "--jobs", "2",
                "--out", str(tmp_path / "cli"), "--quiet")
    trace, worst, progress = tiltsim.falsify(
        "scenarios/paper-lqg.toml",
        {"actuator_command": {"delay_ms": [0, 40], "jitter_ms": 10}},
        budget=4, jobs=1, set={"run.duration_s": 2})
    assert trace.encode() == (tmp_path / "cli" / "worst" / "timing.csv").read_bytes()
    want = read(tmp_path / "cli" / "progress.csv")
    assert list(progress["method"]) == list(want["method"])
    np.testing.assert_array_equal(progress["best_so_far"], want["best_so_far"])
    cli = json.loads((tmp_path / "cli" / "result.json").read_text())
    assert worst["worst_metric"] == cli["worst_metric"]
    with pytest.raises(tiltsim.ScenarioError, match="delay_ms"):
        tiltsim.falsify("scenarios/paper-lqg.toml",
                        {"actuator_command": {"delay_ms": [9, 1]}}, budget=2)



def test_falsify_takes_the_command_lines_requirements_margin_and_shards(tmp_path: Path) -> None:
    bounds = tmp_path / "b.toml"
    bounds.write_text("[measurement]\ndelay_ms = [0, 60]\n")
    reqs = ["p_ct < 25.48", "always |lat_acc| < 100", "valid"]
    args = [a for r in reqs for a in ("--requirement", r)]
    cli_out = tmp_path / "cli"
    p = tiltsim_cli("falsify", "scenarios/paper-lqg.toml", "--bounds", str(bounds), "--set",
                    "run.duration_s=7", "--budget", "4", "--jobs", "2", *args, "--margin",
                    "--margin-steps", "1", "--out", str(cli_out), "--quiet", check=False)
    cli = json.loads((cli_out / "result.json").read_text())
    assert p.returncode == (3 if cli["violated"] else 0), p.stderr
    _, worst, progress = tiltsim.falsify(
        "scenarios/paper-lqg.toml", bounds, requirement=reqs, budget=4, jobs=1,
        set={"run.duration_s": 7}, margin=(4.0, 1))
    for key in ("requirements", "sensitivity", "timing_margin", "margin", "verdict"):
        assert worst[key] == cli[key], key
    assert [r["requirement"] for r in worst["requirements"]] == [
        "p_ct_en12299_standing_pct < 25.48", "always |lat_acc| < 100", "valid"]
    want = read(cli_out / "progress.csv")
    np.testing.assert_array_equal(progress["margin"], want["margin"])
    assert list(progress["violated"]) == list(want["violated"])
    shard = tmp_path / "shard"
    tiltsim.falsify("scenarios/paper-lqg.toml", bounds, requirement="valid", budget=4,
                    set={"run.duration_s": 2}, shard="1/2", out=shard)
    assert json.loads((shard / "result.json").read_text())["shard"] == "1/2"
    for bad, match in [({"margin": (0.5, 1)}, "margin"), ({"shard": "3/2"}, "shard"),
                       ({"restarts": 0}, "restarts")]:
        with pytest.raises((tiltsim.ScenarioError, TypeError, ValueError), match=match):
            tiltsim.falsify("scenarios/paper-lqg.toml", bounds, requirement="valid", budget=4,
                            **bad)
    with pytest.raises(tiltsim.ScenarioError, match="`wobble` is not a signal"):
        tiltsim.falsify("scenarios/paper-lqg.toml", bounds, requirement=["always wobble < 1"])


SMALL_LINE = """# two curves between three straights
chainage_m,length_m,radius_m,cant_mm,transition_m,shape,vmax_conventional_kmh,vmax_tilting_kmh
0,3000,,,,,160,200
3000,700,1100,130,120,clothoid,160,200
3700,1500,,,,,160,200
5200,600,-800,150,140,cosine,130,150
5800,2500,,,,,160,200
"""


def test_a_route_gives_the_per_transition_table_of_the_command_line(tmp_path: Path) -> None:
    line = tmp_path / "small.csv"
    line.write_text(SMALL_LINE)
    scenario = "scenarios/tilting-pi-drive.toml"
    tiltsim_cli("route", str(line), scenario, "--jobs", "2", "--out", str(tmp_path / "cli"),
                "--quiet")
    df, details = tiltsim.route(line, [scenario], jobs=2, out=tmp_path / "py", details=True)
    assert (tmp_path / "py" / "transitions.csv").read_bytes() == \
        (tmp_path / "cli" / "transitions.csv").read_bytes()
    cli = read(tmp_path / "cli" / "transitions.csv")
    assert list(df.columns) == list(cli.columns)
    pd.testing.assert_frame_equal(df, cli, check_dtype=False)
    # Two curves, an entry and an exit each, at the chainages the file gives.
    assert list(df["chainage_m"]) == [3000.0, 3580.0, 5200.0, 5660.0]
    assert list(df["transition"]) == ["entry", "exit", "entry", "exit"]
    # The first curve runs at its cant deficiency limit, √(g·R·(h + 275 mm)/1500 mm); the
    # second's local limit binds (150 km/h is under its cant deficiency speed, 169.8 km/h).
    assert df["binding"][0].startswith("cant deficiency")
    assert df["speed_kmh"][0] == pytest.approx(3.6 * (9.81 * 1100 * 405 / 1500) ** 0.5)
    assert df["binding"][2].startswith("speed limit")
    assert df["speed_kmh"][2] == pytest.approx(150.0)
    journey = details["journey"]
    assert journey["tilting_s"] < journey["conventional_s"]
    assert details["variants"][0]["segments"] > 2


def test_a_bad_route_names_its_line_and_field(tmp_path: Path) -> None:
    line = tmp_path / "bad.csv"
    line.write_text(SMALL_LINE.replace("cosine", "spiral"))
    with pytest.raises(tiltsim.ScenarioError, match=r"bad.csv:6: shape: `spiral`"):
        tiltsim.route(line, ["scenarios/tilting-pi-drive.toml"])
