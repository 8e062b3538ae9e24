"""The recorder's flush: a chunk holds the filled rows only, as arrays of its own; from a device buffer only those
rows are copied to the host (a whole per-patch buffer is up to 256 MB, flushed after every launch)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp

from aca_warp.hf.model import build_model
from aca_warp.hf.recorder import Recorder, rows_to_host
from aca_warp.scene import Record
from tests.test_watchdog import scene


class DeviceBuffer:
    """A stand-in for a recording buffer on a GPU (over a CPU array): slicing gives the rows; copying the whole
    buffer to the host is an error."""

    def __init__(self, array: wp.array) -> None:
        self.array, self.shape, self.dtype = array, array.shape, array.dtype
        self.device = type("Device", (), {"is_cpu": False})()

    def __getitem__(self, key: slice) -> wp.array:
        return self.array[key]

    def numpy(self) -> np.ndarray:
        raise AssertionError("the whole buffer was copied to the host")


def test_rows_to_host_copies_the_filled_rows_only():
    """On the CPU the rows are copied out of the buffer (it is overwritten by the next chunk); from a device buffer
    only the filled rows cross, and no row gives an empty array of the buffer's row shape and dtype."""
    buf = wp.array(np.arange(24, dtype=np.float32).reshape(6, 4), device="cpu")
    rows = rows_to_host(buf, 2)
    buf.fill_(-1.0)
    assert rows.shape == (2, 4) and rows[1, 3] == 7.0
    dev = DeviceBuffer(wp.array(np.arange(24, dtype=np.float32).reshape(6, 4), device="cpu"))
    assert rows_to_host(dev, 3).tolist() == np.arange(12, dtype=np.float32).reshape(3, 4).tolist()
    empty = rows_to_host(dev, 0)
    assert empty.shape == (0, 4) and empty.dtype == np.float32


def test_flush_hands_over_the_filled_rows_of_device_buffers():
    """A flush after three recorded samples, two of them with per-patch rows, reads three global rows and two
    velocity rows from device buffers (never the whole buffers) and resets the row counters."""
    s = dataclasses.replace(scene(), record=Record(sample_dt=1e-6, patches=("velocity",), window=(0, 1e-5),
                                                   decimation=2))  # fmt: skip
    model = build_model([s])
    rec = Recorder(model, s.record, rows=8, n_samples=10)
    rec.globals.assign(np.arange(rec.globals.size, dtype=np.float64).reshape(rec.globals.shape))
    rec.velocity.assign(np.arange(rec.velocity.size, dtype=np.float32).reshape(rec.velocity.shape))
    whole_g, whole_v = rec.globals.numpy().copy(), rec.velocity.numpy().copy()
    rec.counters.assign(np.array([3, 3, 2, 0], dtype=np.int32))
    rec.globals, rec.velocity = DeviceBuffer(rec.globals), DeviceBuffer(rec.velocity)  # type: ignore[assignment]
    chunk, table = rec.flush()
    assert chunk.time.tolist() == [0.0, 1e-6, 2e-6] and chunk.patch_time.tolist() == [0.0, 2e-6]
    np.testing.assert_array_equal(chunk.globals, whole_g[:3])
    np.testing.assert_array_equal(chunk.velocity, whole_v[:2])
    assert rec.counters.numpy()[1:3].tolist() == [0, 0] and table.shape[0] == 1


@pytest.mark.skipif(not wp.is_cuda_available(), reason="needs a CUDA device")
def test_rows_from_a_cuda_buffer_are_a_host_copy():
    """On a GPU the rows handed over are a host array of their own: refilling the buffer leaves them unchanged."""
    buf = wp.array(np.arange(24, dtype=np.float32).reshape(6, 4), device="cuda:0")
    rows = rows_to_host(buf, 3)
    buf.fill_(-1.0)
    assert rows.tolist() == np.arange(12, dtype=np.float32).reshape(3, 4).tolist()
    assert rows_to_host(buf, 0).shape == (0, 4)


def test_flush_cost_script_runs_both_ways_and_restores_the_package(tmp_path):
    """scripts/recorder_flush_cost.py: each way hands over the same samples, the JSON names the machine and the
    command, and the package's flush is in place again afterwards."""
    import json

    from scriptload import load_script

    import aca_warp.hf.recorder as recorder

    out = tmp_path / "flush.json"
    argv = ["--seeds", "2", "--patches", "30", "--duration", "1e-4", "--window", "5e-5", "--dt", "1e-7"]
    assert load_script("recorder_flush_cost").main([*argv, "--repeat", "1", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["pads"] == 2 and doc["patches"] == [30] and doc["machine"] and "--seeds 2" in doc["command"]
    rows, whole = doc["runs"]["rows"][0], doc["runs"]["whole"][0]
    assert rows["bytes"] == whole["bytes"] > 0 and rows["steps"] == whole["steps"] == 1000
    assert recorder.rows_to_host.__module__ == "aca_warp.hf.recorder"
