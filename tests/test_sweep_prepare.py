"""Shards prepared ahead in a pool of processes: the same results as tasks that prepare their own shards, on every
path (serial, overlapped threads, Dask), and a failed preparation is its shard's failure, never a hang."""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures.process import BrokenProcessPool
from importlib import resources
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import psutil
import pytest
from procs import gated, gated_one, small_sweep_doc

from aca_warp.hf.recorder import GLOBAL_NAMES
from aca_warp.sweep import load_spec, load_sweep, run_sweep
from aca_warp.sweep.prepare import _KEPT, PreparedShard, Preparer, SpooledShard, prepare_shard

# 2 M x 2 seeds x 2 loads = 8 pads of 20 patches in 3 shards (the last of 2 pads); 3 µs simulated
SMALL = small_sweep_doc(
    "small",
    count=20,
    duration=3e-6,
    parameters={"friction.M": [0.6, 0.8], "patches.seed": [1, 2], "load.normal_force": [300.0, 450.0]},
)


def _spec(tmp_path: Path | None = None) -> object:
    """The small sweep; with ``tmp_path``, its base scene a TOML file there (base.toml) instead of the preset."""
    doc = json.loads(json.dumps(SMALL))
    if tmp_path is not None:
        (tmp_path / "base.toml").write_text(resources.files("aca_warp.data").joinpath("hf1.toml").read_text())
        doc["sweep"]["base"] = "base.toml"
    return load_spec(doc, base_dir=tmp_path or Path.cwd())


def _outputs(d: Path) -> dict:
    s = load_sweep(d)
    return {k: s[k] for k in ("time", "pad_index", *GLOBAL_NAMES)}


def _recording(submit, handed: list[str]):
    """A sweep feed's ``submit`` that first notes what each shard's task is handed (its type's name) in ``handed``."""

    def recorded(i, prepared):
        handed.append(type(prepared).__name__)
        return submit(i, prepared)

    return recorded


def _in_time(fn, seconds: float = 180.0):
    """``fn()`` in a thread; fails the test (instead of hanging it) when it has not returned within ``seconds``."""
    out: dict = {}

    def call() -> None:
        try:
            out["value"] = fn()
        except BaseException as e:  # noqa: BLE001  (raised again in the test's thread)
            out["error"] = e

    t = threading.Thread(target=call, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still running after {seconds} s"
    if "error" in out:
        raise out["error"]
    return out["value"]


@pytest.mark.parametrize("overlap", [False, True])
def test_prepared_shards_give_the_same_files(tmp_path: Path, overlap: bool) -> None:
    """In this process, serial and overlapped: a pool of two processes (the shards it has ready when their turn
    comes; the others, the first among them, are prepared by their tasks) gives every output of every pad bit for bit
    as shards that prepare themselves; without a pool nothing is prepared ahead."""
    spec = _spec()
    runs = {}
    for prepare in (0, 2):
        out = tmp_path / f"p{prepare}"
        res = run_sweep(spec, out, workers=0, overlap=overlap, prepare=prepare)
        assert res.ran == [0, 1, 2] and not res.failed
        for s in res.summaries:  # a shard prepared ahead is uploaded, one prepared in its task built
            assert ("upload" in s["timings"]) == ("prepare_ahead" in s["timings"]) != ("build" in s["timings"])
        assert prepare > 0 or all("prepare_ahead" not in s["timings"] for s in res.summaries)
        started = [s["timings"]["spans"] for s in res.summaries if "pool_start" in s["timings"]["spans"]]
        assert len(started) <= prepare  # (none where the tasks made every shard: a loaded machine)
        for spans in started:  # the first shard a pool process made carries that process's start, before its work
            begun, warp, ready = spans["pool_warp"] + spans["pool_start"][1:]
            assert spans["pool_start"][0] == begun <= warp <= ready <= spans["prepare_ahead"][0]
        runs[prepare] = _outputs(out)
    for k, v in runs[0].items():
        assert v.tobytes() == runs[2][k].tobytes(), k


def test_a_pool_process_s_first_shard_carries_its_start(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The first shard a pool process prepares carries that process's start (begun, Warp started, ready), the ones
    after it none; a task given it lays the start out as the spans pool_warp and pool_start."""
    from aca_warp.sweep import prepare as prep_mod
    from aca_warp.sweep.shard import run_shard

    spec = _spec()
    monkeypatch.setattr(prep_mod, "_STARTED", [100.0, 100.5, 100.7])
    first = prep_mod.prepare_shard(spec.doc, str(spec.base_dir), 0)
    assert first.process_start == (100.0, 100.5, 100.7) and prep_mod._STARTED == []
    assert prep_mod.prepare_shard(spec.doc, str(spec.base_dir), 1).process_start == ()
    spans = run_shard(spec.doc, str(spec.base_dir), str(tmp_path), 0, prepared=first)["timings"]["spans"]
    assert spans["pool_warp"] == [100.0, 100.5] and spans["pool_start"] == [100.0, 100.7]


def test_host_model_is_the_built_model() -> None:
    """A batch's model made on the host (neighbours searched on the run's device, the CPU here) holds every array of
    the model build_model makes, bit for bit, and the run's checks made from it equal those made from the device
    model (also with the initial state in equilibrium)."""
    from aca_warp.hf.loop import preflight
    from aca_warp.hf.model import build_model, host_model, upload
    from aca_warp.hf.state import initial_state
    from aca_warp.sweep.prepare import run_options

    doc = json.loads(json.dumps(SMALL))
    doc["base"]["initial"] = {"state": "equilibrium", "perturbation": 0.01, "seed": 4}
    spec = load_spec(doc, base_dir=Path.cwd())
    scenes = spec.scenes(spec.shard_pads(0))
    built = build_model(scenes, device="cpu", precision="fp32")
    host = host_model(scenes, device="cpu", precision="fp32")
    assert set(host.arrays) == set(built.arrays) and host.nbr_count == built.nnz
    for k, a in built.arrays.items():
        assert host.arrays[k].dtype == a.numpy().dtype and host.arrays[k].tobytes() == a.numpy().tobytes(), k
    up = upload(host, "cpu")
    view = upload(host, "cpu", copy=False)
    assert view.arrays["nbr_index"].ptr == host.arrays["nbr_index"].ctypes.data  # the host arrays themselves
    s_built, s_view = initial_state(built), initial_state(view)
    for a, b in zip(s_built.numpy(), s_view.numpy(), strict=True):
        assert a.tobytes() == b.tobytes() and np.any(a != 0)
    options = run_options(spec)
    c_built = preflight(built, s_built, options, spec.base.record)
    c_view = preflight(view, s_view, options, spec.base.record)
    assert c_built.estimate == c_view.estimate
    assert c_built.mu_bound.tobytes() == c_view.mu_bound.tobytes()
    assert c_built.watch_bound.tobytes() == c_view.watch_bound.tobytes()
    assert all(up.arrays[k].numpy().tobytes() == a.numpy().tobytes() for k, a in built.arrays.items())


@pytest.mark.parametrize("memory_fraction", [0.5, 1e-12], ids=["one-batch", "a-batch-per-pad"])
def test_prepared_batches_give_the_task_s_own_file(tmp_path: Path, memory_fraction: float) -> None:
    """A shard prepared with its batches (models, initial states and checks made on the host) gives the file of a
    task that builds them itself: every dataset and attribute bit for bit but the timings; its task uploads them
    instead of building, also when every pad is its own batch."""
    from procs import assert_same_datasets

    from aca_warp.sweep.prepare import prepare_shard
    from aca_warp.sweep.shard import run_shard

    spec = _spec()
    prepared = prepare_shard(spec.doc, str(spec.base_dir), 1, device="cpu", memory_fraction=memory_fraction)
    assert [(b.start, b.stop) for b in prepared.batches] == (
        [(0, 3)] if memory_fraction == 0.5 else [(0, 1), (1, 2), (2, 3)]
    )
    summaries = {}
    for name, given in (("own", None), ("prepared", prepared)):
        (tmp_path / name).mkdir()
        args = (spec.doc, str(spec.base_dir), str(tmp_path / name), 1, "cpu")
        summaries[name] = run_shard(*args, memory_fraction=memory_fraction, prepared=given)["timings"]
    assert "upload" in summaries["prepared"] and "build" not in summaries["prepared"]
    assert "build" in summaries["own"] and "upload" not in summaries["own"]
    a, b = tmp_path / "own" / "shard-00001.h5", tmp_path / "prepared" / "shard-00001.h5"
    assert_same_datasets(a, b)
    # what the clock and the free memory at the moment say (the capacity from the memory free when each was planned;
    # the batches, asserted above, are the same)
    times = {"timings", "wall_time", "compile_time", "batch_capacity"}
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        assert {k: str(v) for k, v in fa.attrs.items() if k not in times} == {
            k: str(v) for k, v in fb.attrs.items() if k not in times
        }


def test_prepare_shard_equals_the_spec() -> None:
    """A prepared shard holds the spec's pads and scenes for it (patches shared between pads of one layout)."""
    spec = _spec()
    p = prepare_shard(spec.doc, str(spec.base_dir), 1)
    assert p.index == 1 and p.pads.tolist() == [3, 4, 5] and p.spec.hash == spec.hash
    want = spec.scenes([3, 4, 5])
    for got, ref in zip(p.scenes, want, strict=True):
        assert got.patches.x.tobytes() == ref.patches.x.tobytes() and got.normal_force == ref.normal_force
    assert p.scenes[1].patches is p.scenes[2].patches  # pads 4 and 5: seed 1


@pytest.mark.parametrize("prepare", [0, 1])
def test_failed_preparation_fails_its_shards(tmp_path: Path, prepare: int) -> None:
    """The base scene file vanishes after the spec was read: every shard's preparation raises (in the pool, or in the
    task), every shard is recorded failed with that error, and the sweep returns (no hang)."""
    spec = _spec(tmp_path)
    (tmp_path / "base.toml").unlink()
    res = _in_time(lambda: run_sweep(spec, tmp_path / "out", workers=0, prepare=prepare))
    assert sorted(res.failed) == [0, 1, 2] and res.ran == []
    assert all("'base.toml': no such file in" in e for e in res.failed.values()), res.failed
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert [s["state"] for s in manifest["shards"]] == ["failed"] * 3


def test_pool_without_the_device_makes_scenes_only() -> None:
    """A pool process that cannot start Warp on the device it was given (here a GPU this machine does not have; on
    a GPU host, one in exclusive-process mode held by its worker) prepares the scenes and leaves the models to the
    task, instead of failing every shard."""
    spec = _spec()
    prep = Preparer(spec.doc, str(spec.base_dir), processes=1, ahead=1, device="cuda:7")
    try:
        prep.plan([1])
        got = _in_time(lambda: prep.get(1), 120)
    finally:
        prep.close()
    assert got.index == 1 and len(got.scenes) == 3 and got.batches == [] and got.capacity == 0


def _same_shard(a: PreparedShard, b: PreparedShard) -> None:
    assert a.index == b.index and a.pads.tolist() == b.pads.tolist() and len(a.batches) == len(b.batches)
    for x, y in zip(a.scenes, b.scenes, strict=True):
        assert x.patches.x.tobytes() == y.patches.x.tobytes() and x.normal_force == y.normal_force
    for x, y in zip(a.batches, b.batches, strict=True):
        assert sorted(x.model.arrays) == sorted(y.model.arrays)
        assert all(x.model.arrays[k].tobytes() == y.model.arrays[k].tobytes() for k in x.model.arrays)
        assert x.u.tobytes() == y.u.tobytes() and x.v.tobytes() == y.v.tobytes()


def test_spooled_shard_is_the_prepared_shard(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """With a spool, the pool leaves a prepared shard in a file only this user can read, in a folder only this user
    can enter; loading it gives the shard bit for bit and removes the file; closing removes the folder (and the
    files no task took), and the folder a killed sweep left is removed by the next one. A spool that cannot take the
    file (gone here; full on a real machine) leaves the shard to travel by value."""
    import os
    import stat
    import subprocess
    import sys

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    base = tmp_path / "aca-warp" / "sweep"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    base.mkdir(parents=True, mode=0o700)
    stale = base / f"spool-{int(dead.stdout)}-left"
    stale.mkdir()
    (stale / "shard-00001.pkl").write_bytes(b"x" * 100)
    spec = _spec()
    ref = prepare_shard(spec.doc, str(spec.base_dir), 1, device="cpu")
    prep = Preparer(spec.doc, str(spec.base_dir), processes=1, ahead=2, spool=True, device="cpu")
    try:
        assert not stale.exists()
        folder = Path(prep.spool)
        assert folder.parent == base and stat.S_IMODE(folder.stat().st_mode) == 0o700
        prep.plan([1, 2])
        got = _in_time(lambda: prep.get(1), 120)
        assert isinstance(got, SpooledShard) and got.index == 1
        assert stat.S_IMODE(os.stat(got.path).st_mode) == 0o600 and Path(got.path).parent == folder
        _same_shard(got.load(), ref)
        assert not Path(got.path).exists() and got.load() is None  # a task run again prepares the shard itself
        _in_time(lambda: prep._future(2).result(), 120)  # shard 2's file: never taken
        assert len(list(folder.glob("shard-*.pkl"))) == 1  # beside the marks of the begun preparations
        assert sorted(f.name for f in folder.glob("began-*")) == ["began-00001", "began-00002"]
    finally:
        prep.close()
    assert not folder.exists()
    prep = Preparer(spec.doc, str(spec.base_dir), processes=1, ahead=1, spool=True, device="cpu")
    try:
        shutil.rmtree(prep.spool)
        prep.plan([1])
        got = _in_time(lambda: prep.get(1), 120)
    finally:
        prep.close()
    assert isinstance(got, PreparedShard)
    _same_shard(got, ref)
    from aca_warp.sweep.shard import run_shard

    gone = SpooledShard(1, str(tmp_path / "taken.pkl"))  # a task run again after its worker died: it builds itself
    (tmp_path / "out").mkdir()
    summary = run_shard(spec.doc, str(spec.base_dir), str(tmp_path / "out"), 1, "cpu", prepared=gone)
    assert summary["state"] == "done" and "build" in summary["timings"]


def _pool_processes(before: set[int] = frozenset()) -> list[psutil.Process]:
    """The pool's worker processes: the children of this process's fork server (the pool forks them there), leaving
    out the processes in ``before`` (pools of earlier tests in this worker)."""
    servers = [p for p in psutil.Process().children() if "forkserver" in " ".join(p.cmdline())]
    return [c for s in servers for c in s.children() if c.pid not in before]


def test_dead_pool_process_fails_its_shard(tmp_path: Path) -> None:
    """A pool process killed while it prepares a shard: waiting for that shard raises (BrokenProcessPool) instead of
    waiting for ever, and so does asking for the shards left waiting behind it (not taken for a pool that has made
    all its shards)."""
    doc = json.loads(json.dumps(SMALL))
    doc["base"]["patches"] = {"count": 6000, "area_min": 2e-9, "area_max": 4e-9}  # seconds of placement per layout
    doc["sweep"]["shard_size"] = 1  # a shard per pad
    spec = load_spec(doc, base_dir=Path.cwd())
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    prep = Preparer(spec.doc, str(spec.base_dir), processes=1, ahead=3)
    assert spec.shard_count >= 5
    try:
        prep.plan(range(5))
        deadline = time.monotonic() + 60
        while not (kids := _pool_processes(before)) and time.monotonic() < deadline:
            time.sleep(0.05)
        # killed as soon as it exists: a spawned process needs seconds to import and place 6000 patches, so the kill
        # lands before the preparation can finish on any machine (a fixed wait of 1 s did not on a fast idle one)
        assert kids and not prep.poll(0)
        for k in kids:
            k.kill()
        for i in range(5):  # the three sent to the pool, and the two left waiting behind them
            with pytest.raises(BrokenProcessPool):
                _in_time(lambda i=i: prep.get(i), 60)
    finally:
        prep.close()


def test_pool_processes_end_with_a_killed_client(tmp_path: Path) -> None:
    """A process that made a pool and is killed (SIGKILL: no clean-up of its own) leaves no pool process behind:
    each ends within seconds of its client, and the fork server with them."""
    import signal
    import subprocess
    import sys

    client = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\n"
            "from aca_warp.sweep import load_spec\n"
            "from aca_warp.sweep.prepare import Preparer\n"
            "from procs import small_sweep_doc\n"
            "spec = load_spec(small_sweep_doc('k', count=20, duration=3e-6, parameters={'patches.seed': [1, 2]}))\n"
            "p = Preparer(spec.doc, str(spec.base_dir), 2, 2, device='cpu')\n"
            "p.plan([0, 1])\n"  # shard 1 never taken: the pool is kept (it is let go once every shard is taken)
            "p.get(0)\n"
            "print('ready', flush=True)\n"
            "time.sleep(600)\n",
        ],
        stdout=subprocess.PIPE,
        text=True,
        cwd=str(Path(__file__).parent),
    )
    try:
        assert client.stdout.readline().strip() == "ready"
        tree = [c for c in psutil.Process(client.pid).children(recursive=True)]
        pool = [c for c in tree if "forkserver" in " ".join(c.cmdline())]
        assert pool, [c.cmdline() for c in tree]  # the fork server and its pool process(es)
        client.send_signal(signal.SIGKILL)
        client.wait(30)
        _, alive = psutil.wait_procs(pool, timeout=30)
        assert not alive, [(p.pid, p.cmdline()[-1][:40]) for p in alive]
    finally:
        if client.poll() is None:
            client.kill()


def test_prepared_shards_on_dask(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On a Dask worker of a local cluster this process started, reached through a client, shards prepared by the
    client's pool (models made on the host) are handed over as their spool files and give the serial path's outputs
    bit for bit, without Dask's warning about large task graphs (a prepared shard of 256 hf1 pads is ~90 MB; here the
    warning's threshold is 1 byte, so that every task would raise it); a failed preparation is the shard's failure
    there too. The worker has glibc's sliding mmap threshold (no MALLOC_TRIM_THRESHOLD_ from its nanny)."""
    pytest.importorskip("distributed")
    import warnings

    import dask
    from distributed import Client

    from aca_warp.sweep import cluster as sweep_cluster
    from aca_warp.sweep import local_cluster

    handed: list[str] = []
    fed = sweep_cluster._feed

    def feed(book, submit, preparer, **kwargs) -> None:
        fed(book, _recording(submit, handed), preparer, **kwargs)

    monkeypatch.setattr(sweep_cluster, "_feed", feed)
    spec = _spec(tmp_path)
    run_sweep(spec, tmp_path / "serial", workers=0, overlap=False)
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)  # Dask's nannies set it (65536) unless told not to
    cluster, device = local_cluster("cpu", 1)
    client = Client(cluster)
    try:
        assert list(client.run(os.environ.get, "MALLOC_TRIM_THRESHOLD_").values()) == [None]
        assert "MALLOC_TRIM_THRESHOLD_" not in os.environ  # nor in this process, for what it starts later
        big = {"distributed.admin.large-graph-warning-threshold": "1B"}
        with dask.config.set(big), warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            res = _in_time(lambda: run_sweep(spec, tmp_path / "dask", device=device, client=client, prepare=1))
        assert not [w for w in said if "large graph" in str(w.message)]
        assert res.ran == [0, 1, 2] and not res.failed
        for s in res.summaries:  # prepared ahead (and uploaded) or, not ready when a worker would wait, in the task
            assert ("upload" in s["timings"]) == ("prepare_ahead" in s["timings"]) != ("build" in s["timings"])
        ahead = sum("prepare_ahead" in s["timings"] for s in res.summaries)
        assert sorted(handed) == ["NoneType"] * (3 - ahead) + ["SpooledShard"] * ahead, handed  # files, not models
        a, b = _outputs(tmp_path / "serial"), _outputs(tmp_path / "dask")
        for k, v in a.items():
            assert v.tobytes() == b[k].tobytes(), k
        shutil.copy(tmp_path / "base.toml", tmp_path / "kept.toml")
        (tmp_path / "base.toml").unlink()
        res = _in_time(lambda: run_sweep(spec, tmp_path / "gone", device=device, client=client, prepare=1))
        assert sorted(res.failed) == [0, 1, 2] and all("'base.toml': no such file in" in e for e in res.failed.values())
    finally:
        client.close()
        cluster.close()
    assert np.isfinite(a["mu"]).all()


@pytest.mark.parametrize("pool", ["ahead", "behind"])
def test_head_start_prepares_every_worker_s_first_shard(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, pool: str
) -> None:
    """A sweep that starts its own cluster starts its pool first: when the pool has the first shards ready by the
    time the workers are (held here until it has), the first shard of every worker is uploaded, not built; when it
    has not (its work held back until the sweep ends), every worker builds its first shard rather than wait."""
    pytest.importorskip("distributed")
    import functools

    from aca_warp.sweep import cluster

    gate = tmp_path / "gate"
    if pool == "ahead":
        gate.touch()
    made = Preparer.__init__

    def held(self: Preparer, *args, **kwargs) -> None:
        made(self, *args, **kwargs)
        self.prepare = functools.partial(gated, str(gate), self.prepare)

    fed = cluster._feed

    handed: list[str] = []

    def feed(book, submit, preparer, **kwargs) -> None:
        if pool == "ahead":  # the cluster took as long as the pool needed for the first shard of each worker
            for i in (0, 1):
                _in_time(lambda i=i: preparer._future(i).result(), 120)
        fed(book, _recording(submit, handed), preparer, **kwargs)
        spools.append(preparer.spool)

    spools: list[str] = []

    monkeypatch.setattr(Preparer, "__init__", held)
    monkeypatch.setattr(cluster, "_feed", feed)
    try:
        res = _in_time(lambda: run_sweep(_spec(), tmp_path / "out", device="cpu", workers=2, prepare=2))
    finally:
        gate.touch()  # lets the held pool processes finish
    assert res.ran == [0, 1, 2] and not res.failed
    first: dict[str, dict] = {}
    for s in sorted(res.summaries, key=lambda s: s["timings"]["run_start"]):
        first.setdefault(s["process"], s["timings"])
    assert len(first) == 2
    phase = "upload" if pool == "ahead" else "build"
    assert all(phase in t for t in first.values()), [sorted(t) for t in first.values()]
    # a local cluster's workers are handed the prepared shards' files, not the shards; the spool is gone after
    assert handed[:2] == (["SpooledShard"] * 2 if pool == "ahead" else ["NoneType"] * 2), handed
    assert "PreparedShard" not in handed and spools and not Path(spools[0]).exists()


def test_bench_script_runs_every_configuration(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """scripts/bench_sweep.py on the CPU with tiny settings: the new path overlapped (and as the command runs it),
    sequential and with the warm-up's pool kept, each in a process that imported the code it names; rates and ratios
    from the shards' own timings; the device's time line (start, busy, idle, tail) adds up to the wall time; the
    host phases include the pool's work and the turn's (upload, set-up with the checks given). With ``--baseline``
    the same configurations run for a second checkout (here this one): its runs are listed, and its processes import
    the code of that checkout (a package view of it; checked on its host-phase process, the cheapest: the sweeps of
    the baseline run the same functions as the new code's, in the same way). The children share the tests' kernel
    cache (the script gives each code its own, empty one where WARP_CACHE_PATH is unset: kernels compiled twice, for
    identical code)."""
    pytest.importorskip("distributed")
    import warp as wp
    from scriptload import load_script

    cache = Path(wp.config.kernel_cache_dir)  # WARP_CACHE_PATH/<Warp version>
    assert cache.name == wp.config.version, cache
    monkeypatch.setenv("WARP_CACHE_PATH", str(cache.parent))

    bench = load_script("bench_sweep")
    repo = Path(bench.__file__).resolve().parent.parent
    out, md = tmp_path / "b.json", tmp_path / "b.md"
    argv = ["--device", "cpu", "--units", "1", "--pads", "8", "--patches", "12", "--shard-size", "4"]
    argv += ["--duration", "3e-6", "--prepare", "1", "--kept-pool", "--json", str(out), "--md", str(md)]
    assert bench.main([*argv, "--dir", str(tmp_path / "w")]) == 0
    doc = json.loads(out.read_text())
    rows = {(r["code"], r["mode"]): r for r in doc["results"]}
    assert set(rows) == {("new", "overlapped"), ("new", "sequential"), ("new", "kept")}
    assert any("prepare_ahead" in sh for sh in rows[("new", "kept")]["shards"])  # its pool ran (kept: tests above)
    assert "partial" not in doc  # written after every run, whole at the end
    for r in rows.values():
        assert r["patch_steps"] == 8 * 12 * 300 and r["package"].startswith(str(tmp_path / "w"))
        assert r["in_shard_rate"] == pytest.approx(r["patch_steps"] / sum(s["kernel"] for s in r["shards"]))
        assert r["wall_over_in_shard"] == pytest.approx(r["wall_rate"] / r["in_shard_rate"])
        assert set(r["phase_median_s"]) == set(bench.PHASES) == set(r["phase_least_s"]) and r["runs"] == 1
        assert r["phase_median_s"]["kernel"] > 0
        devices = r["timeline"]["devices"]  # one worker process: its device's time adds up to the call's
        assert len(devices) == 1 and sum(d["shards"] for d in devices.values()) == 2
        for d in devices.values():
            assert d["start"] + d["busy"] + d["idle"] + d["tail"] == pytest.approx(r["wall_s"])
            assert min(d["start"], d["busy"], d["idle"], d["tail"]) >= 0
        for sh in r["timeline"]["shards"]:
            assert 0 <= sh["turn"][0] <= sh["phases"]["kernel"][0] < sh["turn"][1] <= r["wall_s"]
    (host,) = doc["host"]
    assert host["code"] == "new" and host["repeats"] == 3 and host["pads"] == 4
    phases = ("prepare", "build", "setup", "pool", "upload", "setup_checked")
    assert all(0 < host["cpu_s"][p] and 0 < host["wall_s"][p] for p in phases)
    new = rows[("new", "overlapped")]
    assert new["prepare"] == 1 and new["workers"] == 1 and new["command_wall_s"] > 0
    assert new["command_exit_s"] > new["command_wall_s"]  # the process ends after the call returns
    # the command's shards alone: from its first device turn (after the cluster's start) to the call's end
    first_turn = min(d["start"] for d in new["command_timeline"]["devices"].values())
    assert new["command_shards_s"] == pytest.approx(new["command_wall_s"] - first_turn) and first_turn > 0
    assert new["command_shards_speedup_vs_fewest_units"] == 1.0
    text = md.read_text()
    assert len(text.splitlines()) == 1 and "new sequential on 1 CPU worker" in text
    assert "idle between turns" in text and "the whole call as the command runs it" in text
    assert "to its process's end" in text
    assert "its shards, from the first device turn to the end" in text
    # --baseline: its configurations, and its processes import that checkout's code
    args = bench.parse_args([*argv, "--baseline", str(repo)])
    runs = bench.configurations(args)
    assert [(c["code"], c["mode"], c["units"]) for c in runs] == [
        ("new", "overlapped", 1), ("new", "sequential", 1), ("new", "kept", 1), ("baseline", "overlapped", 1)
    ]  # fmt: skip
    assert runs[3]["prepare"] is None  # a baseline runs with its own default pool
    scratch = tmp_path / "b"
    scratch.mkdir()
    h = bench.run_child(repo, {**runs[0], "code": "baseline", "mode": "host", "repeat": 1}, scratch)
    assert h["code"] == "baseline" and h["package"] == str(scratch / "view-baseline" / "aca_warp")
    assert all(0 < h["cpu_s"][p] for p in phases)


def test_a_free_task_waits_for_a_begun_preparation(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A task whose device is free takes a shard whose preparation a pool process has begun (held here until the
    task has asked for it), rather than make the shard itself; a shard whose preparation has not begun (held before
    its mark), or began longer ago than ``BEGUN_WAIT_S``, is left to the task."""
    import functools

    from aca_warp.sweep import prepare as prep_mod

    monkeypatch.setattr(prep_mod, "BEGUN_WAIT_S", 600.0)  # however slow this machine
    spec = _spec()
    gate = tmp_path / "gate-expired"  # marked, then held past the (short) wait
    p = Preparer(spec.doc, str(spec.base_dir), 1, 1, device="cpu")
    p.prepare = functools.partial(prep_mod._begin, p.folder, functools.partial(gated, str(gate), p.work))
    try:
        p.plan([0])
        _in_time(lambda: _until(lambda: p.began(0)), 120)
        monkeypatch.setattr(prep_mod, "BEGUN_WAIT_S", 0.2)
        t = time.monotonic()
        assert _in_time(lambda: p.take(0, lambda: True), 120) is None and time.monotonic() - t < 60
    finally:
        gate.touch()
        p.close()
    monkeypatch.setattr(prep_mod, "BEGUN_WAIT_S", 600.0)
    for begun in (True, False):
        gate = tmp_path / f"gate-{begun}"  # one per case, left in place: the held processes see it and finish
        p = Preparer(spec.doc, str(spec.base_dir), 1, 1, device="cpu")
        if begun:  # shard 0 marked, then held
            p.prepare = functools.partial(prep_mod._begin, p.folder, functools.partial(gated_one, str(gate), 0, p.work))
        else:  # shard 0 held before its mark
            p.prepare = functools.partial(gated_one, str(gate), 0, p.prepare)
        try:
            p.plan([0, 1])
            if begun:
                _in_time(lambda p=p: _until(lambda: p.began(0)), 120)
                asked: list[int] = []
                threading.Timer(0.3, gate.touch).start()
                shard = _in_time(lambda p=p, asked=asked: p.take(0, lambda: asked.append(0) or True), 120)
                assert isinstance(shard, PreparedShard) and shard.index == 0 and not asked
                # no pool process writes into the folder while it is removed: shard 1 prepared first
                _in_time(lambda p=p: _until(lambda: p.first_ready([1]) == 1), 120)
            else:
                time.sleep(0.5)  # the pool process holds shard 0 before marking it
                assert not p.began(0) and p.take(0, lambda: True) is None
        finally:
            p.close()  # before the gate opens: a process held before its mark then finds no folder to write into
            gate.touch()
        assert not Path(p.folder).exists()


def test_a_free_worker_waits_for_a_begun_preparation(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On Dask too: a worker with nothing to do is handed the first shard once the pool process that has begun it
    is done (its file, not the shard), instead of the shard unprepared."""
    pytest.importorskip("distributed")
    import functools

    from aca_warp.sweep import cluster
    from aca_warp.sweep import prepare as prep_mod

    monkeypatch.setattr(prep_mod, "BEGUN_WAIT_S", 600.0)  # however slow the cluster's start on this machine

    gate = tmp_path / "gate"
    made = Preparer.__init__

    def held(self: Preparer, *args, **kwargs) -> None:
        made(self, *args, **kwargs)  # marked, then held until the feed below has seen the worker free
        self.prepare = functools.partial(prep_mod._begin, self.folder, functools.partial(gated, str(gate), self.work))

    fed = cluster._feed
    handed: list[str] = []

    def feed(book, submit, preparer, **kwargs) -> None:
        _in_time(lambda: _until(lambda: preparer.began(0)), 120)
        threading.Timer(0.5, gate.touch).start()
        fed(book, _recording(submit, handed), preparer, **kwargs)

    res = _fed_sweep(tmp_path, monkeypatch, held, feed, gate, prepare=1)
    assert res.ran == [0, 1, 2] and not res.failed
    assert handed[0] == "SpooledShard", handed


def test_a_ready_shard_goes_before_one_still_being_prepared(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """On Dask, a free worker is handed the next shard whose preparation is ready while the first one's is still
    under way (held here until the second shard has been handed over), not left waiting behind it; every shard runs
    prepared, and the sweep's outputs are those of the same sweep in this process."""
    pytest.importorskip("distributed")
    import functools

    from aca_warp.sweep import cluster
    from aca_warp.sweep import prepare as prep_mod

    monkeypatch.setattr(prep_mod, "BEGUN_WAIT_S", 600.0)  # however slow the cluster's start on this machine
    gate = tmp_path / "gate"
    made = Preparer.__init__

    def held(self: Preparer, *args, **kwargs) -> None:
        made(self, *args, **kwargs)  # shard 0 marked as begun, then held
        work = functools.partial(gated_one, str(gate), 0, self.work)
        self.prepare = functools.partial(prep_mod._begin, self.folder, work)

    fed = cluster._feed
    handed: list[tuple[int, str]] = []

    def noted(submit):
        def submitted(i, prepared):
            handed.append((i, type(prepared).__name__))
            if i == 1:
                gate.touch()
            return submit(i, prepared)

        return submitted

    def feed(book, submit, preparer, **kwargs) -> None:
        _in_time(lambda: _until(lambda: preparer.began(0) and preparer.poll(1)), 120)
        fed(book, noted(submit), preparer, **kwargs)

    res = _fed_sweep(tmp_path, monkeypatch, held, feed, gate, prepare=2)
    assert res.ran == [0, 1, 2] and not res.failed
    assert handed[0] == (1, "SpooledShard") and sorted(handed) == [(i, "SpooledShard") for i in range(3)], handed
    monkeypatch.undo()
    alone = run_sweep(_spec(), tmp_path / "alone", device="cpu", workers=0)
    assert alone.ran == [0, 1, 2]
    a, b = _outputs(tmp_path / "out"), _outputs(tmp_path / "alone")
    assert all(np.array_equal(a[k], b[k]) for k in a), [k for k in a if not np.array_equal(a[k], b[k])]


def _fed_sweep(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    held: Callable[..., None],
    feed: Callable[..., None],
    gate: Path,
    *,
    prepare: int,
) -> Any:
    """The small sweep on a one-worker local cluster, its pool's ``Preparer.__init__`` replaced by ``held`` and the
    client's feed by ``feed``; ``gate`` is touched when it ends, whatever happened (the held pool processes go on)."""
    from aca_warp.sweep import cluster

    monkeypatch.setattr(Preparer, "__init__", held)
    monkeypatch.setattr(cluster, "_feed", feed)
    try:
        return _in_time(lambda: run_sweep(_spec(), tmp_path / "out", device="cpu", workers=1, prepare=prepare))
    finally:
        gate.touch()


def _until(done, seconds: float = 120.0) -> None:
    deadline = time.monotonic() + seconds
    while not done():
        assert time.monotonic() < deadline
        time.sleep(0.01)


def test_bench_sweep_preparations() -> None:
    """scripts/bench_sweep.py's account of who made a call's shards: the pool's preparations begun before its first
    had finished (the first wave) apart from the later ones, each with its hand-over, the shards their tasks made
    themselves, and the start of each pool process that made a shard; in words in the Markdown line."""
    from scriptload import load_script

    bench = load_script("bench_sweep")

    def shard(**phases: tuple[float, float]) -> dict:
        return {"phases": {k: list(v) for k, v in phases.items()}}

    shards = [
        shard(prepare=(0.0, 0.05), build=(0.1, 0.3), setup=(0.3, 0.4), kernel=(0.4, 0.7)),
        shard(
            prepare_ahead=(0.2, 0.6),
            prepare=(0.7, 0.75),
            upload=(0.75, 0.77),
            setup=(0.77, 0.78),
            pool_warp=(0.01, 0.15),
            pool_start=(0.01, 0.19),
        ),
        shard(prepare_ahead=(0.55, 0.9), prepare=(1.0, 1.1), upload=(1.1, 1.12), setup=(1.12, 1.13)),
        shard(prepare_ahead=(0.6, 0.85), prepare=(1.2, 1.25), upload=(1.25, 1.26), setup=(1.26, 1.27)),
    ]
    p = bench.preparations(shards)
    assert p["first"] == pytest.approx([0.4, 0.35]) and p["later"] == pytest.approx([0.25])
    assert p["handover_first"] == pytest.approx([0.08, 0.13]) and p["handover_later"] == pytest.approx([0.07])
    assert p["own"] == pytest.approx([0.35])
    assert p["pool_begun"] == [0.01] and p["pool_ready"] == [0.19] and p["pool_warp"] == pytest.approx([0.14])
    text = bench.made_by(p)
    assert "pool processes begun 1, 0.01–0.01 s into the call, ready 1, 0.19–0.19 s (Warp started after 1, " in text
    assert "before its first was done 2, 0.35–0.40 s (their hand-over 2, 0.08–0.13 s)" in text, text
    assert "later 1, 0.25–0.25 s" in text and "by their tasks 1, 0.35–0.35 s" in text
    alone = bench.made_by(bench.preparations([shards[0]]))
    assert bench.preparations([shards[0]])["first"] == [] and "pool before its first was done none" in alone
    assert "pool processes" not in alone


def test_bench_sweep_kinds_and_steps() -> None:
    """scripts/bench_sweep.py's sweeps: ``seeds`` gives every pad a patch seed of its own (1…pads), ``product`` the
    M × F_N × 8 seeds of ``hf1_product_doc``; ``--dt default`` leaves the step to the sweep's default (1e-6/3 s for the
    seeds of hf1's physics, 5e-8 s for the product, whose M and load vary), a number names it; the seeds sweep warms
    up on two shards per unit (a power of two, at most the sweep)."""
    from scriptload import load_script

    from aca_warp.sweep import hf1_product_doc, load_spec

    bench = load_script("bench_sweep")
    cfg = {"pads": 2048, "shard_size": 256, "patches": None, "precision": "fp32", "units": 2}
    seeds = load_spec(bench.sweep_doc(hf1_product_doc, {**cfg, "sweep": "seeds", "dt": None}, 1e-3))
    assert seeds.doc["parameters"] == {"patches.seed": {"range": [1, 2049]}} and seeds.dt == 1e-6 / 3
    product = load_spec(bench.sweep_doc(hf1_product_doc, {**cfg, "sweep": "product", "dt": None}, 1e-3))
    assert set(product.doc["parameters"]) == {"friction.M", "load.normal_force", "patches.seed"}
    assert product.dt == 5e-8
    assert load_spec(bench.sweep_doc(hf1_product_doc, {**cfg, "sweep": "seeds", "dt": 2e-8}, 1e-3)).dt == 2e-8
    assert bench.warm_up_pads({**cfg, "sweep": "seeds"}) == 1024
    assert bench.warm_up_pads({**cfg, "sweep": "seeds", "units": 1, "pads": 256}) == 256
    assert bench.warm_up_pads({**cfg, "sweep": "product"}) == 2048


def test_default_pool_size(monkeypatch: pytest.MonkeyPatch) -> None:
    """The preparation pool's default: 2 processes per GPU of a local CUDA sweep, 4 per GPU for a sweep with at
    least one patch layout per two pads (its preparation binds), at least 4, at most the cores the workers leave (one
    kept for the client), at least 1; none on the CPU or for a cluster given by address."""
    from aca_warp.sweep import hf1_product_doc, run

    seeds = load_spec({"sweep": {"name": "s", "base": "hf1"}, "parameters": {"patches.seed": {"range": [1, 65]}}})

    def of_seeds(seeds: list[int]) -> Any:
        return load_spec({"sweep": {"name": "l", "base": "hf1"}, "parameters": {"patches.seed": seeds}})

    half, fewer = of_seeds(list(range(1, 33)) + [1] * 32), of_seeds(list(range(1, 32)) + [1] * 33)
    product = load_spec(hf1_product_doc("p", 4, 2, 8, shard_size=16, duration=1e-6, precision="fp32"))
    assert (
        seeds.layout_count,
        product.layout_count,
        load_spec({"sweep": {"name": "b", "base": "hf1"}}).layout_count,
    ) == (64, 8, 1)
    monkeypatch.setattr(run.os, "cpu_count", lambda: 32)
    assert run.prepare_processes("cuda:0", None, True) == run.prepare_processes("cuda:0", None, True, product) == 4
    assert run.prepare_processes("cuda:0", None, True, seeds) == 4  # one GPU: at least 4 either way
    assert run.prepare_processes("cuda:0,cuda:1", None, True) == 4
    assert (
        run.prepare_processes("cuda:0,cuda:1", None, True, seeds)
        == run.prepare_processes("cuda:0,cuda:1", None, True, half)
        == 8
    )
    assert run.prepare_processes("cuda:0,cuda:1", None, True, fewer) == 4  # 31 layouts of 64 pads
    two_each = load_spec(hf1_product_doc("q", 2, 1, 8, shard_size=16, duration=1e-6, precision="fp32"))
    assert (two_each.layout_count, two_each.pad_count) == (8, 16)  # no pad's layout its own, one per two pads
    assert run.prepare_processes("cuda:0,cuda:1", None, True, two_each) == 8
    assert run.prepare_processes("cuda:0,cuda:1,cuda:2,cuda:3", None, True) == 8
    assert run.prepare_processes("cuda:0,cuda:1,cuda:2,cuda:3", None, True, seeds) == 16
    assert run.prepare_processes("cpu", None, True, seeds) == run.prepare_processes("cuda:0", None, False, seeds) == 0
    monkeypatch.setattr(run.os, "cpu_count", lambda: 4)
    assert run.prepare_processes("cuda:0", None, True) == 2  # 4 cores, one worker, the client
    assert run.prepare_processes("cuda:0,cuda:1", None, True, seeds) == 1  # 4 cores, two workers, the client
    assert run.prepare_processes("cuda:0", 3, True) == 1


def test_bench_sweep_host_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--host-only``: the host phases of one shard per code and no sweep (no run rows); the seeds sweep's shard has
    a layout per pad."""
    import warp as wp
    from scriptload import load_script

    monkeypatch.setenv("WARP_CACHE_PATH", str(Path(wp.config.kernel_cache_dir).parent))
    bench = load_script("bench_sweep")
    out, md = tmp_path / "h.json", tmp_path / "h.md"
    argv = ["--device", "cpu", "--host-only", "--host-repeat", "1", "--sweep", "seeds", "--pads", "8", "--patches"]
    argv += ["12", "--shard-size", "4", "--json", str(out), "--md", str(md), "--dir", str(tmp_path / "w")]
    assert bench.main(argv) == 0
    doc = json.loads(out.read_text())
    assert doc["results"] == [] and doc["runs"] == [] and doc["sweep"]["kind"] == "seeds"
    (host,) = doc["host"]
    assert host["code"] == "new" and host["pads"] == 4 and host["wall_s"]["prepare"] > 0
    assert "new: host time per shard (least of 1" in md.read_text()


def _slow_exit(seconds: float) -> None:
    """A pool process's initializer: its exit takes ``seconds`` (as a GPU context's teardown does)."""
    import multiprocessing.util

    multiprocessing.util.Finalize(None, time.sleep, args=(seconds,), exitpriority=10)


def test_closing_the_pool_does_not_wait_for_its_processes_to_exit() -> None:
    """The pool is let go (:func:`_let_go`) and dropped in this thread at once, although its processes take 2 s to
    exit (a plain ``shutdown(wait=False)`` followed by the executor's collection here waits for them: the collection
    takes the lock its manager thread holds while it joins them, in Python 3.12); they do exit, in the background,
    and the executor is collected there."""
    import gc
    import multiprocessing
    import weakref
    from concurrent.futures import ProcessPoolExecutor

    from aca_warp.sweep.prepare import _let_go

    pool = ProcessPoolExecutor(
        2, mp_context=multiprocessing.get_context("forkserver"), initializer=_slow_exit, initargs=(2.0,)
    )
    assert list(pool.map(abs, [-1, -2, -3])) == [1, 2, 3]
    procs = list(pool._processes.values())
    ref = weakref.ref(pool)
    t = time.perf_counter()
    _let_go(pool)
    time.sleep(0.2)  # the manager thread is joining the processes now
    del pool
    gc.collect()
    assert time.perf_counter() - t < 1.5  # their exit takes 2 s
    assert ref() is not None and any(p.is_alive() for p in procs)  # not collected here: its processes still exit
    for p in procs:
        p.join(10)
    deadline = time.monotonic() + 10
    while ref() is not None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert ref() is None and not any(p.is_alive() for p in procs)  # collected once they had


def test_pool_processes_are_let_go_once_every_planned_shard_is_taken() -> None:
    """Once each planned shard has been taken or dropped, the pool's processes exit before :meth:`Preparer.close`
    (while the last shards would run); a shard asked of the pool after that is refused, not silently prepared."""
    spec = _spec()
    prep = Preparer(spec.doc, str(spec.base_dir), processes=2, ahead=2, device="cpu")
    try:
        prep.plan([0, 1, 2])
        assert _in_time(lambda: prep.get(0), 120).index == 0
        procs = list(prep.pool._processes.values())
        assert procs and all(p.is_alive() for p in procs) and not prep.released
        prep.forget(2)
        assert not prep.released  # shard 1 still planned
        assert _in_time(lambda: prep.get(1), 120).index == 1
        assert prep.released
        deadline = time.monotonic() + 30
        while any(p.is_alive() for p in procs) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert not any(p.is_alive() for p in procs)  # gone before close()
        with pytest.raises(RuntimeError, match="has made all its shards"):
            prep.get(0)
    finally:
        prep.close()


@pytest.fixture
def kept_clean() -> Iterator[None]:
    """After a test of the kept pool: no block open, no call holding it, none kept (a failed test's leftovers are let
    go here, so that they cannot reach the next test)."""
    yield
    from aca_warp.sweep.prepare import _let_go

    with _KEPT.lock:
        left = (_KEPT.depth, len(_KEPT.users), _KEPT.pool is not None)
        if _KEPT.pool is not None:
            _let_go(_KEPT.pool)
        _KEPT.depth, _KEPT.pool, _KEPT.key = 0, None, None
        _KEPT.users.clear()
    assert left == (0, 0, False), left


def _wait_gone(procs: list, seconds: float = 30.0) -> bool:
    """Whether every process of ``procs`` (multiprocessing processes) has exited within ``seconds``."""
    deadline = time.monotonic() + seconds
    while any(p.is_alive() for p in procs) and time.monotonic() < deadline:
        time.sleep(0.02)
    return not any(p.is_alive() for p in procs)


def test_a_kept_pool_serves_the_next_calls(tmp_path: Path, kept_clean: None) -> None:
    """Inside :func:`keep_preparation_pool` the second sweep call prepares its shards in the processes the first call
    started, which outlive the first call; the block's end lets them go; the outputs are those of sweeps with a pool
    of their own and of sweeps without a pool, bit for bit. Outside a block every call has a pool of its own."""
    from aca_warp.sweep import keep_preparation_pool

    spec = _spec()
    run_sweep(spec, tmp_path / "none", workers=0, overlap=True, prepare=0)
    run_sweep(spec, tmp_path / "own", workers=0, overlap=True, prepare=2)
    with keep_preparation_pool():
        first = Preparer(spec.doc, str(spec.base_dir), processes=2, ahead=2, device="cpu")
        first.plan([0, 1, 2])
        for i in (0, 1, 2):
            assert _in_time(lambda i=i: first.get(i), 120).index == i
        first.close()
        procs = list(first.pool._processes.values())
        assert first.kept and first.released and procs and all(p.is_alive() for p in procs)  # kept past its call
        res = [
            _in_time(lambda k=k: run_sweep(spec, tmp_path / f"kept{k}", workers=0, overlap=True, prepare=2))
            for k in range(2)
        ]
        second = Preparer(spec.doc, str(spec.base_dir), processes=2, ahead=2, device="cpu")
        assert second.pool is first.pool and second.kept
        second.close()
        assert {p.pid for p in second.pool._processes.values()} == {p.pid for p in procs}  # the same processes
    assert _wait_gone(procs)  # let go at the block's end
    assert all(any("prepare_ahead" in s["timings"] for s in r.summaries) for r in res)  # the kept pool made some
    outputs = {name: _outputs(tmp_path / name) for name in ("none", "own", "kept0", "kept1")}
    for name in ("own", "kept0", "kept1"):
        for k, v in outputs["none"].items():
            assert v.tobytes() == outputs[name][k].tobytes(), (name, k)
    alone = Preparer(spec.doc, str(spec.base_dir), processes=1, ahead=1, device="cpu")
    try:
        assert not alone.kept and alone.pool is not first.pool
    finally:
        alone.close()


def test_a_kept_pool_is_replaced_when_broken_or_unlike(kept_clean: None) -> None:
    """A kept pool whose process died, or one made for another number of processes, is let go and a new one kept in
    its place; an inner block's end keeps the pool, the outermost lets it go."""
    from aca_warp.sweep import keep_preparation_pool

    spec = _spec()

    def preparer(processes: int) -> Preparer:
        prep = Preparer(spec.doc, str(spec.base_dir), processes=processes, ahead=1, device="cpu")
        prep.plan([0])
        assert _in_time(lambda: prep.get(0), 120).index == 0
        prep.close()
        return prep

    with keep_preparation_pool():
        first = preparer(1)
        for p in first.pool._processes.values():
            p.kill()
        assert _wait_gone(list(first.pool._processes.values()))
        with keep_preparation_pool():
            second = preparer(1)  # the first pool is broken now
            assert second.pool is not first.pool and second.kept
        assert preparer(1).pool is second.pool  # kept past the inner block
        procs = list(second.pool._processes.values())
        third = preparer(2)
        assert third.pool is not second.pool and _wait_gone(procs)  # the unlike pool let go
        procs = list(third.pool._processes.values())
        assert all(p.is_alive() for p in procs)
    assert _wait_gone(procs)


def test_a_kept_pool_in_use_is_never_let_go_under_its_call(kept_clean: None) -> None:
    """While a call uses the kept pool, another call that needs other settings gets a pool of its own (the kept one
    stays), and the block's end leaves the pool to that call, whose end lets it go."""
    from aca_warp.sweep import keep_preparation_pool

    spec = _spec()
    with keep_preparation_pool():
        using = Preparer(spec.doc, str(spec.base_dir), processes=1, ahead=1, device="cpu")
        other = Preparer(spec.doc, str(spec.base_dir), processes=2, ahead=1, device="cpu")
        try:
            assert using.kept and not other.kept and other.pool is not using.pool
            other.plan([0])
            assert _in_time(lambda: other.get(0), 120).index == 0
        finally:
            other.close()
        using.plan([1, 2])
        assert _in_time(lambda: using.get(1), 120).index == 1
    procs = list(using.pool._processes.values())
    assert procs and all(p.is_alive() for p in procs)  # the block has ended: its call still has the pool
    assert _KEPT.pool is using.pool and _KEPT.users == {using}  # still kept, for its call alone
    assert _in_time(lambda: using.get(2), 120).index == 2  # its last shard: the pool is let go now
    using.close()
    assert _wait_gone(procs)


def test_a_pool_with_a_dead_process_is_not_usable() -> None:
    """A pool one of whose processes has died is not taken for work, also before the pool's own thread has noticed and
    marked it broken (a stand-in pool whose dead process it has not noticed: it would still take a task)."""
    from aca_warp.sweep.prepare import _usable

    class Process:
        def __init__(self, alive: bool) -> None:
            self.alive = alive

        def is_alive(self) -> bool:
            return self.alive

    class Pool:
        def __init__(self, *alive: bool) -> None:
            self._processes = {k: Process(a) for k, a in enumerate(alive)}

        def submit(self, fn: Callable[[], int]) -> Any:
            return type("Task", (), {"cancel": lambda self: True})()

    assert _usable(Pool(True, True))  # type: ignore[arg-type]
    assert not _usable(Pool(True, False))  # type: ignore[arg-type]
