"""Interrupts of an ``aca-warp`` command: SIGINT (Ctrl-C) and SIGTERM end it like Ctrl-C, with one line and exit
130 or 143 (128 + the signal), the files it writes closed as described in docs/faults.md "Interrupts".

Python turns SIGINT into :class:`KeyboardInterrupt` at the next bytecode, anywhere; SIGTERM kills the process
outright by default, leaving a ``.partial`` and its lock behind. :func:`installed` (the command line's) makes both
raise: SIGINT a :class:`KeyboardInterrupt`, SIGTERM a :class:`Terminated` (a KeyboardInterrupt, so every writer that
closes its file after Ctrl-C does so after SIGTERM too). Writes that must not stop half-way (a chunk of samples
appended to several datasets, a checkpoint, the closing of a file) run inside :func:`deferred`: a signal that
arrives there is raised when the write is done. After the first interrupt has been raised, later signals are
ignored while the command closes its files (a second Ctrl-C would otherwise stop that clean-up half-way), except
inside :func:`second_signal_exits`, for a clean-up that may wait long (a sweep waits for its Dask workers): there a
second signal ends the process at once, with one line (one within :data:`SAME_SIGNAL_S` of the first is that one
delivered twice, as ``timeout -s INT`` does to the process and its group, and is ignored). An
interrupt raised while Python runs a finalizer (``__del__``, a weakref callback) is swallowed there by Python, which
prints it as "Exception ignored"; :func:`installed` catches it in ``sys.unraisablehook`` instead and raises it again
a millisecond later (a SIGALRM timer, the command's ``installed`` owns SIGALRM), from ordinary code; one that the
work never saw (its command ended within that millisecond, or code beyond ours dropped it) is reported at the exit
as a signal that did not stop the command (:func:`finished`). A write that completes the command's output (the swap
of ``/analysis``) runs inside :func:`deferred` with ``completes``: a signal that arrives there is reported the same
way, since the output it leaves is whole.
Without :func:`installed` (the Python API) Python's own SIGINT handling applies and :func:`deferred` defers nothing.

The end of a process: once a command's result is final, :func:`installed` (``hold=True``) leaves SIGINT and SIGTERM
recorded, not acted on (Python's default handlers would kill the process, or raise, in the middle of the
interpreter's shutdown, ≈ 0.5 s of clean-ups: exit −15 or −2, or 143 without a word), and :func:`exit_process` runs
the clean-ups (``atexit``), then ends the process with ``os._exit``: with the command's exit code, or with 128 + the
signal and one line when a signal came meanwhile.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, NoReturn

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Terminated(KeyboardInterrupt):
    """SIGTERM received: handled as Ctrl-C (files closed, marked interrupted), exit 143."""


@dataclass
class _State:
    installed: bool = False
    depth: int = 0  # nesting of deferred()
    pending: int | None = None  # a signal that arrived inside deferred()
    raised: bool = False  # the first interrupt has been raised: ignore the rest
    second_exits: bool = False  # ... or end the process at the second one (second_signal_exits)
    last: int | None = None  # the last signal received
    final: bool = False  # the command's result is final: signals are recorded only (finished())
    withheld: bool = False  # a finalizer swallowed the interrupt: it is raised again in a millisecond (_unraisable)
    raised_at: float = 0.0  # time.monotonic() of the first interrupt raised


_state = _State()


SAME_SIGNAL_S = 0.1  # a second signal this soon after the first is the same one, delivered twice [s]


def _interrupt(signum: int) -> KeyboardInterrupt:
    _state.raised = True
    _state.raised_at = time.monotonic()
    return Terminated("terminated (SIGTERM)") if signum == signal.SIGTERM else KeyboardInterrupt()


def _handler(signum: int, frame: object) -> None:
    if _state.final:
        _late.append(signum)
        return
    _state.last = signum
    if _state.raised:
        if _state.second_exits and time.monotonic() - _state.raised_at > SAME_SIGNAL_S:
            with contextlib.suppress(OSError):
                os.write(2, b"aca-warp: a second interrupt: stopped at once; the next run cleans up what it left\n")
            os._exit(128 + signum)
        return
    if _state.depth > 0:
        _state.pending = signum
        return
    raise _interrupt(signum)


def _again(signum: int, frame: object) -> None:
    """SIGALRM: deliver the interrupt a finalizer swallowed (:func:`_unraisable`)."""
    _state.withheld = False
    if _state.last is not None:
        _handler(_state.last, frame)


def _unraisable(previous: Callable[[Any], object]) -> Callable[[Any], None]:
    """A ``sys.unraisablehook`` that delivers again an interrupt a finalizer swallowed (module docstring)."""

    def hook(u: Any) -> None:
        if isinstance(u.exc_value, KeyboardInterrupt) and _state.installed and _state.last is not None:
            # it never reached the command: raise it again in a millisecond (SIGALRM, :func:`_again`), from
            # ordinary code; nothing here may block or run Python code that a signal could interrupt
            _state.raised = False
            _state.withheld = True
            signal.setitimer(signal.ITIMER_REAL, 1e-3)
            return
        previous(u)

    return hook


def exit_code(e: BaseException | None = None) -> int:
    """128 + the signal behind ``e`` (or the last one received): 130 for SIGINT, 143 for SIGTERM."""
    if isinstance(e, Terminated) or (e is None and _state.last == signal.SIGTERM):
        return 128 + signal.SIGTERM
    return 128 + signal.SIGINT


def received() -> int | None:
    """The last signal received while :func:`installed` was in effect, or None."""
    return _state.last


_late: list[int] = []  # signals received after the result was final (finished(), installed(hold=True))


def _record(signum: int, frame: object) -> None:
    _late.append(signum)


def finished(*, unseen: bool = True) -> None:
    """The command's result is final (its work done, or its error decided): from now on SIGINT and SIGTERM are only
    recorded, for :func:`exit_process` to report; nothing raises any more. With ``unseen`` (the command did not
    handle an interrupt itself), an interrupt its work never saw is recorded the same way: one a finalizer swallowed
    and not yet raised again (:func:`_unraisable`), or one that code beyond ours caught and dropped, so that the work
    went on to its end. The command's output is then whole, and the exit's line says that the signal did not stop it
    (an interrupt raised now would report the output of a command cut short)."""
    first = not _state.final
    _state.final = True  # first: a redelivery that runs from here on only records its signal
    if not _state.installed:
        return
    signal.setitimer(signal.ITIMER_REAL, 0.0)
    if first and unseen and _state.last is not None and (_state.withheld or _state.raised):
        _late.append(_state.last)
    _state.withheld = False


@contextmanager
def installed(*, hold: bool = False) -> Iterator[None]:
    """Make SIGINT and SIGTERM raise (module docstring) for the body; the previous handlers come back after it,
    or, with ``hold`` (the process ends next: :func:`exit_process`), handlers that only record a signal. Does nothing
    outside the main thread (Python delivers signals to the main thread only)."""
    global _state
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {s: signal.getsignal(s) for s in (*SIGNALS, signal.SIGALRM)}
    hook = sys.unraisablehook
    saved = _state
    _state = _State(installed=True)
    _late.clear()
    try:
        sys.unraisablehook = _unraisable(hook)
        for s in SIGNALS:
            signal.signal(s, _handler)
        signal.signal(signal.SIGALRM, _again)
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        for s, h in before.items():
            signal.signal(s, _record if hold and s in SIGNALS else h)
        sys.unraisablehook = hook
        _state = saved


def exit_process(code: int, late: Callable[[int, int], str]) -> NoReturn:
    """End the process after :func:`installed` (``hold=True``): run the ``atexit`` clean-ups, flush stdout and
    stderr, and ``os._exit`` with ``code``, or, when SIGINT or SIGTERM came after the result was final, print
    ``late(signal, code)`` (one line) and exit with 128 + that signal (130, 143). Nothing after the command's work
    can be cut short by a signal, nor is the interpreter's own teardown run (the operating system frees the rest)."""
    try:
        atexit._run_exitfuncs()  # what sys.exit would run first, here with the signals only recorded
    except BaseException:  # noqa: BLE001  (a clean-up that fails must not change the command's result)
        pass
    if _late:
        signum = signal.SIGTERM if signal.SIGTERM in _late else signal.SIGINT
        with contextlib.suppress(OSError, ValueError):
            print(late(signum, code), file=sys.stderr)
        code = 128 + signum
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    os._exit(code)


@contextmanager
def deferred(*, completes: bool = False) -> Iterator[None]:
    """Run the body without being interrupted half-way: a SIGINT or SIGTERM that arrives meanwhile is raised when
    the body has finished (not when it raised an error of its own: that error ends the command anyway). Only the
    main thread defers: Python raises a signal's exception there and nowhere else, so another thread's body is never
    cut by it, and an interrupt deferred for another thread would be raised in that thread, not the command's.

    With ``completes`` (the body completes the command's output: the swap of ``/analysis`` into the run file) the
    result is final at the body's end (:func:`finished`): a signal that arrived meanwhile (also when the body
    raised), or comes later, is reported at the exit as one that did not stop the command, not raised as an
    interrupt whose line would describe the output of a command cut short. Without :func:`installed` it changes
    nothing."""
    if not _state.installed or threading.current_thread() is not threading.main_thread():
        yield
        return
    _state.depth += 1
    try:
        yield
    finally:
        _state.depth -= 1
        if completes and _state.depth == 0 and _state.pending is not None:
            _late.append(_state.pending)
            _state.pending = None
    if completes:
        finished()
    elif _state.depth == 0 and _state.pending is not None and not _state.raised:
        signum, _state.pending = _state.pending, None
        raise _interrupt(signum)


def undivided(call: Callable[..., None]) -> Callable[..., None]:
    """``call`` run whole (:func:`deferred`): a SIGINT or SIGTERM that arrives during it is raised after it (a
    writer's append, whose datasets keep equal lengths; a checkpoint; a snapshot)."""

    def run(*args: Any) -> None:
        with deferred():
            call(*args)

    return run


@contextmanager
def second_signal_exits() -> Iterator[None]:
    """In the body, a signal that comes while the first interrupt is being handled (later than :data:`SAME_SIGNAL_S`
    after it) ends the process at once with one line and exit code 128 + the signal, leaving its files as a kill
    would (for a clean-up that may wait long, such as a sweep waiting for its Dask workers; the next call of the
    command cleans up). Without :func:`installed` it changes nothing."""
    before = _state.second_exits
    _state.second_exits = True
    try:
        yield
    finally:
        _state.second_exits = before
