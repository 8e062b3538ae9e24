"""Running a sweep: every unfinished shard of a spec, in this process (serial or overlapped threads) or on Dask.

:func:`run_sweep` holds the directory's lock, prepares the manifest and hands the shards to one of three paths:
:func:`_run_in_process` (one shard after another), :func:`_run_in_process_overlapped` (:data:`PIPELINE_DEPTH`
shard tasks in threads: one steps while the next waits ready and the last finishes its file, samples written behind
the run), or :func:`~aca_warp.sweep.cluster._run_on_dask` (the same threads in every worker process, one per GPU); on
every path a :class:`~aca_warp.sweep.prepare.Preparer` may make the shards ahead in a pool of processes
(:func:`prepare_processes`): scenes, models on the host, initial states and the runs' checks, so that a task only
uploads, runs and writes. A ``KeyboardInterrupt`` stops the shards in flight, marks them ``interrupted`` and is
raised again.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aca_warp.common.devices import get_device
from aca_warp.common.errors import StorageError
from aca_warp.common.files import OutputLock, check_room, folder_named
from aca_warp.sweep.cluster import (
    ClusterStart,
    _have_dask,
    _run_on_dask,
    check_scheduler,
    cuda_ordinals,
    device_sharing,
    started_here,
)
from aca_warp.sweep.manifest import MANIFEST, SweepResult, _Book, _one_line, finished_shards, prepare_dir
from aca_warp.sweep.overlap import PIPELINE_DEPTH, ShardCancelled, ShardContext
from aca_warp.sweep.prepare import PreparedShard, Preparer, check_runs
from aca_warp.sweep.shard import run_shard, shard_bytes, shard_name
from aca_warp.sweep.spec import SweepError, SweepSpec


def run_sweep(
    spec: SweepSpec,
    out_dir: str | Path,
    *,
    device: str = "cpu",
    workers: int | None = None,
    scheduler: str | None = None,
    overwrite: bool = False,
    memory_fraction: float = 0.5,
    log: Callable[[str], None] | None = None,
    client: Any = None,
    overlap: bool = True,
    prepare: int | None = None,
) -> SweepResult:
    """Run every unfinished shard of ``spec`` into ``out_dir``.

    ``workers=0`` runs the shards in this process (no Dask). Otherwise a local Dask cluster is started
    (``workers`` processes; default one per GPU of ``device``, or one per CPU core for ``cpu``), or the cluster at
    ``scheduler`` is used (its workers run on ``device``: ``cuda`` there means each worker's first visible GPU), or
    an open Dask ``client`` (``device`` as for a scheduler; see :func:`local_cluster`; a scheduler that does not
    answer within :data:`~aca_warp.sweep.cluster.CONNECT_TIMEOUT_S` is refused before anything is written).
    ``overlap`` (default): :data:`PIPELINE_DEPTH` shard tasks at a time in this process or in each local worker
    (threads), taking the device in turns (:class:`KernelTurn`), each writing its samples behind its run (a writer
    thread), so that one shard runs while the next waits ready and the last finishes its file; False: the serial
    path (one task per process, writes inline), same results bit for bit. ``prepare``: processes that make the
    shards ahead of their tasks (:mod:`aca_warp.sweep.prepare`: scenes and, where the neighbour search can run on a
    device of the run's kind here (:func:`prepare_device`), models on the host, initial states and the runs'
    checks; 0: each task makes its own; None: :func:`prepare_processes`), same results bit for bit. The manifest is
    updated as shards finish. A ``KeyboardInterrupt`` (Ctrl-C, or SIGTERM as the CLI maps it) stops the shards in
    flight, marks them ``interrupted`` in the manifest (the next call runs them) and is raised again.
    """
    t0 = time.perf_counter()
    say = log or (lambda s: None)
    folder_named(out_dir, SweepError)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SweepError(f"{out} exists and is not a folder")
    spec.check_records()
    check_runs(spec)  # a step, a load or a step count a pad cannot take: one line, before anything is written
    early = None
    try:
        if scheduler is None and client is None and workers != 0 and _have_dask():
            # a local cluster: Dask imported in a thread of its own while this call checks its devices and prepares
            # the manifest; its processes start once the call knows it runs shards (ClusterStart.go in _run_todo)
            early = ClusterStart(device, workers, overlap=overlap)
        if scheduler is None and client is None:  # validate before anything is written
            check_local_gpus(device)
        if scheduler is not None and client is None:
            check_scheduler(scheduler)  # a bad address or no answer: one line, nothing written
        out.mkdir(parents=True, exist_ok=True)
        # one sweep per directory: held until the last shard is recorded
        try:
            lock = OutputLock.acquire(out / MANIFEST, what="wait for that sweep to finish or stop it")
        except StorageError:  # a folder that takes no new file (read only): fine if it holds this sweep finished
            done = None if overwrite else finished_shards(spec, out)
            if done is None:
                raise
            say(f"{len(done)} of {spec.shard_count} shard(s) already finished, skipped ({out} takes no new file)")
            return SweepResult(out, [], done, {}, [], time.perf_counter() - t0, 0, 0)
        try:
            manifest = prepare_dir(spec, out, overwrite=overwrite)
            book = _Book(spec, out, manifest, say)
            check_room(  # after prepare_dir: the shards it will run, the files of another sweep it removed gone
                out,
                shard_bytes(spec, book.todo),
                "a larger run.sample_dt or a shorter run.duration",
                whose=f"the {len(book.todo)} shard file(s) to write",
                written="no shard was written (run the same command again when there is room)",
            )
            book.result.workers = 0
            if book.todo:
                options = {"memory_fraction": memory_fraction, "overlap": overlap, "prepare": prepare, "early": early}
                _run_todo(book, spec, device, workers, scheduler, client, **options)
            book.result.ran.sort()
            book.result.wall_time = time.perf_counter() - t0
            return book.result
        finally:
            lock.release()
    finally:
        if early is not None:
            early.close(quiet=True)  # a call that stopped before its shards, or ran none (the Dask path closed it)


def check_local_gpus(device: str) -> None:
    """The GPUs ``device`` names for a local sweep (``cuda``, ``cuda:0,1``): this machine's, or one SceneError line
    naming those it has; nothing for ``cpu``."""
    if device != "cpu":
        for k in cuda_ordinals(device):
            get_device(f"cuda:{k}")


def _run_todo(
    book: _Book,
    spec: SweepSpec,
    device: str,
    workers: int | None,
    scheduler: str | None,
    client: Any,
    *,
    memory_fraction: float,
    overlap: bool,
    prepare: int | None,
    early: ClusterStart | None,
) -> None:
    """Run ``book.todo`` (the arguments of :func:`run_sweep`): its preparation pool, then the in-process or the
    Dask path (``early``: the local cluster, starting)."""
    args = (spec.doc, str(spec.base_dir), str(book.out.resolve()))
    if workers is None and scheduler is None and client is None and not _have_dask():
        book.say("Dask is not installed (pip install 'aca-warp[sweep]'): running the shards in this process")
        workers = 0
    local = scheduler is None and client is None
    processes = prepare_processes(device, workers, local, spec) if prepare is None else prepare
    sharing = device_sharing(device, workers, scheduler, client)
    preparer = None
    if processes > 0:
        made = {"device": prepare_device(device, local), "memory_fraction": memory_fraction, "sharing": sharing}
        # the workers of a local cluster (this call's, or one this process started) read the prepared
        # shards from files; those of a scheduler's cluster may be on other hosts: by value
        spool = (local and workers != 0) or (client is not None and started_here(client))
        preparer = Preparer(*args[:2], processes, ahead=2 * processes, spool=spool, **made)
    try:
        if early is not None:  # after the pool's fork server has started (Preparer), before its first processes
            early.go(warm=preparer is not None)
        if preparer is not None:
            preparer.plan(book.todo)  # the pool starts its processes now, beside the local cluster's start
        if workers == 0 and local:
            dev = device if device == "cpu" else f"cuda:{cuda_ordinals(device)[0]}"
            run = _run_in_process_overlapped if overlap else _run_in_process
            run(book, args, dev, memory_fraction, preparer)
        else:
            job = (book, args, device, workers, scheduler, client, memory_fraction, overlap, preparer, sharing)
            _run_on_dask(*job, started=early)
    finally:
        if preparer is not None:
            preparer.close()


# default preparation processes (prepare_processes): per GPU of a local sweep, and at least; twice as many per GPU
# for a sweep that makes at least one layout per two pads (a sweep over patch seeds: its preparation binds on two
# GPUs; on one, a larger pool's slower start outweighs it: docs/sweeps.md)
PREPARE_PER_GPU, PREPARE_LEAST = 2, 4
LAYOUT_PREPARE_PER_GPU = 4


def prepare_processes(device: str, workers: int | None, local: bool, spec: SweepSpec | None = None) -> int:
    """Default size of the preparation pool: on CUDA :data:`PREPARE_PER_GPU` per GPU of a local sweep (a cluster
    this call starts, or this process), :data:`LAYOUT_PREPARE_PER_GPU` for a ``spec`` with at least one patch layout
    per two pads (:attr:`~aca_warp.sweep.spec.SweepSpec.layout_count` ≥ pads / 2), at least :data:`PREPARE_LEAST`
    and at most the cores its workers leave; 0 (each task makes its own shard) on the CPU, whose cores the workers
    use, and with a scheduler or client given (their hosts are not known here)."""
    if device == "cpu" or not local:
        return 0
    gpus = len(cuda_ordinals(device))
    busy = gpus if workers is None else workers
    per_gpu = PREPARE_PER_GPU
    if spec is not None and 2 * spec.layout_count >= spec.pad_count:
        per_gpu = LAYOUT_PREPARE_PER_GPU
    return max(1, min(max(per_gpu * gpus, PREPARE_LEAST), (os.cpu_count() or 1) - busy - 1))


def prepare_device(device: str, local: bool) -> str | None:
    """Where a preparation pool searches the neighbours of the models it makes (a device of the run's kind, so that
    they are the task's own bit for bit): the CPU for a CPU sweep, the first GPU of a local CUDA sweep, this host's
    first GPU for a cluster's (the workers' GPUs are taken to be of its model); None where this host has no GPU (the
    pool makes the scenes only, the tasks their models)."""
    if device == "cpu":
        return "cpu"
    if local:
        return f"cuda:{cuda_ordinals(device)[0]}"
    import warp as wp

    from aca_warp.common.devices import init_warp

    init_warp()
    return "cuda:0" if wp.get_cuda_device_count() > 0 else None


def _take(preparer: Preparer | None, i: int, idle: Callable[[], bool], cancel: Any = None) -> PreparedShard | None:
    """Shard ``i`` as the pool prepared it, or None (its task prepares it) when there is no pool, or when it is not
    ready and ``idle()`` says the device would wait for it (:meth:`Preparer.take`)."""
    return None if preparer is None else preparer.take(i, idle, cancel)


def _run_in_process(book: _Book, args: tuple, dev: str, memory_fraction: float, preparer: Preparer | None) -> None:
    """The serial path: one shard after another in this thread (``preparer``: scenes made ahead)."""
    running: set[int] = set()
    try:
        for i in book.todo:
            running = {i}
            book.queued([i])
            try:
                prepared = _take(preparer, i, lambda: True)  # nothing else runs: ready, or prepared in the task
                summary = run_shard(*args, i, dev, memory_fraction=memory_fraction, prepared=prepared)
            except StorageError as e:  # the device is full: the other shards would fail the same way
                book.failed(i, _one_line(e))
                book.stopped(set())
                raise
            except Exception as e:  # e.g. a pad whose combination of values is invalid: as on a Dask worker
                (book.out / (shard_name(i) + ".partial")).unlink(missing_ok=True)
                book.failed(i, _one_line(e))
                continue
            book.done(i, summary)
    except KeyboardInterrupt:  # run_shard has dropped the shard's .partial (or its file finished: adopted)
        book.stopped(running)
        raise


def _run_in_process_overlapped(
    book: _Book, args: tuple, dev: str, memory_fraction: float, preparer: Preparer | None
) -> None:
    """The overlapped path in this process: :data:`PIPELINE_DEPTH` shard tasks in threads, the device in turns
    (``preparer``: shards made ahead; one that is not ready when no other task is under way is made by its task)."""
    from concurrent.futures import ThreadPoolExecutor, as_completed, wait

    cancel = threading.Event()
    ctx = ShardContext(overlap=True, cancel=cancel)
    started: set[int] = set()
    active: set[int] = set()  # tasks that hold their shard and have not finished
    guard = threading.Lock()

    def task(i: int) -> dict:
        started.add(i)

        def idle() -> bool:  # no other task under way: claim the device for this one, prepared here
            with guard:
                if not active:
                    active.add(i)
                return i in active

        try:
            prepared = _take(preparer, i, idle, cancel)
            with guard:
                active.add(i)
            return run_shard(*args, i, dev, memory_fraction=memory_fraction, ctx=ctx, prepared=prepared)
        finally:
            with guard:
                active.discard(i)

    book.queued(book.todo)
    pool = ThreadPoolExecutor(max_workers=PIPELINE_DEPTH, thread_name_prefix="aca-warp-shard")
    futures = {pool.submit(task, i): i for i in book.todo}

    def take(fut: Any) -> BaseException | None:
        """Record a finished task; returns a storage error or a stop, which end the sweep."""
        i = futures[fut]
        try:
            book.done(i, fut.result())
        except ShardCancelled as e:
            return e
        except StorageError as e:
            book.failed(i, _one_line(e))
            return e
        except Exception as e:
            (book.out / (shard_name(i) + ".partial")).unlink(missing_ok=True)
            book.failed(i, _one_line(e))
        return None

    end: BaseException | None = None
    try:
        for fut in as_completed(futures):
            end = take(fut)
            if end is not None:
                break
    except BaseException as e:  # KeyboardInterrupt in this (the main) thread
        end = e
    if end is None:
        pool.shutdown()
        return
    cancel.set()  # the others stop at their next chunk or phase
    for fut in futures:
        fut.cancel()
    wait([f for f in futures if not f.cancelled()])
    pool.shutdown()
    for fut, i in futures.items():
        if fut.done() and not fut.cancelled() and i not in book.recorded:
            take(fut)
    book.stopped(started)
    raise end
