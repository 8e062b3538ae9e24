"""Shards prepared ahead of their runs: a shard's spec, scenes and models made in a pool of CPU processes and handed
to the task that runs it.

Everything a shard task does before its kernel, but putting arrays on the device, needs the host: the spec resolved,
the pads' scenes (patch layouts generated, placed and checked), each batch's model as NumPy arrays
(:func:`~aca_warp.hf.model.host_model`: contact solve, neighbour lists, coupling springs), its initial state and the
run's checks (:func:`~aca_warp.hf.loop.preflight`: the stable-step estimate, the μ and watchdog bounds).
:func:`prepare_shard` does it; :class:`Preparer` runs it in a pool of processes ahead of the runs, so that a GPU
worker only uploads, steps and hands samples to its writer while the next shards are made beside it.

The neighbour search is a Warp kernel, and a CUDA device and the CPU round its distances differently, so a pool that
makes models runs that search on a device of the run's kind (``device``: the CPU, or a GPU of the sweep); the models
are then the ones the task would build itself, bit for bit, and so are the results. The pool's processes are forked
from this process's fork server (``forkserver``: a fresh process that imported this module once, never Warp's
runtime started, so that a pool starts in a fraction of a second after the first), ignore SIGINT (the client stops
the sweep) and start Warp themselves (a process of its own: Warp's CPU runtime is not safe for threads). A
preparation that raises, or a pool process that dies, fails its shard with that error: no task waits for it for
ever.

A prepared shard is mostly its models (≈ 100 MB for 256 hf1 pads of 1758 patches). For the workers of a local
cluster the pool leaves it in a file of a spool folder only this user can enter (:class:`SpooledShard`), and the
task reads it there, rather than have it pickled into the client, sent through the scheduler to the worker over the
cluster's encrypted connections and unpickled there (0.53–0.66 s for 256 hf1 pads against 0.08–0.16 s from the
file on this project's 2-core CPU container, ``scripts/bench_spool.py``); a shard that cannot be written there (no
room) travels by value as before.

Each sweep call starts its own pool and lets it go as its last shards run; a script that runs sweeps one after
another keeps one pool for all of them with :func:`keep_preparation_pool`.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import itertools
import multiprocessing
import multiprocessing.forkserver
import os
import pickle
import shutil
import signal
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from aca_warp.common.errors import AcaError, SceneError, sweep_spec
from aca_warp.common.links import create_new, private_dir
from aca_warp.scene import Scene
from aca_warp.scene.parts import pairs_within
from aca_warp.sweep.overlap import ShardCancelled
from aca_warp.sweep.spec import DRAW_PARAMETERS, SweepSpec, _resolve

if TYPE_CHECKING:  # the command line's parser imports this module: no Warp until a sweep runs
    from aca_warp.hf.loop import Preflight
    from aca_warp.hf.model import HostModel
    from aca_warp.hf.options import RunOptions

# -------------------------------------------------------------------------------------------- memory


def pad_bytes(scene: Scene, precision: str) -> int:
    """Estimated device bytes of one pad in a batch (model, state, solver scratch, CSR, recorder) [B].

    Per patch: 10 model arrays and ``patch_pad`` (10 T + 4), state u, u̇, force and the synchronous velocity
    (4 T), adaptive trial buffers (5 T); per directed link: index, inverse distance, stiffness (4 + 2 T); per
    pad: 257 recorded rows × 5 float64. Doubled for the neighbour build's temporaries and allocator slack.
    """
    t = 4 if precision == "fp32" else 8
    p = scene.patches
    links = 2 * pairs_within(p.x, p.y, scene.material.coupling_radius)
    per_patch = 10 * t + 4 + 4 * t + 5 * t + 4
    return int(2 * (p.count * per_patch + links * (4 + 2 * t) + 257 * 5 * 8))


def device_memory(device: str) -> int:
    """Free memory of a Warp device (CUDA: free device memory; CPU: available host memory) [B]."""
    import warp as wp

    dev = wp.get_device(device)
    if dev.is_cuda:
        return int(dev.free_memory)
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover
        return int(dev.total_memory or 8 * 2**30)


def batch_capacity(scene: Scene, precision: str, device: str, *, fraction: float = 0.5, sharing: int = 1) -> int:
    """How many pads like ``scene`` fit in ``fraction`` of the device's free memory, split ``sharing`` ways."""
    return max(1, int(fraction * device_memory(device) / max(1, sharing) / pad_bytes(scene, precision)))


def shard_capacity(scenes: list[Scene], precision: str, device: str, fraction: float, sharing: int) -> int:
    """Pads per batch of a shard of ``scenes`` (:func:`batch_capacity` of its largest pad)."""
    largest = max(scenes, key=lambda s: s.patches.count)
    return batch_capacity(largest, precision, device, fraction=fraction, sharing=sharing)


# --------------------------------------------------------------------------------------------- shards


def run_options(spec: SweepSpec) -> RunOptions:
    """The options every pad of the sweep runs with (engine auto: the on-chip kernel where the model allows it, on
    CUDA and on the CPU, else the general one)."""
    from aca_warp.hf.options import RunOptions

    return RunOptions(
        duration=spec.duration,
        integrator=spec.integrator,
        dt=spec.dt,
        tolerance=spec.tolerance,
        fast_math=spec.fast_math,
        growth_dt=spec.growth_dt,
        crossing=spec.crossing,
    )


@dataclass
class PreparedBatch:
    """One batch of a prepared shard, ready to be put on the device.

    Attributes:
        start, stop: The batch is the shard's pads [start, stop) (rows of its file).
        model: The batch's model on the host.
        u, v: Initial displacements [m] and velocities [m/s] in the model's precision, shape (patches,).
        checked: The run's checks and bounds, made from the host model.
    """

    start: int
    stop: int
    model: HostModel
    u: np.ndarray
    v: np.ndarray
    checked: Preflight


@dataclass
class PreparedShard:
    """What a shard task needs before it puts its batches on the device.

    Attributes:
        index: The shard.
        spec: The sweep, resolved from its doc (not checked again).
        pads: Global indices of the shard's pads, in its row order, shape (pads,).
        scenes: The pads' scenes (pads of one layout share its :class:`~aca_warp.scene.Patches`).
        seconds: Time the preparation took [s].
        span: Wall-clock times (``time.time()``) the preparation began and ended [s].
        capacity: Pads per batch the batches were cut for (0: no batches made; the task builds its models).
        batches: The shard's batches, in row order (empty: the task builds them).
        process_start: With the first shard a pool process prepares, that process's start (``time.time()`` [s]):
            begun, Warp started, ready (its kernels loaded); empty otherwise.
    """

    index: int
    spec: SweepSpec
    pads: np.ndarray
    scenes: list[Scene]
    seconds: float
    span: tuple[float, float] = (0.0, 0.0)
    capacity: int = 0
    batches: list[PreparedBatch] = field(default_factory=list)
    process_start: tuple[float, ...] = ()


@dataclass(frozen=True)
class SpooledShard:
    """A prepared shard left by the pool in a file of its spool folder (:class:`Preparer` with ``spool``): what a
    local Dask worker is handed instead of the shard's models; the task reads them from the file (:meth:`load`).

    Attributes:
        index: The shard.
        path: The file (a pickle of the :class:`PreparedShard`, mode 0600, in a folder only this user can enter).
    """

    index: int
    path: str

    def load(self) -> PreparedShard | None:
        """The prepared shard; the file is removed. None when the file is gone (read by an earlier try of the task,
        whose worker then died and Dask ran it again): the task then prepares the shard itself, to the same result."""
        try:
            with open(self.path, "rb") as f:
                prepared = pickle.load(f)
        except FileNotFoundError:
            return None
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path)
        if not isinstance(prepared, PreparedShard) or prepared.index != self.index:
            raise ValueError(f"{self.path} does not hold shard {self.index}")
        return prepared


@sweep_spec()  # its refusals name the spec's keys (run.dt), not options a sweep does not have
def prepare_shard(
    doc: dict,
    base_dir: str,
    index: int,
    *,
    device: str | None = None,
    memory_fraction: float = 0.5,
    sharing: int = 1,
) -> PreparedShard:
    """Resolve the spec ``doc`` (overrides applied) and make the scenes of shard ``index``; with ``device`` (the run's
    device, or one of its kind: the neighbour search runs there) also its batches (:func:`prepare_batch`), cut by
    the capacity of ``device`` (:func:`shard_capacity`)."""
    t, began = time.perf_counter(), time.time()
    spec = _resolve(copy.deepcopy(doc), Path(base_dir), check=False)
    pads = spec.shard_pads(index)
    scenes = spec.scenes(pads)
    cap, batches = 0, []
    if device is not None and device not in _UNUSABLE:
        cap = shard_capacity(scenes, spec.precision, device, memory_fraction, sharing)
        batches = [
            prepare_batch(spec, scenes, b0, min(b0 + cap, len(scenes)), device) for b0 in range(0, len(scenes), cap)
        ]
    started, _STARTED[:] = tuple(_STARTED), []  # with this process's first shard only
    span = (began, time.time())
    return PreparedShard(index, spec, pads, scenes, time.perf_counter() - t, span, cap, batches, started)


def prepare_batch(spec: SweepSpec, scenes: list[Scene], start: int, stop: int, device: str) -> PreparedBatch:
    """The batch of ``scenes[start:stop]`` on the host: its model (neighbours searched on ``device``), initial state
    and the run's checks, made from host arrays that the device copy will hold bit for bit."""
    from aca_warp.hf.loop import preflight
    from aca_warp.hf.model import host_model, upload
    from aca_warp.hf.state import initial_state

    host = host_model(scenes[start:stop], device=device, precision=spec.precision)
    view = upload(host, "cpu", copy=False)  # the host arrays as a model, for the NumPy work that reads one
    state = initial_state(view)
    checked = preflight(view, state, run_options(spec), spec.base.record)
    u, v = (a.copy() for a in state.numpy())
    return PreparedBatch(start, stop, host, u, v, checked)


CORNER_PARAMETERS = 4  # swept parameters up to which every corner of their ranges is checked (2^4 pads at most)


def check_pads(spec: SweepSpec) -> list[int]:
    """The pads whose runs :func:`check_runs` checks, sorted: the first and the last, and where the bounds bind
    first, at the ends of the swept parameters' ranges (the seeds aside): for each parameter a pad at its smallest
    value and one at its largest, and every pad whose values all lie at an end of their ranges (the corners of a
    product sweep; of up to :data:`CORNER_PARAMETERS` parameters, else the two where all are smallest or all
    largest). The stable step falls with the load, the stiffnesses and the friction law's slope, each of which a
    corner takes at its end; a pad inside them that its layout makes stiffer is met by its shard's own check."""
    pads = {0, spec.pad_count - 1}
    ends: dict[str, tuple[Any, Any]] = {}
    for key, values in spec.parameters.items():
        if key in DRAW_PARAMETERS or isinstance(values[0], str):  # draws and text (initial.state) are no ranges
            continue
        ends[key] = (min(values), max(values))
        pads.update(values.index(v) for v in ends[key])
    keys = list(ends)
    columns = [np.asarray(spec.parameters[k]) for k in keys]  # (pads,) each
    corners = itertools.product(*(ends[k] for k in keys)) if len(keys) <= CORNER_PARAMETERS else []
    for corner in [*corners, tuple(lo for lo, _ in ends.values()), tuple(hi for _, hi in ends.values())]:
        at = np.ones(spec.pad_count, dtype=bool)
        for column, v in zip(columns, corner, strict=True):
            at &= column == v
        pads.update(np.flatnonzero(at)[:1].tolist())
    return sorted(pads)


@sweep_spec()  # the messages name the spec's keys (run.dt)
def check_runs(spec: SweepSpec) -> None:
    """Refuse, before a sweep writes anything, a run its pads cannot take: the checks of a run (the step as the
    run takes it against the stable-step estimate, the int32 step counts, the contact solution:
    :func:`~aca_warp.hf.loop.preflight`) on the pads of :func:`check_pads`, one host model each with its neighbours
    searched on the CPU. A pad failing them is one line that names it (its error as raised: a StabilityError, a
    PhysicsError); every shard makes the same checks for each of its pads. A pad whose scene cannot be made (a bad
    combination of good values) is left to its shard, which fails with the reason."""
    for p in check_pads(spec):
        try:
            scene = spec.scene(p)
        except SceneError:
            continue
        try:
            prepare_batch(spec, [scene], 0, 1, "cpu")
        except AcaError as e:
            e.args = (f"pad {p} ({spec.pad_values(p)}): {e}",)
            raise e from None


# what a pool process runs, imported by the fork server (Warp's module, not its runtime: nothing is started there)
_PRELOAD = [
    __name__,
    "aca_warp.hf.loop",
    "aca_warp.hf.model",
    "aca_warp.hf.state",
    "aca_warp.kernels.neighbours",
    "scipy.spatial",
]


_UNUSABLE: set[str] = set()  # devices this pool process could not start Warp on: it makes scenes only
# this pool process's start (time.time() [s]): begun, Warp started, ready (kernels loaded); handed with its first shard
_STARTED: list[float] = []


def _spooled(prepare: Callable[[int], PreparedShard], spool: str, index: int) -> PreparedShard | SpooledShard:
    """In a pool process: shard ``index`` prepared and written to a new file in ``spool``; the shard itself when the
    file cannot be written (no room, the folder gone): it then travels by value."""
    prepared = prepare(index)
    path = Path(spool) / f"shard-{index:05d}-{os.getpid()}-{time.monotonic_ns()}.pkl"
    try:
        with os.fdopen(create_new(path, "prepared shard", mode=0o600), "wb") as f:
            pickle.dump(prepared, f, protocol=pickle.HIGHEST_PROTOCOL)
    except (OSError, SceneError):
        with contextlib.suppress(OSError):
            path.unlink()
        return prepared
    return SpooledShard(index, str(path))


def _begun_name(index: int) -> str:
    """The name of the mark of shard ``index``'s begun preparation in the call's private folder."""
    return f"began-{index:05d}"


BEGUN_WAIT_S = 5.0  # how long after its preparation began a free task still waits for a shard [s]


def _begin(
    folder: str | None, work: Callable[[int], PreparedShard | SpooledShard], index: int
) -> PreparedShard | SpooledShard:
    """In a pool process: mark in ``folder`` (new, or renewed) that shard ``index``'s preparation begins now, the
    mark holding ``time.monotonic_ns()`` (one clock for every process of the host, whatever the file system's
    clock; :meth:`Preparer.began`), then do it (``work``). No folder, or one that is gone (the call closed): no
    mark."""
    if folder is not None:
        with contextlib.suppress(OSError, SceneError):
            fd = create_new(Path(folder) / _begun_name(index), "mark of a begun preparation", mode=0o600)
            with os.fdopen(fd, "w") as f:
                f.write(str(time.monotonic_ns()))
    return work(index)


SPOOL_PREFIX = "spool-"


def _spool_folder() -> str:
    """A new spool folder for this process's sweep, in the user's private folder (``sweep/spool-PID-*``); those of
    sweeps whose process is gone (killed) are removed first."""
    base = private_dir("sweep")
    for old in base.glob(f"{SPOOL_PREFIX}*"):
        pid = old.name.removeprefix(SPOOL_PREFIX).split("-")[0]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(old, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f"{SPOOL_PREFIX}{os.getpid()}-", dir=base)


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


CLIENT_POLL_S = 1.0  # how often a pool process looks whether the process that started its pool still lives [s]


def _end_with(client: int) -> None:
    """In a pool process: exit once process ``client`` (the one whose pool this is) has gone. A pool process holds
    both ends of its task queue and the fork server's liveness pipe, so a killed client would leave it, and the fork
    server, waiting for ever."""
    while _alive(client):
        time.sleep(CLIENT_POLL_S)
    os._exit(0)


def _start_process(device: str | None, client: int) -> None:
    """In a pool process: Ctrl-C reaches the whole process group, the client alone handles it; the process ends
    when ``client`` (the pid of the process that made the pool) has gone (:func:`_end_with`); with ``device``, Warp
    started, the neighbour search's kernels loaded there and the checks' CPU kernels, before the first shard. A
    device this process cannot use (a GPU in exclusive-process mode, held by its worker) is left to the tasks: this
    process makes scenes only."""
    begun = time.time()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_end_with, args=(client,), name="aca-warp-client-watch", daemon=True).start()
    warp = begun
    if device is not None:
        from aca_warp.common.devices import init_warp, load_kernels

        init_warp()  # before any import that starts Warp: quietly
        warp = time.time()
        from aca_warp.kernels import neighbours, step_bound

        load_kernels([step_bound], "cpu")  # the runs' checks
        try:
            load_kernels([neighbours], device)
        except Exception:  # noqa: BLE001  (no context there: the tasks build their models)
            _UNUSABLE.add(device)
    _STARTED[:] = [begun, warp, time.time()]


class Preparer:
    """A pool of ``processes`` CPU processes that prepares the shards of one sweep call (:func:`prepare_shard`; with
    ``device``, their models too), at most ``ahead`` of them at a time beyond those taken.

    :meth:`plan` names the shards in the order they will be taken; :meth:`get` waits for one (starting it now if it
    had not started) and returns it (with ``spool``: a :class:`SpooledShard` where its file could be written) or
    raises its error; :meth:`poll` says whether one is ready without waiting, :meth:`first_ready` which is;
    :meth:`take` waits while the device has work, else leaves the shard to its task; :meth:`forget` drops one.
    Safe to use from several threads. The processes are let go once every planned shard has been taken or dropped;
    :meth:`close` cancels what has not started. Inside :func:`keep_preparation_pool` the pool is the kept one: it
    stays for the next call, and only this call's preparations not begun are cancelled.
    """

    def __init__(
        self, doc: dict, base_dir: str, processes: int, ahead: int, *, spool: bool = False, **shard_options: Any
    ) -> None:
        """``spool``: leave the prepared shards in files of a private spool folder (:class:`SpooledShard`; for the
        workers of a local cluster), removed with the folder by :meth:`close`; ``shard_options``: the keyword
        arguments of :func:`prepare_shard` (``device``, ``memory_fraction``, ``sharing``), with its defaults."""
        device = shard_options.get("device")
        # this call's private folder: the marks of begun preparations and the spooled shards; without spool a pool
        # that cannot have one works unmarked (began() is then False)
        self.folder: str | None = None
        try:
            self.folder = _spool_folder()
        except (OSError, SceneError):
            if spool:
                raise
        self.spool = self.folder if spool else None
        made = functools.partial(prepare_shard, doc, base_dir, **shard_options)
        # what a pool process does for a shard (work), behind the mark that it has begun (prepare)
        self.work: Callable[[int], PreparedShard | SpooledShard] = (
            made if self.spool is None else functools.partial(_spooled, made, self.spool)
        )
        self.prepare: Callable[[int], PreparedShard | SpooledShard] = functools.partial(_begin, self.folder, self.work)
        self.ahead = max(1, ahead)
        self.pool, self.kept = _KEPT.acquire(processes, device, self)
        self.waiting: deque[int] = deque()
        self.futures: dict[int, Future] = {}
        self.lock = threading.Lock()
        self.planned = False
        self.released = False  # every planned shard taken or dropped (or closed): the processes let go, no more asked

    def plan(self, indices: Iterable[int]) -> None:
        """Prepare these shards, in this order, as room allows (once per call). Once each of them has been taken
        (:meth:`get`) or dropped (:meth:`forget`), the pool's processes are let go (unless the pool is kept), while
        the last shards run: the call's end (and its process's exit) then waits for none of them, but for a dropped
        shard's preparation that a process had begun (it finishes, unused)."""
        with self.lock:
            self.planned = True
            self.waiting.extend(indices)
            self._top_up()

    def _top_up(self) -> None:
        """Start waiting preparations while fewer than ``ahead`` are under way; let the processes go once nothing
        is waiting or under way (under the lock). A broken pool (a process died) starts nothing more: the shards
        left waiting raise its error when asked for (:meth:`get`)."""
        while self.waiting and len(self.futures) < self.ahead:
            i = self.waiting.popleft()
            try:
                self.futures[i] = self.pool.submit(self.prepare, i)
            except BrokenProcessPool:
                self.waiting.appendleft(i)
                break
        if self.planned and not self.waiting and not self.futures:
            self._release()

    def _release(self) -> None:
        """Refuse further shards and let the processes go, once (under the lock: two shutdowns of one executor at
        once race on its queues); a kept pool (:func:`keep_preparation_pool`) stays, only this call's preparations
        not begun are cancelled."""
        if not self.released:
            self.released = True
            if self.kept:
                _KEPT.release(self.pool, self)
                for fut in self.futures.values():
                    fut.cancel()
            else:
                _let_go(self.pool)

    def _future(self, index: int) -> Future:
        with self.lock:
            if index not in self.futures:  # asked for out of turn: start it now
                if self.released:
                    raise RuntimeError(f"shard {index} was asked of a preparation pool that has made all its shards")
                if index in self.waiting:
                    self.waiting.remove(index)
                self.futures[index] = self.pool.submit(self.prepare, index)
            return self.futures[index]

    def poll(self, index: int) -> bool:
        """Whether shard ``index``'s preparation has finished (successfully or not)."""
        return self._future(index).done()

    def first_ready(self, order: Iterable[int]) -> int | None:
        """The first shard of ``order`` whose preparation has finished (successfully or not), starting none; None
        when none has."""
        with self.lock:
            done = {i for i, fut in self.futures.items() if fut.done()}
        return next((i for i in order if i in done), None) if done else None

    def began(self, index: int) -> bool:
        """Whether a pool process began preparing shard ``index`` (:func:`_begin`) less than :data:`BEGUN_WAIT_S`
        ago: the rest of it takes less than the task would take to make the shard itself (on one H200 host a 256-pad
        hf1 shard takes 0.5–0.7 s in the pool, 0.9 s or more in the task's turn), so a task that is free waits for
        it; a preparation begun longer ago (a loaded machine, a stalled process) is left to the task."""
        if self.folder is None:
            return False
        try:
            began_ns = int((Path(self.folder) / _begun_name(index)).read_text() or "x")
        except (OSError, ValueError):  # no mark, or one being written
            return False
        return (time.monotonic_ns() - began_ns) / 1e9 < BEGUN_WAIT_S

    def forget(self, index: int) -> None:
        """Drop shard ``index``: its task prepares it itself (a preparation under way finishes unused)."""
        with self.lock:
            if index in self.waiting:
                self.waiting.remove(index)
            fut = self.futures.pop(index, None)
            if fut is not None:
                fut.cancel()
            self._top_up()

    def get(self, index: int, cancel: threading.Event | None = None) -> PreparedShard | SpooledShard:
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

    def take(
        self, index: int, idle: Callable[[], bool], cancel: threading.Event | None = None
    ) -> PreparedShard | SpooledShard | None:
        """Shard ``index`` prepared, waiting for it while ``idle()`` is False (the device has other work) or its
        preparation has begun (:meth:`began`); None once it is neither ready nor begun and ``idle()`` is True: the
        shard is then dropped (:meth:`forget`) and its task prepares it, rather than leave the device waiting.
        Raises as :meth:`get`."""
        while not self.poll(index):
            if not self.began(index) and idle():
                self.forget(index)
                return None
            if cancel is not None and cancel.is_set():
                raise ShardCancelled()
            time.sleep(0.005)
        return self.get(index, cancel)

    def close(self) -> None:
        """Cancel the preparations not begun and let the pool's processes go (they finish the one in hand, unused);
        the spool folder is removed with the files no task took (one written into it meanwhile keeps it until the
        next sweep, which removes the folders of processes that are gone)."""
        try:
            with self.lock:
                self.waiting.clear()
                self._release()
        finally:
            if self.kept:  # again, should an interrupt have come between the release's flag and its end: once counts
                _KEPT.release(self.pool, self)
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)


def _new_pool(processes: int, device: str | None) -> ProcessPoolExecutor:
    """A pool of ``processes`` processes forked from this process's fork server, each started by
    :func:`_start_process` (Warp on ``device``) when it is first needed."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(_PRELOAD)  # imported once by this process's fork server, not per process
    # started now, with this process's environment as it is (a local cluster's nanny, started next, sets
    # OMP_NUM_THREADS and others in it); the pool's processes are forked from it as they are needed
    multiprocessing.forkserver.ensure_running()
    return ProcessPoolExecutor(
        max_workers=max(1, processes), mp_context=context, initializer=_start_process, initargs=(device, os.getpid())
    )


class _KeptPool:
    """The pool kept across sweep calls (:func:`keep_preparation_pool`): the open blocks (``depth``), the pool, what it
    was made for (processes, device) and the calls using it now (``users``, their :class:`Preparer`). A pool in use is
    never let go under a call: one made for other settings is then made for the asking call alone, and the block's
    end leaves a pool in use to its last call's end (:meth:`release`)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.depth = 0
        self.pool: ProcessPoolExecutor | None = None
        self.key: tuple[int, str | None] | None = None
        self.users: set[object] = set()  # the calls' Preparers

    def enter(self) -> None:
        with self.lock:
            self.depth += 1

    def exit(self) -> None:
        with self.lock:
            self.depth -= 1
            self._drop_if_done()

    def acquire(self, processes: int, device: str | None, user: object) -> tuple[ProcessPoolExecutor, bool]:
        """A pool for a call: (pool, kept). Outside a block, or where the kept pool is another's in use (other
        settings), a new one of the call's own; else the kept one if it was made for the same processes and device
        and still works, else a new one, kept in its place (a broken pool is let go, in use or not: its calls'
        shards fail with its error already)."""
        key = (max(1, processes), device)
        with self.lock:
            if self.depth == 0:
                return _new_pool(processes, device), False
            if self.pool is not None and not _usable(self.pool):
                _let_go(self.pool)
                self.pool = None
                self.users.clear()
            if self.pool is not None and self.key != key:
                if self.users:
                    return _new_pool(processes, device), False
                _let_go(self.pool)
                self.pool = None
            if self.pool is None:
                self.pool, self.key = _new_pool(processes, device), key
            self.users.add(user)
            return self.pool, True

    def release(self, pool: ProcessPoolExecutor, user: object) -> None:
        """``user`` (a call that had ``pool`` from :meth:`acquire` as the kept one) is done with it; again: no
        effect."""
        with self.lock:
            if pool is self.pool:
                self.users.discard(user)
                self._drop_if_done()

    def _drop_if_done(self) -> None:
        """Let the pool go once no block is open and no call uses it (under the lock)."""
        if self.depth == 0 and not self.users and self.pool is not None:
            _let_go(self.pool)
            self.pool = self.key = None


_KEPT = _KeptPool()


@contextlib.contextmanager
def keep_preparation_pool() -> Iterator[None]:
    """Keep the preparation pool of a sweep call for the next calls of this process until the block ends.

    Without it, each :func:`~aca_warp.sweep.run_sweep` call with a preparation pool starts its own (its processes
    start Warp and a GPU context: 0.6 s on an H200 host before their first shard, and their first shard takes longer
    than the next ones) and lets it go once its last shards are taken. Inside the block, a call finds the pool an
    earlier call of the block made and keeps it: a script that runs one sweep after another on a local cluster it
    started has its next shards prepared from the call's start. (A call given a client or scheduler has no pool
    unless it asks for one, ``prepare=N``: the cluster's hosts are not known to it.) A call that needs another pool
    (another number of processes or device) makes a new one and keeps that instead (or, while another call of this
    process uses the kept one, one of its own); one that finds the kept pool broken (a process died) replaces it.
    Blocks may nest; the outermost block's end lets the pool go (without waiting for its processes to exit; after
    the last call still using it, if any). Results are the same bit for bit with or without it::

        with keep_preparation_pool():
            for doc in docs:
                run_sweep(load_spec(doc), out / doc["sweep"]["name"], device=device, client=client, prepare=4)
    """
    _KEPT.enter()
    try:
        yield
    finally:
        _KEPT.exit()


def _usable(pool: ProcessPoolExecutor) -> bool:
    """Whether ``pool`` takes work: not one with a dead process (the pool's own thread marks it broken only when it
    notices, a moment later), nor a broken pool, which refuses a task at once, nor one shut down."""
    processes = getattr(pool, "_processes", None) or {}  # the executor's own table of its processes
    if any(not p.is_alive() for p in list(processes.values())):
        return False
    try:
        pool.submit(int).cancel()
    except (BrokenProcessPool, RuntimeError):
        return False
    return True


def _let_go(pool: ProcessPoolExecutor) -> None:
    """Shut ``pool`` down without waiting for its processes to exit: a thread of its own shuts it down, waiting
    for them, and holds the last reference until they have. (In Python 3.12 the executor's collection waits on the
    lock that its manager thread holds while it joins the processes, a GPU context's teardown each: 0.2–0.3 s at the
    end of every sweep call on an H200 host, were the executor collected in the caller's thread.) The interpreter
    still waits for them at its exit."""
    threading.Thread(
        target=pool.shutdown, kwargs={"cancel_futures": True}, name="aca-warp-pool-exit", daemon=True
    ).start()
