"""Overlapped sweeps: the same files as the sequential path, bit for bit; the writer thread and the device's turns."""

from __future__ import annotations

import threading
import time
import types
from pathlib import Path

import h5py
import numpy as np
import pytest
from procs import assert_same_datasets

from aca_warp.sweep import ChunkWriter, KernelTurn, ShardCancelled, load_spec, run_sweep

# 8 pads of 20 patches in 3 shards (3, 3, 2 pads); 40 µs at 0.1 µs samples: 401 samples in 16 recorder chunks (the
# CPU engine's chunk is a graph of at most 256 steps: 25 samples of 10 steps), so that the writer joins chunks and the
# time axis is appended several times
SPEC = {
    "sweep": {"base": "hf1", "shard_size": 3, "name": "overlap"},
    "run": {"duration": 4e-5, "precision": "fp32", "sample_dt": 1e-7},
    "base": {"patches": {"count": 20}},
    "parameters": {"friction.M": [0.6, 0.9], "patches.seed": {"range": [1, 5]}},
}
# attributes that say how long something took or how much memory there was, not what was computed
_TIMES = {"timings", "wall_time", "compile_time", "batch_capacity"}


def _attrs(path: Path) -> dict:
    with h5py.File(path, "r") as f:
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in f.attrs.items() if k not in _TIMES}


def _assert_same_files(a: Path, b: Path, shards: int = 3) -> None:
    names = sorted(p.name for p in a.glob("shard-*.h5"))
    assert names == sorted(p.name for p in b.glob("shard-*.h5")) and len(names) == shards
    for n in names:
        assert_same_datasets(a / n, b / n)
        assert _attrs(a / n) == _attrs(b / n), n


@pytest.fixture(scope="module")
def sequential(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sweep one shard after another with inline writes, each shard one batch: the files every overlapped run of
    this module must equal (the files do not depend on how the pads are batched)."""
    seq = tmp_path_factory.mktemp("overlap") / "seq"
    r = run_sweep(load_spec(SPEC, base_dir=Path.cwd()), seq, workers=0, overlap=False)
    assert r.ran == [0, 1, 2] and not r.failed and not r.faults, (r.ran, r.failed, r.faults)
    return seq


@pytest.mark.parametrize("memory_fraction", [0.5, 1e-12], ids=["one-batch", "a-batch-per-pad"])
def test_overlapped_files_equal_sequential(tmp_path: Path, sequential: Path, memory_fraction: float) -> None:
    """In this process: two shard tasks in threads (scenes and files beside runs, writes behind them) against one
    shard after another with inline writes; also when every pad is its own batch (rows appended per batch, by both
    paths)."""
    spec = load_spec(SPEC, base_dir=Path.cwd())
    if memory_fraction < 0.5:  # the sequential path's rows appended per batch too
        r = run_sweep(spec, tmp_path / "seq", workers=0, overlap=False, memory_fraction=memory_fraction)
        assert r.ran == [0, 1, 2] and not r.failed and not r.faults, (r.ran, r.failed, r.faults)
        _assert_same_files(sequential, tmp_path / "seq")
    ovl = tmp_path / "ovl"
    r = run_sweep(spec, ovl, workers=0, overlap=True, memory_fraction=memory_fraction)
    assert r.ran == [0, 1, 2] and not r.failed and not r.faults, (r.ran, r.failed, r.faults)
    _assert_same_files(sequential, ovl)
    with h5py.File(ovl / "shard-00002.h5", "r") as f:
        assert f["global/mu"].shape == (2, 401) and f["global/time"].shape == (401,)
        assert np.all(np.isfinite(f["global/mu"][()]))
        assert (f.attrs["batch_capacity"] >= 3) == (memory_fraction == 0.5)
    summary = {s["index"]: s for s in r.summaries}[0]
    assert summary["batches"] == (1 if memory_fraction == 0.5 else 3)
    assert summary["timings"]["kernel"] > 0 and summary["timings"]["run_end"] >= summary["timings"]["run_start"]


def test_overlapped_shards_do_warp_work_one_at_a_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two shard tasks in threads never call Warp at the same time: a model build beside another shard's run fails
    now and then on the CPU (the run captures a CPU graph; scripts/warp_cpu_threads.py measures it), so the build is
    done in the device's turn too. Every build and run is widened by a short sleep, so that two of them would
    overlap if the turn allowed it."""
    import aca_warp.hf.loop as loop
    import aca_warp.hf.model as model

    inside, most, guard = [0], [0], threading.Lock()

    def counted(f):
        def g(*args, **kwargs):
            with guard:
                inside[0] += 1
                most[0] = max(most[0], inside[0])
            try:
                time.sleep(0.05)
                return f(*args, **kwargs)
            finally:
                with guard:
                    inside[0] -= 1

        return g

    monkeypatch.setattr(model, "build_model", counted(model.build_model))
    monkeypatch.setattr(loop, "run_hf", counted(loop.run_hf))
    spec = load_spec(SPEC, base_dir=Path.cwd())
    r = run_sweep(spec, tmp_path / "ovl", workers=0, overlap=True, memory_fraction=1e-12)
    assert r.ran == [0, 1, 2] and not r.failed and not r.faults, (r.ran, r.failed, r.faults)
    assert most[0] == 1


def test_overlapped_on_dask_equals_sequential(tmp_path: Path, sequential: Path) -> None:
    """A Dask worker process (two shard tasks in its threads) with writes behind its runs, against the sequential
    path in this process (two worker processes: tests/test_sweep.py::test_dask_equals_serial_and_resume)."""
    spec = load_spec(SPEC, base_dir=Path.cwd())
    ovl = tmp_path / "dask"
    r = run_sweep(spec, ovl, workers=1, overlap=True)
    assert r.workers == 1 and sorted(r.ran) == [0, 1, 2] and not r.failed
    _assert_same_files(sequential, ovl)


def _chunk(t0: float, k: int, pads: int = 2) -> types.SimpleNamespace:
    t = t0 + np.arange(k, dtype=np.float64)
    return types.SimpleNamespace(time=t, globals=np.repeat(t[:, None, None], pads, axis=1).repeat(3, axis=2))


def test_chunk_writer_joins_chunks_of_a_batch_and_keeps_order() -> None:
    written: list[tuple[int, int, np.ndarray]] = []
    w = ChunkWriter(lambda item: written.append((item[0], item[1], item[2].time.copy())), rows=5)
    w.put((0, 2, _chunk(0, 3)))
    w.put((0, 2, _chunk(3, 3)))  # 6 rows held: one write of both
    w.put((0, 2, _chunk(6, 2)))
    w.put((2, 4, _chunk(0, 1)))  # another batch: the held rows of the first go out first
    w.close()
    assert [(b0, b1, t.tolist()) for b0, b1, t in written] == [
        (0, 2, [0, 1, 2, 3, 4, 5]),
        (0, 2, [6, 7]),
        (2, 4, [0]),
    ]
    assert w.seconds >= 0.0


def test_chunk_writer_raises_the_first_write_error_in_the_run_thread() -> None:
    calls = []

    def write(item: tuple) -> None:
        calls.append(item[0])
        raise OSError(28, "No space left on device")

    w = ChunkWriter(write, rows=1)
    w.put((0, 1, _chunk(0, 1, 1)))
    with pytest.raises(OSError, match="No space"):
        for _ in range(200):  # the error reaches a later put (or close) once the thread has met it
            w.put((0, 1, _chunk(0, 1, 1)))
            time.sleep(0.01)
        w.close()
    w.abort()
    assert calls == [0]  # nothing more was written after the first error


def test_kernel_turn_is_one_at_a_time_and_cancellable() -> None:
    import warp as wp

    dev = wp.get_device("cpu")
    cancel = threading.Event()
    a = KernelTurn(dev, cancel, processes=True)
    b = KernelTurn(dev, cancel, processes=True)
    a.enter()
    a.enter()  # idempotent
    entered = threading.Event()
    errors: list[BaseException] = []

    def other() -> None:
        try:
            b.enter()
            entered.set()
        except ShardCancelled as e:
            errors.append(e)

    t = threading.Thread(target=other)
    t.start()
    time.sleep(0.2)
    assert not entered.is_set()  # a holds the device
    cancel.set()
    t.join(5)
    assert len(errors) == 1 and not entered.is_set()
    a.exit()
    cancel.clear()
    b.enter()  # free again
    assert b.fd is None  # CPU: no turn across processes
    b.exit()


def test_gpu_turn_across_processes_is_a_file_lock(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A turn on a GPU (a stand-in device) holds the GPU's lock file, which another process (here: another open
    file, as flock sees one) cannot take until the turn ends; a turn that waits for that lock stops when the sweep
    stops, and gives the process's own turn back."""
    import fcntl
    import os

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))  # the user's private folder (tests/test_links.py)
    gpu = types.SimpleNamespace(is_cuda=True, uuid="GPU-test-0", pci_bus_id=None)
    cancel = threading.Event()
    a = KernelTurn(gpu, cancel, processes=True)
    a.enter()
    path = tmp_path / "aca-warp" / "kernel" / "GPU-test-0.lock"
    assert a.fd is not None and path.exists()
    other = os.open(path, os.O_RDWR)  # another process's view of the lock
    try:
        with pytest.raises(BlockingIOError):
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        a.exit()
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free once the turn ended
        b = KernelTurn(gpu, cancel, processes=True)
        got: list[str] = []

        def second() -> None:
            try:
                b.enter()
                got.append("turn")
            except ShardCancelled:
                got.append("cancelled")

        t = threading.Thread(target=second)
        t.start()
        time.sleep(0.2)
        assert got == []  # the other process holds the GPU
        cancel.set()
        t.join(5)
        assert got == ["cancelled"] and b.fd is None and not b.locked and not b.lock.locked()
    finally:
        os.close(other)


# 8 pads of 150 patches in 4 shards of 2; 0.4 ms in steps of 20 ns, 2 µs samples: tenths of a second of stepping per
# shard on one core (on the on-chip engine, which auto takes on the CPU), long beside a shard's upload
PIPELINE = {
    "sweep": {"base": "hf1", "shard_size": 2, "name": "pipeline"},
    "run": {"duration": 4e-4, "precision": "fp32", "sample_dt": 2e-6, "dt": 2e-8},
    "base": {"patches": {"count": 150}},
    "parameters": {"friction.M": [0.6, 0.7, 0.8, 0.9], "patches.seed": [1, 2]},
}


def test_pipeline_overlaps_preparation_and_writing_with_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The overlapped path with a preparation pool, in this process, from the phase times every shard records: the
    shards the pool made were made while an earlier shard was on the device and were ready when it came free; a
    shard's turn on the device (upload, set-up, run) began as soon as the one before had run; the last writes of a
    shard went on during the next one's turn (every write made slow here); the files equal the sequential path's."""
    import aca_warp.sweep.shard as shard
    from aca_warp.sweep.prepare import Preparer

    spec = load_spec(PIPELINE, base_dir=Path.cwd())
    warm = Preparer(spec.doc, str(spec.base_dir), 1, 1, device="cpu")  # this process's fork server, started once
    warm.get(0)
    warm.close()
    seq = tmp_path / "seq"
    run_sweep(spec, seq, workers=0, overlap=False, prepare=0)
    made = shard._chunk_writer

    def slow(*args):
        write = made(*args)

        def slowly(item):
            time.sleep(0.15)
            write(item)

        return slowly

    monkeypatch.setattr(shard, "_chunk_writer", slow)
    r = run_sweep(spec, tmp_path / "ovl", workers=0, overlap=True, prepare=1)
    assert r.ran == [0, 1, 2, 3] and not r.failed, (r.ran, r.failed)
    _assert_same_files(seq, tmp_path / "ovl", 4)
    t = {s["index"]: s["timings"] for s in r.summaries}
    span = {i: t[i]["spans"] for i in t}
    order = sorted(t, key=lambda i: span[i]["kernel"][0])  # the runs, in the order the device took them
    ahead = [i for i in order[1:] if "upload" in t[i]]
    assert len(ahead) >= 2, {i: sorted(t[i]) for i in t}  # the pool kept ahead of all but the first shard or two
    for k, i in enumerate(order[1:]):
        before = order[k]
        turn = span[i]["upload" if i in ahead else "build"][0]  # the device's turn of shard i began
        assert span[before]["kernel"][1] <= turn  # one shard on the device at a time
        assert span[before]["write"][1] > turn  # the file of the one before still written meanwhile
        if i in ahead:
            assert span[i]["prepare_ahead"][0] < span[before]["kernel"][1]  # made while an earlier shard ran
            assert span[i]["prepare_ahead"][1] <= span[before]["kernel"][1]  # ready when the device came free
            assert turn - span[before]["kernel"][1] < 0.25  # taken at once (a thread's wake-up on a busy machine)
