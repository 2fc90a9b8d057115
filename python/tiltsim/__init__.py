"""tiltsim for notebooks: run, sweep and compare tilt-control studies of a railway vehicle.

The simulations run in this process through tiltsim's library crates (the same code as the
``tiltsim`` command line, byte for byte the same numbers). The interpreter's lock is released
while they run; Ctrl-C stops them within a second and raises :class:`Interrupted`.

    >>> import tiltsim
    >>> r = tiltsim.run("scenarios/paper-mpc.toml", set={"controller.mpc.output_weight": 5.0})
    >>> r.time, r.lat_acc             # NumPy arrays, one value per row (SI units)
    >>> r.comfort["p_ct_en12299"]["standing_pct"], r.raised_flags
    >>> df = r.frame()                # a pandas DataFrame (pandas optional)

A scenario is a path to a TOML file, TOML text, or a dict of the same tables.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import sys
import sysconfig
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _tiltsim
from .errors import Interrupted, ParticipantError, ScenarioError, TiltsimError

__all__ = [
    "run",
    "replay_timing",
    "sweep",
    "falsify",
    "route",
    "compare",
    "linearize",
    "signals",
    "Result",
    "Linearization",
    "TiltsimError",
    "ScenarioError",
    "ParticipantError",
    "Interrupted",
]

__version__: str = _tiltsim.__version__

Scenario = Union[str, "os.PathLike[str]", Mapping[str, Any]]
Progress = Union[None, bool, Callable[[int, int], Any]]


def _scenario(scenario: Scenario) -> tuple[str, str, str]:
    """(kind, value, origin) of a scenario given as a path, TOML text or a dict."""
    if isinstance(scenario, Mapping):
        try:
            text = json.dumps(scenario, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise ScenarioError(
                f"<dict>: {e}: allowed numbers, strings, booleans, lists and dicts"
            ) from None
        return ("json", text, "<dict>")
    if isinstance(scenario, os.PathLike):
        p = os.fspath(scenario)
        return ("file", str(p), str(p))
    if isinstance(scenario, str):
        if "\n" in scenario or ("=" in scenario and not os.path.exists(scenario)):
            return ("toml", scenario, "<string>")
        return ("file", scenario, scenario)
    raise ScenarioError(
        f"scenario: a {type(scenario).__name__}: allowed a path, TOML text or a dict"
    )


def _setting_text(key: str, v: Any) -> str:
    """A setting's value as the command line's ``--set KEY=VALUE`` writes it."""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_setting_text(key, x) for x in v) + "]"
    raise ScenarioError(
        f"set {key}: {v!r}: allowed a number, a word, True/False or a list of numbers"
    )


def _settings(set: Optional[Mapping[str, Any]]) -> list[tuple[str, str]]:
    if set is None:
        return []
    if not isinstance(set, Mapping):
        raise ScenarioError(f"set: a {type(set).__name__}: allowed a dict of KEY: VALUE")
    return [(str(k), _setting_text(str(k), v)) for k, v in set.items()]


def _participant_exe() -> Optional[str]:
    """The ``tiltsim`` command that serves participant processes (the IPC transport): the
    one named by ``TILTSIM_PARTICIPANT_EXE``, else this package's own."""
    named = os.environ.get("TILTSIM_PARTICIPANT_EXE")
    if named:
        return named
    for scripts in (sysconfig.get_path("scripts"), os.path.dirname(sys.executable)):
        found = shutil.which("tiltsim", path=scripts)
        if found:
            return found
    return None


class _Bar:
    """A progress bar: tqdm's when it is installed, else a line on standard error."""

    def __init__(self, unit: str) -> None:
        self.unit = unit
        self.bar: Any = None
        self.last = -1

    def __call__(self, done: int, total: int) -> None:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            percent = done * 100 // max(total, 1)
            if percent != self.last:
                self.last = percent
                sys.stderr.write(f"\r{percent:3d} % of {total} {self.unit}")
                if done >= total:
                    sys.stderr.write("\n")
                sys.stderr.flush()
            return
        if self.bar is None:
            self.bar = tqdm(total=total, unit=self.unit)
        self.bar.update(done - self.bar.n)
        if done >= total:
            self.bar.close()


def _progress(progress: Progress, unit: str) -> Optional[Callable[[int, int], Any]]:
    if progress is None or progress is False:
        return None
    if progress is True:
        return _Bar(unit)
    if callable(progress):
        return progress
    raise ScenarioError(f"progress: {progress!r}: allowed None, True or a callable(done, total)")


def _fspath(f: str, name: str, p: Any) -> str:
    """Argument ``name`` of ``f`` as a path; a TypeError naming it for anything else."""
    try:
        return os.fspath(p)
    except TypeError:
        raise TypeError(
            f"{f}: {name}: a path (a str or an os.PathLike), not {p!r} ({type(p).__name__})"
        ) from None


def _frame(columns: Mapping[str, Any]) -> Any:
    """A pandas DataFrame of the columns, or the dict itself when pandas is not installed."""
    try:
        import pandas as pd
    except ImportError:
        return dict(columns)
    return pd.DataFrame(dict(columns))


_SIGNALS: list[tuple[str, str, str]] = [tuple(s) for s in _tiltsim.signals()]  # type: ignore[misc]


def signals() -> list[tuple[str, str, str]]:
    """Every recorded signal of a run as ``(name, unit, description)``, in column order
    (the columns of ``timeseries.csv``; units as in ``columns.csv``)."""
    return list(_SIGNALS)


class Result:
    """One run: its recorded signals as NumPy arrays and its summary.

    Every signal of :func:`signals` is an attribute (``r.lat_acc``) and an item
    (``r["lat_acc"]``): a read-only array with one value per row, row 0 at the start time and
    row k+1 after tick k. The arrays view the rows the run recorded in place (no copy).
    """

    def __init__(self, raw: Mapping[str, Any]) -> None:
        self._columns: dict[str, np.ndarray] = dict(raw["columns"])
        #: The run's summary (the content of ``summary.json``), keys carrying their units.
        self.summary: dict[str, Any] = json.loads(raw["summary"])
        #: The directory the run wrote, or None for a run that kept no files.
        self.out_dir: Optional[Path] = Path(raw["out_dir"]) if raw.get("out_dir") else None
        #: Seconds the library spent in the call (from reading the scenario to the analysed
        #: summary, temporary files removed): the rest of the call's time is the Python side's
        #: (its arguments, the result's arrays, the summary's JSON).
        self.library_s: float = float(raw.get("library_s", float("nan")))

    @property
    def time(self) -> np.ndarray:
        """Simulated time of each row (s)."""
        return self._columns["time"]

    @property
    def signals(self) -> tuple[str, ...]:
        """The names of the recorded signals, in column order."""
        return tuple(self._columns)

    @property
    def units(self) -> dict[str, str]:
        """The unit of each signal (ASCII symbols; ``1`` a pure number, empty for a code)."""
        return {name: unit for name, unit, _ in _SIGNALS}

    @property
    def status(self) -> str:
        """How the run ended: ``completed``, ``degraded``, ``failed`` or ``interrupted``."""
        return str(self.summary["status"])

    @property
    def comfort(self) -> dict[str, Any]:
        """Ride comfort: P_CT (standing and seated, %), lateral acceleration and roll speed
        statistics, as in ``summary.json``."""
        return dict(self.summary.get("comfort") or {})

    @property
    def flags(self) -> dict[str, dict[str, Any]]:
        """The validity checks, each with ``raised`` and its measures (oscillation, bump
        stop, drive limit, chopper, thermal, P_CT range)."""
        return dict(self.summary.get("flags") or {})

    @property
    def raised_flags(self) -> list[str]:
        """The names of the flags this run raised. Some make its comfort not valid (see
        :attr:`valid`); the others (bump stop, drive limit, chopper, thermal) are physics of
        the run worth knowing."""
        return [k for k, v in self.flags.items() if isinstance(v, dict) and v.get("raised")]

    @property
    def valid(self) -> bool:
        """Completed, and its comfort describes a working tilt system answering the run's
        question (``summary["comfort_valid"]``: no oscillation, P_CT within the formula's
        range, real time kept), as the terminal report judges it."""
        return self.status == "completed" and bool(self.summary.get("comfort_valid"))

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._columns[name]
        except KeyError:
            raise KeyError(f"{name!r}: not a signal; the signals are {', '.join(self._columns)}") from None

    def __getattr__(self, name: str) -> np.ndarray:
        columns = self.__dict__.get("_columns", {})
        if name in columns:
            return columns[name]
        raise AttributeError(f"{type(self).__name__} has no attribute or signal {name!r}")

    def __dir__(self) -> Iterable[str]:
        return sorted(set(super().__dir__()) | set(self._columns))

    def __len__(self) -> int:
        return len(self.time)

    def frame(self) -> Any:
        """The signals as a pandas DataFrame indexed by simulated time (index ``time``, s),
        one column per other signal; pandas copies them. ``frame().attrs["units"]`` gives
        each column's unit. Raises ImportError when pandas is not installed."""
        import pandas as pd

        columns = {k: v for k, v in self._columns.items() if k != "time"}
        f = pd.DataFrame(columns, index=pd.Index(self.time, name="time"))
        f.attrs["units"] = {k: u for k, u in self.units.items() if k in columns}
        return f

    def _repr_html_(self) -> str:
        """A notebook's view: the run, its status, its comfort (EN 12299 first) and its flags."""
        from html import escape

        def pct(method: str, where: str) -> str:
            v = (self.comfort.get(method) or {}).get(where)
            return f"{v:.2f} %" if isinstance(v, (int, float)) else "n/a"

        verdict = "valid" if self.valid else "<b>NOT VALID</b>"
        rows = [
            ("status", escape(self.status)),
            ("rows", f"{len(self)} ({self.time[-1]:.3f} s)" if len(self) else "0"),
            ("P<sub>CT</sub> standing (EN 12299)", pct("p_ct_en12299", "standing_pct")),
            ("P<sub>CT</sub> seated (EN 12299)", pct("p_ct_en12299", "seated_pct")),
            ("P<sub>CT</sub> standing (the paper's form)", pct("p_ct_paper", "standing_pct")),
            ("comfort", verdict),
            ("flags raised", escape(", ".join(self.raised_flags)) or "none"),
        ]
        if self.out_dir is not None:
            rows.append(("files", escape(str(self.out_dir))))
        body = "".join(f"<tr><th style='text-align:left'>{k}</th><td>{v}</td></tr>" for k, v in rows)
        title = escape(str(self.summary.get("scenario")))
        return f"<table><caption>tiltsim run <code>{title}</code></caption>{body}</table>"

    def __repr__(self) -> str:
        p = (self.comfort.get("p_ct_en12299") or {}).get("standing_pct")
        p_text = f", P_CT standing (EN 12299) {p:.2f} %" if isinstance(p, (int, float)) else ""
        if p_text and not self.valid:
            # As the terminal report: a number under a raised flag is not a result.
            p_text += " NOT VALID"
        flags = ", flags: " + ", ".join(self.raised_flags) if self.raised_flags else ""
        return (
            f"<tiltsim.Result {self.summary.get('scenario')!r}: {self.status}, {len(self)} rows"
            f"{p_text}{flags}>"
        )


def run(
    scenario: Scenario,
    *,
    set: Optional[Mapping[str, Any]] = None,
    transport: Optional[str] = None,
    master: Optional[str] = None,
    seed: Optional[int] = None,
    duration: Optional[float] = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    record: bool = False,
    plots: bool = False,
    progress: Progress = None,
    raise_on_failure: bool = True,
    execution: Optional[str] = None,
) -> Result:
    """Runs a scenario, as ``tiltsim run`` does, and returns its :class:`Result`.

    ``execution`` is ``"lock-step"`` or ``"free"`` (every participant on its own clock over
    ``transport="ipc"``; the timing goes to ``timing.csv`` in ``out``, which
    :func:`replay_timing` replays exactly). A free run that fell behind real time has the
    ``not real-time`` flag raised and ``valid`` False.

    ``set`` changes scenario values by dotted key (``{"controller.mpc.output_weight": 5.0}``).
    ``transport`` is ``"in-process"`` or ``"ipc"`` (participants as processes over shared
    memory); ``master`` ``"gauss-seidel"`` or ``"jacobi"``; ``seed`` and ``duration`` (s)
    override the file's. With ``out`` the run writes its files there (``timeseries.csv``,
    ``summary.json``, ``events.csv``, and with ``plots`` its figures, with ``record`` its
    ``run.mcap``); without, it leaves no file. ``progress`` is True for a bar or a
    callable(done, total) called with ticks done.

    Raises :class:`ScenarioError` for invalid input, :class:`ParticipantError` when the run
    fails (its ``result`` holds what was recorded; with ``raise_on_failure=False`` the
    result is returned instead) and :class:`Interrupted` on Ctrl-C.
    """
    kind, value, origin = _scenario(scenario)
    raw = _tiltsim.run(
        kind,
        value,
        origin,
        _settings(set),
        out=out,
        transport=transport,
        master=master,
        seed=seed,
        duration=duration,
        record=record,
        plots=plots,
        exe=_participant_exe(),
        progress=_progress(progress, "ticks"),
        execution=execution,
    )
    return _checked(Result(raw), raise_on_failure)


def replay_timing(
    run_dir: Union[str, "os.PathLike[str]"],
    *,
    scenario: Optional[Scenario] = None,
    transport: Optional[str] = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    plots: bool = False,
    progress: Progress = None,
    raise_on_failure: bool = True,
) -> Result:
    """Replays the timing a free run recorded in ``run_dir/timing.csv`` exactly, in
    lock-step, as ``tiltsim replay-timing`` does; returns its :class:`Result`, whose rows are
    the free run's bit for bit. ``scenario`` (default: ``run_dir/scenario.toml``) may be
    another system, which then sees the same timing. A partial trace (a free run that
    ended early or was killed) is replayed as far as it goes; ``summary["trace_partial"]``
    says what it lacked. ``out`` as for :func:`run`.
    """
    run_dir = _fspath("replay_timing", "run_dir", run_dir)
    kind, value, origin = _scenario(
        scenario if scenario is not None else os.path.join(run_dir, "scenario.toml")
    )
    raw = _tiltsim.run(
        kind,
        value,
        origin,
        [],
        out=out,
        transport=transport or "in-process",
        plots=plots,
        exe=_participant_exe(),
        progress=_progress(progress, "ticks"),
        replay_trace=os.path.join(run_dir, "timing.csv"),
    )
    return _checked(Result(raw), raise_on_failure)


def _checked(result: Result, raise_on_failure: bool) -> Result:
    s = result.summary
    if result.status == "interrupted":
        raise Interrupted(
            f"interrupted: {s.get('steps_completed')} of {s.get('steps_planned')} steps recorded",
            result,
        )
    if result.status == "failed" and raise_on_failure:
        raise ParticipantError(
            f"{s.get('error') or 'run failed'}; {s.get('steps_completed')} of "
            f"{s.get('steps_planned')} steps recorded",
            result,
        )
    return result


def sweep(
    scenario: Scenario,
    *,
    samples: Optional[int] = None,
    spread: float = 0.22,
    seed: int = 1,
    grid: Union[None, str, tuple[str, Sequence[float]], Mapping[str, Sequence[float]]] = None,
    set: Optional[Mapping[str, Any]] = None,
    jobs: Optional[int] = None,
    transport: Optional[str] = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    series: bool = False,
    progress: Progress = None,
) -> Any:
    """Runs many samples in parallel, as ``tiltsim sweep`` does; returns their table (the
    columns of ``samples.csv``: ``sample_id``, the parameters, ``status``, every comfort
    metric, ``validity_flags``) as a DataFrame (a dict of arrays without pandas).

    Either ``samples=N`` (Monte Carlo: uniform factors of half-width ``spread`` on masses,
    inertias and suspension, drawn from ``seed``) or ``grid``: ``"KEY=START:STOP:STEP"``,
    ``"KEY=V1,V2"``, ``(KEY, values)`` or ``{KEY: values}``. ``jobs`` parallel runs (default:
    the CPUs). With ``out`` the sweep writes its files there (the same bytes as the command
    line). With ``series=True`` returns ``(samples, series)``, ``series`` being the tidy
    lateral acceleration (``sample_id``, ``time``, ``lat_acc``) every 10 ms.

    Raises :class:`Interrupted` on Ctrl-C, its ``result`` holding the samples that had
    finished.
    """
    kind, value, origin = _scenario(scenario)
    if isinstance(grid, str):
        grid = _tiltsim.parse_grid(grid)
    elif isinstance(grid, Mapping):
        if len(grid) != 1:
            raise ScenarioError(f"grid: {len(grid)} keys: allowed one KEY: values")
        grid = next(iter(grid.items()))
    if grid is not None:
        try:
            key, values = grid
            grid = (str(key), [float(v) for v in values])
        except (TypeError, ValueError):
            raise TypeError(
                'sweep: grid: "KEY=START:STOP:STEP", "KEY=V1,V2", (KEY, values) or '
                f"{{KEY: values}} with numbers for values, not {grid!r}"
            ) from None
    raw = _tiltsim.sweep(
        kind,
        value,
        origin,
        _settings(set),
        samples=samples,
        spread=spread,
        seed=seed,
        grid=grid,
        jobs=jobs,
        transport=transport,
        out=out,
        exe=_participant_exe(),
        progress=_progress(progress, "samples"),
    )
    table = _frame(raw["samples"])
    result = (table, _frame(raw["series"])) if series else table
    if raw["interrupted"]:
        n = len(raw["samples"]["sample_id"])
        raise Interrupted(f"interrupted: {n} samples had finished", result)
    return result


def route(
    route_file: Union[str, "os.PathLike[str]"],
    scenarios: Sequence[Scenario] = (),
    *,
    rho: Optional[Sequence[float]] = None,
    cd_tilting: Optional[Sequence[float]] = None,
    cd_conventional: float = 150.0,
    accel: float = 0.5,
    brake: float = 0.6,
    running: Optional[str] = None,
    jobs: Optional[int] = None,
    transport: Optional[str] = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    details: bool = False,
) -> Any:
    """Runs scenarios over a whole line, as ``tiltsim route`` does; returns the table of every
    transition of every variant (the columns of ``transitions.csv``: ``variant``,
    ``controller``, ``rho``, ``running``, ``curve``, ``transition``, ``chainage_m``,
    ``radius_m``, ``cant_mm``, ``shape``, ``speed_kmh``, ``cant_deficiency_mm``,
    ``p_ct_standing_pct``, ..., ``binding``) as a DataFrame (a dict of arrays without pandas).

    ``route_file`` is a route CSV (docs/scenarios.md, "Routes"); each scenario (a path, TOML
    text or a dict) runs on the conventional profile if passive, else on the tilting one
    (``running`` = ``"conventional"`` or ``"tilting"`` for all); ``rho`` and ``cd_tilting``
    (mm) are lists each tilting scenario runs at. With ``out`` the study writes its files
    there. With ``details=True`` returns ``(transitions, details)``, ``details`` holding
    ``variants`` (each variant's summary: journey time, P_CT under each reading, N_MV, the
    motion-sickness doses) and ``journey`` (the two profiles' journey times).
    """
    raw = _tiltsim.route(
        route_file,
        [_scenario(s) for s in scenarios],
        rho=rho,
        cd_tilting=cd_tilting,
        cd_conventional=cd_conventional,
        accel=accel,
        brake=brake,
        running=running,
        jobs=jobs,
        transport=transport,
        out=out,
        exe=_participant_exe(),
    )
    table = _frame(raw["transitions"])
    if details:
        return table, {"variants": raw["variants"], "journey": raw["journey"]}
    return table


def falsify(
    scenario: Scenario,
    bounds: Union[str, "os.PathLike[str]", Mapping[str, Mapping[str, Any]]],
    *,
    objective: Optional[str] = None,
    requirement: Union[None, str, Sequence[str]] = None,
    budget: Optional[int] = None,
    seed: int = 1,
    set: Optional[Mapping[str, Any]] = None,
    jobs: Optional[int] = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    shard: Optional[str] = None,
    restarts: Optional[int] = None,
    margin: Union[bool, tuple[float, int]] = False,
) -> tuple[str, dict, Any]:
    """Searches the admissible timing for the one that hurts the ride most, as ``tiltsim
    falsify`` does: the obvious adversaries, CMA-ES from the best of them and an evolution of
    the timing histories, against uniform random sampling with the same ``budget`` (default:
    from the number of coordinates searched, as ``tiltsim falsify``).

    ``bounds``: a bounds file's path, or a dict per link
    (``{"actuator_command": {"delay_ms": [0, 60], "jitter_ms": 10, "loss_pct": 1}}``).
    ``objective``: a metric to maximise (default ``p_ct``); or ``requirement``, one or a
    list judged all at once, whose margin is minimised: on a metric (``"p_ct < 35"``), on
    validity (``"valid"``, ``"no flags"``, ``"no oscillation"``) or on signals over time
    (``"always |lat_acc| < 1.2"``); ``worst["requirements"]`` gives each one's margin and
    whether it holds at the worst timing. ``margin=True`` (or ``(largest scale, bisection
    steps)``, default ``(4, 4)``) adds the requirements' timing margin
    (``worst["timing_margin"]``, as ``--margin``); ``shard="I/N"`` runs one shard of the search
    and ``restarts=N`` the N shards in one process, as ``--shard`` and ``--restarts``.
    ``worst["sensitivity"]`` gives each bound's share of the worst timing. Returns ``(trace, worst, progress)``: the
    worst timing as ``timing.csv`` text (``tiltsim replay-timing`` replays it), the worst
    result (``result.json``'s fields) and every evaluation of both methods as a DataFrame
    (a dict of arrays without pandas). With ``out`` the files stay there.
    """
    kind, value, origin = _scenario(scenario)
    if margin is True:
        margin = (4.0, 4)
    elif margin is False:
        margin = None
    if isinstance(bounds, Mapping):
        lines = []
        for link, fields in bounds.items():
            lines.append(f"[{link}]")
            for k, v in fields.items():
                lines.append(f"{k} = {_setting_text(str(k), v)}")
        text, bounds_origin = "\n".join(lines) + "\n", "<bounds dict>"
    else:
        bounds_origin = _fspath("falsify", "bounds", bounds)
        try:
            text = Path(bounds_origin).read_text()
        except OSError as e:
            raise ScenarioError(f"{bounds_origin}: {e}") from None
    raw = _tiltsim.falsify(
        kind,
        value,
        origin,
        _settings(set),
        text,
        bounds_origin,
        objective=objective,
        requirement=requirement,
        budget=budget,
        seed=seed,
        jobs=jobs,
        out=out,
        shard=shard,
        restarts=restarts,
        margin=margin,
    )
    worst = dict(raw["worst"])
    for key in ("requirements", "sensitivity", "timing_margin"):
        if isinstance(worst.get(key), str):
            worst[key] = json.loads(worst[key])
    return raw["trace"], worst, _frame(raw["progress"])


def compare(
    scenarios: Sequence[Scenario],
    *,
    transport: Optional[str] = None,
    out: Union[None, str, "os.PathLike[str]"] = None,
    progress: Progress = None,
) -> Any:
    """Runs each scenario and lays them out like the paper's Table 4, as ``tiltsim compare``
    does: the rows of its ``table.csv``, tidy (one row per metric and run: every comfort
    metric for each controller and the ideal tilt, the differences to the ideal tilt, the
    numbers behind the validity flags and the trade-off) as a DataFrame (a dict of lists
    without pandas). ``value``, ``paper`` and ``difference`` are floats, read exactly (NaN
    where the table has no number); ``metric`` is a key whose unit and meaning the
    ``columns.csv`` beside ``table.csv`` gives (and ``unit`` on every row). Pivot with
    ``df.pivot_table(index="metric", columns="run", values="value", aggfunc="first")``.
    With ``out`` the runs, tables and figures stay there.
    """
    if isinstance(scenarios, (str, bytes, os.PathLike)):
        raise TypeError(
            "compare: scenarios: a list of scenarios (paths, TOML texts or dicts), not one "
            f"{type(scenarios).__name__}; for one scenario use tiltsim.run, or pass [{scenarios!r}]"
        )
    specs = [_scenario(s) for s in scenarios]
    raw = _tiltsim.compare(
        specs,
        transport=transport,
        out=out,
        exe=_participant_exe(),
        progress=_progress(progress, "runs"),
    )
    for note in raw["notes"]:
        sys.stderr.write(f"note: {note}\n")
    return _compare_table(raw["table_csv"])


# The columns of a compare's table.csv that hold numbers (an empty cell: none).
_COMPARE_NUMBERS = ("value", "paper", "difference")


def _compare_table(text: str) -> Any:
    """A compare's ``table.csv`` text as a DataFrame (a dict of lists without pandas): its
    numbers parsed by Python's ``float``, which reads shortest round-trip text exactly, the
    other columns as text ("" where empty)."""
    import csv

    reader = csv.reader(io.StringIO(text))
    header = next(reader, [])
    rows = list(reader)
    table: dict = {c: [r[i] for r in rows] for i, c in enumerate(header)}
    for c in _COMPARE_NUMBERS:
        if c in table:
            table[c] = [float(v) if v else float("nan") for v in table[c]]
    try:
        import pandas as pd
    except ImportError:
        return table
    df = pd.DataFrame(table, columns=header)
    for c in _COMPARE_NUMBERS:
        if c in df:
            df[c] = df[c].astype("float64")
    return df


class Linearization:
    """The design model of a scenario and its controller's gains (``tiltsim linearize``).

    ``A``, ``B``, ``G`` (Γ, the disturbance input), ``C``: the continuous model of the nine
    states; ``Ad``, ``Bd``, ``Gd``, ``Cd`` its zero-order-hold discretisation at the
    controller's period; ``K`` the state-feedback gain and ``L`` the estimator gain of an
    LQG (``L`` alone for an MPC's Kalman filter; None where the controller has none).
    ``report`` is the whole report as a dict.
    """

    def __init__(self, report: dict[str, Any]) -> None:
        self.report = report
        cont, disc = report["continuous"], report["discrete"]
        self.A, self.B, self.G, self.C = (np.array(cont[k], dtype=float) for k in "ABGC")
        self.Ad, self.Bd, self.Gd, self.Cd = (np.array(disc[k], dtype=float) for k in "ABGC")
        self.period_s: float = float(disc["period_s"])
        self.states: list[str] = list(report["states"])
        lqg, mpc = report.get("lqg"), report.get("mpc")
        self.K: Optional[np.ndarray] = np.array(lqg["K_op"], dtype=float) if lqg else None
        if lqg:
            self.L: Optional[np.ndarray] = np.array(lqg["K_est"], dtype=float)
        elif mpc:
            self.L = np.array(mpc["L_est"], dtype=float)
        else:
            self.L = None

    @property
    def Gamma(self) -> np.ndarray:
        """Γ, the disturbance input matrix (the same as ``G``)."""
        return self.G

    def __repr__(self) -> str:
        gains = [n for n in ("K", "L") if getattr(self, n) is not None]
        return f"<tiltsim.Linearization {self.report.get('scenario')!r}: 9 states, gains {gains}>"


def linearize(scenario: Scenario, *, set: Optional[Mapping[str, Any]] = None) -> Linearization:
    """The design model and the controller's gains of a scenario, as ``tiltsim linearize``
    reports them, as NumPy arrays (:class:`Linearization`): A, B, Γ (``G``), C of the nine
    states, their zero-order-hold discretisation at the controller's period, and K and L
    (LQG state feedback and Kalman gain; L alone for the MPC's Kalman filter), ready for
    python-control (``control.ss(lin.A, lin.B, lin.C, 0)``). ``set`` changes scenario
    values by dotted key as in :func:`run`."""
    kind, value, origin = _scenario(scenario)
    return Linearization(json.loads(_tiltsim.linearize(kind, value, origin, _settings(set))))
