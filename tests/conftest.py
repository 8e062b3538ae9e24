"""Shared test setup: quiet Warp, the devices to test on, one kernel load per session.

Kernels compile into Warp's own kernel cache, the one ``aca-warp`` uses (``~/.cache/warp/<version>``, or
``WARP_CACHE_PATH``): compiled once per machine and Warp version, by the tests or the command line, for every
checkout. Tests that take a ``device`` argument are run once per entry of :data:`DEVICES` ("cpu", plus "cuda:0"
where a CUDA device is present).
"""

from __future__ import annotations

import os

import warp as wp

if hasattr(wp, "LOG_WARNING") and hasattr(wp.config, "log_level"):
    wp.config.log_level = wp.LOG_WARNING

import pytest

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
