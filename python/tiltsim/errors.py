"""The exceptions tiltsim raises, one class per kind of failure.

Each carries the message the command line prints for the same failure: the file, the field
and what is allowed for bad input; the participant and the step for a failed run.
"""

from __future__ import annotations

from typing import Any


class TiltsimError(Exception):
    """Base class of tiltsim's errors (not of :class:`Interrupted`)."""


class ScenarioError(TiltsimError, ValueError):
    """Invalid input: a scenario, a setting or an argument. The message names the file (or
    ``<dict>``/``<string>``), the field and what is allowed."""


class ParticipantError(TiltsimError, RuntimeError):
    """A run failed: a participant died, stalled or sent bad data, or an output could not be
    written. ``result`` holds what was recorded up to the failure (``None`` when the run
    could not start)."""

    def __init__(self, message: str, result: Any = None) -> None:
        super().__init__(message)
        self.result = result


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (or a progress callback that raised) stopped a run, sweep or comparison.
    ``result`` holds what had finished: the rows recorded so far, or the samples that had
    ended. A subclass of ``KeyboardInterrupt``, so ``except Exception`` does not swallow it."""

    def __init__(self, message: str, result: Any = None) -> None:
        super().__init__(message)
        self.result = result
