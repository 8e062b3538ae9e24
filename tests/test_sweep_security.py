"""The local Dask cluster of ``aca-warp sweep --workers N`` is closed to other users of the host: every port its
processes listen on (found by inspecting the process tree, not guessed) is on 127.0.0.1 and speaks TLS with this
sweep's own credentials, so a plain ``distributed.Client`` (or a plain Dask RPC) can neither connect nor run a task
through any of them, while the sweep itself completes (aca_warp.sweep.cluster.cluster_security); Dask's work
folders and their lock files are in the user's private folder, not in the shared temporary folder."""

from __future__ import annotations

import asyncio
import gc
import ipaddress
import json
import os
import time
import warnings
from pathlib import Path

import psutil
import pytest
from procs import started

dask = pytest.importorskip("dask")
pytest.importorskip("distributed")

PROBE_S = 4.0  # how long a plain client or RPC may take to get through [s] (on loopback it takes milliseconds)
# The sweep must outlive the probe, which takes all of PROBE_S at the HTTP ports (they never answer a Dask
# handshake): one shard of 60 ms of 25 patches, about 20 s of one worker at load 3 on the 2-core machine (eight shards
# of 2 ms, as before, ended while the probe ran once the kernels were cached); the other worker stays idle.
SPEC = (
    '[sweep]\nbase = "hf1"\nshard_size = 1\n[run]\nduration = 6e-2\nprecision = "fp32"\n'
    '[base.patches]\ncount = 25\n[parameters]\n"friction.M" = [0.8]\n'
)


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
    (tmp_path / "spec.toml").write_text(SPEC)
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
        assert sweep.wait(timeout=300) == 0, sweep.stderr.read()
    shards = json.loads((out / "manifest.json").read_text())["shards"]
    assert [s["state"] for s in shards] == ["done"]
    assert list((tmp_path / "tmp").iterdir()) == []  # Dask's work folders and locks: in the private folder
    assert (tmp_path / "run" / "aca-warp" / "dask").is_dir()
