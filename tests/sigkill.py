"""Shared by the checkpoint tests: run an ``aca-warp`` command in a subprocess and SIGKILL it after its first
checkpoint is on disk."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py

from aca_warp.common.checkpoint import has_checkpoint

# ``aca_warp.cli`` with its automatic checkpoints from the first chunk or step end on (not after 5 s of wall time)
AUTO_AT_ONCE = (
    "-c",
    "import sys; import aca_warp.common.checkpoint as c; c.AUTO_WALL_S = 0.0; from aca_warp.cli import main; "
    "sys.exit(main(sys.argv[1:]))",
)


def kill_after_first_checkpoint(
    args: list[str], part: Path, *, poll: float, python: tuple[str, ...] = ("-m", "aca_warp.cli")
) -> None:
    """Run ``python -m aca_warp.cli ARGS`` (``python``: the interpreter's arguments before ``ARGS``, e.g.
    :data:`AUTO_AT_ONCE`) and kill it with SIGKILL as soon as ``part`` (the run's ``.partial``) holds a checkpoint;
    asserts that the run was still going then and died by the signal. ``poll`` [s]. The file is read while the run
    is stopped (SIGSTOP), so the kill comes before the run can write anything more."""
    env = {**os.environ, "HDF5_USE_FILE_LOCKING": "FALSE"}
    proc = subprocess.Popen([sys.executable, *python, *args], env=env, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    checkpointed = False
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if part.exists():
                # look with the run stopped (SIGSTOP), so that it cannot finish between a look and the kill on a
                # busy machine; a look that lands mid-write fails and the run goes on (SIGCONT)
                os.kill(proc.pid, signal.SIGSTOP)
                try:
                    with h5py.File(part, "r", locking=False) as f:
                        checkpointed = has_checkpoint(f)
                except Exception:  # noqa: BLE001  (the writer may be mid-flush: try again)
                    checkpointed = False
                if checkpointed:
                    break
                os.kill(proc.pid, signal.SIGCONT)
            time.sleep(poll)
        assert proc.poll() is None, f"the run ended before it could be killed: {proc.stderr.read().decode()}"
        assert checkpointed
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
