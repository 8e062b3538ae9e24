"""The on-chip adaptive engine (aca_warp.hf.onchip_adaptive) against the general engine's adaptive integrator.

On the CPU Warp runs a block as one thread, so the on-chip kernel does the general kernels' per-patch operations
in the same order: μ(t) and every global output, the per-patch histories, the final (u, u̇) and the step counts
must be bit-identical, across launch boundaries and for two pads that take different steps. With Warp's CPU
fibers a block has real threads and barriers: the state stays bit-identical (no cross-thread sums in it), which
fails if a barrier is missing between a stage and the next (a thread would read a neighbour's stale stage state).
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from aca_warp.common.errors import SceneError
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.onchip_layout import choose_engine
from aca_warp.hf.options import RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import Growth, Initial, Record, preset

RECORD = Record(sample_dt=1e-6, patches=("velocity", "displacement"), window=(2e-6, 1.5e-5), decimation=2)


def _scenes():
    """Two hf1 pads that differ in load, speed and initial state, so that they choose different steps."""
    s = preset("hf1").replace(record=RECORD)
    return [s, s.replace(normal_force=700.0, angular_velocity=5.0 / 0.13, initial=Initial(perturbation=0.02, seed=3))]


def _run(engine: str, precision: str, fibers: bool = False, **tuning):
    old = wp.config.enable_cpu_blocks
    wp.config.enable_cpu_blocks = fibers
    try:
        model = build_model(_scenes(), device="cpu", precision=precision)
        state = initial_state(model)
        opts = RunOptions(duration=2e-5, integrator="adaptive", engine=engine, tolerance=1e-5)
        res = run_hf(model, state, opts, tuning=EngineTuning(**tuning))
    finally:
        wp.config.enable_cpu_blocks = old
    return res, res.collect(), state.u.numpy(), state.v.numpy()


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_bit_identical_to_general_on_cpu(precision):
    rg, cg, ug, vg = _run("general", precision)
    ro, co, uo, vo = _run("onchip", precision, samples_per_launch=7)  # three launches, the last one short
    assert "step:adaptive:onchip" in ro.stages and "step:adaptive" in rg.stages
    assert ro.complete and rg.complete and ro.steps == rg.steps and ro.rejected == rg.rejected
    np.testing.assert_array_equal(co.time, cg.time)
    np.testing.assert_array_equal(co.globals, cg.globals)
    np.testing.assert_array_equal(co.patch_time, cg.patch_time)
    np.testing.assert_array_equal(co.velocity, cg.velocity)
    np.testing.assert_array_equal(co.displacement, cg.displacement)
    np.testing.assert_array_equal(uo, ug)
    np.testing.assert_array_equal(vo, vg)
    assert co.globals.shape[0] == 21 and co.velocity.shape[0] == 7
    assert np.ptp(cg.globals[1:, :, 0], axis=0).min() > 0  # μ moves: the comparison is not of a rest state


def test_cpu_fibers_same_state():
    """64 threads per block on Warp's CPU fibers: the state is the same bit for bit, the sums of the global
    outputs differ only in summation order."""
    _, cg, ug, vg = _run("general", "fp64")
    _, co, uo, vo = _run("onchip", "fp64", fibers=True, block_dim=64, samples_per_launch=5)
    np.testing.assert_array_equal(uo, ug)
    np.testing.assert_array_equal(vo, vg)
    np.testing.assert_array_equal(co.velocity, cg.velocity)
    np.testing.assert_allclose(co.globals, cg.globals, rtol=1e-12, atol=1e-15)


def test_step_underflow_is_a_fault_on_both_engines():
    """A tolerance no step can meet: the step shrinks below MIN_STEP within the first interval and the run stops
    with that fault at t = 0, keeping no sample after it, on both engines alike."""
    faults = []
    for engine in ("general", "onchip"):
        model = build_model([preset("hf1").replace(record=Record(sample_dt=1e-6))], device="cpu")
        res = run_hf(model, initial_state(model), RunOptions(duration=4e-6, integrator="adaptive", tolerance=1e-30,
                                                             engine=engine))  # fmt: skip
        assert not res.complete and res.fault is not None and res.fault.cause == "step-size underflow"
        faults.append((res.fault.time, res.collect().globals.shape[0], res.rejected > 0))
    assert faults[0] == faults[1] == (0.0, 0, True)


def _varying_area(engine: str, fibers: bool = False, **tuning):
    """2 µs of two growing varying_area pads (the second 300 patches smaller, 0.7 of the load): an event every
    0.202 µs, each re-solving the contact of patches of different heights."""
    import dataclasses

    s = preset("varying_area").replace(record=Record(sample_dt=1e-6))
    p = s.patches
    small = dataclasses.replace(p, x=p.x[:-300], y=p.y[:-300], area=p.area[:-300], height=p.height[:-300])
    old = wp.config.enable_cpu_blocks
    wp.config.enable_cpu_blocks = fibers
    try:
        model = build_model([s, s.replace(patches=small, normal_force=0.7 * s.normal_force)], device="cpu")
        state = initial_state(model)
        opts = RunOptions(duration=2e-6, integrator="adaptive", engine=engine, tolerance=1e-5)
        res = run_hf(model, state, opts, tuning=EngineTuning(**tuning))
    finally:
        wp.config.enable_cpu_blocks = old
    assert res.complete and "growth" in res.stages
    grown = {k: model.host(k) for k in ("area", "k_diag", "normal_force", "pad_gap", "pad_matrix_force")}
    return res, res.collect().globals, state.u.numpy(), grown


def test_growing_pads_bit_identical_to_general():
    """Growing pads on chip: every block landing on the events grows its patches, updates the links and re-solves
    the contact; on the CPU the samples, the state and the grown model equal the general engine's bit for bit."""
    rg, gg, ug, mg = _varying_area("general")
    ro, go, uo, mo = _varying_area("onchip", samples_per_launch=1)
    assert "step:adaptive:onchip" in ro.stages and (ro.steps, ro.rejected) == (rg.steps, rg.rejected)
    np.testing.assert_array_equal(go, gg)
    np.testing.assert_array_equal(uo, ug)
    for k in mg:
        np.testing.assert_array_equal(mo[k], mg[k], err_msg=k)
    fresh = build_model([preset("varying_area")], device="cpu")
    assert np.all(mo["area"][: fresh.patch_count] > fresh.host("area"))


def test_growing_pads_cpu_fibers():
    """The same with 64 fiber threads per block: the contact's block sums run in a tree, so everything agrees to
    rounding; a barrier missed between growing, linking and the contact shows as an O(1) error."""
    _, gg, ug, mg = _varying_area("general")
    _, go, uo, mo = _varying_area("onchip", fibers=True, block_dim=64, samples_per_launch=1)
    for k in mg:
        np.testing.assert_allclose(mo[k], mg[k], rtol=1e-9, atol=0, err_msg=k)
    np.testing.assert_allclose(uo, ug, rtol=0, atol=1e-9 * np.abs(ug).max())
    np.testing.assert_allclose(go, gg, rtol=1e-9, atol=1e-15)


def test_growing_scene_and_options():
    """A growing scene runs the adaptive integrator on chip when asked (``auto`` too); bad tuning is refused."""
    s = preset("hf1").replace(record=Record(sample_dt=1e-6), growth=Growth(increment=1e-9, interval=1e-6))
    model = build_model([s], device="cpu")
    assert choose_engine(model, "auto", "adaptive") == "onchip"
    model = build_model([preset("hf1").replace(record=Record(sample_dt=1e-6))], device="cpu")
    with pytest.raises(SceneError, match="samples_per_launch"):
        run_hf(model, initial_state(model), RunOptions(duration=2e-6, integrator="adaptive", engine="onchip"),
               tuning=EngineTuning(samples_per_launch=0))  # fmt: skip
    with pytest.raises(SceneError, match="block_dim"):
        run_hf(model, initial_state(model), RunOptions(duration=2e-6, integrator="adaptive", engine="onchip"),
               tuning=EngineTuning(block_dim=2048))  # fmt: skip


def test_cuda_lane_path_builds():
    """The stage evaluation with several lanes per patch (warp shuffles; CUDA only, checked against the general
    engine by scripts/onchip_gpu_check.py --integrator adaptive) passes Warp's code generation and compiles."""
    from aca_warp.kernels.hf_onchip_adaptive import onchip_dp5_kernel

    for dtype in (wp.float32, wp.float64):
        wp.load_module(onchip_dp5_kernel(dtype, 1, 64, 8).module, device="cpu")


def test_profiling_ablations():
    """``ablate`` (scripts/profile_onchip_adaptive.py) leaves parts out: without ``record`` no sample after the
    first has its global outputs; unknown names are refused."""
    from aca_warp.kernels.hf_onchip_adaptive import onchip_dp5_kernel

    model = build_model([preset("hf1").replace(record=Record(sample_dt=1e-6))], device="cpu")
    opts = RunOptions(duration=3e-6, integrator="adaptive", engine="onchip")
    g = run_hf(model, initial_state(model), opts, tuning=EngineTuning(ablate=frozenset({"record"}))).collect().globals
    assert g[0, 0, 0] > 0 and np.all(g[1:] == 0)
    with pytest.raises(ValueError, match="unknown ablations"):
        onchip_dp5_kernel(wp.float64, ablate=frozenset({"friction"}))


def test_non_finite_state_is_the_same_fault_on_both_engines():
    """A patch with a non-finite velocity: the watchdog names it at sample 0 on both engines (the trial's error is
    not finite, so no step is accepted after it either)."""
    faults = []
    for engine in ("general", "onchip"):
        model = build_model([preset("hf1").replace(record=Record(sample_dt=1e-6))], device="cpu")
        state = initial_state(model)
        v = state.v.numpy()
        v[123] = np.nan
        state.v.assign(v)
        res = run_hf(model, state, RunOptions(duration=4e-6, integrator="adaptive", engine=engine))
        assert not res.complete and res.fault is not None
        faults.append((res.fault.time, res.fault.pad, res.fault.patch, res.fault.cause))
    assert faults[0] == faults[1] and faults[0][2] == 123


def test_neighbour_lists_from_global_memory(monkeypatch):
    """Where a block's neighbour lists do not fit shared memory beside the stage displacements (large pads on few
    blocks), they are read from global memory: the same results bit for bit."""
    import aca_warp.hf.onchip_adaptive as OA

    model = build_model(_scenes()[:1], device="cpu")
    assert OA.tile_sizes(model, 1)[1] > 0  # on the CPU an hf1 pad's lists fit
    _, cg, ug, vg = _run("general", "fp64")
    monkeypatch.setattr(OA, "smem_limit", lambda m: 64 * 1024)
    assert OA.tile_sizes(model, 1)[1] == 0
    _, co, uo, vo = _run("onchip", "fp64", samples_per_launch=9)
    np.testing.assert_array_equal(co.globals, cg.globals)
    np.testing.assert_array_equal(uo, ug)
    np.testing.assert_array_equal(vo, vg)


def test_pads_of_different_sizes():
    """An hf1 pad and the same pad without its last 700 patches (different patch counts and neighbour lists) in
    one batch: bit-identical to the general engine, each pad with its own steps."""
    import dataclasses

    rec = Record(sample_dt=1e-6)
    s = preset("hf1").replace(record=rec)
    p = s.patches
    small = dataclasses.replace(p, x=p.x[:-700], y=p.y[:-700], area=p.area[:-700], height=p.height[:-700])
    out = {}
    for engine in ("general", "onchip"):
        model = build_model([s, s.replace(patches=small, normal_force=300.0)], device="cpu")
        sizes = np.diff(model.pad_patch_start_host)
        assert sizes[0] != sizes[1]
        state = initial_state(model)
        res = run_hf(model, state, RunOptions(duration=1e-5, integrator="adaptive", engine=engine),
                     tuning=EngineTuning(samples_per_launch=4))  # fmt: skip
        out[engine] = (res.collect().globals, state.u.numpy(), res.steps, res.rejected)
    np.testing.assert_array_equal(out["onchip"][0], out["general"][0])
    np.testing.assert_array_equal(out["onchip"][1], out["general"][1])
    assert out["onchip"][2:] == out["general"][2:]


@pytest.mark.parametrize(("cap", "launches"), [(None, 1), (3 * 3516, 7), (100, 20)])
def test_a_cpu_launch_covers_at_most_the_patch_sample_cap(cap, launches, monkeypatch):
    """On the CPU a launch of the adaptive kernel covers at most ``CPU_PATCH_SAMPLES_PER_LAUNCH`` patch-samples in whole
    sample intervals and at least one (a batch larger than the cap: one per launch): two hf1 pads (3516 patches),
    20 samples in 1, ceil(20 / 3) or 20 launches; the same bits as the general engine in every case."""
    from aca_warp.hf import onchip_adaptive

    if cap is not None:
        monkeypatch.setattr(onchip_adaptive, "CPU_PATCH_SAMPLES_PER_LAUNCH", cap)
    calls = []
    real = onchip_adaptive.OnchipAdaptiveEngine._launch

    def counted(self, samples, *a):
        calls.append(samples)
        return real(self, samples, *a)

    monkeypatch.setattr(onchip_adaptive.OnchipAdaptiveEngine, "_launch", counted)
    ro, co, uo, _ = _run("onchip", "fp64")
    assert ro.complete and len(calls) == launches and sum(calls) == 20
    _, cg, ug, _ = _run("general", "fp64")
    np.testing.assert_array_equal(co.globals, cg.globals)
    np.testing.assert_array_equal(uo, ug)
