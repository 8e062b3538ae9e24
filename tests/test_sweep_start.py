"""The start of a sweep's local cluster: begun in a thread before the call checks its devices, prepares its manifest
and starts its pool; closed when the call stops before its shards; not begun for a call that will run nothing."""

from __future__ import annotations

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
    """Records the call's order of events in ``events``; a start that is never used (:meth:`result` fails)."""

    def __init__(self, events: list[str], device: str, workers: int | None, threads: int, *, warm: bool) -> None:
        self.events = events
        events.append(f"start {device} workers={workers} threads={threads} warm={warm}")

    def result(self):
        raise AssertionError("not reached in these tests")

    def close(self, *, quiet: bool) -> None:
        self.events.append(f"close quiet={quiet}")


def _fake(monkeypatch: pytest.MonkeyPatch, events: list[str]) -> None:
    monkeypatch.setattr(sweep_run, "ClusterStart", lambda *a, **k: FakeStart(events, *a, **k))


@pytest.mark.parametrize("stop", [SceneError("device 'cuda:9' is not available"), KeyboardInterrupt()])
def test_cluster_starts_before_the_checks_and_closes_when_the_call_stops(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, stop: BaseException
) -> None:
    """The cluster of a local GPU sweep starts before its devices are checked (a check that fails, or Ctrl-C there,
    closes it quietly and writes nothing); its workers load their kernels where a pool prepares the shards."""
    events: list[str] = []
    _fake(monkeypatch, events)

    def check(device: str):
        events.append(f"check {device}")
        raise stop

    monkeypatch.setattr(sweep_run, "get_device", check)
    out = tmp_path / "out"
    with pytest.raises(type(stop)):
        run_sweep(load_spec(SPEC, base_dir=tmp_path), out, device="cuda:0", workers=1)
    assert events == ["start cuda:0 workers=1 threads=2 warm=True", "check cuda:0", "close quiet=True"]
    assert not out.exists()


def test_no_cluster_starts_for_a_call_that_will_run_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A finished sweep run again, and a directory that holds another sweep (refused), start no cluster; with
    ``overwrite`` the other sweep is replaced and the cluster starts (here on the CPU, without a pool: no warm-up)."""
    spec = load_spec(SPEC, base_dir=tmp_path)
    out = tmp_path / "out"
    assert run_sweep(spec, out, workers=0).ran == [0]
    events: list[str] = []
    _fake(monkeypatch, events)
    res = run_sweep(spec, out, workers=1)
    assert res.ran == [] and res.skipped == [0] and events == []
    other = load_spec(SPEC | {"run": SPEC["run"] | {"duration": 3e-6}}, base_dir=tmp_path)
    with pytest.raises(SweepError, match="different sweep"):
        run_sweep(other, out, workers=1)
    assert events == []
    with pytest.raises(AssertionError, match="not reached"):
        run_sweep(other, out, workers=1, overwrite=True, overlap=False)
    assert events[0] == "start cpu workers=1 threads=1 warm=False" and set(events[1:]) == {"close quiet=True"}
    # the directory holds the other sweep now, its shard not run: a call for it will run, one for the first will not
    assert sweep_run._will_run(other, out, overwrite=False) and not sweep_run._will_run(spec, out, overwrite=False)


def test_a_failed_start_is_raised_where_the_cluster_is_used(monkeypatch: pytest.MonkeyPatch) -> None:
    """What the start's thread raised (e.g. no cryptography for TLS) is raised by ``result``; ``close`` then has
    nothing to close."""

    def refuse(*args, **kwargs):
        raise SweepError("a local Dask cluster is secured with TLS, which needs the cryptography package")

    monkeypatch.setattr(sweep_cluster, "local_cluster", refuse)
    start = sweep_cluster.ClusterStart("cpu", 1, 1, warm=False)
    with pytest.raises(SweepError, match="cryptography"):
        start.result()
    start.close(quiet=False)
    start.close(quiet=False)


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
    for bad in (["--repeat", "0"], ["--json", str(tmp_path / "missing" / "x.json")]):
        with pytest.raises(SystemExit) as e:
            script.main(bad)
        assert e.value.code == 2
