"""Shared test setup: quiet Warp, the devices to test on, one kernel load per session.

Kernels compile into Warp's own kernel cache, the one ``aca-warp`` uses (``~/.cache/warp/<version>``, or
``WARP_CACHE_PATH``): compiled once per machine and Warp version, by the tests or the command line, for every
checkout. Tests that take a ``device`` argument are run once per entry of :data:`DEVICES` ("cpu", plus "cuda:0"
where a CUDA device is present).
"""

from __future__ import annotations

import gc
import json
import os
from pathlib import Path

import pytest
import warp as wp

from aca_warp.common.devices import init_warp

init_warp()  # quietly, as the command line does: Warp's log at warnings, no note of a missing CUDA driver

# ACA_WARP_TEST_DEVICES="cuda:0" restricts the device-parametrised tests (e.g. on a GPU machine whose Warp
# build cannot compile CPU kernels); run them there with `-k cuda`.
DEVICES: list[str] = (
    os.environ["ACA_WARP_TEST_DEVICES"].split(",")
    if os.environ.get("ACA_WARP_TEST_DEVICES")
    else ["cpu"] + (["cuda:0"] if wp.is_cuda_available() else [])
)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrise every test with a ``device`` argument over :data:`DEVICES`."""
    if "device" in metafunc.fixturenames:
        metafunc.parametrize("device", DEVICES)


def _load(names: tuple[str, ...]) -> None:
    """Load (compile, or fetch from the kernel cache) the kernel modules ``aca_warp.kernels.<name>`` on every device."""
    import importlib

    for name in names:
        module = importlib.import_module(f"aca_warp.kernels.{name}")
        for dev in DEVICES:
            wp.load_module(module, device=dev)


# Every test file's time in the last measured suite [s] (scripts/time_tests.py --durations): the order of the files
SUITE_TIMES = Path(__file__).resolve().parent.parent / "docs" / "benchmarks" / "test_suite.json"


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist (``-n``): every test file runs on one worker (``--dist loadfile`` in place of the default
    ``load``), so that a module's shared runs (its module-scoped fixtures) are made once, not once per worker; the
    files are handed out in the order of the collection (:func:`pytest_collection_modifyitems`: longest first), not
    by their number of tests; and the kernel modules many tests load compile once, here in the controller before the
    workers start (on an empty kernel cache every worker would otherwise compile them at the same time; the workers
    fetch them from the cache)."""
    if getattr(config, "workerinput", None) is None and getattr(config.option, "numprocesses", None):
        if getattr(config.option, "dist", None) == "load":
            config.option.dist = "loadfile"
        if hasattr(config.option, "loadscopereorder"):
            config.option.loadscopereorder = False
        _load(("hf", "neighbours", "hf_adaptive", "lf_contact", "lf_thermal", "lf_wear", "lf_patches", "lf_record"))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In a pytest-xdist worker: the test files in decreasing time of the last measured suite (:data:`SUITE_TIMES`;
    files it lacks last, in their own order; the tests of a file keep theirs), so that a long file starts early
    instead of running alone at the end while the other workers are idle (greedy longest-first scheduling)."""
    if getattr(config, "workerinput", None) is None:
        return
    try:
        seconds = json.loads(SUITE_TIMES.read_text()).get("file_seconds", {})
    except (OSError, ValueError):
        return
    items.sort(key=lambda item: -float(seconds.get(item.nodeid.split("::")[0], 0.0)))


def pytest_collection_finish(session: pytest.Session) -> None:
    """Once the tests are collected, the objects alive then (the imported modules, Warp's builtins, the collected
    items: some 370 000) are moved out of the garbage collector's reach (``gc.freeze``): they live until the process
    ends, and every full collection would otherwise walk them again — the automatic ones during the tests and the
    five pytest makes at the end of every process (≈ 0.45 s each). What the tests create is collected as before."""
    gc.freeze()


@pytest.fixture(scope="session")
def references(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Uninterrupted runs that the limited, interrupted and resumed runs of several test files (test_storage.py,
    test_cli_faults.py) must equal, read only: HF (``procs.HF_SCENE``, 1 ms, 40 patches with per-patch histories;
    ``hf_scene``, ``hf``) and LF (test_lf_checkpoint's pad, first applied for 1 s; ``lf_scene``, ``lf``). Made once
    per test session: under pytest-xdist in the folder the workers share, by the first worker that asks (a second
    waits for its lock, then reads them)."""
    import fcntl

    from procs import HF_DT, HF_SCENE
    from test_lf_checkpoint import lf_scene

    from aca_warp.cli import main

    base = tmp_path_factory.getbasetemp()
    d = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "references"
    d.mkdir(exist_ok=True)
    paths = {"hf_scene": d / "hf.toml", "hf": d / "hf.h5", "lf_scene": d / "lf.toml", "lf": d / "lf.h5"}
    with open(d / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (d / "made").exists():
            paths["hf_scene"].write_text(HF_SCENE)
            paths["lf_scene"].write_text(lf_scene(1.0))
            assert main(["hf", str(paths["hf_scene"]), "-o", str(paths["hf"]), "--no-progress", *HF_DT]) == 0
            assert main(["lf", str(paths["lf_scene"]), "-o", str(paths["lf"]), "--no-progress"]) == 0
            (d / "made").touch()
    return paths


@pytest.fixture(scope="session", autouse=True)
def _load_kernels() -> None:
    """Load the kernel modules nearly every test uses once per device, before any test runs."""
    _load(("hf", "neighbours"))
