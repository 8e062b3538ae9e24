"""The start of a sweep's local cluster: begun in a thread before the call checks its devices, prepares its manifest
and starts its pool; closed when the call stops before its shards; not begun for a call that will run nothing."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from procs import small_sweep_doc

from aca_warp.common.errors import SceneError
from aca_warp.sweep import SweepError, load_spec, run_sweep
from aca_warp.sweep import cluster as sweep_cluster
from aca_warp.sweep import run as sweep_run

pytest.importorskip("distributed")

SPEC = small_sweep_doc("start", count=16, duration=2e-6, parameters={"patches.seed": {"range": [1, 3]}})


class FakeStart:
    """Records the call's order of events in ``events``; a start whose cluster is never used (:meth:`result` fails)."""

    def __init__(self, events: list[str], device: str, workers: int | None, *, overlap: bool) -> None:
        self.events = events
        events.append(f"start {device} workers={workers} overlap={overlap}")

    def go(self, *, warm: bool) -> None:
        self.events.append(f"go warm={warm}")

    def result(self):
        raise AssertionError("not reached in these tests")

    def close(self, *, quiet: bool) -> None:
        self.events.append(f"close quiet={quiet}")


def _fake(monkeypatch: pytest.MonkeyPatch, events: list[str]) -> None:
    monkeypatch.setattr(sweep_run, "ClusterStart", lambda *a, **k: FakeStart(events, *a, **k))


@pytest.mark.parametrize("stop", [SceneError("device 'cuda:9' is not available"), KeyboardInterrupt()])
def test_cluster_begins_before_the_checks_and_spawns_nothing_when_the_call_stops(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stop: BaseException
) -> None:
    """The start of a local GPU sweep's cluster begins (Dask imported in its thread) before the devices are
    checked; a check that fails, or Ctrl-C there, closes it without its go: no process spawned, nothing written."""
    events: list[str] = []
    _fake(monkeypatch, events)

    def check(device: str):
        events.append(f"check {device}")
        raise stop

    monkeypatch.setattr(sweep_run, "get_device", check)
    out = tmp_path / "out"
    with pytest.raises(type(stop)):
        run_sweep(load_spec(SPEC, base_dir=tmp_path), out, device="cuda:0", workers=1)
    assert events == ["start cuda:0 workers=1 overlap=True", "check cuda:0", "close quiet=True"]
    assert not out.exists()


def test_cluster_goes_only_for_a_call_that_runs_shards(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A finished sweep run again, a directory that holds another sweep (refused) and one whose lock another sweep
    holds (refused) give the start no go; with ``overwrite`` the other sweep is replaced and the cluster goes (here
    on the CPU, without a pool: no warm-up)."""
    from aca_warp.common.files import locked_output

    spec = load_spec(SPEC, base_dir=tmp_path)
    out = tmp_path / "out"
    assert run_sweep(spec, out, workers=0).ran == [0]
    events: list[str] = []
    _fake(monkeypatch, events)
    res = run_sweep(spec, out, workers=1)
    assert res.ran == [] and res.skipped == [0]
    assert events == ["start cpu workers=1 overlap=True", "close quiet=True"]
    other = load_spec(SPEC | {"run": SPEC["run"] | {"duration": 3e-6}}, base_dir=tmp_path)
    events.clear()
    with pytest.raises(SweepError, match="different sweep"):
        run_sweep(other, out, workers=1)
    assert events == ["start cpu workers=1 overlap=True", "close quiet=True"]
    events.clear()
    with locked_output(out / "manifest.json", what="wait"), pytest.raises(SceneError, match="is being written by"):
        run_sweep(other, out, workers=1, overwrite=True)
    assert events == ["start cpu workers=1 overlap=True", "close quiet=True"]
    events.clear()
    with pytest.raises(AssertionError, match="not reached"):
        run_sweep(other, out, workers=1, overwrite=True, overlap=False)
    assert events[:2] == ["start cpu workers=1 overlap=False", "go warm=False"]
    # the Dask path closes the start; the call closes it again (idempotent)
    assert set(events[2:]) == {"close quiet=True"}


def test_a_failed_start_is_raised_where_the_cluster_is_used(monkeypatch: pytest.MonkeyPatch) -> None:
    """What the start's thread raised (e.g. no cryptography for TLS) is raised by ``result``; ``close`` then has
    nothing to close."""

    def refuse(*args, **kwargs):
        raise SweepError("a local Dask cluster is secured with TLS, which needs the cryptography package")

    monkeypatch.setattr(sweep_cluster, "local_cluster", refuse)
    start = sweep_cluster.ClusterStart("cpu", 1, overlap=False)
    start.go(warm=False)
    with pytest.raises(SweepError, match="cryptography"):
        start.result()
    start.close(quiet=False)
    start.close(quiet=False)


def test_a_start_closed_early_leaves_no_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """A start closed before its go spawns nothing and its thread ends at once; one closed once its cluster exists
    returns at once too, and the thread, at its next step, closes that cluster (no client made, no worker left)."""
    import threading

    import psutil

    made: list = []
    ready = threading.Event()
    real = sweep_cluster.local_cluster

    def watched(*args, **kwargs):
        out = real(*args, **kwargs)
        made.append(out[0])
        ready.set()
        time.sleep(0.5)  # the call closes the start meanwhile
        return out

    monkeypatch.setattr(sweep_cluster, "local_cluster", watched)
    me = psutil.Process()

    def ours() -> set[int]:  # this test's worker processes: not the multiprocessing helpers other tests leave
        keep = ("resource_tracker", "forkserver")
        return {p.pid for p in me.children(recursive=True) if not any(k in " ".join(p.cmdline()) for k in keep)}

    before = ours()
    idle = sweep_cluster.ClusterStart("cpu", 1, overlap=False)
    idle.close(quiet=True)
    idle._thread.join(30)
    assert not idle._thread.is_alive() and not made
    busy = sweep_cluster.ClusterStart("cpu", 1, overlap=False)
    busy.go(warm=True)
    assert ready.wait(120)
    t = time.perf_counter()
    busy.close(quiet=True)
    assert time.perf_counter() - t < 0.2  # does not wait for the start
    busy._thread.join(120)
    assert not busy._thread.is_alive() and busy.error is None and busy.client is None
    assert made[0].status.name == "closed"
    deadline = time.monotonic() + 30
    while ours() - before and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not ours() - before


def test_the_pool_s_fork_server_starts_before_the_go(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With a pool, the call makes its Preparer (whose fork server starts then, before a nanny can set its
    environment variables in this process) before it gives the cluster's start its go, and asks for the warm-up."""
    events: list[str] = []
    _fake(monkeypatch, events)
    real = sweep_run.Preparer

    def recorded(*args, **kwargs):
        events.append("preparer")
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep_run, "Preparer", recorded)
    with pytest.raises(AssertionError, match="not reached"):
        run_sweep(load_spec(SPEC, base_dir=tmp_path), tmp_path / "out", workers=1, prepare=1)
    assert events[:3] == ["start cpu workers=1 overlap=True", "preparer", "go warm=True"], events


def test_start_parts_script(tmp_path: Path) -> None:
    """``scripts/sweep_start_parts.py`` times a fresh process's start part by part and a local cluster's start,
    warm-up and close; a bad option exits 2."""
    from scriptload import load_script

    script = load_script("sweep_start_parts")
    out = tmp_path / "parts.json"
    assert script.main(["--workers", "1", "--repeat", "1", "--json", str(out)]) == 0
    import json

    doc = json.loads(out.read_text())
    (fresh,) = doc["fresh"]
    assert list(fresh) == [
        "import numpy", "import warp", "wp.init", "context + first alloc", "import aca_warp sweep", "load kernels.hf",
        "load kernels.neighbours", "import distributed",
    ]  # fmt: skip
    assert all(v >= 0 for v in fresh.values())
    (start,) = doc["cluster"]
    assert start["local_cluster"] > 0 and len(start["warm (per worker, inside)"]) == 1 and start["close"] > 0
    for bad in (["--repeat", "0"], ["--workers", "0"], ["--json", str(tmp_path / "missing" / "x.json")]):
        with pytest.raises(SystemExit) as e:
            script.main(bad)
        assert e.value.code == 2


@pytest.mark.parametrize("go", [False, True])
def test_a_process_exits_cleanly_with_a_start_under_way(go: bool) -> None:
    """A process that exits with a cluster start not closed (waiting for its go, or under way): the exit closes it
    and waits for its thread (no abort inside the TLS key's generation, no wait for a go that never comes)."""
    import subprocess
    import sys

    code = (
        "import time\n"
        "from aca_warp.sweep.cluster import ClusterStart\n"
        "s = ClusterStart('cpu', 1, overlap=False)\n"
        f"if {go}:\n"
        "    time.sleep(0.3)\n"
        "    s.go(warm=False)\n"
        "    time.sleep(0.3)\n"
    )
    t = time.monotonic()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert time.monotonic() - t < 25  # well inside EXIT_WAIT_S (30 s): the start did not wait for a go
