"""The parts of a shard task that let shards overlap: a writer thread behind the run, the device taken in turns,
and the cancel event of a stopping sweep.

:class:`ChunkWriter` writes a shard's recorded chunks to its HDF5 file in a thread while the run goes on;
:class:`KernelTurn` gives one shard at a time the device (the :data:`PIPELINE_DEPTH` shard tasks of a process, and
processes that share a GPU), from putting its model there to the end of its run, so that the next shard waits ready
and the last one's file is finished beside the current run; :class:`ShardContext` says how a shard task runs and
carries the event that stops it (:class:`ShardCancelled`). None of them decides what a kernel computes: results are
the same bit for bit with or without them.
"""

from __future__ import annotations

import fcntl
import os
import queue
import re
import threading
import time
import types
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aca_warp.common.links import open_lock_file, private_dir

PIPELINE_DEPTH = 2  # shard tasks at a time per device in the overlapped path: one runs, one waits ready or writes


class ShardCancelled(BaseException):
    """Raised inside a shard task when its sweep stops (Ctrl-C, SIGTERM, a full disk): the shard is left unfinished
    (its ``.partial`` is deleted and the shard run again by the next sweep call)."""


_STOP = object()  # the end of a writer's queue


class ChunkWriter:
    """Writes a shard's recorded chunks behind its run: a thread fed through a bounded queue.

    :meth:`put` takes a chunk ``(b0, b1, chunk)`` (pads [b0, b1) of the shard). Consecutive chunks of one batch are
    joined until they hold ``rows`` samples (the HDF5 chunk length of the shard's datasets) or ``limit`` bytes, so
    that an engine that flushes a few samples at a time costs few HDF5 calls and few thread hand-overs, while an
    engine that flushes large chunks (the on-chip one: a launch's samples of every pad, 2 MB for 256 pads) has each
    written as it comes, beside its own run, rather than all at the end, beside the next shard's start; then they
    go to the thread as one write, waiting while ``depth`` writes wait already. :meth:`close` writes the rest and
    waits. The first error of a write ends the writing: nothing more is written, writes still queued are dropped (the
    run is not held up by a full queue), and the error is raised by the next :meth:`put` or by :meth:`close`, so that
    it stops the run in the shard's own thread. :attr:`seconds` is the time spent writing, :attr:`span` the
    wall-clock times (``time.time()``) the first write began and the last one ended [s].
    """

    def __init__(self, write: Callable[[Any], None], *, depth: int = 4, rows: int = 4096, limit: int = 2**20) -> None:
        self._write = write
        self._queue: queue.Queue = queue.Queue(maxsize=depth)
        self._rows, self._limit = rows, limit
        self._held: list = []  # chunks of one batch not yet handed over
        self._held_rows = self._held_bytes = 0
        self._drop = False
        self.error: BaseException | None = None
        self.seconds = 0.0
        self.span: list[float] = []
        self._thread = threading.Thread(target=self._loop, name="aca-warp-shard-writer", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            if self.error is None and not self._drop:
                t, began = time.perf_counter(), time.time()
                try:
                    self._write(item)
                except BaseException as e:  # noqa: BLE001  (handed to the shard's thread by put/close)
                    self.error = e
                self.seconds += time.perf_counter() - t
                self.span = [self.span[0] if self.span else began, time.time()]

    def _raise(self) -> None:
        if self.error is not None:
            raise self.error

    def _enqueue(self, item: Any) -> None:
        while True:
            self._raise()
            try:
                self._queue.put(item, timeout=0.05)
                return
            except queue.Full:
                continue

    def _hand_over(self) -> None:
        """Queue the held chunks as one write."""
        if not self._held:
            return
        b0, b1, _ = self._held[0]
        chunks = [c for _, _, c in self._held]
        self._held, self._held_rows, self._held_bytes = [], 0, 0
        if len(chunks) > 1:
            joined = types.SimpleNamespace(
                time=np.concatenate([c.time for c in chunks]), globals=np.concatenate([c.globals for c in chunks])
            )
            chunks = [joined]
        self._enqueue((b0, b1, chunks[0]))

    def put(self, item: tuple[int, int, Any]) -> None:
        """Take a chunk for writing; raises the writer's error, if it had one."""
        self._raise()
        if self._held and self._held[0][0] != item[0]:
            self._hand_over()  # another batch: its rows start again at 0
        chunk = item[2]
        if len(chunk.time) == 0:
            return
        self._held.append(item)
        self._held_rows += len(chunk.time)
        self._held_bytes += chunk.globals.nbytes
        if self._held_rows >= self._rows or self._held_bytes >= self._limit:
            self._hand_over()

    def close(self) -> None:
        """Write everything taken, and wait; raises the writer's error, if it had one."""
        self._hand_over()
        self._queue.put(_STOP)  # the loop keeps taking items after an error, so this never waits for long
        self._thread.join()
        self._raise()

    def abort(self) -> None:
        """Stop without writing what is still held or queued (waits for a write in progress)."""
        self._drop = True
        self._held = []
        self._queue.put(_STOP)
        self._thread.join()


_TURN_LOCKS: dict[str, threading.Lock] = {}
_TURN_LOCKS_GUARD = threading.Lock()


class KernelTurn:
    """A shard's turn on its device: one shard's Warp work at a time, from putting its model on the device to the end
    of its run; the others wait ready (their models made on the host) or finish their files meanwhile.

    * Shard tasks of one process (threads): a lock per device. CUDA: the device's one stream would order another
      task's copies and launches behind the running kernel anyway (each of its host synchronisations waiting for a
      launch to end), and a turn keeps the stream's work one shard's. CPU: Warp's CPU runtime is not safe for two
      threads at once: the general engine captures its steps in a CPU graph, and an array allocation or a launch of
      another thread during that capture fails (``'NoneType' object has no attribute 'track_array'``) or would be
      recorded into the graph; and the CPU kernels of one Warp module find their tile memory through one static
      pointer, which concurrent launches overwrite.
    * Processes that share a GPU (more workers than GPUs, or a cluster's workers started so): also a file lock named
      after the GPU (host-local, in the user's private folder, :func:`~aca_warp.common.links.private_dir`: another
      user cannot hold it), so that their runs alternate instead of time-slicing the GPU.

    :meth:`enter` waits for both (polled: a stopping sweep is not held up). Neither decides what a kernel computes
    (pads of a shard are one batch wherever it runs), only when it runs.
    """

    def __init__(self, device: Any, cancel: threading.Event | None, *, processes: bool) -> None:
        self.device = device
        self.cancel = cancel
        self.processes = processes and device.is_cuda
        with _TURN_LOCKS_GUARD:
            self.lock = _TURN_LOCKS.setdefault(str(device), threading.Lock())
        self.locked = False
        self.fd: int | None = None
        self.waited = 0.0  # seconds spent waiting for a turn

    def enter(self) -> None:
        """Wait for the device's turn (idempotent); raises :class:`ShardCancelled` on a stop."""
        if self.locked:
            return
        t = time.perf_counter()
        while not self.lock.acquire(timeout=0.05):
            self._check()
        self.locked = True
        try:
            if self.processes:
                self._file_lock()
        except BaseException:
            self.exit()
            raise
        self.waited += time.perf_counter() - t

    def _check(self) -> None:
        if self.cancel is not None and self.cancel.is_set():
            raise ShardCancelled()

    def _file_lock(self) -> None:
        """The GPU's turn among processes: its lock file, created 0600 in the private folder, never through a link."""
        key = self.device.uuid or self.device.pci_bus_id or str(self.device)
        try:
            path = private_dir("kernel") / f"{re.sub(r'[^A-Za-z0-9_.-]', '_', key)}.lock"
            fd = open_lock_file(path, "GPU turn lock", 0o600)
        except OSError:
            self.processes = False  # no turn across processes: the runs share the GPU as they come
            return
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                self.fd = fd
                return
            except BlockingIOError:
                try:
                    self._check()
                except ShardCancelled:
                    os.close(fd)
                    raise
                time.sleep(0.01)
            except OSError:
                os.close(fd)
                self.processes = False
                return

    def exit(self) -> None:
        """End the turn (idempotent)."""
        if self.fd is not None:
            os.close(self.fd)  # drops the flock
            self.fd = None
        if self.locked:
            self.locked = False
            self.lock.release()


_STOPS: dict[str, threading.Event] = {}
_STOPS_GUARD = threading.Lock()


def stop_event(token: str) -> threading.Event:
    """The cancel event of the sweep call ``token`` in this process (a Dask worker's shard tasks wait on it)."""
    with _STOPS_GUARD:
        return _STOPS.setdefault(token, threading.Event())


def stop_sweep(token: str) -> None:
    """Stop this process's shard tasks of the sweep call ``token`` at their next chunk or phase (run on every Dask
    worker by the client when the sweep is stopped; tasks that start later stop at once)."""
    stop_event(token).set()


@dataclass
class ShardContext:
    """How a shard task runs (:func:`run_shard`).

    Attributes:
        overlap: The overlapped path: chunks written behind the run by a :class:`ChunkWriter`, the device taken in
            turns (:class:`KernelTurn`) by the tasks of the process (and processes on the GPU). False: the serial
            path (writes inline, no turns).
        cancel: Set to stop the task at its next chunk or phase (:class:`ShardCancelled`).
        processes: Take turns with other processes on the same GPU (overlap only).
    """

    overlap: bool = False
    cancel: threading.Event | None = None
    processes: bool = True

    def check(self) -> None:
        """Raise :class:`ShardCancelled` when the sweep is stopping."""
        if self.cancel is not None and self.cancel.is_set():
            raise ShardCancelled()
