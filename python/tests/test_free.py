"""Free runs and their lock-step replays from Python: the same pipeline, the same files and
the same bytes as the command line."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import tiltsim
from conftest import tiltsim_cli


def test_a_free_run_from_python_replays_bit_for_bit_and_as_the_command_line_does(
    tmp_path: Path,
) -> None:
    free_dir = tmp_path / "free"
    r = tiltsim.run("scenarios/pi-drive.toml", execution="free", transport="ipc",
                    duration=2.0, out=free_dir, raise_on_failure=False)
    assert r.status == "completed", r.summary.get("error")
    assert r.summary["execution"] == "free"
    # The command line's files: the recorded timing, perf.json with the wall-clock values.
    for name in ("timeseries.csv", "timing.csv", "summary.json", "perf.json", "scenario.toml"):
        assert (free_dir / name).is_file(), name
    perf = json.loads((free_dir / "perf.json").read_text())
    assert perf, "perf.json is empty"
    # Whether the plant kept real time depends on the machine; the judgement is always there,
    # and a run that did not keep it is not a valid result.
    assert "not_real_time" in r.flags
    if r.flags["not_real_time"]["raised"]:
        assert not r.valid
        assert "NOT VALID" in repr(r)
    else:
        assert r.valid and "NOT VALID" not in repr(r), r.raised_flags

    replayed = tiltsim.replay_timing(free_dir, out=tmp_path / "py-replay")
    assert replayed.summary["execution"] == "replay-timing"
    assert replayed.summary.get("trace_partial") is None
    # The replay keeps the free run's judgement on real time, made from the same trace.
    assert replayed.flags["not_real_time"]["raised"] == r.flags["not_real_time"]["raised"]
    assert replayed.valid == r.valid
    # The replay in lock-step computes the free run's rows exactly.
    assert len(replayed) == len(r) == 2001
    for name in r.signals:
        np.testing.assert_array_equal(replayed[name], r[name], err_msg=name, strict=True)
    # And the command line's replay of the same trace writes the same bytes.
    tiltsim_cli("replay-timing", str(free_dir), "--out", str(tmp_path / "cli-replay"), "-q")
    for name in ("timeseries.csv", "events.csv"):
        assert (tmp_path / "py-replay" / name).read_bytes() == (
            tmp_path / "cli-replay" / name
        ).read_bytes(), name
    assert (tmp_path / "py-replay" / "timeseries.csv").read_bytes() == (
        free_dir / "timeseries.csv"
    ).read_bytes()


def test_a_free_run_too_large_for_the_disk_is_refused_before_anything_runs(
    tmp_path: Path,
) -> None:
    out = tmp_path / "huge"
    # An hour at 10 us is 3.6e8 rows of about 670 B: over 300 GB, as the command line says.
    free = shutil.disk_usage(tmp_path).free
    assert free < 300e9, f"this check needs less than 300 GB free under {tmp_path}, has {free}"
    with pytest.raises(tiltsim.ScenarioError, match="free on the disk") as refused:
        tiltsim.run("scenarios/pi-drive.toml", execution="free", transport="ipc",
                    duration=3600.0, set={"run.dt_s": 1e-5}, out=out)
    assert "360000000 steps" in str(refused.value)
    assert not out.exists() or not any(out.iterdir())


def test_replaying_a_directory_without_a_timing_trace_names_the_file(tmp_path: Path) -> None:
    lock = tmp_path / "lock"
    tiltsim.run("scenarios/pi-drive.toml", transport="in-process", duration=0.5, out=lock)
    with pytest.raises(tiltsim.ScenarioError, match="timing.csv"):
        tiltsim.replay_timing(lock)
