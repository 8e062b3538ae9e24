"""The local Dask cluster of ``aca-warp sweep --workers N`` is closed to other users of the host: every port its
processes listen on (found by inspecting the process tree, not guessed) is on 127.0.0.1 and speaks TLS with this
sweep's own credentials, so a plain ``distributed.Client`` (or a plain Dask RPC) can neither connect nor run a task
through any of them while its shard runs (aca_warp.sweep.cluster.cluster_security); Dask's work folders and their
lock files are in the user's private folder, not in the shared temporary folder. Once every port has been tried the
sweep is stopped (SIGTERM: one line, exit 143, its shard marked interrupted): that a secured local cluster finishes
its shards is checked by the sweeps on local clusters of test_sweep_prepare.py and test_sweep_overlap.py, and the
rest of this shard would be seconds of stepping that check nothing more."""

from __future__ import annotations

import asyncio
import gc
import ipaddress
import json
import os
import signal
import time
import warnings
from pathlib import Path

import psutil
import pytest
from procs import error_lines, started, wait_for

dask = pytest.importorskip("dask")
pytest.importorskip("distributed")

PROBE_S = 4.0  # how long a plain client or RPC may take to get through [s] (on loopback it takes milliseconds)
# The sweep must outlive the probe, which takes all of PROBE_S at the HTTP ports (they never answer a Dask
# handshake): one shard of 400 patches (the other worker stays idle; few enough steps that 60 s stay a plausible
# duration on the CPU's fast on-chip engine) whose simulated time takes RUN_S of stepping at the
# pace measured here just before (:func:`run_duration`; a fixed duration is minutes on a loaded machine and, on a fast
# idle one, may end while the probe runs, as eight shards of 2 ms once did), and at least MIN_DURATION_S. The sweep is
# stopped once the probe is done, so a long RUN_S costs nothing.
RUN_S = 60.0
MIN_DURATION_S = 2e-2
SPEC = (
    '[sweep]\nbase = "hf1"\nshard_size = 1\n[run]\nduration = {duration:.3g}\nprecision = "fp32"\n'
    '[base.patches]\ncount = 400\n[parameters]\n"friction.M" = [0.8]\n'
)


def run_duration() -> float:
    """The simulated time [s] of SPEC's pad that takes about RUN_S of stepping on one core of this machine now: its
    pace measured by 0.2 ms in this process (graph captures excluded), at least MIN_DURATION_S."""
    import tomllib

    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state
    from aca_warp.sweep import load_spec

    spec = load_spec(tomllib.loads(SPEC.format(duration=2e-4)))
    model = build_model(spec.scenes([0]), device="cpu", precision=spec.precision)
    options = RunOptions(duration=2e-4, integrator=spec.integrator, dt=spec.dt, tolerance=spec.tolerance)
    res = run_hf(model, initial_state(model), options, record=spec.base.record)
    return max(MIN_DURATION_S, RUN_S * 2e-4 / res.wall_time)


def listening(pid: int) -> set[tuple[int, str, int]]:
    """(pid, address, port) of every listening TCP socket of process ``pid`` and its descendants."""
    try:
        root = psutil.Process(pid)
        procs = [root, *root.children(recursive=True)]
    except psutil.NoSuchProcess:
        return set()
    out = set()
    for p in procs:
        try:
            conns = p.net_connections(kind="tcp")
        except psutil.NoSuchProcess:
            continue
        out |= {(p.pid, c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN}
    return out


async def plain_client(address: str) -> str:
    """What a plain ``distributed.Client`` (no security) gets at ``address``: 'refused: ...' (no connection within
    PROBE_S), or it runs code on the scheduler and every worker (``run_on_scheduler``, ``run``: at once, not queued
    behind the running shards): 'ran code in pids ...'."""
    from distributed import Client

    try:
        client = await asyncio.wait_for(Client(address, asynchronous=True, timeout=PROBE_S - 2), PROBE_S)
    except Exception as e:  # noqa: BLE001  (any failure to connect is the outcome wanted)
        return f"refused: {type(e).__name__}"
    try:
        pids = [await client.run_on_scheduler(os.getpid), *(await client.run(os.getpid)).values()]
        return f"ran code in pids {pids}"
    except Exception as e:  # noqa: BLE001
        return f"connected, code not run: {type(e).__name__}"
    finally:
        await client.close()


async def plain_rpc(address: str) -> str:
    """What a plain Dask RPC (the protocol of the workers' and nannies' handlers, ``run`` among them) gets at
    ``address``: 'refused: ...' or 'answered ...'."""
    from distributed.core import rpc

    r = rpc(address, timeout=PROBE_S - 2)
    try:
        reply = await asyncio.wait_for(r.identity(), PROBE_S)
        return f"answered identity: {reply.get('type')}"
    except Exception as e:  # noqa: BLE001
        return f"refused: {type(e).__name__}"
    finally:
        await r.close_rpc()


async def probe(addresses: list[str]) -> tuple[dict[str, str], dict[str, str]]:
    """:func:`plain_client` and :func:`plain_rpc` at every address, all at once."""
    with dask.config.set({"distributed.comm.timeouts.connect": f"{PROBE_S - 2:g}s"}):
        out = await asyncio.gather(*(plain_client(a) for a in addresses), *(plain_rpc(a) for a in addresses))
    with warnings.catch_warnings():  # the clients that never connected, collected now, quietly
        warnings.simplefilter("ignore", RuntimeWarning)
        gc.collect()
    return dict(zip(addresses, out[: len(addresses)], strict=True)), dict(
        zip(addresses, out[len(addresses) :], strict=True)
    )


def test_plain_client_cannot_use_a_running_sweep(tmp_path: Path) -> None:
    (tmp_path / "spec.toml").write_text(SPEC.format(duration=run_duration()))
    out = tmp_path / "out"
    (tmp_path / "tmp").mkdir()
    (tmp_path / "run").mkdir(mode=0o700)
    folders = {"TMPDIR": str(tmp_path / "tmp"), "XDG_RUNTIME_DIR": str(tmp_path / "run")}
    with started(["sweep", str(tmp_path / "spec.toml"), "-o", str(out), "--workers", "2"], **folders) as sweep:
        ports: set[tuple[int, str, int]] = set()
        deadline = time.monotonic() + 120
        while len({pid for pid, _, _ in ports}) < 3 and time.monotonic() < deadline:  # the sweep and 2 workers
            assert sweep.poll() is None, sweep.stderr.read()
            ports = listening(sweep.pid)
            time.sleep(0.2)
        time.sleep(1.0)
        ports |= listening(sweep.pid)  # scheduler, nannies and workers: every one of them
        assert len(ports) >= 5 and len({pid for pid, _, _ in ports}) >= 3, ports
        assert all(ipaddress.ip_address(ip).is_loopback for _, ip, _ in ports), ports
        addresses = [f"tcp://{ip}:{port}" for _, ip, port in sorted(ports)]
        clients, rpcs = asyncio.run(probe(addresses))
        assert sweep.poll() is None, "the sweep ended before every port was tried; lengthen its runs"
        assert all(v.startswith("refused") for v in clients.values()), clients
        assert all(v.startswith("refused") for v in rpcs.values()), rpcs
        assert list((tmp_path / "tmp").iterdir()) == []  # while it runs, too
        wait_for(out / "shard-00000.h5.partial", sweep)  # its shard begun (long since, but on a loaded machine)
        sweep.send_signal(signal.SIGTERM)
        _, err = sweep.communicate(timeout=120)
        assert sweep.returncode == 143, err
        lines = error_lines(err)
        assert len(lines) == 1 and "shard(s) 0 marked interrupted" in lines[0], err
    shards = json.loads((out / "manifest.json").read_text())["shards"]
    assert [s["state"] for s in shards] == ["interrupted"]
    assert list((tmp_path / "tmp").iterdir()) == []  # Dask's work folders and locks: in the private folder
    assert (tmp_path / "run" / "aca-warp" / "dask").is_dir()


def test_prepared_shards_go_through_files_only_to_workers_started_here() -> None:
    """A sweep given a client hands its workers the spool files of prepared shards only when the client's cluster is
    a local one this process started (a LocalCluster, or a SpecCluster of nannies as the sweep's own): its workers
    are this host's and this user's. A client connected to a scheduler's address, or a cluster class that starts its
    workers elsewhere, whose workers may be on other hosts or of other users, gets the shards by value."""
    from types import SimpleNamespace

    from distributed import LocalCluster, Nanny, SpecCluster, Worker
    from distributed.deploy.ssh import Worker as SSHWorker

    from aca_warp.sweep.cluster import started_here

    def made(cls: type, *workers: type) -> SimpleNamespace:
        cluster = cls.__new__(cls)  # the object alone: no scheduler or worker started
        cluster.worker_spec = {f"w{i}": {"cls": w, "options": {}} for i, w in enumerate(workers)}
        return SimpleNamespace(cluster=cluster)

    assert started_here(made(SpecCluster, Nanny, Nanny))  # as local_cluster makes it
    assert started_here(made(LocalCluster, Worker))
    assert not started_here(made(SpecCluster))  # no workers
    assert not started_here(made(SpecCluster, Nanny, SimpleNamespace))  # one worker of another kind
    assert not started_here(made(SpecCluster, SSHWorker, SSHWorker))  # as distributed.SSHCluster makes it

    class Remote(SpecCluster):  # a cluster class of its own (a batch system's, the cloud's)
        pass

    assert not started_here(made(Remote, Nanny))
    assert not started_here(SimpleNamespace(cluster=None))  # Client("tls://host:port"): no cluster object
    assert not started_here(object())


@pytest.mark.parametrize("verbose", ["", "1"])
def test_local_workers_drop_dask_s_log_of_a_failed_task(verbose: str) -> None:
    """What a local worker runs as it starts drops Dask's "Compute Failed" log of a shard task that raised (the
    sweep says the failure in one line, on stderr and in the manifest), unless ACA_WARP_VERBOSE asks for it (its
    traceback is then the one of an unexpected error), and the heartbeat errors of a shutdown; it keeps the worker's
    other errors."""
    import subprocess
    import sys

    from aca_warp.sweep.cluster import _WORKER_PRELOAD

    code = (
        _WORKER_PRELOAD
        + "logging.basicConfig()\nlog = logging.getLogger('distributed.worker')\n"
        + "log.error('Compute Failed\\nKey: shard-0\\nTraceback: ...')\n"
        + "log.error('Failed to communicate with scheduler during heartbeat.')\nlog.error('another error')\n"
    )
    env = {**os.environ, "ACA_WARP_VERBOSE": verbose}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0 and "another error" in r.stderr and "heartbeat" not in r.stderr, r.stderr
    assert ("Compute Failed" in r.stderr) == bool(verbose), r.stderr
