"""Exceptions with messages meant for the user: one line that says what is wrong and how to fix it."""

from __future__ import annotations


class AcaError(Exception):
    """Base class of all errors aca_warp reports to a user (the CLI prints them as one line)."""


class SceneError(AcaError, ValueError):
    """A scene, patch file or command-line option is invalid; raised before any simulation starts."""


class StabilityError(AcaError, ValueError):
    """An explicit step exceeds the solver's stable-step estimate (pass ``force=True`` to run anyway)."""


class SimulationFault(AcaError, RuntimeError):
    """The simulation produced a non-finite value; carries where and when.

    Attributes:
        time: Simulated time of the first sample at which the fault was seen [s].
        pad: Index of the pad in the batch.
        patch: Index of the first faulty patch within its pad.
        cause: Likely cause, in words.
    """

    def __init__(self, message: str, *, time: float, pad: int, patch: int, cause: str) -> None:
        super().__init__(message)
        self.time = time
        self.pad = pad
        self.patch = patch
        self.cause = cause
