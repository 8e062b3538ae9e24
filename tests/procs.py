"""Shared by the tests: ``aca-warp`` in a subprocess (optionally under a file-size limit), stopped, killed; small
scenes (``scripts/small_scenes.py``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from scriptload import load_script

from aca_warp.scene import Friction, Growth, Initial, Pad, Patches, Record, Scene

_scenes = load_script("small_scenes")
small_scene_toml = _scenes.small_scene_toml
small_lf_scene_toml = _scenes.small_lf_scene_toml
three_applications = _scenes.three_applications


# the HF reference scene of the file-size, interrupt and resume tests (tests/test_storage.py, test_cli_faults.py):
# 2001 samples: the per-patch histories fill 2 chunk rows of 1024 samples (327 kB each); 1.3 MB stops the run when
# the second row begins (t = 512 µs), after the checkpoint at 500 µs; the whole file is 1.6 MB
HF_SCENE = small_scene_toml(
    "full", count=40, duration=1.0e-3, sample_dt=5.0e-7, perturbation=1.0e-3, patches=("velocity", "displacement")
)
# HF_SCENE's step [s] (strang's default, well inside its stable step) and precision: the file sizes and checkpoint
# times the storage tests expect are those of fp64 states
HF_DT = ["--dt", "5e-8", "--precision", "fp64"]


def nine_patch_scene(
    name: str = "grow",
    *,
    sample_dt: float,
    duration: float,
    increment: float | None = None,
    interval: float = 0.0,
    patches: tuple[str, ...] = (),
    centre_off: bool = False,
    **fields: Any,
) -> Scene:
    """9 HF1-size patches on a 1.5 mm grid at r = 0.13 m (seeded areas, 3 µm; ``centre_off``: the middle one moved
    4.5 mm off the grid, coupled to only some), M = 0.8, sharing 20 N with the matrix, sliding at 10 m/s, from a
    seeded initial perturbation of 0.05 m/s; samples every ``sample_dt`` [s] over ``duration`` [s] (``patches``: the
    per-patch histories recorded); growing by ``increment`` [m] · √A every ``interval`` [s] when ``increment`` is
    given. ``fields``: other Scene fields, or these replaced (``normal_force``, ``angular_velocity``, ``initial``)."""
    pos = [(i * 1.5e-3, 0.13 + j * 1.5e-3) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    if centre_off:
        pos[4] = (4.5e-3, 0.13)
    area = np.random.default_rng(2).uniform(2e-8, 8e-8, len(pos))
    p = Patches(np.array([q[0] for q in pos]), np.array([q[1] for q in pos]), area, np.full(len(pos), 3e-6))
    growth = None if increment is None else Growth(increment=increment, interval=interval)
    return Scene(
        **{
            "name": name,
            "pad": Pad(),
            "patches": p,
            "friction": Friction(M=0.8),
            "normal_force": 20.0,
            "initial": Initial(perturbation=0.05, seed=3),
            "record": Record(sample_dt=sample_dt, patches=patches),
            "growth": growth,
            "duration": duration,
            **fields,
        }
    )


# runs ``aca_warp.cli`` with RLIMIT_FSIZE = argv[1] bytes and SIGXFSZ ignored (writes past it fail with EFBIG).
# The limit is the soft one, lifted while Warp compiles a module (``Module._compile``, which a load calls only for a
# module the kernel cache lacks): on a cache that lacks one of the run's kernels (which depends on what ran before
# on the machine), the compile would otherwise meet the limit first (clang cannot write its precompiled header, an
# object file above the limit is lost) instead of the run's files. Nested or concurrent compiles are counted.
LIMITED = """
import resource, signal, sys, threading
import warp._src.context as context
lim = int(sys.argv[1])
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
compiling = [0, threading.Lock()]
def limit(step):
    with compiling[1]:
        compiling[0] += step
        soft = lim if compiling[0] == 0 else resource.RLIM_INFINITY
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, resource.RLIM_INFINITY))
compile_module = context.Module._compile
def compile_unlimited(self, *args, **kwargs):
    limit(1)
    try:
        return compile_module(self, *args, **kwargs)
    finally:
        limit(-1)
context.Module._compile = compile_unlimited
limit(0)
from aca_warp.cli import run
run(sys.argv[2:])
"""


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
    """stderr without Warp's start-up notes and the note that kernels are being compiled (printed on a kernel cache
    that lacks one of the command's kernels, which depends on what ran before on the machine)."""
    return [
        line
        for line in stderr.splitlines()
        if line.strip() and not line.startswith(("Warp ", "compiling kernels (once per machine"))
    ]


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


def assert_same_run_file(a: Path, b: Path, keys: tuple[str, ...]) -> None:
    """Same datasets (:func:`assert_same_datasets`) and the same root attributes ``keys``; both complete, without a
    checkpoint."""
    assert_same_datasets(a, b)
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        for key in keys:
            assert fa.attrs[key] == fb.attrs[key], key
        assert fa.attrs["complete"] and fb.attrs["complete"]
        assert "checkpoint" not in fa and "checkpoint" not in fb


def assert_refused(capsys: Any, cases: list[tuple[list[str], str]]) -> None:
    """Each ``aca-warp ARGV`` of ``cases`` (in this process; ``capsys``: pytest's fixture) exits 2 with one line on
    stderr that holds its message."""
    from aca_warp.cli import main

    for argv, message in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], (argv, err)


def small_sweep_doc(name: str, *, count: int, duration: float, parameters: dict[str, Any]) -> dict[str, Any]:
    """A sweep spec (as for :func:`~aca_warp.sweep.load_spec`) over hf1 pads of ``count`` patches, shards of 3 pads,
    ``duration`` [s] in fp32; ``parameters``: the spec's [parameters] table."""
    return {
        "sweep": {"base": "hf1", "shard_size": 3, "name": name},
        "run": {"duration": duration, "precision": "fp32"},
        "base": {"patches": {"count": count}},
        "parameters": parameters,
    }


def gated(gate: str, fn: Any, *args: Any) -> Any:
    """``fn(*args)`` once the file ``gate`` exists (at most 120 s later): work of a pool process held back by a test."""
    deadline = time.monotonic() + 120.0
    while not Path(gate).exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    return fn(*args)


def gated_one(gate: str, held: int, fn: Any, index: int) -> Any:
    """``fn(index)``, held back as :func:`gated` for shard ``held`` only: one slow preparation among quick ones."""
    return gated(gate, fn, index) if index == held else fn(index)


def one_shard_sweep(folder: Path, m_values: list[float], *, duration: float, sample_dt: float = 1.0e-6) -> Path:
    """Sweep hf1 pads of 12 patches in fp32, one per friction factor M of ``m_values``, all in one shard, in this
    process (``--workers 0``) into ``folder/sw``; the shard's path."""
    from aca_warp.cli import main

    spec = folder / "s.toml"
    spec.write_text(
        f'[sweep]\nbase = "hf1"\nshard_size = {len(m_values)}\n[run]\nduration = {duration!r}\n'
        f'sample_dt = {sample_dt!r}\nprecision = "fp32"\n[base.patches]\ncount = 12\n[parameters]\n'
        f'"friction.M" = {list(m_values)!r}\n'
    )
    assert main(["sweep", str(spec), "-o", str(folder / "sw"), "--workers", "0", "--quiet"]) == 0
    return folder / "sw" / "shard-00000.h5"


@contextmanager
def interrupted_at_second_checkpoint(monkeypatch: Any) -> Iterator[None]:
    """Within the block, ``aca-warp hf`` runs stop with a KeyboardInterrupt right after their second checkpoint was
    written (as Ctrl-C there would); the real ``run_hf`` is back after it."""
    from aca_warp.hf import runner

    real = runner.run_hf

    def interrupted(*args: Any, on_checkpoint: Any = None, **kw: Any) -> Any:
        seen = []

        def ckpt(c: Any) -> None:
            on_checkpoint(c)
            seen.append(c.sim_time)
            if len(seen) == 2:
                raise KeyboardInterrupt

        return real(*args, on_checkpoint=ckpt, **kw)

    monkeypatch.setattr(runner, "run_hf", interrupted)
    try:
        yield
    finally:
        monkeypatch.setattr(runner, "run_hf", real)


@contextmanager
def cpu_fibers(on: bool) -> Iterator[None]:
    """Warp's cooperative CPU blocks (block_dim fiber threads per CPU block, real barriers) switched ``on`` or off for
    the duration of the block, the setting before restored."""
    import warp as wp

    old = wp.config.enable_cpu_blocks
    wp.config.enable_cpu_blocks = on
    try:
        yield
    finally:
        wp.config.enable_cpu_blocks = old
