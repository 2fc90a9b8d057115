"""The extension module under ``tiltsim`` (Rust, through PyO3). Call the package's functions
(:func:`tiltsim.run`, ...) rather than these: they take the scenario as ``(kind, value,
origin)`` and settings as text, as the package hands them over."""

from typing import Any, Callable, Optional


__version__: str
BUILD: str

class Rows:
    """The rows of a run; the arrays of ``run``'s ``columns`` view them in place."""

def run(
    kind: str,
    value: str,
    origin: str,
    settings: list[tuple[str, str]],
    out: Optional[str] = None,
    transport: Optional[str] = None,
    master: Optional[str] = None,
    seed: Optional[int] = None,
    duration: Optional[float] = None,
    record: bool = False,
    plots: bool = False,
    exe: Optional[str] = None,
    progress: Optional[Callable[[int, int], Any]] = None,
    execution: Optional[str] = None,
    replay_trace: Optional[str] = None,
) -> dict[str, Any]:
    """``{"summary": JSON text, "columns": {name: read-only array}, "out_dir": str | None,
    "library_s": float}``."""

def sweep(
    kind: str,
    value: str,
    origin: str,
    settings: list[tuple[str, str]],
    samples: Optional[int] = None,
    spread: float = 0.22,
    seed: int = 1,
    grid: Optional[tuple[str, list[float]]] = None,
    jobs: Optional[int] = None,
    transport: Optional[str] = None,
    out: Optional[str] = None,
    exe: Optional[str] = None,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> dict[str, Any]:
    """``{"samples": {column: array or list}, "series": {column: array}, "interrupted": bool,
    "out_dir": str | None}``."""

def compare(
    scenarios: list[tuple[str, str, str]],
    transport: Optional[str] = None,
    out: Optional[str] = None,
    exe: Optional[str] = None,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> dict[str, Any]:
    """``{"table_csv": str, "summaries": [JSON text], "notes": [str], "out_dir": str | None}``."""

def linearize(kind: str, value: str, origin: str, settings: list[tuple[str, str]]) -> str:
    """The report of ``tiltsim linearize`` as JSON text."""

def signals() -> list[tuple[str, str, str]]:
    """``(name, unit, description)`` of every column of a run's time series."""

def parse_grid(spec: str) -> tuple[str, list[float]]:
    """``KEY=START:STOP:STEP`` or ``KEY=V1,V2,...`` as ``(key, values)``."""

def cli(argv: list[str]) -> int:
    """The command line with ``argv`` (program name first); its exit code."""

def falsify(
    kind: str,
    value: str,
    origin: str,
    settings: list[tuple[str, str]],
    bounds: str,
    bounds_origin: str,
    objective: Optional[str] = None,
    requirement: Optional[list[str]] = None,
    budget: int = 200,
    seed: int = 1,
    jobs: Optional[int] = None,
    out: Optional[str] = None,
    shard: Optional[str] = None,
    restarts: Optional[int] = None,
    margin: Optional[tuple[float, int]] = None,
) -> dict[str, Any]: ...

def route(
    route: str,
    scenarios: list[tuple[str, str, str]],
    rho: Optional[list[float]] = None,
    cd_tilting: Optional[list[float]] = None,
    cd_conventional: float = 150.0,
    accel: float = 0.5,
    brake: float = 0.6,
    running: Optional[str] = None,
    jobs: Optional[int] = None,
    transport: Optional[str] = None,
    out: Optional[str] = None,
    exe: Optional[str] = None,
) -> dict[str, Any]: ...
