"""Shards prepared ahead of their runs: a shard's spec and scenes made in a pool of CPU processes and handed to the
task that runs it.

The first phase of a shard task, :func:`prepare_shard` (the spec resolved, the pads' scenes made: patch layouts
generated, placed and checked), needs NumPy and no Warp device. :class:`Preparer` runs it in a pool of processes
ahead of the runs, so that the GPU workers only build, set up, step and write: while shard k steps, the scenes of the
next shards are made beside it (a sweep whose pads each have a layout of their own spends seconds per shard on them,
pure Python). The pool's processes are started fresh (``spawn``), ignore SIGINT (the client stops the sweep) and
never use Warp (whose CPU runtime is not safe for threads; processes keep it apart anyway). A preparation that
raises, or a pool process that dies, fails its shard with that error: no task waits for it for ever. The prepared
scenes are the ones the task would make itself, so results are the same bit for bit.
"""

from __future__ import annotations

import copy
import multiprocessing
import signal
import threading
import time
from collections import deque
from collections.abc import Iterable
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from aca_warp.scene import Scene
from aca_warp.sweep.overlap import ShardCancelled
from aca_warp.sweep.spec import SweepSpec, _resolve


@dataclass
class PreparedShard:
    """What a shard task needs before it builds its model.

    Attributes:
        index: The shard.
        spec: The sweep, resolved from its doc (not checked again).
        pads: Global indices of the shard's pads, in its row order, shape (pads,).
        scenes: The pads' scenes (pads of one layout share its :class:`~aca_warp.scene.Patches`).
        seconds: Time the preparation took [s].
    """

    index: int
    spec: SweepSpec
    pads: np.ndarray
    scenes: list[Scene]
    seconds: float


def prepare_shard(doc: dict, base_dir: str, index: int) -> PreparedShard:
    """Resolve the spec ``doc`` (overrides applied) and make the scenes of shard ``index``."""
    t = time.perf_counter()
    spec = _resolve(copy.deepcopy(doc), Path(base_dir), check=False)
    pads = spec.shard_pads(index)
    scenes = spec.scenes(pads)
    return PreparedShard(index, spec, pads, scenes, time.perf_counter() - t)


def _ignore_sigint() -> None:
    """In a pool process: Ctrl-C reaches the whole process group; the client alone handles it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class Preparer:
    """A pool of ``processes`` CPU processes that prepares the shards of one sweep call (:func:`prepare_shard`), at
    most ``ahead`` of them at a time beyond those taken.

    :meth:`plan` names the shards in the order they will be taken; :meth:`get` waits for one (starting it now if it
    had not started) and returns it or raises its error; :meth:`poll` says whether one is ready without waiting.
    Safe to use from several threads. :meth:`close` cancels what has not started.
    """

    def __init__(self, doc: dict, base_dir: str, processes: int, ahead: int) -> None:
        self.args = (doc, base_dir)
        self.ahead = max(1, ahead)
        self.pool = ProcessPoolExecutor(
            max_workers=max(1, processes), mp_context=multiprocessing.get_context("spawn"), initializer=_ignore_sigint
        )
        self.waiting: deque[int] = deque()
        self.futures: dict[int, Future] = {}
        self.lock = threading.Lock()

    def plan(self, indices: Iterable[int]) -> None:
        """Prepare these shards, in this order, as room allows."""
        with self.lock:
            self.waiting.extend(indices)
            self._top_up()

    def _top_up(self) -> None:
        while self.waiting and len(self.futures) < self.ahead:
            i = self.waiting.popleft()
            self.futures[i] = self.pool.submit(prepare_shard, *self.args, i)

    def _future(self, index: int) -> Future:
        with self.lock:
            if index not in self.futures:  # asked for out of turn: start it now
                if index in self.waiting:
                    self.waiting.remove(index)
                self.futures[index] = self.pool.submit(prepare_shard, *self.args, index)
            return self.futures[index]

    def poll(self, index: int) -> bool:
        """Whether shard ``index``'s preparation has finished (successfully or not)."""
        return self._future(index).done()

    def get(self, index: int, cancel: threading.Event | None = None) -> PreparedShard:
        """Shard ``index``, prepared: waits for it; raises its error, or :class:`ShardCancelled` when ``cancel`` is
        set while it waits."""
        fut = self._future(index)
        try:
            while True:
                try:
                    return fut.result(timeout=0.05)
                except TimeoutError:
                    if cancel is not None and cancel.is_set():
                        raise ShardCancelled() from None
        finally:
            with self.lock:
                self.futures.pop(index, None)
                self._top_up()

    def close(self) -> None:
        """Cancel the preparations not begun and let the pool's processes go (they finish the one in hand)."""
        with self.lock:
            self.waiting.clear()
        self.pool.shutdown(wait=False, cancel_futures=True)
