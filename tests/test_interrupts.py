"""The command line's signal handling (aca_warp.common.interrupts), in this process where it is deterministic: an
interrupt that lands in a finalizer is raised again, ``deferred`` holds one back, a second one is ignored or (in
``second_signal_exits``) ends the process, and ``aca-warp sweep`` takes these rules rather than its own."""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aca_warp.common import interrupts


class _SignalsInFinalizer:
    """An object whose finalizer sends ``sig`` to this process and runs Python code afterwards, so that the handler
    raises inside ``__del__``, where Python swallows the exception."""

    def __init__(self, sig: int) -> None:
        self.sig = sig

    def __del__(self) -> None:
        os.kill(os.getpid(), self.sig)
        for _ in range(1000):
            pass


def _ordinary_code(seconds: float = 2.0) -> None:
    """Python bytecode for ``seconds`` (a signal handler runs between bytecodes)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        time.sleep(0.001)


@pytest.mark.parametrize(("sig", "kind"), [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, interrupts.Terminated)])
def test_interrupt_in_a_finalizer_is_raised_again(sig: int, kind: type) -> None:
    with interrupts.installed():
        with pytest.raises(KeyboardInterrupt) as e:
            obj = _SignalsInFinalizer(sig)
            del obj
            gc.collect()
            _ordinary_code()
        assert type(e.value) is kind
        assert interrupts.exit_code(e.value) == 128 + sig


def test_deferred_raises_at_its_end_and_later_signals_are_ignored() -> None:
    steps = []
    with interrupts.installed():
        with pytest.raises(interrupts.Terminated):
            with interrupts.deferred():
                os.kill(os.getpid(), signal.SIGTERM)
                _ordinary_code(0.05)
                steps.append("body finished")
        os.kill(os.getpid(), signal.SIGINT)  # while the first is handled: ignored
        _ordinary_code(0.05)
        steps.append("clean-up finished")
    assert steps == ["body finished", "clean-up finished"]


def test_another_threads_deferred_neither_holds_back_nor_takes_the_interrupt() -> None:
    """A writer thread inside ``deferred`` while the signal comes: the command's thread is interrupted at once, and
    the writer's body ends normally (it is never cut by a signal) without the interrupt raised in it."""
    import threading

    inside, release, outcome = threading.Event(), threading.Event(), []

    def writer() -> None:
        try:
            with interrupts.deferred():
                inside.set()
                release.wait(5)
            outcome.append("finished")
        except KeyboardInterrupt:
            outcome.append("interrupted in the writer")

    with interrupts.installed():
        t = threading.Thread(target=writer)
        t.start()
        inside.wait(5)
        with pytest.raises(interrupts.Terminated):
            os.kill(os.getpid(), signal.SIGTERM)
            _ordinary_code(0.5)
        release.set()
        t.join(5)
    assert outcome == ["finished"]


SECOND = """
import os, signal, sys, time
from aca_warp.common import interrupts
with interrupts.installed(), interrupts.second_signal_exits():
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
    except KeyboardInterrupt:
        print("first", flush=True)
        time.sleep(float(sys.argv[1]))
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(2)
        print("clean-up went on", flush=True)
sys.exit(1)
"""


def test_second_signal_exits_at_once() -> None:
    """A second signal during the clean-up ends the process with one line; one that comes right after the first is
    that one delivered twice (``timeout -s INT`` signals the process and its group) and the clean-up goes on."""
    r = subprocess.run([sys.executable, "-c", SECOND, "0.3"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 130, r.stderr
    assert r.stdout.split() == ["first"] and "a second interrupt: stopped at once" in r.stderr
    r = subprocess.run([sys.executable, "-c", SECOND, "0"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stdout.split() == ["first", "clean-up", "went", "on"], r.stderr


def test_sweep_command_raises_an_interrupt_from_a_finalizer(tmp_path: Path, monkeypatch, capsys) -> None:
    """A SIGTERM whose interrupt Python swallowed in a finalizer still stops the sweep (exit 143, one line)."""
    import aca_warp.sweep.run as sweep_run  # the command imports run_sweep from there when it runs
    from aca_warp.cli import main

    ran = []

    def run_sweep(*args, **kwargs):
        obj = _SignalsInFinalizer(signal.SIGTERM)
        del obj
        gc.collect()
        _ordinary_code()
        ran.append("finished")  # not reached: the interrupt is raised again
        raise AssertionError("the sweep ran to its end")

    monkeypatch.setattr(sweep_run, "run_sweep", run_sweep)
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nbase = "hf1"\n[run]\nduration = 1e-4\n[parameters]\n"friction.M" = [0.6]\n')
    code = main(["sweep", str(spec), "-o", str(tmp_path / "out"), "--workers", "0", "--quiet"])
    err = capsys.readouterr().err
    assert code == 143, err
    assert ran == []
    assert err.startswith("aca-warp: terminated (SIGTERM);") and "Exception ignored" not in err


def _finalizer_at_the_end(tmp_path: Path) -> list[Path]:
    obj = _SignalsInFinalizer(signal.SIGTERM)
    del obj  # the finalizer runs here (no gc.collect: it would outlast the millisecond of the redelivery)
    return [tmp_path / "figure.png"]  # at once: the redelivery timer has not fired yet


def _dropped_by_other_code(tmp_path: Path) -> list[Path]:
    try:
        os.kill(os.getpid(), signal.SIGTERM)
        _ordinary_code()
    except BaseException:  # noqa: BLE001  (what a careless library might do)
        pass
    return [tmp_path / "figure.png"]


@pytest.mark.parametrize("work", [_finalizer_at_the_end, _dropped_by_other_code], ids=["finalizer", "dropped"])
def test_an_interrupt_the_work_never_saw_is_reported_at_exit(tmp_path: Path, monkeypatch, capsys, work) -> None:
    """A SIGTERM swallowed in a finalizer at the very end of a command's work (before it is raised again), or caught
    and dropped by code beyond ours while the work then went on to its end: the command's output is whole, so it is
    not reported as interrupted half-way; the signal is recorded for the exit's line ("the command's work was not
    stopped") and exit 143, not lost."""
    import aca_warp.plots as plots
    from aca_warp.cli import main

    monkeypatch.setattr(plots, "plot_run", lambda *args, **kwargs: work(tmp_path))
    run = tmp_path / "run.h5"
    run.write_bytes(b"")
    try:
        code = main(["plot", str(run), "-o", str(tmp_path / "figs")])
        err = capsys.readouterr().err
        assert code == 0 and "interrupted" not in err and "Exception ignored" not in err, err
        assert interrupts._late == [signal.SIGTERM]
    finally:
        interrupts._late.clear()


def test_a_signal_while_the_output_is_completed_does_not_interrupt() -> None:
    """Inside ``deferred(completes=True)`` (the swap of /analysis) a signal is held back as in ``deferred``, but then
    recorded as one that did not stop the command (its output whole), not raised; so is any signal after it."""
    try:
        with interrupts.installed():
            with interrupts.deferred(completes=True):
                os.kill(os.getpid(), signal.SIGTERM)
                _ordinary_code(0.05)
            _ordinary_code(0.05)  # nothing raised at its end
            os.kill(os.getpid(), signal.SIGINT)
            _ordinary_code(0.05)  # nor for a later signal: the result is final
            assert interrupts._late == [signal.SIGTERM, signal.SIGINT]
    finally:
        interrupts._late.clear()


def test_an_interrupt_a_finalizer_swallowed_as_a_command_fails_is_reported_at_exit() -> None:
    """The same interrupt when the command ends with an error instead, its handlers left at once (the process ends
    next): recorded as a signal that came as it exited, for the exit's one line and 128 + the signal."""
    before = {s: signal.getsignal(s) for s in interrupts.SIGNALS}
    with interrupts.installed(hold=True):
        obj = _SignalsInFinalizer(signal.SIGINT)
        del obj
        interrupts.finished()  # what the command line does once its error is decided
    try:
        _ordinary_code(0.05)
        assert interrupts._late == [signal.SIGINT]
    finally:
        interrupts._late.clear()
        for s, handler in before.items():
            signal.signal(s, handler)
