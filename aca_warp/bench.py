"""Throughput profiling of the HF step: ``aca-warp bench`` and ``scripts/bench_hf.py``.

Per case (device, precision, integrator, engine, pads) one row with: device, Warp version, precision, patches, pads,
compile time (first kernel-module load of the process, then graph capture), per-stage times (contact solve,
neighbour build, whole model build, capture, stepping, recording), steps/s, patch-steps/s, ns per patch-step,
achieved memory bandwidth against the device peak, and the μ error against a reference run (fp64 ``strang``
at a quarter of the step, over the same window).

Timing method (all on warm kernels):

* ``wall_s``, ``steps_per_s``, ``patch_steps_per_s``: one run (:func:`aca_warp.hf.loop.run_hf` with the case's
  ``engine``: ``general`` is :func:`aca_warp.hf.loop.run_hf`, ``onchip`` the on-chip kernel (``blocks_per_pad``: its
  thread-block cluster size, :func:`aca_warp.hf.onchip.default_cluster`; ``block_dim``: its threads per block, None
  for the general engine), ``auto`` resolves as
  ``aca-warp hf`` does) over the timed window, recording every sample (what a user's run does; graph capture and
  compilation excluded, as in ``RunResult.wall_time``). ``engine`` in the row is the resolved one.
* ``stepping_s``: the bare step, ``HFSolver.step`` captured into one graph of ``GRAPH_STEPS`` steps and replayed,
  scaled to the run's step count (no recording, no host reads). Not for ``adaptive`` (no fixed step) nor for
  the on-chip engine (its state stays in shared memory: no per-step global traffic, so no bandwidth either).
* ``recording_s`` = ``wall_s`` − ``stepping_s``: sample kernels, host flushes, the run's first (eager) block.

Memory traffic per step is a model, counted from the arrays each kernel of the step reads and writes
(``bytes_per_step``): every per-patch array once per kernel that touches it, every CSR link once (index + k_ij),
neighbour displacements u_j assumed to hit in cache (patches are spatially sorted), per-pad arrays neglected.
With T the state size (4 or 8 B), n patches and E directed links:

    strang              n (8 + 12 T) + E (4 + T)    strang_advance: patch_pad, inv_mass, damping, F_N, r, F_s,
                                                    u rw, v rw; spring_forces: nbr_start, k_diag, u, F_s out
    symplectic-euler,   n (8 + 11 T) + E (4 + T)    velocity kernel (patch_pad, nbr_start, k_diag, inv_mass,
    implicit-friction                               damping, F_N, r, u, v rw) + drift (v, u rw)
    adaptive            n (12 + 27 T) + E (4 + T)   trial open (local args, u, v, F_s, 4 trial outs), trial
                                                    close (model args, 4 trial ins, F_s out), commit (3 in, 3 out)

Achieved bandwidth = bytes_per_step × steps / stepping time (run time for ``adaptive``). Device peak: CUDA, the
data-sheet peak of known devices (``PEAK_TABLE``: H100, H200, A100), else the driver's memory clock and bus width
(``2 × clock × width / 8``), else unknown; CPU, one thread's NumPy copy rate (``2 × bytes / time`` of a 128 MiB
``np.copyto``), since Warp's CPU kernels are serial.
"""

from __future__ import annotations

import argparse
import ctypes
import itertools
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.errors import SceneError, StorageError, option
from aca_warp.hf.options import (
    DEFAULT_SPLIT_TOLERANCE,
    DEFAULT_TOLERANCE,
    ONCHIP_INTEGRATORS,
    crossing_words,
    fast_math_unfit,
)

GRAPH_STEPS = 200
# Data-sheet peaks [B/s] by device-name fragment; used when the driver query is unavailable.
# Sources: NVIDIA H100 Tensor Core GPU data sheet (SXM5 80 GB HBM3: 3.35 TB/s; PCIe 80 GB HBM2e: 2.0 TB/s;
# NVL 94 GB: 3.9 TB/s); NVIDIA H200 Tensor Core GPU data sheet (141 GB HBM3e: 4.8 TB/s);
# NVIDIA A100 data sheet (80 GB SXM: 2.039 TB/s).
PEAK_TABLE: tuple[tuple[str, float, str], ...] = (
    ("H200", 4.8e12, "NVIDIA H200 data sheet, HBM3e 4.8 TB/s"),
    ("H100 NVL", 3.9e12, "NVIDIA H100 data sheet, NVL 3.9 TB/s"),
    ("H100 PCIe", 2.0e12, "NVIDIA H100 data sheet, PCIe 2.0 TB/s"),
    ("H100", 3.35e12, "NVIDIA H100 data sheet, SXM5 HBM3 3.35 TB/s"),
    ("A100", 2.039e12, "NVIDIA A100 data sheet, 80 GB SXM 2.039 TB/s"),
)
_STREAM_CACHE: dict[str, float] = {}


def bytes_per_step(integrator: str, patches: int, links: int, precision: str) -> int | None:
    """Modelled device-memory traffic of one step of all pads [B] (module docstring: the count); None for the
    integrators whose step mixes kinds of trial (``controlled``, ``auto``: no model of their traffic)."""
    t = 4 if precision == "fp32" else 8
    per_patch = {
        "strang": 8 + 12 * t,
        "symplectic-euler": 8 + 11 * t,
        "implicit-friction": 8 + 11 * t,
        "adaptive": 12 + 27 * t,
    }.get(integrator)
    return None if per_patch is None else int(patches * per_patch + links * (4 + t))


def cpu_stream_bandwidth(nbytes: int = 128 * 2**20, repeats: int = 3) -> float:
    """One thread's copy bandwidth: 2 × ``nbytes`` / best time of ``np.copyto`` [B/s] (cached per process)."""
    if "cpu" not in _STREAM_CACHE:
        a = np.ones(nbytes // 8)
        b = np.empty_like(a)
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            np.copyto(b, a)
            best = min(best, time.perf_counter() - t0)
        _STREAM_CACHE["cpu"] = 2.0 * a.nbytes / best
    return _STREAM_CACHE["cpu"]


def _driver_peak(ordinal: int) -> float | None:
    """2 × memory clock × bus width / 8 from the CUDA driver [B/s], or None when the query fails."""
    try:
        cuda = ctypes.CDLL("libcuda.so.1")
        dev = ctypes.c_int()
        if cuda.cuDeviceGet(ctypes.byref(dev), ordinal) != 0:
            return None
        clock, width = ctypes.c_int(), ctypes.c_int()
        # CU_DEVICE_ATTRIBUTE_MEMORY_CLOCK_RATE = 36 (kHz), CU_DEVICE_ATTRIBUTE_GLOBAL_MEMORY_BUS_WIDTH = 37 (bit)
        if cuda.cuDeviceGetAttribute(ctypes.byref(clock), 36, dev) != 0:
            return None
        if cuda.cuDeviceGetAttribute(ctypes.byref(width), 37, dev) != 0:
            return None
        if clock.value <= 0 or width.value <= 0:
            return None
        return 2.0 * clock.value * 1e3 * width.value / 8.0
    except (OSError, AttributeError):
        return None


def peak_bandwidth(device: Any) -> tuple[float | None, str]:
    """Peak memory bandwidth of a Warp device [B/s] and where the number comes from."""
    if not device.is_cuda:
        return cpu_stream_bandwidth(), "measured: one-thread numpy copy (2 x 128 MiB moved), best of 3"
    for frag, peak, src in PEAK_TABLE:
        if frag in device.name:
            return peak, src
    drv = _driver_peak(device.ordinal)
    if drv is not None:
        return drv, "CUDA driver: 2 x memory clock x bus width"
    return None, "unknown"


def bench_scene(
    name: str = "hf1", patches: int | None = None, sample_dt: float = 1.0e-6, allow_implausible: bool = False
):
    """The preset ``name`` (or a TOML scene path) with ``patches`` generated patches (default: the scene's);
    ``allow_implausible`` as ``aca-warp hf --allow-implausible``."""
    import dataclasses

    from aca_warp.scene import PatchGenerator, Record, load_scene

    scene = load_scene(name, allow_implausible=allow_implausible)
    if patches is not None:
        origin = dict((scene.origin or {}).get("patches", {}))
        if "file" in origin:
            raise SceneError("--patches needs a scene whose patches come from the generator")
        fields = {f.name for f in dataclasses.fields(PatchGenerator)}
        gen = PatchGenerator(**{**{k: v for k, v in origin.items() if k in fields}, "count": patches})
        scene = scene.replace(patches=gen.generate(scene.pad))
    return scene.replace(record=Record(sample_dt=sample_dt))


def load_modules(device: Any) -> float:
    """Load (compile, or fetch from the kernel cache) the HF kernel modules on ``device``, and on the CPU the one of
    a run's checks (the stable-step estimate's row sums); wall time [s]."""
    import warp as wp

    import aca_warp.kernels.hf
    import aca_warp.kernels.neighbours
    import aca_warp.kernels.step_bound

    t0 = time.perf_counter()
    wp.load_module(aca_warp.kernels.hf, device=device)
    wp.load_module(aca_warp.kernels.neighbours, device=device)
    wp.load_module(aca_warp.kernels.step_bound, device="cpu")
    wp.synchronize_device(device)
    return time.perf_counter() - t0


def _stepping_time(
    model: Any, state: Any, integrator: str, dt: float, steps: int, crossing: str = "point"
) -> float | None:
    """Wall time of ``steps`` bare steps (no recording) replayed from a captured graph [s]; None for the
    step-controlled integrators (each pad its own step: no bare fixed step to time). ``crossing``: strang's
    treatment of steps that cross zero slip."""
    import warp as wp

    from aca_warp.hf.options import STEP_CONTROLLED
    from aca_warp.hf.solver import HFSolver

    if integrator in STEP_CONTROLLED:
        return None
    solver = HFSolver(model, integrator, dt, force=True, crossing=crossing)
    dev = model.device
    if integrator == "strang":
        solver.prepare(state)
    solver.step(state, dt, first=True)  # strang's opening step differs from the rest
    with wp.ScopedCapture(device=dev) as cap:
        for _ in range(GRAPH_STEPS):
            solver.step(state, dt)
    reps = max(1, round(steps / GRAPH_STEPS))
    wp.capture_launch(cap.graph)  # warm replay
    wp.synchronize_device(dev)
    t0 = time.perf_counter()
    for _ in range(reps):
        wp.capture_launch(cap.graph)
    wp.synchronize_device(dev)
    return (time.perf_counter() - t0) * steps / (reps * GRAPH_STEPS)


def run_case(
    scene: Any,
    device: str,
    precision: str,
    integrator: str,
    pads: int,
    dt: float,
    duration: float,
    warmup: float = 2.0e-6,
    stages: bool = True,
    engine: str = "general",
    fast_math: bool = False,
    crossing: str = "point",
) -> dict:
    """Time one configuration; returns a result row (with ``mu``, pad 0's μ(t), for the error; popped later).
    ``fast_math``: the on-chip strang kernel compiled with CUDA fast math (``RunOptions.fast_math``); ``crossing``:
    strang's treatment of steps that cross zero slip (``RunOptions.crossing``)."""
    import warp as wp

    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.onchip_layout import choose_engine
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import Record

    dev = wp.get_device(device)
    scenes = [scene] * pads
    row: dict[str, Any] = _stage_times(scene, pads, dev) if stages else {}
    t0 = time.perf_counter()
    model = build_model(scenes, device=dev, precision=precision)
    wp.synchronize_device(dev)
    build_time = time.perf_counter() - t0
    state = initial_state(model)
    rec = Record(sample_dt=scene.record.sample_dt)
    engine = choose_engine(model, engine, integrator, fast_math)
    options = RunOptions(engine=engine, integrator=integrator, dt=dt, fast_math=fast_math, crossing=crossing)
    # compiles, captures; at least one sample interval (a shorter run records nothing and is refused)
    warm = run_hf(model, state, options.with_duration(max(warmup, rec.sample_dt)), record=rec)
    res = run_hf(model, state, options.with_duration(duration), record=rec)
    mu = res.collect().globals[:, 0, 0]
    n = model.patch_count
    onchip = engine == "onchip"
    bare = stages and not onchip  # the on-chip step has no bare-step graph to time
    stepping = _stepping_time(model, initial_state(model), integrator, res.dt, res.steps, crossing) if bare else None
    row.update(
        {
            "device": str(model.device),
            "device_name": model.device.name,
            "warp_version": wp.__version__,
            "precision": precision,
            "integrator": integrator,
            "engine": engine,
            "fast_math": fast_math,
            "crossing": crossing,
            "blocks_per_pad": res.blocks_per_pad,
            "block_dim": res.block_dim,
            "pads": pads,
            "patches": n,
            "patches_per_pad": n // pads,
            "links": model.nnz,
            "dt": res.dt,
            "steps": res.steps,
            "rejected": res.rejected,
            "compile_time_s": warm.compile_time,
            "capture_s": warm.compile_time,
            "model_build_s": build_time,
            "wall_s": res.wall_time,
            "stepping_s": stepping,
            "recording_s": None if stepping is None else max(res.wall_time - stepping, 0.0),
            "steps_per_s": res.steps / res.wall_time,
            "patch_steps_per_s": n * res.steps / res.wall_time,
            "ns_per_patch_step": 1e9 * res.wall_time / (n * res.steps),
            "stepping_patch_steps_per_s": None if stepping is None else n * res.steps / stepping,
            **_bandwidth_fields(model, res, stepping, integrator, precision, onchip, dev),
            "complete": res.complete,
            "mu": mu,
        }
    )
    return row


def _stage_times(scene: Any, pads: int, dev: Any) -> dict[str, Any]:
    """The two host/device stages inside build_model, timed alone for ``pads`` copies of ``scene``: ``contact_s``
    (the contact solve of every pad) and ``neighbours_s`` (the neighbour lists on ``dev``), both wall time [s]."""
    import warp as wp

    from aca_warp.hf.contact import solve_scene_contact
    from aca_warp.kernels.neighbours import build_neighbours

    row: dict[str, Any] = {}
    t0 = time.perf_counter()
    for s in [scene] * pads:
        solve_scene_contact(s)
    row["contact_s"] = time.perf_counter() - t0
    x = np.tile(scene.patches.x, pads)
    y = np.tile(scene.patches.y, pads)
    pad_of = np.repeat(np.arange(pads, dtype=np.int32), scene.patches.count)
    t0 = time.perf_counter()
    build_neighbours(x, y, pad_of, np.full(pads, scene.material.coupling_radius), dev)
    wp.synchronize_device(dev)
    row["neighbours_s"] = time.perf_counter() - t0
    return row


def _bandwidth_fields(
    model: Any, res: Any, stepping: float | None, integrator: str, precision: str, onchip: bool, dev: Any
) -> dict[str, Any]:
    """The bandwidth fields of a row: ``bytes_per_step`` [B] (None on the on-chip engine), ``bandwidth_Bps``
    [B/s] over the bare stepping time ``stepping`` [s] where measured, else over the run's wall time, the device's
    ``peak_bandwidth_Bps`` [B/s] with its ``peak_bandwidth_source``, and the ``bandwidth_fraction`` reached."""
    moved = None if onchip else bytes_per_step(integrator, model.patch_count, model.nnz, precision)
    bw_time = stepping if stepping is not None else res.wall_time
    bandwidth = None if moved is None else moved * res.steps / max(bw_time, 1e-12)
    peak, peak_src = peak_bandwidth(dev)
    return {
        "bytes_per_step": moved,
        "bandwidth_Bps": bandwidth,
        "peak_bandwidth_Bps": peak,
        "peak_bandwidth_source": peak_src,
        "bandwidth_fraction": None if peak is None or bandwidth is None else bandwidth / peak,
    }


def _engine_cell(r: dict) -> str:
    """The engine of a row, with the on-chip cluster size when a pad ran on more than one block ("onchip ×8")."""
    k = r.get("blocks_per_pad", 1)
    fast = ", fast math" if r.get("fast_math") else ""
    return r.get("engine", "general") + (f" ×{k}" if k > 1 else "") + fast + crossing_words(r.get("crossing", "point"))


def _cases(
    pads: tuple[int, ...],
    precisions: tuple[str, ...],
    integrators: tuple[str, ...],
    engines: tuple[str, ...],
    maths: tuple[str, ...],
) -> Iterator[tuple[int, str, str, str, bool]]:
    """The cases (pads, precision, integrator, engine, fast math) of a benchmark in the order they are timed: the
    on-chip engine only for its integrators, fast math only where it fits (strang in fp32, not the general engine)."""
    for npads, prec, integ, eng, kind in itertools.product(pads, precisions, integrators, engines, maths):
        fast = kind == "fast"
        if eng == "onchip" and integ not in ONCHIP_INTEGRATORS:
            continue
        if fast and (fast_math_unfit(integ, prec) is not None or eng == "general"):
            continue
        yield npads, prec, integ, eng, fast


def _no_case(integrators: tuple[str, ...], engines: tuple[str, ...]) -> str:
    """Why the cases of ``integrators`` × ``engines`` (and the other axes) are none, in one line."""
    if engines and set(engines) == {"onchip"} and integrators:
        given = option("engines=('onchip',)", "--engine onchip")
        general = option("'general' to engines", "--engine general")
        return (
            f"{given}: the on-chip engine implements the {' and '.join(ONCHIP_INTEGRATORS)} integrators only (got "
            f"{', '.join(integrators)}): no case to run; add {general} or one of those integrators"
        )
    return "no case to run: give at least one precision, integrator, engine, batch size and math"


def _row_line(r: dict) -> str:
    """The line a timed case prints."""
    err = r["mu_rel_error_max"]
    return (
        f"{r['device_name'][:24]:>24s} {r['precision']} {r['integrator']:>17s} {_engine_cell(r):>18s} "
        f"pads={r['pads']:5d} {r['patch_steps_per_s']:.3g} patch-steps/s {r['ns_per_patch_step']:.3g} ns/patch-step, "
        + ("" if r["bandwidth_Bps"] is None else f"{r['bandwidth_Bps'] / 1e9:.3g} GB/s, ")
        + f"compile {r['compile_time_s']:.2f} s"
        + ("" if err is None else f", mu err {err:.2e}")
    )


def run_bench(
    *,
    device: str = "cpu",
    scene: str = "hf1",
    patches: int | None = None,
    precisions: tuple[str, ...] = ("fp64", "fp32"),
    integrators: tuple[str, ...] = ("strang",),
    engines: tuple[str, ...] = ("auto",),
    maths: tuple[str, ...] = ("exact",),
    pads: tuple[int, ...] = (1,),
    dt: float | None = 1.0e-8,
    duration: float = 2.0e-5,
    sample_dt: float = 1.0e-6,
    reference: bool = True,
    stages: bool = True,
    log: Any = None,
    crossing: str | None = None,
    allow_implausible: bool = False,
) -> dict:
    """Run every case; returns ``{"machine", "scene", ..., "results": [rows]}`` (JSON-able). ``maths``: ``exact``
    and/or ``fast`` (CUDA fast math, on-chip strang in fp32 only: other cases are not run with it). ``dt`` None:
    strang's default step for the scene and sample interval (:func:`~aca_warp.hf.options.step_asked`), for every
    case. ``crossing``: strang's treatment of steps that cross zero slip, for every strang case
    (:data:`~aca_warp.hf.options.CROSSINGS`; ``mean`` with strang only); None: its default for the scene, as
    ``aca-warp hf`` takes it (:func:`~aca_warp.hf.options.crossing_asked`).

    Everything is checked before the first case runs, as ``aca-warp hf`` checks a run (SceneError): a step or
    duration outside the plausible range of an HF run unless ``allow_implausible``
    (:func:`~aca_warp.common.plausible.check`), a sample interval shorter than the step
    (:func:`~aca_warp.hf.recorder.check_sample_step`; a bench has no ``force``), and options that leave no case to
    run (e.g. the on-chip engine alone with an integrator it does not implement). The fixed step the cases take is
    the step shortened so that a whole number of steps fills a sample interval
    (:func:`~aca_warp.hf.solver.fitted_step`): ``dt_s`` in the result, ``dt_asked_s`` the step asked for."""
    import warp as wp

    from aca_warp.common import plausible
    from aca_warp.common.devices import get_device
    from aca_warp.common.files import machine
    from aca_warp.hf.options import check_crossing, crossing_asked, default_follows, step_asked
    from aca_warp.hf.recorder import check_sample_step
    from aca_warp.hf.solver import fitted_step
    from aca_warp.scene import Record

    sc = bench_scene(scene, patches, sample_dt, allow_implausible)
    step = step_asked("strang", dt, [sc], sample_dt)
    if not (duration > 0 and step > 0 and sample_dt > 0):
        raise SceneError("duration, dt and sample interval must be > 0")
    Record(sample_dt=sample_dt).check_duration(
        duration, option("sample_dt", "--sample-dt"), option("duration", "--duration")
    )
    plausible.check("duration", duration, "hf_duration", allow=sc.allow_implausible)
    if dt is not None:
        plausible.check("dt", dt, "hf_step", allow=sc.allow_implausible)
    check_sample_step(sample_dt, step, follows=default_follows("strang", dt, step))
    taken = fitted_step(step, sample_dt)
    if abs(taken - step) <= 1e-9 * step:  # whole steps fill the interval: the step as asked, not its rounding
        taken = step
    for integrator in integrators:  # before the first case, not after some have run
        check_crossing(crossing, integrator)
    if "fast" in maths and not any(c[4] for c in _cases((1,), precisions, integrators, engines, maths)):
        raise SceneError(
            "fast math compiles the on-chip strang kernel in fp32 only: add fp32, strang and auto or onchip"
        )
    if not any(True for _ in _cases(pads, precisions, integrators, engines, maths)):
        raise SceneError(_no_case(integrators, engines))
    dev = get_device(device)
    if "fast" in maths and dev.is_cpu:
        raise SceneError("fast math applies to CUDA devices only (Warp's CPU build has no fast math)")
    module_load = load_modules(dev)
    rows = []
    refs: dict[int, np.ndarray] = {}
    for npads, prec, integ, eng, fast in _cases(pads, precisions, integrators, engines, maths):
        try:
            r = run_case(
                sc, device, prec, integ, npads, step, duration, stages=stages, engine=eng, fast_math=fast,
                crossing=crossing_asked(integ, crossing, [sc]),
            )  # fmt: skip
        except SceneError as e:
            if not fast:
                raise
            if log:  # e.g. a pad that does not fit on chip: its exact rows stand, no fast one
                log(f"{prec} {integ} {eng} pads={npads}: no fast-math case: {e}")
            continue
        mu = r.pop("mu")
        r["module_load_s"] = module_load
        r["mu_rel_error_max"] = None
        if reference:
            if npads not in refs:  # reference: fp64 strang at dt/4 over the same two windows
                refs[npads] = run_case(sc, device, "fp64", "strang", 1, step / 4, duration, stages=False)["mu"]
            n = min(len(mu), len(refs[npads]))
            scale = max(np.abs(refs[npads][:n]).max(), 1e-300)
            r["mu_rel_error_max"] = float(np.max(np.abs(mu[:n] - refs[npads][:n])) / scale)
        rows.append(r)
        if log:
            log(_row_line(r))
    return {
        "machine": machine(dev),
        "warp_version": wp.__version__,
        "scene": scene,
        "duration_s": duration,
        "dt_s": taken,
        "dt_asked_s": step,
        "dt_is_default": dt is None,
        "sample_dt_s": sample_dt,
        "module_load_s": module_load,
        "results": rows,
    }


def _tolerances(integrators: list[str]) -> str:
    """The error controls of the step-controlled ``integrators`` among those of a bench's rows, for its header:
    `` (adaptive: tolerance 1e-05)``, …; "" when none of them ran."""
    words = {
        "adaptive": f"adaptive: tolerance {DEFAULT_TOLERANCE:g}",
        "controlled": f"controlled: split tolerance {DEFAULT_SPLIT_TOLERANCE:g}",
        "auto": f"auto: tolerance {DEFAULT_TOLERANCE:g}, split tolerance {DEFAULT_SPLIT_TOLERANCE:g}",
    }
    ran = [words[i] for i in dict.fromkeys(integrators) if i in words]
    return f" ({'; '.join(ran)})" if ran else ""


def markdown(out: dict) -> str:
    """A Markdown table of a :func:`run_bench` result."""
    asked = out.get("dt_asked_s", out["dt_s"])
    how = ["strang's default for the scene"] if out.get("dt_is_default") else []
    if asked != out["dt_s"]:
        interval = out["sample_dt_s"]
        how.append(f"{asked:g} s asked, shortened so that whole steps fill the {interval:g} s sample interval")
    step = f"{out['dt_s']:g} s" + (f" ({'; '.join(how)})" if how else "")
    tolerances = _tolerances([r["integrator"] for r in out["results"]])
    lines = [
        f"Machine: {out['machine']['device_name']}. Scene {out['scene']}, timed window {out['duration_s']:g} s "
        f"simulated, dt = {step}{tolerances}, "
        f"Warp {out['warp_version']}. "
        "μ error: max |μ − μ_ref| / max|μ_ref| against fp64 strang at dt/4. Bandwidth: modelled bytes per step "
        "(aca_warp/bench.py) over the bare-step time.",
        "",
        "| device | precision | integrator | engine | pads | patches | steps/s | patch-steps/s | ns/patch-step "
        "| GB/s (of peak) | compile [s] | μ error |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in out["results"]:
        frac = "" if r["bandwidth_fraction"] is None else f" ({100 * r['bandwidth_fraction']:.2g} %)"
        if r["bandwidth_Bps"] is not None:
            bw = f"{r['bandwidth_Bps'] / 1e9:.3g}{frac}"
        else:  # no bare step timed: the on-chip engine, or a step-controlled integrator
            bw = "– (on chip)" if r.get("engine") == "onchip" else "– (no fixed step)"
        err = "–" if r["mu_rel_error_max"] is None else f"{r['mu_rel_error_max']:.1e}"
        lines.append(
            f"| {r['device_name']} | {r['precision']} | {r['integrator']} | {_engine_cell(r)} | {r['pads']} "
            f"| {r['patches']} | {r['steps_per_s']:.3g} | {r['patch_steps_per_s']:.3g} | {r['ns_per_patch_step']:.3g} "
            f"| {bw} | {r['compile_time_s']:.2f} | {err} |"
        )
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------------- CLI


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp bench``."""
    from aca_warp.common.argtypes import int_at_least, positive, step_or_default
    from aca_warp.hf.options import CROSSING_HELP, CROSSINGS, ENGINES, INTEGRATORS

    p = sub.add_parser(
        "bench",
        help="measure HF step throughput (steps/s, patch-steps/s, bandwidth, error against a reference)",
        description="Benchmark the HF step per device, precision, integrator and batch size; prints one line "
        "per case and writes JSON rows\n(aca_warp/bench.py documents every field and the byte count).\n"
        "Checked before anything is measured: the step and duration (as aca-warp hf checks them) and the output "
        "files:\nan existing --json or --markdown file is kept unless --overwrite. The files are written whole at "
        "the end\n(a temporary file beside each, then renamed).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Example: aca-warp bench --device cuda:0 --precision fp32 --pads 1 1024 --json bench.json\n"
        "Exit codes: 0 done, 2 bad input, 3 a case stopped on a non-finite value, 4 an output could not be written.",
    )
    p.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    p.add_argument("--scene", default="hf1", help="preset or TOML scene (default hf1)")
    p.add_argument(
        "--precision", nargs="+", choices=("fp32", "fp64"), default=["fp64", "fp32"], help="precisions (default both)"
    )
    p.add_argument("--pads", nargs="+", type=int_at_least(1), default=[1], metavar="N", help="batch sizes (default 1)")
    p.add_argument("--patches", type=int_at_least(1), metavar="N", help="patches per pad (default: the scene's)")
    p.add_argument(
        "--integrator", nargs="+", choices=INTEGRATORS, default=["strang"], help="integrators (default strang)"
    )
    p.add_argument(
        "--engine",
        nargs="+",
        choices=ENGINES,
        default=["auto"],
        help="HF engines (default auto: on-chip where the model allows it, else general; onchip: strang, adaptive)",
    )
    p.add_argument(
        "--math",
        nargs="+",
        choices=("exact", "fast"),
        default=["exact"],
        help="exact (default) and/or fast: the on-chip strang kernel compiled with CUDA fast math, timed for fp32 "
        "cases only (aca-warp hf --fast-math; docs/onchip.md, 'Fast math')",
    )
    p.add_argument(
        "--dt",
        type=step_or_default,
        default=1.0e-8,
        metavar="S",
        help="fixed step [s] (default 1e-8, the step of the published tables, which ran the point treatment: "
        "--crossing point), or 'default': strang's default step for the scene, as `aca-warp hf` takes it (3.33e-7 "
        "or 2.5e-7 by regime for the shipped presets' physics, 5e-8 for any other scene; "
        "docs/numerics.md); refused, as by aca-warp hf, when longer than the sample interval or beyond 1e-5 s; "
        "shortened so that whole steps fill a sample interval (JSON dt_s: the step taken, dt_asked_s: this one)",
    )
    p.add_argument("--crossing", choices=CROSSINGS, help=CROSSING_HELP)
    p.add_argument("--duration", type=positive, default=2.0e-5, metavar="S", help="timed window [s] (default 2e-5)")
    p.add_argument("--sample-dt", type=positive, default=1.0e-6, metavar="S", help="sample interval [s] (default 1e-6)")
    p.add_argument("--no-reference", action="store_true", help="skip the fp64 dt/4 reference run (no μ error)")
    p.add_argument("--no-stages", action="store_true", help="skip the per-stage timings")
    p.add_argument(
        "--allow-implausible",
        action="store_true",
        help="run a step or duration far outside an HF run's range (dt beyond 1e-5 s, a duration beyond 1 s) and a "
        "scene with values far outside a brake pad's, refused otherwise as likely unit mistakes (as aca-warp hf)",
    )
    p.add_argument("--json", metavar="FILE", help="write the result rows as JSON here (a new file unless --overwrite)")
    p.add_argument(
        "--markdown", metavar="FILE", help="also write a Markdown table here (a new file unless --overwrite)"
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing --json or --markdown file (refused otherwise, before anything is measured)",
    )
    p.set_defaults(handler=_cmd_bench)


EXAMPLE_NAMES = {"--json": "bench.json", "--markdown": "bench.md"}  # file names the refusals suggest


def check_outputs(outputs: dict[str, str | None], overwrite: bool, scene: str | None = None) -> dict[str, Path]:
    """The output files of a bench, by option (``--json``, ``--markdown``; None: not asked for), checked before
    anything is measured: SceneError (exit 2) for an empty name, a name of a folder, two options naming one file, the
    ``scene`` file itself, an existing file without ``overwrite``, a missing folder; StorageError (exit 4) for a
    folder that takes no new file (:func:`~aca_warp.common.files.check_output_path`, as ``aca-warp hf`` checks its
    run file)."""
    from aca_warp.common.files import check_not_input, check_output_name, check_output_path

    given = {flag: path for flag, path in outputs.items() if path is not None}
    examples = {flag: EXAMPLE_NAMES.get(flag, "bench.json") for flag in given}
    for flag, text in given.items():
        check_output_name(text, flag=flag, example=examples[flag])
    flags = list(given)
    for i, flag in enumerate(flags):
        for other in flags[:i]:
            a, b = Path(given[other]), Path(given[flag])
            if os.path.realpath(a) == os.path.realpath(b) or (a.exists() and b.exists() and os.path.samefile(a, b)):
                raise SceneError(f"{other} and {flag} name the same file {given[flag]}; give each its own file")
    for text in given.values():
        check_not_input(text, {"scene file": scene}, "bench")
    return {
        flag: check_output_path(text, overwrite=overwrite, flag=flag, example=examples[flag])
        for flag, text in given.items()
    }


def write_outputs(texts: dict[Path, str]) -> None:
    """Write each text to its file whole, one after the other (:func:`~aca_warp.common.files.whole`: a temporary
    file beside it, then renamed), so that a failure leaves no half-written file. A file that cannot be written:
    StorageError (exit 4), one line naming it, the cause and what was written."""
    from aca_warp.common.files import UNWRITABLE, whole
    from aca_warp.common.links import LinkError

    done: list[Path] = []
    path = next(iter(texts), Path("."))
    try:
        for path, text in texts.items():
            with whole(path) as fh:
                fh.write(text.encode("utf-8"))
            done.append(path)
    except (OSError, SceneError) as e:  # SceneError: whole() found a folder at the name
        if isinstance(e, LinkError):  # a link planted at the temporary file: its own refusal
            raise
        code = getattr(e, "errno", None) or 0
        why = (
            UNWRITABLE.get(code)
            or getattr(e, "strerror", None)
            or ("a folder is there" if isinstance(e, SceneError) else type(e).__name__)
        )
        kept = f"{', '.join(map(str, done))} written, the rest not" if done else "nothing was written"
        err = StorageError(
            f"cannot write {path} ({why}); {kept} (the results are in the lines above): choose another output "
            "folder and run again"
        )
        err.errno = getattr(e, "errno", None)  # type: ignore[attr-defined]
        raise err from None


def _cmd_bench(args: argparse.Namespace) -> int:
    outputs = check_outputs({"--json": args.json, "--markdown": args.markdown}, args.overwrite, args.scene)
    out = run_bench(
        device=args.device,
        scene=args.scene,
        patches=args.patches,
        precisions=tuple(args.precision),
        integrators=tuple(args.integrator),
        engines=tuple(args.engine),
        maths=tuple(args.math),
        pads=tuple(args.pads),
        dt=args.dt,
        duration=args.duration,
        sample_dt=args.sample_dt,
        reference=not args.no_reference,
        stages=not args.no_stages,
        log=lambda s: print(s, flush=True),
        crossing=args.crossing,
        allow_implausible=args.allow_implausible,
    )
    render = {"--json": lambda: json.dumps(out, indent=1), "--markdown": lambda: markdown(out)}
    write_outputs({path: render[flag]() for flag, path in outputs.items()})
    for path in outputs.values():
        print(f"wrote {path}")
    return 0 if all(r["complete"] for r in out["results"]) else 3
