"""Shared by the tests: ``aca-warp`` in a subprocess (optionally under a file-size limit), stopped, killed; small
scenes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from aca_warp.scene import Friction, Growth, Initial, Pad, Patches, Record, Scene


def nine_patch_scene(*, increment: float, interval: float, sample_dt: float, duration: float) -> Scene:
    """9 HF1-size patches on a 1.5 mm grid sharing 20 N with the matrix, sliding at 10 m/s (seeded areas and
    initial perturbation), growing by ``increment`` [m] · √A every ``interval`` [s]; samples every ``sample_dt``
    [s] over ``duration`` [s]."""
    pos = [(i * 1.5e-3, 0.13 + j * 1.5e-3) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    area = np.random.default_rng(2).uniform(2e-8, 8e-8, len(pos))
    p = Patches(np.array([q[0] for q in pos]), np.array([q[1] for q in pos]), area, np.full(len(pos), 3e-6))
    return Scene(
        name="grow",
        pad=Pad(),
        patches=p,
        friction=Friction(M=0.8),
        normal_force=20.0,
        initial=Initial(perturbation=0.05, seed=3),
        record=Record(sample_dt=sample_dt),
        growth=Growth(increment=increment, interval=interval),
        duration=duration,
    )


# runs ``aca_warp.cli`` with RLIMIT_FSIZE = argv[1] bytes and SIGXFSZ ignored (writes past it fail with EFBIG)
LIMITED = (
    "import resource, signal, sys; lim = int(sys.argv[1]); signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
    "resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim)); from aca_warp.cli import run; run(sys.argv[2:])"
)


def small_scene_toml(
    name: str = "small",
    *,
    count: int = 60,
    duration: float = 2.0e-6,
    sample_dt: float = 1.0e-7,
    patches: tuple[str, ...] = (),
    perturbation: float | None = None,
    disc: bool = True,
    tables: dict[str, dict] | None = None,
) -> str:
    """A small HF scene file: ``count`` HF1-size patches (seed 4, 3 µm), 20 N, samples every ``sample_dt`` [s] for
    ``duration`` [s]; ``patches``: the per-patch histories recorded; ``perturbation``: a seeded initial velocity
    perturbation [m/s] (seed 2); ``disc``: the disc at 10 m/s stated; ``tables`` ({table: {key: value}}): keys
    replaced or added."""
    doc: dict[str, dict] = {"scene": {"name": name}, "load": {"normal_force": 20.0}}
    if disc:
        doc["disc"] = {"sliding_speed": 10.0}
    doc["patches"] = {"count": count, "area_min": 2.0e-8, "area_max": 8.0e-8, "height": 3.0e-6, "seed": 4}
    if perturbation is not None:
        doc["initial"] = {"perturbation": perturbation, "seed": 2}
    doc["record"] = {"sample_dt": sample_dt, **({"patches": list(patches)} if patches else {})}
    doc["run"] = {"duration": duration}
    for t, kv in (tables or {}).items():
        doc.setdefault(t, {}).update(kv)
    return "".join(f"[{t}]\n" + "".join(f"{k} = {v!r}\n" for k, v in kv.items()) for t, kv in doc.items())


def env(**extra: str) -> dict[str, str]:
    """The environment of a subprocess: this one's (the same kernel cache), plus ``extra``."""
    return {**os.environ, **extra}


def cli(args: list[str], *, limit: int | None = None, **extra: str) -> subprocess.CompletedProcess:
    """Run ``aca-warp ARGS`` in a subprocess (under a file-size limit of ``limit`` bytes) and wait for it."""
    pre = [sys.executable, "-c", LIMITED, str(limit)] if limit is not None else [sys.executable, "-m", "aca_warp.cli"]
    return subprocess.run([*pre, *args], env=env(**extra), capture_output=True, text=True, timeout=300)


def start(args: list[str], **extra: str) -> subprocess.Popen:
    """Start ``aca-warp ARGS`` in a subprocess."""
    return subprocess.Popen(
        [sys.executable, "-m", "aca_warp.cli", *args],
        env=env(**extra),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@contextmanager
def started(args: list[str], **extra: str) -> Iterator[subprocess.Popen]:
    """:func:`start` for the body; killed (if still running) and its pipes closed after it."""
    proc = start(args, **extra)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


def wait_for(path: Path, proc: subprocess.Popen, *, poll: float = 0.0005, timeout: float = 120.0) -> None:
    """Wait until ``path`` exists while ``proc`` runs (asserts that it appeared before ``proc`` ended)."""
    deadline = time.monotonic() + timeout
    while not path.exists():
        assert proc.poll() is None, f"{proc.args} ended before {path} appeared: {proc.stderr.read()}"
        assert time.monotonic() < deadline, f"{path} did not appear"
        time.sleep(poll)


def stop(proc: subprocess.Popen, timeout: float = 10.0) -> None:
    """SIGSTOP ``proc`` and wait until every thread of it has stopped (it keeps its files and locks, writes
    nothing more): the signal is delivered asynchronously, and a thread running on another core could otherwise
    still write after this returns."""
    os.kill(proc.pid, signal.SIGSTOP)
    deadline = time.monotonic() + timeout
    tasks = Path(f"/proc/{proc.pid}/task")
    while True:
        states = []
        for stat in tasks.glob("*/stat"):
            try:
                states.append(stat.read_text().rsplit(")", 1)[1].split()[0])
            except (OSError, IndexError):
                continue  # a thread that just ended
        if states and all(s in "tT" for s in states):
            return
        assert time.monotonic() < deadline, f"{proc.args} did not stop: thread states {states}"
        time.sleep(0.001)


def resume(proc: subprocess.Popen) -> None:
    """SIGCONT ``proc``."""
    os.kill(proc.pid, signal.SIGCONT)


def error_lines(stderr: str) -> list[str]:
    """stderr without Warp's start-up notes."""
    return [line for line in stderr.splitlines() if line.strip() and not line.startswith("Warp ")]


def datasets(path: Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file by path."""
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None)
    return out


def assert_same_datasets(a: Path, b: Path) -> None:
    """Same dataset names, dtypes, shapes and bits."""
    da, db = datasets(a), datasets(b)
    assert sorted(da) == sorted(db)
    for k in da:
        assert da[k].dtype == db[k].dtype and da[k].shape == db[k].shape, k
        assert da[k].tobytes() == db[k].tobytes(), k
