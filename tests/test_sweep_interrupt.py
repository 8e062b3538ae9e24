"""Ctrl-C and SIGTERM during ``aca-warp sweep``: one line, exit 130/143, the running shards marked ``interrupted``,
and a rerun that finishes them (the finished ones untouched) with the files of an uninterrupted sweep."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest
from procs import assert_same_datasets, error_lines, start

from aca_warp.cli import main

# 6 pads of 200 patches in 3 shards of 2; 0.5 ms simulated (about a quarter of a second of stepping per shard on one
# idle core on the on-chip engine, 50 times the polling interval; the signal comes while a shard runs, found by
# polling its .partial every 5 ms)
SPEC = """[sweep]
base = "hf1"
shard_size = 2
name = "interrupt"
[run]
duration = 5e-4
precision = "fp32"
sample_dt = 1e-5
[base.patches]
count = 200
[parameters]
"friction.M" = [0.6, 0.7, 0.8, 0.9, 0.95, 0.85]
"""


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The spec file and an uninterrupted sweep of it (sequential, in one process)."""
    d = tmp_path_factory.mktemp("sweep_ref")
    spec = d / "spec.toml"
    spec.write_text(SPEC)
    assert main(["sweep", str(spec), "-o", str(d / "ref"), "--workers", "0", "--no-overlap", "--quiet"]) == 0
    return spec, d / "ref"


def _states(out: Path) -> list[str]:
    return [s["state"] for s in json.loads((out / "manifest.json").read_text())["shards"]]


def _wait_for_running_shard(out: Path, proc, timeout: float = 120.0) -> None:
    """Until one shard is finished and another is being written (its ``.partial`` exists)."""
    deadline = time.monotonic() + timeout
    while True:
        assert proc.poll() is None, f"the sweep ended first: {proc.stderr.read()}"
        assert time.monotonic() < deadline, "no shard finished in time"
        try:
            done = _states(out).count("done")
        except (FileNotFoundError, json.JSONDecodeError):
            done = 0
        if done >= 1 and list(out.glob("shard-*.h5.partial")):
            return
        time.sleep(0.005)


@pytest.mark.parametrize(
    ("sig", "code", "word", "mode"),
    [
        (signal.SIGINT, 130, "interrupted", ["--workers", "0"]),
        (signal.SIGTERM, 143, "terminated (SIGTERM)", ["--workers", "0", "--no-overlap"]),
        (signal.SIGTERM, 143, "terminated (SIGTERM)", ["--workers", "2"]),
    ],
    ids=["sigint-overlapped", "sigterm-sequential", "sigterm-dask"],
)
def test_signal_marks_running_shards_and_rerun_finishes(
    tmp_path: Path, reference: tuple[Path, Path], sig: int, code: int, word: str, mode: list[str], capsys
) -> None:
    spec, ref = reference
    for attempt in range(3):
        out = tmp_path / f"out{attempt}"
        args = ["sweep", str(spec), "-o", str(out), "--quiet", *mode]
        proc = start(args)
        _wait_for_running_shard(out, proc)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=120)
        states = _states(out)
        assert proc.returncode == code, stderr
        if "work was not stopped" in stderr or "after every shard had finished" in stderr:
            continue  # on a loaded machine the signal came after the last shard's end: nothing to interrupt; again
        lines = error_lines(stderr)
        assert len(lines) == 1, stderr  # no traceback, no Dask shutdown chatter
        assert lines[0].startswith(f"aca-warp: {word};") and "run the same command again" in lines[0]
        assert "Traceback" not in stderr and "Traceback" not in stdout
        # the signal came after the shards that ran had finished (on two Dask workers the first two run side by
        # side, and on a loaded machine the second may end between the first's end and the signal): nothing was
        # left to interrupt, and nothing was; the check needs a signal during a run, so it is made again
        if "interrupted" in states or set(states) - {"done", "pending"}:
            break
        assert "marked interrupted" not in lines[0], lines[0]
    else:
        pytest.fail(f"no signal reached the sweep during a shard in 3 attempts (shard states {states})")
    assert "interrupted" in states and "queued" not in states, states
    assert set(states) <= {"done", "interrupted", "pending"}, (states, (out / "manifest.json").read_text())
    hit = [i for i, s in enumerate(states) if s == "interrupted"]
    assert f"shard(s) {', '.join(map(str, hit))} marked interrupted" in lines[0]
    assert not list(out.glob("*.partial"))  # a stopped shard deletes its file (Dask workers too)
    finished = {p.name: p.stat().st_mtime_ns for p in out.glob("shard-*.h5")}
    assert len(finished) == states.count("done") >= 1

    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0"]) == 0  # the rerun, in this process
    assert f"{3 - len(finished)} shard(s) run, {len(finished)} skipped" in capsys.readouterr().out
    assert _states(out) == ["done"] * 3
    assert {n: (out / n).stat().st_mtime_ns for n in finished} == finished  # finished shards were not redone
    assert not list(out.glob("*.partial"))
    for i in range(3):
        assert_same_datasets(ref / f"shard-0000{i}.h5", out / f"shard-0000{i}.h5")


def test_sync_cancel_error_of_distributed_is_dropped(caplog) -> None:
    """distributed's NameError when an interrupted ``sync`` call is cancelled (tornado logs it as a callback
    exception, seen on a SIGTERM-stopped Dask sweep) is filtered out of the client's log; other tornado errors stay."""
    import logging

    from aca_warp.sweep.cluster import _drop_sync_cancel_errors

    _drop_sync_cancel_errors()
    _drop_sync_cancel_errors()  # once only
    log = logging.getLogger("tornado.application")
    assert len(log.filters) == len(set(log.filters))
    with caplog.at_level(logging.ERROR, logger="tornado.application"):
        log.error("Exception in callback functools.partial(<function sync.<locals>.cancel at 0x7f45569b3100>)")
        log.error("Exception in callback something else")
    assert [r.getMessage() for r in caplog.records] == ["Exception in callback something else"]
