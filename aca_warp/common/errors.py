"""Exceptions with messages meant for the user: one line that says what is wrong and how to fix it.

The command line prints an :class:`AcaError` as one ``aca-warp: error:`` line and exits with its
``exit_code`` (docs/faults.md): 2 bad input, 3 unphysical result, 4 the output could not be written.

A message that names an option names it the way its reader passes it: as a Python parameter (``overwrite=True``)
from the Python API, as a flag (``--overwrite``) from the command line, which runs its commands inside
:func:`command_line`, and as a key of the sweep spec while a spec is read (:func:`sweep_spec`, entered by
``aca_warp.sweep.load_spec``) where the option has one there; messages build the name with :func:`option`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from contextlib import contextmanager

_readers = ["python"]  # who reads the messages, innermost last: "command line" (command_line()), "sweep" (sweep_spec())


def option(python: str, flag: str, spec: str | None = None) -> str:
    """The name of an option in a message: ``python`` (a parameter, e.g. ``overwrite=True``) for the Python API,
    ``flag`` (e.g. ``--overwrite``) inside :func:`command_line`, ``spec`` (a key of the sweep spec, e.g.
    ``run.sample_dt``) inside :func:`sweep_spec` where given (else the name of the API or command line around it)."""
    if _readers[-1] == "sweep" and spec is not None:
        return spec
    return flag if "command line" in _readers else python


def with_article(noun: str) -> str:
    """``noun`` after its indefinite article, for a message: "a run file", "an LF run file"."""
    return f"{'an' if noun[:1] in 'aeiouAEIOU' or noun[:2] in ('LF', 'HF') else 'a'} {noun}"


def nearest(name: str, names: Iterable[str]) -> str | None:
    """The one of ``names`` nearest to a mistyped ``name`` (case aside; ``difflib``'s ratio ≥ 0.6), or None."""
    import difflib

    known = {str(n).lower(): str(n) for n in names}
    near = difflib.get_close_matches(str(name).lower(), list(known), n=1)
    return known[near[0]] if near else None


def did_you_mean(name: str, names: Iterable[str]) -> str:
    """The clause `` (did you mean 'X'?)`` for the one of ``names`` nearest to a mistyped ``name`` (:func:`nearest`),
    or ""."""
    near = nearest(name, names)
    return f" (did you mean {near!r}?)" if near is not None else ""


@contextmanager
def _read_by(reader: str) -> Iterator[None]:
    _readers.append(reader)
    try:
        yield
    finally:
        _readers.pop()


def command_line() -> contextlib.AbstractContextManager[None]:
    """Messages built in the body name options as command-line flags (:func:`option`)."""
    return _read_by("command line")


def sweep_spec() -> contextlib.AbstractContextManager[None]:
    """Messages built in the body (a sweep spec read and its scenes checked) name an option as the spec's key where
    it has one, else as its reader around passes it (:func:`option`)."""
    return _read_by("sweep")


class AcaError(Exception):
    """Base class of all errors aca_warp reports to a user (the CLI prints them as one line)."""

    exit_code = 2


class SceneError(AcaError, ValueError):
    """A scene, patch file or command-line option is invalid; raised before any simulation starts."""


class StabilityError(AcaError, ValueError):
    """An explicit step exceeds the solver's stable-step estimate (pass ``force=True`` to run anyway)."""


class PhysicsError(AcaError, ValueError):
    """A scene whose solution is not physical (e.g. normal forces that do not carry the load); exit 3."""

    exit_code = 3


class StorageError(AcaError):
    """An output could not be written: no space left on the device, a file-size limit or a disk quota; exit 4.

    The file being written is left as it was at its last flush (its last checkpoint), so the run resumes once
    there is room again."""

    exit_code = 4


class SimulationFault(AcaError, RuntimeError):
    """The simulation produced a non-finite value; carries where and when.

    Attributes:
        time: Simulated time of the first sample at which the fault was seen [s].
        pad: Index of the pad in the batch.
        patch: Index of the first faulty patch within its pad.
        cause: Likely cause, in words.
    """

    exit_code = 3

    def __init__(self, message: str, *, time: float, pad: int, patch: int, cause: str) -> None:
        super().__init__(message)
        self.time = time
        self.pad = pad
        self.patch = patch
        self.cause = cause
