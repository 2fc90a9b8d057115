"""Shared fixtures: the repository, the command-line executable the package is checked against,
and a scratch directory per test."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def cli_exe() -> str:
    """The Rust ``tiltsim`` executable: ``TILTSIM_CLI`` (set by the suite's tests/outside/pytest/python.rs),
    else the release build in this repository. Missing, the tests fail naming it."""
    exe = os.environ.get("TILTSIM_CLI") or str(ROOT / "target" / "release" / "tiltsim")
    if not os.access(exe, os.X_OK):
        pytest.fail(
            f"the tiltsim executable {exe} is missing: build it with `cargo build --release` "
            "or set TILTSIM_CLI"
        )
    return exe


def tiltsim_cli(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    """Runs the command line from the repository's root."""
    p = subprocess.run(
        [cli_exe(), *args], cwd=ROOT, capture_output=True, text=True, timeout=None
    )
    if check and p.returncode != 0:
        pytest.fail(f"tiltsim {' '.join(args)} exited {p.returncode}:\n{p.stderr}")
    return p


@pytest.fixture
def root() -> Path:
    return ROOT


@pytest.fixture(autouse=True)
def in_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """Scenario paths in the tests are relative to the repository."""
    monkeypatch.chdir(ROOT)
