"""Shards on Dask: a local cluster bound to loopback, or an existing scheduler or client.

:func:`local_cluster` starts worker processes (one per GPU, pinned through ``CUDA_VISIBLE_DEVICES``, with
:data:`~aca_warp.sweep.overlap.PIPELINE_DEPTH` threads in the overlapped path: one shard runs while the next waits
ready and the last finishes its file); :func:`_run_on_dask` hands them the shards, prepared ahead where a pool does
(:func:`_feed`), and records them as they finish; on a stop it marks the shards the workers were executing and
closes the cluster without its shutdown chatter.
"""

from __future__ import annotations

import atexit
import contextlib
import os
import sys
import threading
import time
import uuid
import warnings
from collections import deque
from collections.abc import Callable
from typing import Any

from aca_warp.common.links import private_dir
from aca_warp.sweep.manifest import _Book, _one_line
from aca_warp.sweep.overlap import PIPELINE_DEPTH, ShardCancelled, ShardContext, stop_event, stop_sweep
from aca_warp.sweep.prepare import PreparedShard, Preparer, SpooledShard
from aca_warp.sweep.shard import run_shard
from aca_warp.sweep.spec import SweepError


def cuda_ordinals(device: str) -> list[int]:
    """GPU ordinals named by ``device``: ``cuda`` (all), ``cuda:1`` or ``cuda:0,cuda:1``."""
    import warp as wp

    if device == "cuda":
        n = wp.get_cuda_device_count()
        if n == 0:
            raise SweepError("device 'cuda': no CUDA device is available")
        return list(range(n))
    out = []
    for part in device.split(","):
        part = part.strip()
        if not part.startswith("cuda:") or not part[5:].isdigit():
            raise SweepError(f"device {device!r}: expected cpu, cuda, cuda:N or a list cuda:0,cuda:1")
        out.append(int(part[5:]))
    return out


LOOPBACK = "127.0.0.1"  # the only address a local cluster binds


# Run in every local worker process as it starts: ignore SIGINT (Ctrl-C in a terminal reaches the whole process
# group, and the client alone handles it: it stops the cluster and marks the manifest; a worker would die with a
# traceback instead), start Warp quietly, and drop two of Dask's worker logs: the heartbeat errors a worker logs when
# the scheduler has gone first (a stopped sweep's shutdown; a lost scheduler reaches the client), and, unless
# ACA_WARP_VERBOSE is set (aca-warp --verbose), "Compute Failed" with its traceback for a shard task that raised (its
# one line is the sweep's, on stderr and in the manifest).
_WORKER_PRELOAD = (
    "import signal\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n"
    "import logging, os\n"
    "_drop = ('Failed to communicate with scheduler during heartbeat',)\n"
    "if os.environ.get('ACA_WARP_VERBOSE', '') in ('', '0'):\n    _drop += ('Compute Failed',)\n"
    "logging.getLogger('distributed.worker').addFilter(lambda r: not r.getMessage().startswith(_drop))\n"
    "from aca_warp.common.devices import init_warp\ninit_warp()\n"
)


# Dask's nannies give their workers MALLOC_TRIM_THRESHOLD_=65536 (and set it in this process's environment, which
# processes started here later inherit). Setting it turns off glibc's sliding mmap threshold: every NumPy buffer of
# 128 KiB or more is then mapped afresh (its pages faulted in and zeroed) and unmapped on free, which made a worker's
# build of a 256-pad hf1 shard 1.8× and its checks 1.5× slower on a CPU (docs/sweeps.md, "A worker's host work"). These
# workers hold no Dask data to trim (memory_limit 0): None leaves the variable unset.
_NANNY_ENV = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


def local_cluster(device: str, workers: int | None = None, *, threads: int = 1) -> Any:
    """A local Dask cluster of worker processes with ``threads`` threads each: one per GPU (``CUDA_VISIBLE_DEVICES``
    pinned; ``workers`` of them spread over the GPUs in turn, if given) or, for ``cpu``, ``workers`` of them (default
    one per core). Returns (cluster, device seen by workers).

    Scheduler, nannies and workers listen on 127.0.0.1 only, serve no dashboard and speak TLS with mutual
    authentication under credentials made for this cluster alone (:func:`cluster_security`): a Dask worker executes
    whatever pickled function reaches it, so nothing of a local cluster may be reachable from another host, nor
    usable by another local user (a client without the credentials cannot complete a handshake on any of its
    ports); their work folders live in the user's private folder, not in the shared temporary folder. Other hosts
    join only through an external scheduler (``--scheduler``; docs/sweeps.md, "Security").
    The worker processes ignore SIGINT (the client stops them)."""
    import logging

    import dask
    from distributed import Nanny, Scheduler, SpecCluster

    if device == "cpu":
        n = workers or os.cpu_count() or 1
        envs = [{} for _ in range(n)]
        worker_device = "cpu"
    else:
        ords = cuda_ordinals(device)
        visible = os.environ.get("CUDA_VISIBLE_DEVICES")
        names = visible.split(",") if visible else [str(i) for i in range(max(ords) + 1)]
        n = workers or len(ords)
        envs = [{"CUDA_VISIBLE_DEVICES": names[ords[i % len(ords)]]} for i in range(n)]
        worker_device = "cuda:0"
    # every process on loopback and behind TLS with this cluster's own credentials: a Dask worker runs the pickled
    # functions sent to it
    security = cluster_security()
    scratch = str(private_dir("dask"))  # Dask's work folders and their lock files: not in the shared /tmp
    opts = {
        "nthreads": threads,
        "memory_limit": 0,
        "silence_logs": logging.ERROR,
        "host": LOOPBACK,
        "dashboard": False,
        "dashboard_address": f"{LOOPBACK}:0",
        "preload": [_WORKER_PRELOAD],
        "security": security,
        "protocol": "tls",
        "local_directory": scratch,
    }
    spec = {f"w{i}": {"cls": Nanny, "options": {**opts, "env": env}} for i, env in enumerate(envs)}
    scheduler = {
        "dashboard": False,
        "dashboard_address": f"{LOOPBACK}:0",
        "host": LOOPBACK,
        "protocol": "tls",
        "local_directory": scratch,
    }
    with dask.config.set(_NANNY_ENV):  # read as the nannies are made, inside the constructor
        cluster = SpecCluster(
            workers=spec,
            scheduler={"cls": Scheduler, "options": {**scheduler, "security": security}},
            security=security,
            silence_logs=logging.ERROR,
            name="aca-warp-sweep",
        )
    return cluster, worker_device


def cluster_security() -> Any:
    """TLS credentials for one local cluster (``distributed.Security.temporary()``): a key and self-signed
    certificate made in memory for this sweep call, given to its scheduler, nannies, workers and client only (the
    worker processes receive them from their nanny through a pipe, not a file), with encryption required. A
    connection without them fails the TLS handshake, so another user of the host can neither connect to the
    cluster's ports nor run a task on its workers. Needs ``cryptography`` (the ``sweep`` extra)."""
    from distributed import Security

    try:
        return Security.temporary()
    except ImportError:
        raise SweepError(
            "a local Dask cluster is secured with TLS, which needs the cryptography package: "
            "pip install 'aca-warp[sweep]' (or cryptography), or run with --workers 0"
        ) from None


def warm_workers(client: Any, device: str) -> dict[str, float]:
    """Load (compile or fetch from the kernel cache) the HF kernel modules on every worker: address -> [s]."""
    from aca_warp.bench import load_modules

    def load(dev: str) -> float:
        import warp as wp

        wp.config.log_level = wp.LOG_WARNING
        return load_modules(wp.get_device(dev))

    return client.run(load, device)


class ClusterStart:
    """A local cluster (:func:`local_cluster`) started in a thread of its own, with its client and, when asked, its
    workers' kernels loaded (:func:`warm_workers`), so that its worker processes start (≈ 2 s on a GPU host: Python,
    Dask, Warp and CUDA in each) while the call starts its preparation pool and hands out the first shards.

    The thread imports Dask at once, then waits for :meth:`go`, which the call gives once it knows it will run
    shards: its devices checked (Warp started in the calling process first, so that no worker is spawned while
    Warp's start redirects this process's stderr), the directory's lock taken, the manifest made and the pool's fork
    server started (before a nanny sets its environment variables in this process). :meth:`result` waits for the
    start and returns (client, device seen by workers), or raises what the start raised. :meth:`close` closes what
    the start made; before the start has ended (a refused call, Ctrl-C) it does not wait: a start not given
    :meth:`go` spawns nothing, and one under way stops at its next step and closes what it made. A process that exits
    meanwhile waits for that (:func:`_join_starts`, at most :data:`EXIT_WAIT_S`): a thread killed at exit inside
    the TLS key's generation aborts the interpreter."""

    def __init__(self, device: str, workers: int | None, *, overlap: bool) -> None:
        """``overlap``: workers of :data:`PIPELINE_DEPTH` threads (the overlapped path), else of one."""
        self.client: Any = None
        self.worker_device = ""
        self.error: BaseException | None = None
        self._cluster: Any = None
        self._warm = False
        self._go = threading.Event()
        self._lock = threading.Lock()
        self._ended = False  # the thread has ended (under _lock)
        self._abandoned = False  # closed before the thread ended: the thread closes what it made (under _lock)
        self._thread = threading.Thread(
            target=self._start,
            args=(device, workers, PIPELINE_DEPTH if overlap else 1),
            name="aca-warp-cluster-start",
            daemon=True,
        )
        _STARTS.add(self)
        self._thread.start()

    def go(self, *, warm: bool) -> None:
        """Start the cluster now (``warm``: and load the workers' kernels: a pool prepares the shards)."""
        self._warm = warm
        self._go.set()

    def _start(self, device: str, workers: int | None, threads: int) -> None:
        try:
            from distributed import Client

            self._go.wait()
            if not self._abandoned:
                self._cluster, self.worker_device = local_cluster(device, workers, threads=threads)
            if not self._abandoned:
                self.client = Client(self._cluster)
            if self._warm and not self._abandoned:
                # the workers load their kernels before the first shard is handed out: the first turns do not
                # include it
                warm_workers(self.client, self.worker_device)
        except BaseException as e:  # noqa: BLE001  (raised in the caller's thread by result())
            self.error = e
        finally:
            with self._lock:
                self._ended = True
                abandoned = self._abandoned
            if abandoned:
                self._close(quiet=True)
            _STARTS.discard(self)

    def result(self) -> tuple[Any, str]:
        """Wait for the start; (client, device seen by workers), or what the start raised."""
        self._thread.join()
        if self.error is not None:
            raise self.error
        return self.client, self.worker_device

    def close(self, *, quiet: bool) -> None:
        """Close the client and cluster (once; later calls do nothing); ``quiet`` as :func:`_close`."""
        with self._lock:
            ended = self._ended
            self._abandoned = True
        self._go.set()  # a start still waiting for go ends without spawning anything
        if ended:
            self._close(quiet=quiet)

    def _close(self, *, quiet: bool) -> None:
        with self._lock:
            client, cluster, self.client, self._cluster = self.client, self._cluster, None, None
        if client is not None or cluster is not None:
            _close(client, cluster, quiet=quiet)


EXIT_WAIT_S = 30.0  # how long a process that exits waits for a cluster start under way to end [s]
_STARTS: set[ClusterStart] = set()  # the starts whose thread has not ended


@atexit.register
def _join_starts() -> None:
    """At exit: close the cluster starts under way (one not given its go ends at once, one under way stops at its
    next step and closes what it made) and wait for their threads, at most :data:`EXIT_WAIT_S` in all."""
    deadline = time.monotonic() + EXIT_WAIT_S
    for start in list(_STARTS):
        start.close(quiet=True)
        start._thread.join(max(0.0, deadline - time.monotonic()))


def _have_dask() -> bool:
    import importlib.util

    return importlib.util.find_spec("distributed") is not None


CONNECT_TIMEOUT_S = 10.0  # how long a sweep waits for the scheduler at --scheduler to answer [s]


def check_scheduler(address: str, timeout: float | None = None) -> None:
    """Connect once to the Dask scheduler at ``address`` (with the client's TLS settings from Dask's configuration)
    and close again, before a sweep writes anything: :class:`SweepError` with one line for an address Dask cannot
    parse or a scheduler that does not answer within ``timeout`` [s] (default :data:`CONNECT_TIMEOUT_S`)."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    try:
        from distributed.comm import connect
        from distributed.security import Security
    except ImportError:
        raise SweepError("Dask is not installed: pip install 'aca-warp[sweep]' (or dask[distributed])") from None

    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    _refused(address, timeout)

    async def probe() -> None:
        comm = await connect(address, timeout=timeout, **Security().get_connection_args("client"))
        await comm.close()

    async def probe_within() -> None:  # Dask's connect waits for ever on a listener that answers nothing
        await asyncio.wait_for(probe(), timeout)

    pool = ThreadPoolExecutor(1, thread_name_prefix="aca-warp-probe")  # its own event loop, whoever calls
    try:
        pool.submit(asyncio.run, probe_within()).result()
    except ValueError as e:
        raise SweepError(
            f"--scheduler {address!r} is not a Dask scheduler address ({e}); e.g. tcp://HOST:8786"
        ) from None
    except (OSError, asyncio.TimeoutError) as e:  # (asyncio's is no OSError before Python 3.11)
        why = "" if isinstance(e, (TimeoutError, asyncio.TimeoutError)) or "Timed out" in str(e) else f" ({e})"
        raise SweepError(
            f"no Dask scheduler answered at {address} within {timeout:g} s{why}; start it (dask scheduler) or check "
            "the address"
        ) from None
    finally:
        pool.shutdown(wait=False)


def _refused(address: str, timeout: float) -> None:
    """SweepError at once where the host of a TCP or TLS ``address`` refuses the connection (nothing listens on its
    port; Dask's own connect would retry it until its timeout); anything else is left to Dask's connect."""
    import socket

    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        host, port = parse_host_port(location)
    except (ValueError, TypeError):
        return
    if scheme not in ("tcp", "tls"):
        return
    try:  # a refusal comes at once; a host that drops the connection is left to Dask's connect and its timeout
        socket.create_connection((host, port), timeout=min(timeout, 1.0)).close()
    except ConnectionRefusedError:
        raise SweepError(
            f"nothing listens at {address} (connection refused); start the Dask scheduler there (dask scheduler) or "
            "check the address"
        ) from None
    except OSError:  # no route, a timeout: Dask's connect says so
        return


def _not_sync_cancel_error(record: Any) -> bool:
    """Logging filter: False for distributed's own error when a ``sync`` call that a signal interrupted is cancelled
    (``NameError: cannot access free variable 'future'`` in ``distributed.utils.sync.<locals>.cancel``, logged by
    tornado as "Exception in callback functools.partial(<function sync.<locals>.cancel ...>)"): harmless, since the
    sweep stops anyway, and not the one line a stopped sweep prints."""
    return "sync.<locals>.cancel" not in record.getMessage()


def _drop_sync_cancel_errors() -> None:
    """Filter those records (:func:`_not_sync_cancel_error`) out of tornado's callback log in this process."""
    import logging

    log = logging.getLogger("tornado.application")
    if _not_sync_cancel_error not in log.filters:
        log.addFilter(_not_sync_cancel_error)


def _run_on_dask(
    book: _Book,
    args: tuple,
    device: str,
    workers: int | None,
    scheduler: str | None,
    client: Any,
    memory_fraction: float,
    overlap: bool,
    preparer: Preparer | None = None,
    sharing: int = 1,
    started: ClusterStart | None = None,
) -> None:
    """Run ``book.todo`` as Dask tasks (a local cluster, a scheduler's, or ``client``'s); ``preparer``: the shards
    made ahead and sent with the tasks (:func:`_feed`); ``sharing``: tasks that may hold a device's memory at once
    (:func:`device_sharing`); ``started``: the local cluster, begun by the caller and given its go
    (:class:`ClusterStart`, :func:`~aca_warp.sweep.run.run_sweep`), used when there is neither a scheduler nor a
    client, and closed on return."""
    try:
        from distributed import Client
    except ImportError:
        raise SweepError(
            "Dask is not installed: pip install 'aca-warp[sweep]' (or dask[distributed]), or run with --workers 0"
        ) from None
    _drop_sync_cancel_errors()
    own_client = client is None
    futures: dict[Any, int] = {}
    interrupted = False
    token = uuid.uuid4().hex  # this call's tasks, for stop_sweep
    try:
        if client is not None:
            worker_device = "cuda:0" if device.startswith("cuda") else device
        elif scheduler is None:
            if started is None:
                raise ValueError("a local cluster is begun by the caller: pass started=ClusterStart(...)")
            client, worker_device = started.result()
        else:
            if not scheduler.startswith("tls://"):
                print(
                    f"aca-warp: note: {scheduler} is not a tls:// address: that cluster is not authenticated, anyone "
                    "who reaches its scheduler runs code on its workers (docs/sweeps.md, Security)",
                    file=sys.stderr,
                )
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)  # TLS settings, if any, from Dask's configuration
            worker_device = "cuda:0" if device == "cuda" else device
        info = client.scheduler_info(n_workers=-1)["workers"]
        book.result.workers = len(info)
        threads = sum(int(w.get("nthreads", 1)) for w in info.values())
        book.say(f"running {len(book.todo)} shard(s) on {book.result.workers} Dask worker(s), device {worker_device}")
        spec_hash = book.manifest["spec_hash"]

        def submit(i: int, prepared: PreparedShard | SpooledShard | None) -> Any:
            with warnings.catch_warnings():  # a shard prepared by value is its models (~100 MB for 256 hf1 pads)
                warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)
                fut = client.submit(
                    shard_task,
                    *args,
                    i,
                    worker_device,
                    memory_fraction=memory_fraction,
                    sharing=sharing,
                    overlap=overlap,
                    token=token,
                    prepared=prepared,
                    key=f"shard-{spec_hash[:12]}-{i}",
                    pure=False,
                )
            futures[fut] = i
            return fut

        _feed(book, submit, preparer, workers=book.result.workers, threads=threads)
    except BaseException:  # KeyboardInterrupt: stop the tasks, mark the shards that were running, close quietly
        interrupted = True
        if client is None:
            book.stopped(set())
        else:
            _stop_tasks(client, futures, token, book)
        raise
    finally:
        if started is not None:
            started.close(quiet=interrupted)
        else:
            _close(client if own_client else None, None, quiet=interrupted)


def shard_task(
    doc: dict,
    base_dir: str,
    out_dir: str,
    index: int,
    device: str,
    *,
    memory_fraction: float,
    sharing: int,
    overlap: bool,
    token: str,
    prepared: PreparedShard | SpooledShard | None = None,
) -> dict:
    """:func:`~aca_warp.sweep.shard.run_shard` as a Dask task that :func:`~aca_warp.sweep.overlap.stop_sweep`
    (``token``) stops at its next chunk or phase: its ``.partial`` is deleted and ``{"index", "state":
    "interrupted"}`` returned."""
    ctx = ShardContext(overlap=overlap, cancel=stop_event(token))
    try:
        return run_shard(
            doc,
            base_dir,
            out_dir,
            index,
            device,
            memory_fraction=memory_fraction,
            sharing=sharing,
            ctx=ctx,
            prepared=prepared,
        )
    except ShardCancelled:
        return {"index": index, "state": "interrupted"}


def _feed(
    book: _Book,
    submit: Callable[[int, PreparedShard | SpooledShard | None], Any],
    preparer: Preparer | None,
    workers: int,
    threads: int,
) -> None:
    """Hand ``book.todo`` to Dask (``submit``), in order but for prepared shards (below), and record the tasks as
    they finish.

    Without a ``preparer`` every shard is submitted at once (its task prepares it). With one (planned for
    ``book.todo`` already), a shard is submitted while fewer tasks than the cluster's ``threads`` are unfinished (so
    that prepared shards wait in the pool's results, not in the cluster's memory): with its preparation once that is
    ready, or, when fewer tasks than ``workers`` are unfinished (a worker would wait: at the start, or when the pool
    falls behind) and no pool process has begun it (:meth:`~aca_warp.sweep.prepare.Preparer.began`), at once and
    unprepared (its task prepares it). A later shard whose preparation is ready goes before one still being prepared
    (shards of unequal pads take unequal times). A shard whose preparation raised (or whose pool process died) is
    recorded failed, not submitted."""
    from distributed import as_completed

    todo = deque(book.todo)
    index: dict[Any, int] = {}
    running = as_completed()
    while todo or not running.is_empty():
        handed = []
        while todo and (preparer is None or running.count() < threads):
            i = todo[0]
            prepared = None
            if preparer is not None:
                ready = preparer.first_ready(todo)
                if ready is not None:
                    i = ready
                    try:
                        prepared = preparer.get(i)
                    except Exception as e:  # noqa: BLE001  (recorded as the shard's failure)
                        todo.remove(i)
                        book.failed(i, _one_line(e))
                        continue
                elif running.count() < workers and not preparer.began(i):
                    preparer.forget(i)
                else:
                    break
            todo.remove(i)
            fut = submit(i, prepared)
            index[fut] = i
            running.add(fut)
            handed.append(i)
        if handed:
            book.queued(handed)
        finished = [] if running.is_empty() else running.next_batch(block=not todo)
        for fut in finished:
            try:
                summary = fut.result()
            except Exception as e:  # a worker died (KilledWorker) or the shard raised: record, go on
                book.failed(index[fut], _one_line(e))
                continue
            if summary["state"] != "interrupted":  # (stopped by another client's stop_sweep: left to book.stopped)
                book.done(index[fut], summary)
        if todo and not handed and not finished:
            time.sleep(0.005)  # a preparation, or room among the threads, to wait for


STOP_WAIT_S = 60.0  # how long a stopped sweep waits for its running tasks to reach their next chunk [s]


def _stop_tasks(client: Any, futures: dict[Any, int], token: str, book: _Book) -> None:
    """A sweep on Dask stops: queued tasks are cancelled, running ones told to stop (they delete their ``.partial``
    at their next chunk) and waited for, then the manifest is written (:meth:`_Book.stopped`: a shard that finished
    meanwhile is recorded as its file says)."""
    from distributed import wait

    running = _running_shards(client, futures)
    with contextlib.suppress(Exception):
        client.cancel([f for f, i in futures.items() if i not in running])
        client.run(stop_sweep, token)
        wait([f for f, i in futures.items() if i in running], timeout=STOP_WAIT_S)
    book.stopped(running)


def started_here(client: Any) -> bool:
    """Whether ``client`` is connected to a local Dask cluster that this process started (a ``LocalCluster``, or a
    plain ``SpecCluster`` of nannies or workers as :func:`local_cluster` makes): its workers are then processes (or
    threads) of this host and this user, which can read the files of this user's private folders. A cluster class
    that starts its workers elsewhere (SSH, a batch system, the cloud) is not such a cluster."""
    try:
        from distributed import LocalCluster, Nanny, SpecCluster, Worker
    except ImportError:
        return False
    cluster = getattr(client, "cluster", None)
    if type(cluster) not in (LocalCluster, SpecCluster):
        return False
    specs = getattr(cluster, "worker_spec", None) or {}
    return bool(specs) and all(spec.get("cls") in (Nanny, Worker) for spec in specs.values())


def device_sharing(device: str, workers: int | None, scheduler: str | None, client: Any) -> int:
    """Shard tasks whose models may share one device's memory at once (:func:`~aca_warp.sweep.prepare.batch_capacity`
    splits it that many ways): on the CPU every worker of the cluster (local: ``workers``, default one per core; a
    client's: its workers); on GPUs the local workers per GPU (one, unless ``workers`` asks for more than there are
    GPUs); one in this process (``workers=0``) and on a scheduler's cluster (one worker per GPU)."""
    if workers == 0 and scheduler is None and client is None:
        return 1
    if client is not None:
        return len(client.scheduler_info(n_workers=-1)["workers"]) if device == "cpu" else 1
    if scheduler is not None:
        return 1
    if device == "cpu":
        return workers or os.cpu_count() or 1
    gpus = len(cuda_ordinals(device))
    return -(-(workers or gpus) // gpus)


def _running_shards(client: Any, futures: dict[Any, int]) -> set[int]:
    """Shards whose task a worker is executing now (all unfinished ones if the workers cannot be asked)."""
    keys = {fut.key: i for fut, i in futures.items()}

    def executing(dask_worker: Any) -> list:
        return [str(ts.key) for ts in dask_worker.state.executing]

    try:
        running = client.run(executing)
        return {keys[k] for ks in running.values() for k in ks if k in keys}
    except Exception:  # noqa: BLE001  (a cluster going down: assume every unfinished shard had begun)
        return {i for fut, i in futures.items() if not fut.done()}


_QUIET = threading.Lock()


def _close(client: Any, cluster: Any, *, quiet: bool) -> None:
    """Close a client and a local cluster; ``quiet`` (the sweep was stopped): without the shutdown chatter of workers
    stopped mid-task, and without raising."""
    import logging

    if not quiet:
        try:
            if client is not None:
                client.close()
        finally:
            if cluster is not None:
                cluster.close()
        return
    with _QUIET:  # one quiet close at a time (a start's thread may close its own): the levels come back as they were
        loggers = [logging.getLogger(n) for n in ("distributed", "tornado", "asyncio")]
        levels = [q.level for q in loggers]
        for q in loggers:
            q.setLevel(logging.CRITICAL + 1)
        try:
            if client is not None:
                with contextlib.suppress(Exception):
                    client.close(timeout=10)
            if cluster is not None:
                with contextlib.suppress(Exception):
                    cluster.close(timeout=20)
        finally:
            for q, lv in zip(loggers, levels, strict=True):
                q.setLevel(lv)
