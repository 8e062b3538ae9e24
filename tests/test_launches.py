"""Launches packed once and replayed on the CPU (aca_warp.common.launches): the same results as wp.launch, one record
per distinct launch, replays inside a CPU graph capture recorded into the graph, a bounded number kept."""

from __future__ import annotations

import numpy as np
import warp as wp
from aca_warp.kernels import hf as K

from aca_warp.common import launches
from aca_warp.common.launches import Launcher


def arrays(n: int = 5) -> tuple[wp.array, wp.array]:
    v = wp.array(np.linspace(1.0, 2.0, n), dtype=wp.float64, device="cpu")
    return v, wp.zeros(n, dtype=wp.float64, device="cpu")


def test_replays_equal_launches_and_are_recorded_once_per_distinct_launch() -> None:
    launch = Launcher(wp.get_device("cpu"))
    v, u = arrays()
    _, ref = arrays()
    for h in (0.5, 0.5, 0.25, 0.5):
        launch(K.drift, 5, [wp.float64(h), v, u])
        wp.launch(K.drift, dim=5, inputs=[wp.float64(h), v, ref], device="cpu")
    np.testing.assert_array_equal(u.numpy(), ref.numpy())  # the replays move u as the launches move ref
    assert len(launch.recorded) == 2  # h 0.5 (a new wp.float64 each time, the same value) and 0.25
    w = wp.zeros(5, dtype=wp.float64, device="cpu")
    launch(K.drift, 5, [wp.float64(0.5), v, w])  # another array: another launch, its own pointer
    assert len(launch.recorded) == 3
    np.testing.assert_array_equal(w.numpy(), 0.5 * v.numpy())
    np.testing.assert_array_equal(u.numpy(), 1.75 * v.numpy())


def test_replays_inside_a_cpu_capture_are_in_the_graph() -> None:
    launch = Launcher(wp.get_device("cpu"))
    v, u = arrays()
    launch(K.drift, 5, [wp.float64(1.0), v, u])  # recorded outside the capture, then replayed inside it
    with wp.ScopedCapture(device="cpu") as cap:
        launch(K.drift, 5, [wp.float64(1.0), v, u])
    np.testing.assert_array_equal(u.numpy(), v.numpy())  # a capture records, it does not run
    for _ in range(3):
        wp.capture_launch(cap.graph)
    np.testing.assert_array_equal(u.numpy(), 4.0 * v.numpy())


def test_a_launcher_keeps_a_bounded_number_of_launches(monkeypatch) -> None:
    monkeypatch.setattr(launches, "MAX_RECORDED", 3)
    launch = Launcher(wp.get_device("cpu"))
    v, u = arrays()
    for k in range(7):  # a caller passing a new value each time
        launch(K.drift, 5, [wp.float64(float(k)), v, u])
        assert len(launch.recorded) <= 3
    np.testing.assert_array_equal(u.numpy(), 21.0 * v.numpy())


def test_launch_cost_script(tmp_path) -> None:
    """scripts/launch_cost.py: both measurements, both ways, in the JSON with the machine (tiny counts)."""
    import json

    from scriptload import load_script

    out = tmp_path / "cost.json"
    assert load_script("launch_cost").main(["--launches", "3", "--repeat", "1", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["patches"] == 1758 and doc["machine"] and "--launches 3" in doc["command"]
    for case in ("launch", "strang step"):
        assert set(doc["microseconds"][case]) == {"wp.launch", "Launcher"}
        assert all(us > 0 for us in doc["microseconds"][case].values())
