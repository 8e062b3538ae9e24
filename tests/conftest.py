"""Shared test setup: Warp kernel cache, quiet Warp, the devices to test on, one kernel load per session.

``WARP_CACHE_PATH`` is set before anything imports warp, so that compiled kernels land in the git-ignored
``<repo>/.warp_cache`` and are reused between runs. Tests that take a ``device`` argument are run once per
entry of :data:`DEVICES` ("cpu", plus "cuda:0" where a CUDA device is present).
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
os.environ.setdefault("WARP_CACHE_PATH", str(REPO / ".warp_cache"))

import warp as wp  # noqa: E402  (must follow the cache path)

if hasattr(wp, "LOG_WARNING") and hasattr(wp.config, "log_level"):
    wp.config.log_level = wp.LOG_WARNING

import pytest  # noqa: E402

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


@pytest.fixture(scope="session", autouse=True)
def _load_kernels() -> None:
    """Load (compile or fetch from the cache) the kernel modules once per device, before any test runs."""
    import aca_warp.kernels.hf
    import aca_warp.kernels.neighbours

    wp.init()
    for dev in DEVICES:
        wp.load_module(aca_warp.kernels.hf, device=dev)
        wp.load_module(aca_warp.kernels.neighbours, device=dev)
