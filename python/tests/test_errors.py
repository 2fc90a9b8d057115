"""Bad input raises with the command line's message; the API is what its stubs say."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import tiltsim
from tiltsim import _tiltsim
from conftest import ROOT, tiltsim_cli


def test_an_invalid_scenario_file_raises_with_the_command_lines_message(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text((ROOT / "scenarios" / "paper-lqg.toml").read_text().replace(
        "period_s = 0.001", "period_s = -1.0"))
    with pytest.raises(tiltsim.ScenarioError) as e:
        tiltsim.run(bad)
    message = str(e.value)
    assert str(bad) in message and "controller.period_s" in message, message
    cli = tiltsim_cli("run", str(bad), "--out", str(tmp_path / "o"), check=False)
    assert cli.returncode == 2
    # The same words as the command line's, which starts them with "error: ".
    assert message in cli.stderr, (message, cli.stderr)
    assert isinstance(e.value, ValueError) and isinstance(e.value, tiltsim.TiltsimError)


def test_a_bad_setting_or_dict_names_the_field_and_what_is_allowed() -> None:
    with pytest.raises(tiltsim.ScenarioError, match=r"controller\.mode"):
        tiltsim.run("scenarios/paper-lqg.toml", set={"controller.mode": "fuzzy"})
    with pytest.raises(tiltsim.ScenarioError, match=r"no_such_key"):
        tiltsim.run("scenarios/paper-lqg.toml", set={"controller.no_such_key": 1})
    with pytest.raises(tiltsim.ScenarioError, match=r"<dict>.*run\.dt_s"):
        tiltsim.run({"run": {"dt_s": "fast"}})
    with pytest.raises(tiltsim.ScenarioError, match=r"transport.*in-process.*ipc"):
        tiltsim.run("scenarios/paper-lqg.toml", transport="udp")
    with pytest.raises(ValueError, match=r"sweep: samples: a whole number from 1 to 100000"):
        tiltsim.sweep("scenarios/paper-lqg.toml", samples=0)
    with pytest.raises(tiltsim.ScenarioError, match=r"no-such-file\.toml"):
        tiltsim.run("scenarios/no-such-file.toml")


def test_a_participant_that_dies_raises_participant_error_with_what_was_recorded() -> None:
    with pytest.raises(tiltsim.ParticipantError) as e:
        tiltsim.run("scenarios/fault-controller-killed.toml",
                    set={"faults.on_failure": "abort"}, transport="ipc")
    r = e.value.result
    assert r is not None and r.status == "failed"
    # Killed at 8 s: the rows up to then, and the message names the participant.
    assert 7.9 < r.time[-1] < 8.1
    assert "controller" in str(e.value)
    r = tiltsim.run("scenarios/fault-controller-killed.toml", set={"faults.on_failure": "abort"},
                    transport="ipc", raise_on_failure=False)
    assert r.status == "failed" and not r.valid


def stub_names(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    return {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))} | {
        t.id for n in tree.body if isinstance(n, ast.AnnAssign) for t in [n.target]
        if isinstance(t, ast.Name)}


def test_the_extension_modules_stubs_name_every_function_it_has() -> None:
    stub = Path(_tiltsim.__file__).with_name("_tiltsim.pyi")
    assert stub.exists(), "the wheel carries _tiltsim.pyi"
    names = {n for n in dir(_tiltsim) if not n.startswith("__")}
    # Rows is the type of the arrays' owner, never reached by name.
    stubbed = {n for n in stub_names(stub) if not n.startswith("__")} - {"Rows"}
    assert names == stubbed
    assert (Path(tiltsim.__file__).parent / "py.typed").exists()
    for f in (tiltsim.run, tiltsim.sweep, tiltsim.compare, tiltsim.linearize):
        assert f.__doc__ and len(f.__doc__) > 200, f.__name__


def test_the_package_command_is_the_command_line(tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("tiltsim")
    p = subprocess.run([str(exe), "validate", "scenarios/paper-lqg.toml"], cwd=ROOT,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    p = subprocess.run([str(exe), "run", "scenarios/no-such.toml"], cwd=ROOT,
                       capture_output=True, text=True)
    assert p.returncode == 2 and "no-such.toml" in p.stderr


@pytest.mark.parametrize(
    "call, error, words",
    [
        (lambda: tiltsim.run("scenarios/paper-lqg.toml", seed="abc"), TypeError,
         r"run: seed: a whole number from 0 to 18446744073709551615 \(an int\), not 'abc' \(str\)"),
        (lambda: tiltsim.run("scenarios/paper-lqg.toml", seed=-1), ValueError,
         r"run: seed: a whole number from 0 to .*, not -1 \(int\)"),
        (lambda: tiltsim.run("scenarios/paper-lqg.toml", duration="1"), TypeError,
         r"run: duration: a duration in s, a finite number \(an int or a float\), not '1' \(str\)"),
        (lambda: tiltsim.run("scenarios/paper-lqg.toml", transport=3), TypeError,
         r'run: transport: "in-process" or "ipc", not 3 \(int\)'),
        (lambda: tiltsim.run("scenarios/paper-lqg.toml", record="yes"), TypeError,
         r"run: record: True or False, not 'yes' \(str\)"),
        (lambda: tiltsim.run("scenarios/paper-lqg.toml", out=5), TypeError,
         r"run: out: a path \(a str or an os.PathLike\), not 5 \(int\)"),
        (lambda: tiltsim.sweep("scenarios/paper-lqg.toml", samples=2, seed=1.5), TypeError,
         r"sweep: seed: a whole number"),
        (lambda: tiltsim.sweep("scenarios/paper-lqg.toml", samples=2, jobs=0), ValueError,
         r"sweep: jobs: a whole number from 1 to 256 \(an int\), not 0 \(int\)"),
        (lambda: tiltsim.sweep("scenarios/paper-lqg.toml", samples="2"), TypeError,
         r"sweep: samples: a whole number"),
        (lambda: tiltsim.sweep("scenarios/paper-lqg.toml", grid=("k", ["a"])), TypeError,
         r"sweep: grid: "),
        (lambda: tiltsim.compare(["scenarios/paper-lqg.toml"], transport=1), TypeError,
         r"compare: transport: "),
        (lambda: tiltsim.falsify("scenarios/paper-lqg.toml",
                                 {"actuator_command": {"delay_ms": [0, 10]}}, seed="x"),
         TypeError, r"falsify: seed: a whole number"),
        (lambda: tiltsim.falsify("scenarios/paper-lqg.toml", 3), TypeError,
         r"falsify: bounds: a path"),
        (lambda: tiltsim.route("routes/x.csv", [], accel="fast"), TypeError,
         r"route: accel: an acceleration in m/s2, a finite number"),
        (lambda: tiltsim.route(7, []), TypeError, r"route: route_file: a path"),
        (lambda: tiltsim.replay_timing(7), TypeError, r"replay_timing: run_dir: a path"),
    ],
)
def test_an_argument_of_the_wrong_type_or_range_is_named_with_what_it_allows(
    call, error, words
) -> None:
    with pytest.raises(error, match=words):
        call()
