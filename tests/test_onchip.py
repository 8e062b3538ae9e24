"""The on-chip engine (aca_warp.hf.onchip) against the general per-step path (aca_warp.hf.loop.run_hf).

On the CPU Warp runs a block as one thread, so the on-chip kernel does the same operations in the same order
as the general kernels: μ(t), all global outputs, the per-patch histories and the final (u, u̇) must be
bit-identical. With Warp's cooperative CPU fibers (``wp.config.enable_cpu_blocks``) a CPU block has real
threads and barriers: the state and the per-patch histories stay bit-identical (no cross-thread sums), which
fails if any barrier is reached by only part of the block (the CUDA hang of docs/onchip.md gave a 6 % error of μ
here). On CUDA the in-block tree reductions reorder the float64 sums of the global outputs and the
compiler may contract multiply-adds differently in the two kernels, so there they agree to rounding only
(the bounds below are a few hundred ulps of the state precision after 200 steps).
"""

from __future__ import annotations

import dataclasses
import json
from contextlib import contextmanager

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.hf_onchip import readers
from hypothesis import given, settings
from hypothesis import strategies as st
from procs import cpu_fibers
from scriptload import load_script

from aca_warp.common.errors import SceneError
from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.onchip_layout import choose_engine, csr_slots, default_block, default_cluster, pad_sizes
from aca_warp.hf.options import RunOptions
from aca_warp.hf.recorder import GLOBAL_NAMES
from aca_warp.hf.solver import stable_step
from aca_warp.hf.state import initial_state
from aca_warp.scene import Growth, Initial, Patches, Record, preset

RECORD = Record(sample_dt=2e-7, patches=("velocity", "displacement"), window=(4e-7, 2e-6), decimation=2)


def _scenes():
    """Two different hf1-size pads (load, speed and initial state differ) so that per-pad indexing is exercised."""
    s = preset("hf1").replace(record=RECORD)
    return [s, s.replace(normal_force=700.0, angular_velocity=5.0 / 0.13, initial=Initial(perturbation=0.02, seed=3))]


def _both(device: str, precision: str, fibers: bool = False, **onchip_kw):
    out = {}
    for engine in ("general", "onchip"):
        model = build_model(_scenes(), device=device, precision=precision)
        state = initial_state(model)
        if engine == "general":
            res = run_hf(
                model,
                state,
                RunOptions(integrator="strang", crossing="point", duration=2e-6, dt=1e-8, engine="general"),
            )
        else:
            with cpu_fibers(fibers):
                tuning = EngineTuning(samples_per_launch=3, **onchip_kw)
                res = run_hf(
                    model,
                    state,
                    RunOptions(integrator="strang", crossing="point", duration=2e-6, dt=1e-8, engine="onchip"),
                    tuning=tuning,
                )
        assert res.complete and res.steps == 200
        out[engine] = (res.collect(), *state.numpy())
    return out["general"], out["onchip"]


@pytest.mark.parametrize("crossing", ["point", "mean"])
def test_launch_lengths_do_not_change_a_run(device, crossing):
    """A sample's solve is also the next step's friction; a launch that starts after a sample solves it again in
    the kernel's one sample block, so that launches of 1, 4 or all 10 sample intervals give the same bits, on any
    device (the globals, the per-patch histories and the final state)."""
    out = []
    for spl in (1, 4, 10):
        model = build_model(_scenes(), device=device, precision="fp32")
        state = initial_state(model)
        opts = RunOptions(integrator="strang", crossing=crossing, duration=2e-6, dt=1e-8, engine="onchip")
        res = run_hf(model, state, opts, tuning=EngineTuning(samples_per_launch=spl))
        c = res.collect()
        out.append((c.globals, c.velocity, *state.numpy()))
    for other in out[1:]:
        for a, b in zip(out[0], other, strict=True):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("precision", ["fp64", "fp32"])
def test_onchip_matches_general(device, precision):
    (cg, ug, vg), (co, uo, vo) = _both(device, precision)
    np.testing.assert_array_equal(co.time, cg.time)
    np.testing.assert_array_equal(co.patch_time, cg.patch_time)
    assert cg.velocity.shape == (5, 2 * 1758) and cg.globals.shape == (11, 2, 6)
    if device == "cpu":
        for a, b in [(co.globals, cg.globals), (co.velocity, cg.velocity), (co.displacement, cg.displacement)]:
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(uo, ug)
        np.testing.assert_array_equal(vo, vg)
    else:
        rtol = 1e-10 if precision == "fp64" else 2e-4
        np.testing.assert_allclose(co.globals[:, :, 0], cg.globals[:, :, 0], rtol=rtol, atol=0)  # mu
        np.testing.assert_allclose(uo, ug, rtol=0, atol=rtol * np.abs(ug).max())
        np.testing.assert_allclose(vo, vg, rtol=0, atol=rtol * np.abs(vg).max() * 10)


def test_onchip_csr_in_shared_memory_matches(device):
    """fp32 pads fit their neighbour lists in shared memory too; the gathers then read them from there."""
    (cg, ug, vg), (co, uo, vo) = _both(device, "fp32", csr_shared=True, block_dim=256)
    if device == "cpu":
        np.testing.assert_array_equal(co.globals, cg.globals)
        np.testing.assert_array_equal(uo, ug)
    else:
        np.testing.assert_allclose(co.globals[:, :, 0], cg.globals[:, :, 0], rtol=2e-4, atol=0)


@pytest.mark.parametrize(("precision", "block", "csr"), [("fp32", 96, True), ("fp64", 32, False)])
def test_onchip_multithread_block_cpu_fibers(precision, block, csr):
    """Blocks of 96/32 real (fiber) threads, each owning 18–19 / 54–55 patches: every barrier must be reached by
    all threads of the block (uneven patch counts per thread), else the gathers read unfinished drifts; with 96
    threads three share each bank of the on-chip CSR (a wrong slot offset overlaps their links)."""
    (cg, ug, vg), (co, uo, vo) = _both("cpu", precision, fibers=True, block_dim=block, csr_shared=csr)
    np.testing.assert_array_equal(uo, ug)
    np.testing.assert_array_equal(vo, vg)
    np.testing.assert_array_equal(co.velocity, cg.velocity)
    np.testing.assert_array_equal(co.displacement, cg.displacement)
    np.testing.assert_allclose(co.globals, cg.globals, rtol=1e-12, atol=0)  # tree sums in float64


def test_onchip_sample_sums_in_the_order_of_the_block_reduction():
    """With CPU fibers on both engines and blocks of the general engine's record kernel's size (256 threads), the
    on-chip sample sums (each warp's part, then the warps in order) are the general engine's block reduction to the
    bit: any other order of the warps' parts differs in the last bits of some fp64 sum."""
    out = {}
    for engine in ("general", "onchip"):
        model = build_model(_scenes(), device="cpu", precision="fp64")
        state = initial_state(model)
        options = RunOptions(integrator="strang", crossing="point", duration=1e-6, dt=1e-8, engine=engine)
        tuning = EngineTuning(samples_per_launch=3, block_dim=256) if engine == "onchip" else None
        with cpu_fibers(True):
            res = run_hf(model, state, options, tuning=tuning)
        out[engine] = res.collect().globals
    np.testing.assert_array_equal(out["onchip"], out["general"])


def _grown(device: str, precision: str, engine: str, fibers: bool = False, **onchip_kw):
    """Both hf1-size pads growing 1000× faster than Eq. 10 (an event every 20 steps, 10 in the run)."""
    scenes = [s.replace(growth=Growth(increment=1e-6, interval=2e-7)) for s in _scenes()]
    model = build_model(scenes, device=device, precision=precision)
    state = initial_state(model)
    area0 = model.host("area")
    with cpu_fibers(fibers):
        if engine == "general":
            res = run_hf(
                model,
                state,
                RunOptions(integrator="strang", crossing="point", duration=2e-6, dt=1e-8, engine="general"),
            )
        else:
            tuning = EngineTuning(samples_per_launch=3, **onchip_kw)
            res = run_hf(
                model,
                state,
                RunOptions(integrator="strang", crossing="point", duration=2e-6, dt=1e-8, engine="onchip"),
                tuning=tuning,
            )
    assert res.complete and res.steps == 200 and "growth" in res.stages
    keys = ("area", "sqrt_area", "inv_mass", "k_t", "k_n", "damping", "nbr_stiffness", "k_diag", "normal_force")
    keys += ("pad_matrix_force", "pad_matrix_radius", "pad_gap")
    arrays = {k: model.host(k) for k in keys}
    assert np.all(arrays["area"] > area0)
    return res.collect(), state.numpy(), arrays


@pytest.mark.parametrize("precision", ["fp64", "fp32"])
def test_onchip_growth_matches_general(device, precision):
    """Growth events in the kernel (grow, coupling stiffness, contact re-solve every 20 steps) against the general
    path's growth kernels: bit-identical on the CPU (areas, stiffnesses, normal forces, state, μ)."""
    cg, (ug, vg), ag = _grown(device, precision, "general")
    co, (uo, vo), ao = _grown(device, precision, "onchip")
    if device == "cpu":
        for k in ag:
            np.testing.assert_array_equal(ao[k], ag[k], err_msg=k)
        np.testing.assert_array_equal(uo, ug)
        np.testing.assert_array_equal(vo, vg)
        np.testing.assert_array_equal(co.globals, cg.globals)
    else:
        rtol = 1e-10 if precision == "fp64" else 2e-4
        for k in ag:
            np.testing.assert_allclose(ao[k], ag[k], rtol=rtol, atol=0, err_msg=k)
        np.testing.assert_allclose(co.globals[:, :, 0], cg.globals[:, :, 0], rtol=rtol, atol=0)


@pytest.fixture
def grown_tiles_on_one_block(monkeypatch):
    """The block's copies of a growing pad (``onchip_layout.grown_tiles``, used on clusters) on one block too, so that
    the CPU runs that code path (a CPU block cannot be part of a cluster)."""
    from aca_warp.hf import onchip, onchip_layout

    def rule(model, cluster, per_block=None):
        return "pad_growth" in model.arrays

    monkeypatch.setattr(onchip, "grown_tiles", rule)
    monkeypatch.setattr(onchip_layout, "grown_tiles", rule)


@pytest.mark.parametrize("precision", ["fp64", "fp32"])
def test_grown_tiles_match_general(grown_tiles_on_one_block, precision):
    """Growth from the block's own copies of the pad's areas, √A and k_N (the cluster layout's events): the general
    path's bits on the CPU, as the events from the model's arrays."""
    cg, (ug, vg), ag = _grown("cpu", precision, "general")
    for csr in (True, False) if precision == "fp32" else (None,):  # an fp64 pad's lists do not fit the CPU's tiles
        co, (uo, vo), ao = _grown("cpu", precision, "onchip", csr_shared=csr)
        for k in ag:
            np.testing.assert_array_equal(ao[k], ag[k], err_msg=k)
        np.testing.assert_array_equal(uo, ug)
        np.testing.assert_array_equal(vo, vg)
        np.testing.assert_array_equal(co.globals, cg.globals)


@pytest.mark.parametrize("cluster", [8, 2])
@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_grown_tiles_equal_model_arrays_on_clusters(device, monkeypatch, precision, cluster):
    """On a cluster (CUDA sm_90+) the events from the blocks' copies give the bits of the events from the model's
    arrays behind a cluster barrier (the path of a pad too large for the copies): μ, the state, the grown areas,
    normal forces and diagonals of two varying-area pads over 100 µs at 5e-8 s."""
    if wp.get_device(device).is_cpu:
        pytest.skip("no thread-block clusters on the CPU (test_grown_tiles_match_general runs the copies there)")
    from aca_warp.hf import onchip

    rule = onchip.grown_tiles
    out = []
    for copies in (True, False):
        monkeypatch.setattr(onchip, "grown_tiles", rule if copies else (lambda model, cluster, per_block=None: False))
        model = build_model([preset("varying_area")] * 2, device=device, precision=precision)
        state = initial_state(model)
        options = RunOptions(integrator="strang", crossing="point", duration=1e-4, dt=5e-8, engine="onchip")
        res = run_hf(model, state, options, tuning=EngineTuning(cluster=cluster))
        out.append(
            (res.collect().globals, *state.numpy(), *(model.host(k) for k in ("area", "normal_force", "k_diag")))
        )
    for a, b in zip(*out, strict=True):
        np.testing.assert_array_equal(a, b)


def test_grown_tiles_on_clusters_of_growing_pads_only():
    """The three copies (areas, √A, k_N) are counted in a block's shared memory where the kernel keeps them: growing
    pads on a cluster."""
    from aca_warp.hf.onchip_layout import _block_bytes, grown_tiles

    grow = build_model([preset("varying_area")], device="cpu", precision="fp32")
    still = build_model([preset("hf1")], device="cpu", precision="fp32")
    assert grown_tiles(grow, 2) and not grown_tiles(grow, 1) and not grown_tiles(still, 2)
    extra = _block_bytes(grow, 1792, 4096, True, 2) - _block_bytes(still, 1792, 4096, True, 2)
    assert extra == 3 * 1792 * 4
    assert _block_bytes(grow, 1792, 4096, True, 1) == _block_bytes(still, 1792, 4096, True, 1)


def test_grown_tiles_only_where_they_fit_beside_the_state():
    """A growing pad too large for the copies beside its state (here: a per-block limit just below what they need,
    with the largest tiles kernel_tiles may give) grows from the model's arrays, and its blocks count no copies."""
    from aca_warp.hf import onchip_layout as L

    grow = build_model([preset("varying_area")], device="cpu", precision="fp32")
    nmax = L._bucket(L._round_up(L.pad_sizes(grow)[0], 32))
    need = L._state_bytes(grow, nmax, 2) + 3 * nmax * 4 + L._SMEM_RESERVE
    assert L.grown_tiles(grow, 2, need) and not L.grown_tiles(grow, 2, need - 1)
    assert L._block_bytes(grow, nmax, 0, False, 2, need - 1) == L._state_bytes(grow, nmax, 2)


@pytest.mark.parametrize("copies", [False, True], ids=["model", "copies"])
@pytest.mark.parametrize(("precision", "block", "csr"), [("fp32", 96, True), ("fp64", 32, False)])
def test_onchip_growth_multithread_block_cpu_fibers(request, precision, block, csr, copies):
    """Growth with real (fiber) threads per block: the contact re-solve's block sums run in a tree, so against the
    general path (one-thread blocks) everything agrees to rounding; a barrier missed by part of the block (the
    grow → coupling order, the shared CSR copy) shows as an O(1) error in the stiffnesses or forces. ``copies``: the
    events from the block's copies of the pad's areas, √A and k_N (``grown_tiles_on_one_block``), grown by every
    thread and read by others in the stiffness update and the contact (the block barrier after the growth)."""
    if copies:
        request.getfixturevalue("grown_tiles_on_one_block")
    cg, (ug, vg), ag = _grown("cpu", precision, "general")
    co, (uo, vo), ao = _grown("cpu", precision, "onchip", fibers=True, block_dim=block, csr_shared=csr)
    rtol = 1e-9 if precision == "fp64" else 1e-4
    for k in ag:
        np.testing.assert_allclose(ao[k], ag[k], rtol=rtol, atol=0, err_msg=k)
    np.testing.assert_allclose(uo, ug, rtol=0, atol=rtol * np.abs(ug).max())
    np.testing.assert_allclose(co.globals[:, :, 0], cg.globals[:, :, 0], rtol=rtol, atol=0)


def test_engine_choice_and_refusals(device):
    s = preset("hf1").replace(record=Record(sample_dt=1e-7))
    model = build_model([s], device=device, precision="fp32")
    assert choose_engine(model, "auto", "strang") == "onchip"  # on the CPU too: faster, the same bits
    assert choose_engine(model, "onchip", "strang") == "onchip"
    assert choose_engine(model, "general", "strang") == "general"
    assert choose_engine(model, "auto", "implicit-friction") == "general"
    assert choose_engine(model, "auto", "adaptive") == "onchip"
    with pytest.raises(SceneError, match="strang and adaptive"):
        choose_engine(model, "onchip", "implicit-friction")
    with pytest.raises(SceneError, match="unknown engine"):
        choose_engine(model, "fast", "strang")
    grow = build_model([s.replace(growth=Growth(increment=1e-9, interval=1e-6))], device=device, precision="fp32")
    assert choose_engine(grow, "auto", "strang") == "onchip"
    assert choose_engine(grow, "onchip", "strang") == "onchip"
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(integrator="strang", crossing="point", engine="onchip", duration=2e-7, dt=1e-8),
    )
    assert "step:strang:onchip" in res.stages and res.steps == 20


def test_onchip_fault_matches_general(device):
    """Forced beyond the spring limit, both engines stop at the same sample, pad and patch, and say the same of it
    (the runaway patch's energy speed, which the first part with that patch carries on chip)."""
    s = preset("hf1").replace(record=Record(sample_dt=2e-5))
    faults = []
    for engine in ("general", "onchip"):
        model = build_model([s], device=device, precision="fp64")
        dt = 1e-5
        assert dt > 4.0 * stable_step(model).spring
        if engine == "general":
            res = run_hf(
                model,
                initial_state(model),
                RunOptions(integrator="strang", crossing="point", engine=engine, duration=4e-3, dt=dt, force=True),
            )
        else:  # on the CPU with 64 fiber threads per block: the in-block min/sums find the same first patch
            with cpu_fibers(device == "cpu"):
                res = run_hf(
                    model,
                    initial_state(model),
                    RunOptions(
                        integrator="strang", crossing="point", engine="onchip", duration=4e-3, dt=dt, force=True
                    ),
                    tuning=EngineTuning(block_dim=64),
                )
        assert not res.complete
        c = res.collect()
        assert np.all(np.isfinite(c.globals)) and np.all(c.time < res.fault.time)
        faults.append((res.fault.time, res.fault.pad, res.fault.patch, len(c.time), str(res.fault)))
    assert faults[0] == faults[1]
    assert "energy speed" in faults[0][4] and "energy speed 0 m/s" not in faults[0][4], faults[0][4]


def test_parts_buffer_caps_the_launch(monkeypatch):
    """Where a launch's samples' parts would pass their cap, the launch takes fewer samples: the same bits."""
    import aca_warp.hf.onchip as O

    model = build_model(_scenes(), device="cpu", precision="fp64")
    launches: list[int] = []
    launch = O.OnchipEngine._launch
    monkeypatch.setattr(O.OnchipEngine, "_launch", lambda self, *a: (launches.append(a[1]), launch(self, *a))[1])
    runs = []
    for cap in (None, 3 * 2 * O.PART * 8):  # room for 3 samples of 2 one-thread blocks
        if cap is not None:
            monkeypatch.setattr(O, "_PARTS_BYTES", cap)
        launches.clear()
        state = initial_state(model)
        res = run_hf(
            model, state, RunOptions(integrator="strang", crossing="point", duration=2e-6, dt=1e-8, engine="onchip")
        )
        runs.append((res.collect().globals, *state.numpy()))
        assert sum(launches) == 10 and max(launches) == (10 if cap is None else 3)
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(("precision", "fibers"), [("fp64", False), ("fp32", False), ("fp64", True)])
def test_onchip_non_finite_patch_matches_general(precision, fibers):
    """A patch whose inverse mass is NaN keeps sample 0 finite (it enters the motion, not the sums), then turns
    its velocity NaN in the first step: both engines stop at the same sample of its pad and name the patch (on
    chip: found from the warps' first non-finite patches; with fibers, 64 threads per block, among other threads')."""
    s = preset("hf1").replace(record=Record(sample_dt=1e-7))
    faults = []
    for engine in ("general", "onchip"):
        model = build_model([s, s.replace(normal_force=700.0)], device="cpu", precision=precision)
        im = model.arrays["inv_mass"].numpy()
        im[1758 + 1000] = np.nan
        model.arrays["inv_mass"].assign(im)
        options = RunOptions(integrator="strang", crossing="point", engine=engine, duration=1e-6, dt=1e-8)
        with cpu_fibers(fibers and engine == "onchip"):
            res = run_hf(model, initial_state(model), options, tuning=EngineTuning(block_dim=64) if fibers else None)
        assert not res.complete and res.fault is not None
        faults.append((res.fault.time, res.fault.pad, res.fault.patch, res.fault.cause))
    assert faults[0] == faults[1]
    assert faults[0][1] == 1 and faults[0][0] == pytest.approx(1e-7)


def test_cli_engine_option(tmp_path):
    """``aca-warp hf --engine onchip`` runs the on-chip engine (on the CPU too; strang and adaptive, nothing else)
    and records it in the stages."""
    import h5py

    from aca_warp.cli import main

    out = tmp_path / "run.h5"
    args = ["hf", "hf1", "-o", str(out), "--no-progress", "--duration", "4e-7", "--sample-dt", "2e-7"]
    assert main([*args, "--engine", "onchip"]) == 0
    with h5py.File(out, "r") as f:
        assert "step:strang:onchip" in str(f.attrs["stages"]) and f["global/mu"].shape[0] == 3
    assert main([*args, "--engine", "onchip", "--integrator", "implicit-friction", "--overwrite"]) == 2
    assert main([*args, "--engine", "onchip", "--integrator", "adaptive", "--overwrite"]) == 0
    with h5py.File(out, "r") as f:
        assert "step:adaptive:onchip" in str(f.attrs["stages"]) and f["global/mu"].shape[0] == 3


def test_ablations_for_profiling(device):
    """``ablate`` (scripts/profile_onchip.py) leaves out parts of the step: the runs differ; unknown names fail."""
    s = preset("hf1").replace(record=Record(sample_dt=1e-7))
    mus = {}
    for abl in ((), ("gather",), ("friction",), ("gather_half",)):
        model = build_model([s], device=device, precision="fp32")
        res = run_hf(
            model,
            initial_state(model),
            RunOptions(integrator="strang", crossing="point", engine="onchip", duration=2e-7, dt=1e-8),
            tuning=EngineTuning(ablate=frozenset(abl)),
        )
        mus[abl] = res.collect().globals[-1, 0, 0]
    assert len(set(mus.values())) == len(mus), mus
    # gather_half (the first half of every row's links) reads the same links from the on-chip CSR as from global
    half = {}
    for csr in (True, False):
        model = build_model([s], device=device, precision="fp32")
        res = run_hf(
            model,
            initial_state(model),
            RunOptions(integrator="strang", crossing="point", engine="onchip", duration=2e-7, dt=1e-8),
            tuning=EngineTuning(ablate=frozenset({"gather_half"}), csr_shared=csr),
        )
        half[csr] = res.collect().globals[-1, 0]
    if wp.get_device(device).is_cpu:
        np.testing.assert_array_equal(half[True], half[False])
    else:  # the two gathers compile to different code: last bits apart on a GPU (1.6e-10 relative on an H200)
        np.testing.assert_allclose(half[True], half[False], rtol=1e-8)
    with pytest.raises(ValueError, match="unknown ablations"):
        run_hf(
            model,
            initial_state(model),
            RunOptions(integrator="strang", crossing="point", engine="onchip", duration=2e-7, dt=1e-8),
            tuning=EngineTuning(ablate=frozenset({"springs"})),
        )


def test_sample_ablation_leaves_the_motion_and_drops_the_outputs(device):
    """``sample`` (scripts/profile_onchip.py: the cost of a sample's per-patch work) leaves the
    motion as it is, bit for bit, and records zero velocity sums and no patch velocities after sample 0 (which the
    general kernels record)."""
    s = preset("hf1").replace(record=Record(sample_dt=1e-7, patches=("velocity",)))
    got = {}
    for abl in ((), ("sample",)):
        model = build_model([s], device=device, precision="fp32")
        st = initial_state(model)
        res = run_hf(
            model, st, RunOptions(integrator="strang", crossing="point", engine="onchip", duration=5e-7, dt=1e-8),
            tuning=EngineTuning(ablate=frozenset(abl)),
        )  # fmt: skip
        got[abl] = (st.u.numpy().copy(), st.v.numpy().copy(), res.collect())
    full, cut = got[()], got[("sample",)]
    np.testing.assert_array_equal(full[0], cut[0])
    np.testing.assert_array_equal(full[1], cut[1])
    k = GLOBAL_NAMES.index("sum_abs_velocity")
    assert np.all(full[2].globals[1:, 0, k] > 0) and np.all(cut[2].globals[1:, 0, k] == 0)
    assert np.all(np.abs(full[2].velocity[1:]).sum(axis=1) > 0) and np.all(cut[2].velocity[1:] == 0)


def test_a_profile_from_the_state_a_run_reached(tmp_path, monkeypatch):
    """``scripts/profile_onchip.py --saturate S``: every case starts from the state the batch reached after S
    seconds with the treatment asked for, not from the preset's start, and the file says so."""
    prof = load_script("profile_onchip")
    args = prof._parse(["--device", "cpu", "--dt", "2.5e-7", "--sample-dt", "1e-6", "--saturate", "2e-6",
                        "--crossing", "mean", "--window", "1e-6"])  # fmt: skip
    model = build_model([preset("hf1")], device="cpu", precision="fp32")
    start = initial_state(model)
    saved = prof._saturated(args, model)
    assert not np.array_equal(saved["u"], start.u.numpy())
    started = prof._start(model, saved)
    np.testing.assert_array_equal(started.u.numpy(), saved["u"])
    np.testing.assert_array_equal(started.v.numpy(), saved["v"])
    out = tmp_path / "p.json"
    argv = ["--device", "cpu", "--dt", "2.5e-7", "--sample-dt", "1e-6", "--saturate", "2e-6", "--crossing", "mean"]
    assert prof.main([*argv, "--window", "1e-6", "--only", "full [fp32]", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["machine"]["saturate_s"] == 2e-6 and doc["machine"]["crossing"] == "mean"
    assert [r["case"] for r in doc["rows"]] == ["full"] and doc["rows"][0]["steps"] == 4


def test_growth_ablations_for_profiling(device):
    """The growth ablations of ``scripts/profile_onchip.py --growth``: ``coupling`` leaves the link stiffnesses as
    they were, ``contact`` the normal forces; the areas grow either way."""
    s = preset("hf1").replace(record=Record(sample_dt=1e-7), growth=Growth(increment=1e-6, interval=2e-7))
    for abl, frozen, moved in (
        (("coupling",), "nbr_stiffness", "normal_force"),
        (("contact",), "normal_force", "nbr_stiffness"),
    ):
        model = build_model([s], device=device, precision="fp32")
        before = {k: model.host(k) for k in ("area", frozen, moved)}
        run_hf(
            model,
            initial_state(model),
            RunOptions(integrator="strang", crossing="point", engine="onchip", duration=4e-7, dt=1e-8),
            tuning=EngineTuning(ablate=frozenset(abl)),
        )
        assert np.all(model.host("area") > before["area"])
        np.testing.assert_array_equal(model.host(frozen), before[frozen])
        assert not np.array_equal(model.host(moved), before[moved])


@settings(derandomize=True, deadline=None, database=None, max_examples=12)
@given(
    n=st.integers(1, 24),
    seed=st.integers(0, 2**16),
    load=st.sampled_from([0.0, 0.5, 5.0, 50.0]),
    increment=st.floats(1e-8, 1e-5),
    M=st.sampled_from([0.0, 0.8, 2.0]),
    speed=st.sampled_from([0.0, 1e-4, 10.0]),
    precision=st.sampled_from(["fp32", "fp64"]),
)
def test_onchip_growth_fuzzed_small_pads(n, seed, load, increment, M, speed, precision):
    """Random small growing pads (1–24 patches on a 1 mm grid, so 0 to many links; zero load; standstill): the
    on-chip growth gives the general engine's bits on the CPU, including the edge cases of the contact re-solve
    (no load, all patches or none in contact) and pads smaller than a warp."""
    rng = np.random.default_rng(seed)
    cells = rng.choice(36, size=n, replace=False)
    x, y = (cells % 6) * 1e-3 - 2.5e-3, 0.13 + (cells // 6) * 1e-3
    patches = Patches(x, y, rng.uniform(2e-8, 8e-8, n), rng.uniform(1e-6, 4e-6, n))
    base = preset("hf1")
    scene = base.replace(
        patches=patches,
        normal_force=load,
        angular_velocity=speed / 0.13,
        friction=dataclasses.replace(base.friction, M=M),
        initial=Initial(perturbation=1e-3, seed=seed),
        record=Record(sample_dt=2e-7),
        growth=Growth(increment=increment, interval=1e-7),
    )
    out = []
    for engine in ("general", "onchip"):
        model = build_model([scene], device="cpu", precision=precision)
        state = initial_state(model)
        res = run_hf(
            model, state, RunOptions(integrator="strang", crossing="point", duration=4e-7, dt=1e-8, engine=engine)
        )
        assert res.complete and res.steps == 40
        keys = ("area", "nbr_stiffness", "normal_force", "pad_matrix_force", "pad_gap")
        out.append((res.collect().globals, *state.numpy(), *(model.host(k) for k in keys)))
    for a, b in zip(*out, strict=True):
        np.testing.assert_array_equal(a, b)


def test_cluster_split_sizes():
    """pad_sizes(model, K) gives the largest part of a pad's links as the kernel splits it (n·r // K …)."""
    model = build_model(_scenes(), device="cpu", precision="fp32")
    start, nbr = model.pad_patch_start_host, model.host("nbr_start")
    for k in (1, 3, 8):
        parts = []
        for p in range(model.pad_count):
            a, n = start[p], start[p + 1] - start[p]
            cuts = [a + n * r // k for r in range(k + 1)]
            parts += [nbr[cuts[r + 1]] - nbr[cuts[r]] for r in range(k)]
            assert sum(parts[-k:]) == nbr[a + n] - nbr[a]
        assert pad_sizes(model, k) == (int(np.diff(start).max()), max(parts))
    assert pad_sizes(model, 8)[1] < pad_sizes(model, 1)[1] / 4


def test_onchip_kernel_refuses_pads_beyond_int16_indices():
    """The on-chip CSR holds int16 local indices: a kernel for pads of 2**15 patches or more is refused."""
    from aca_warp.kernels.hf_onchip import onchip_kernel

    with pytest.raises(ValueError, match="32768"):
        onchip_kernel(wp.float32, 2**15, 32, True, 32)
    assert onchip_kernel(wp.float32, 2**15 - 1, 32, True, 32) is not None  # built lazily: no compile here


def test_kernel_tiles_are_shared_by_pads_of_about_the_same_size():
    """The kernel's tiles are bucketed (at most 1/16 above the warp-rounded sizes): hf1 pads of eight patch seeds,
    whose neighbour lists differ by a few percent, get one or two kernels instead of six; a bucket that would not
    fit the shared memory the exact tiles fit, or fewer times, falls back to them."""
    from aca_warp.hf import onchip_layout as L

    assert [L._bucket(x) for x in (1, 32, 33, 1758, 23584, 24320)] == [32, 32, 64, 1792, 24576, 24576]
    for x in range(1, 70000, 97):
        assert x <= L._bucket(x) <= max(-(-x // 32) * 32, x + x / 16)
    from aca_warp.sweep.spec import load_spec

    spec = load_spec({"sweep": {"base": "hf1"}, "parameters": {"patches.seed": list(range(1, 9))}})
    models = [build_model([scene], device="cpu", precision="fp32") for scene in spec.scenes(range(8))]
    exact = {L.tile_sizes(m, 1, 640) for m in models}
    assert len(exact) == 6 and len({L.kernel_tiles(m, 1, 640) for m in models}) <= 2  # a bucket edge may fall between
    tight = models[0]
    limit = L._block_bytes(tight, *L.tile_sizes(tight, 1, 640), True, 1)  # the exact tiles just fit
    with _smem_limit(limit):
        assert L.kernel_tiles(tight, 1, 640) == L.tile_sizes(tight, 1, 640)
        assert L.block_config(tight, 1, 640)[2]  # the neighbour lists stay on chip
    with _smem_limit(2 * limit), _as_on_cuda():  # two blocks of the exact tiles share an SM, two of the buckets not
        assert L.kernel_tiles(tight, 1, 640) == L.tile_sizes(tight, 1, 640)
    with _smem_limit(4 * limit), _as_on_cuda():  # 640 threads: three blocks per SM either way (2048 threads)
        assert L.kernel_tiles(tight, 1, 640) != L.tile_sizes(tight, 1, 640)
    with _smem_limit(2 * limit):  # on the CPU no SM is shared: the buckets
        assert L.kernel_tiles(tight, 1, 640) != L.tile_sizes(tight, 1, 640)


@contextmanager
def _as_on_cuda():
    """The layout's estimate of resident blocks per SM as on a CUDA device, for a model on the CPU."""
    from types import SimpleNamespace

    from aca_warp.hf import onchip_layout as L

    saved = L._resident
    gpu = SimpleNamespace(device=SimpleNamespace(is_cpu=False))
    L._resident = lambda model, *args: saved(gpu, *args)
    try:
        yield
    finally:
        L._resident = saved


def test_results_do_not_depend_on_the_tiles(monkeypatch):
    """The tiles are storage: the on-chip kernel with the warp-rounded tiles and with the bucketed ones gives the
    same samples and final state bit for bit (two pads on the CPU)."""
    from aca_warp.hf import onchip as O
    from aca_warp.hf import onchip_layout as L

    def run():
        model = build_model(_scenes(), device="cpu", precision="fp32")
        state = initial_state(model)
        res = run_hf(model, state, RunOptions(engine="onchip", crossing="point", duration=4e-7, dt=1e-8))
        return res.collect().globals, state.u.numpy(), state.v.numpy(), L.kernel_tiles(model, 1, 1)

    g1, u1, v1, tiles = run()
    monkeypatch.setattr(O, "kernel_tiles", L.tile_sizes)  # the exact tiles, as before the buckets
    model = build_model(_scenes(), device="cpu", precision="fp32")
    assert L.tile_sizes(model, 1, 1) != tiles  # another kernel
    g0, u0, v0, _ = run()
    for a, b in ((g1, g0), (u1, u0), (v1, v0)):
        assert a.tobytes() == b.tobytes()


@contextmanager
def _smem_limit(limit: int):
    """The on-chip layout's shared-memory limit set to ``limit`` bytes for every model."""
    from aca_warp.hf import onchip_layout as L

    saved = L.smem_limit
    L.smem_limit = lambda model, per_block=None: limit
    try:
        yield
    finally:
        L.smem_limit = saved


@pytest.mark.parametrize(("cluster", "threads"), [(1, 1), (1, 96), (1, 100), (3, 512), (8, 224)])
def test_csr_slots_bank_interleaved(cluster, threads):
    """The kernel's on-chip CSR layout (link m of a thread at slot W·(s + m) + lane mod W, s the links of the earlier
    threads of its bank): every link of a block gets its own slot, a warp's lanes sit in different banks, and
    csr_slots is the smallest tile that holds the busiest bank."""
    model = build_model(_scenes(), device="cpu", precision="fp32")
    start, nbr = model.pad_patch_start_host, model.host("nbr_start")
    slots = csr_slots(model, cluster, threads)
    w = min(threads, 32)
    top = 0
    for p in range(model.pad_count):
        n = start[p + 1] - start[p]
        for r in range(cluster):
            lo, hi = n * r // cluster, n * (r + 1) // cluster
            links = [nbr[start[p] + i + 1] - nbr[start[p] + i] for i in range(lo, hi)]
            own = [sum(links[i - lo] for i in range(lo + lane, hi, threads)) for lane in range(threads)]
            used = []
            for lane in range(threads):
                s0 = sum(own[q] for q in range(lane % w, lane, w))
                used += [(w * (s0 + m) + lane % w, lane) for m in range(own[lane])]
            pos = [u for u, _ in used]
            assert len(set(pos)) == len(pos) == nbr[start[p] + hi] - nbr[start[p] + lo]
            assert all(u % w == lane % w for u, lane in used)
            top = max(top, max(pos) + 1)
    assert slots - w < top <= slots


@pytest.mark.parametrize(
    ("nmax", "cluster", "growth", "fp64", "expected"),
    [(1758, 1, False, False, 640), (1758, 1, False, True, 512), (1758, 1, True, False, 384),
     (1758, 1, True, True, 384), (1758, 2, False, False, 896), (1758, 2, False, True, 512),
     (1758, 2, True, False, 896), (1758, 2, True, True, 512), (1758, 4, True, False, 448), (1758, 8, False, True, 224),
     (2048, 2, False, False, 1024), (2050, 2, False, False, 512), (4000, 4, False, False, 1024),
     (100, 1, False, False, 128)],
)  # fmt: skip
def test_default_block(nmax, cluster, growth, fp64, expected):
    """Threads per block: the block's part rounded up to 32, capped at 640 (fp32) / 512 (fp64) on one block, 384 for a
    growing pad on one block; on a cluster one thread per patch up to 1024 for an fp32 pad, else 512 (the sizes
    measured fastest on the H100 and H200, docs/onchip.md)."""
    assert default_block(nmax, cluster, growth, fp64) == expected


@pytest.mark.parametrize(
    ("pads", "split", "expected"),
    [(1, False, 8), (14, False, 8), (15, False, 5), (21, False, 5), (22, False, 4), (28, False, 4), (29, False, 2),
     (64, False, 2), (66, False, 2), (67, False, 1), (67, True, 2), (1024, False, 1), (1024, True, 2)],
)  # fmt: skip
def test_default_cluster(pads, split, expected):
    """Blocks per pad on an H100 or H200 (132 SMs): the clusters of 8, 5, 4 and 2 that run in one wave there (14, 21,
    28, 66, measured), else 1, or 2 where only a split pad's CSR fits on chip; a sweep's default 64-pad shard gets
    K = 2."""
    assert default_cluster(pads, 132, split) == expected


def test_a_batch_of_few_pads_widens_its_cluster_until_its_lists_fit():
    """``widen_for_csr``: clusters of 4 or more whose neighbour lists do not fit shared memory take the smallest of 8
    and 16 where they do (the validation's 16 dense LF-state pads: off chip on 5 blocks, on chip on 16), else stay;
    many pads (clusters of 1 or 2) never widen, and a batch whose lists fit keeps its cluster."""
    from aca_warp.hf.onchip_layout import widen_for_csr

    def widen(clusters: tuple[int, ...], fits_from: int) -> list[int]:
        return [widen_for_csr(k, lambda w: w >= fits_from) for k in clusters]

    assert widen((1, 2, 4, 5, 8, 16), 16) == [1, 2, 16, 16, 16, 16]
    assert widen((2, 4, 5, 8), 8) == [2, 8, 8, 8]
    assert widen((4, 5), 5) == [8, 5]
    assert widen((2, 4, 5, 8), 99) == [2, 4, 5, 8]  # fit nowhere: off chip on the cluster the rule gave


def test_cluster_refused_where_it_cannot_run():
    """Clusters need CUDA sm_90+; the size is 1…16 (above 8 only where the device launches it: checked there)."""
    model = build_model([preset("hf1").replace(record=Record(sample_dt=1e-7))], device="cpu", precision="fp32")
    for k, why in (
        (2, "compute capability 9.0"),
        (16, "compute capability 9.0"),
        (0, r"\[1, 16\]"),
        (17, r"\[1, 16\]"),
    ):
        with pytest.raises(SceneError, match=why):
            run_hf(
                model,
                initial_state(model),
                RunOptions(integrator="strang", crossing="point", engine="onchip", duration=1e-7, dt=1e-8),
                tuning=EngineTuning(cluster=k),
            )
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(integrator="strang", crossing="point", engine="onchip", duration=1e-7, dt=1e-8),
    )  # cluster=None: 1 on the CPU
    assert res.complete and res.steps == 10


def test_register_report_respects_launch_bounds(tmp_path):
    """scripts/onchip_registers.py compiles the on-chip kernel to an sm_90 cubin with NVRTC (no GPU) and reads its
    registers and stack frame: the block size's register cap holds (65 536 registers per SM over four schedulers:
    ≤ 128 per thread at 512 threads, ≤ 168 at 384), the kernel without growth does not spill at 512, and the growing
    kernel spills no more at 384 threads (more registers) than at 512."""
    import json

    from tests.scriptload import load_script

    script = load_script("onchip_registers")
    out = tmp_path / "regs.json"
    try:
        script.main(["--clusters", "1", "--precisions", "fp32", "--blocks", "384", "512", "--json", str(out)])
    except RuntimeError as exc:  # a Warp build without NVRTC
        pytest.skip(f"no NVRTC: {exc}")
    rows = {(r["growth"], r["block_dim"]): r for r in json.loads(out.read_text())["rows"]}
    assert set(rows) == {(False, 384), (False, 512), (True, 384), (True, 512)}
    for (_growth, block), r in rows.items():
        assert 0 < r["registers"] <= {384: 168, 512: 128}[block]
    assert rows[(False, 512)]["frame_bytes"] == 0
    assert rows[(True, 384)]["frame_bytes"] <= rows[(True, 512)]["frame_bytes"]


@wp.kernel(enable_backward=False, module="unique")
def _readers_of(
    pad_patch_start: wp.array[wp.int32],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    k: int,
    out: wp.array[wp.int32],
):
    pad, i = wp.tid()
    a = pad_patch_start[pad]
    n = pad_patch_start[pad + 1] - a
    if i < n:
        out[a + i] = readers(a + i, a, n, k, nbr_start, nbr_index)


@pytest.mark.parametrize("k", [2, 3, 8, 16])
def test_halo_readers_cover_every_gather(k):
    """The halo exchange of a k-block cluster sends u_j to the blocks whose bits ``readers`` sets: exactly the
    blocks owning a neighbour of j, so every block receives every u_j its own patches' rows read (lists are
    symmetric), for both pads of a batch (pad start ≠ 0)."""
    model = build_model(_scenes(), device="cpu", precision="fp32")
    start, nbr, idx = model.pad_patch_start_host, model.host("nbr_start"), model.host("nbr_index")
    out = wp.zeros(model.patch_count, dtype=wp.int32, device="cpu")
    most = int(np.diff(start).max())
    arrays = [model.arrays[key] for key in ("pad_patch_start", "nbr_start", "nbr_index")]
    wp.launch(_readers_of, dim=(model.pad_count, most), inputs=[*arrays, k, out], device="cpu")
    mask = out.numpy()
    for p in range(model.pad_count):
        a, n = int(start[p]), int(start[p + 1] - start[p])
        owner = np.searchsorted([n * r // k for r in range(1, k)], np.arange(n), side="right")
        for i in range(n):
            links = idx[nbr[a + i] : nbr[a + i + 1]] - a
            assert mask[a + i] == np.bitwise_or.reduce(1 << owner[links], initial=0)
            for j in links[owner[links] != owner[i]]:  # block owner[i] gathers u_j from another block
                assert mask[a + j] >> owner[i] & 1


def _small_pad(growth: bool):
    """The validation's hf1 pad of seed 1 cut to 60 patches (samples every 1 µs), growing or not."""
    from aca_warp.studies.friction_stats import sector_scenes

    s = sector_scenes(1, 60)[0].replace(record=Record(sample_dt=1e-6))
    return s.replace(growth=Growth(increment=1e-9, interval=1e-6)) if growth else s


@pytest.mark.parametrize("growth", [False, True])
def test_a_checkpoint_continues_on_the_engine_that_wrote_it(growth):
    """A checkpoint names its engine; a run left to ``auto`` continues on it (the general engine's checkpoint of a
    growing pad holds its growth counter, which the on-chip engine does not take), and the resumed samples are the
    uninterrupted run's bit for bit. A checkpoint without the name (written before it was stored) takes ``auto``'s
    choice: on the CPU the on-chip engine, which continues a non-growing general run bit for bit."""
    s = _small_pad(growth)
    opts = RunOptions(integrator="strang", crossing="point", duration=1e-5, checkpoint_interval=3e-6)

    def resumed(engine: str, forget: bool = False):
        """The checkpoints of a run on ``engine``, and the run resumed from the second (its engine name dropped
        when ``forget``) under ``auto``, checked against the uninterrupted samples."""
        model = build_model([s], device="cpu", precision="fp64")
        ckpts = []
        full = run_hf(model, initial_state(model), dataclasses.replace(opts, engine=engine), on_checkpoint=ckpts.append)
        ck = ckpts[1]
        if forget:
            ck = dataclasses.replace(ck, counters={k: v for k, v in ck.counters.items() if k != "onchip"})
        again = build_model([s], device="cpu", precision="fp64")
        rest = run_hf(again, initial_state(again), opts, resume=ck)  # engine "auto"
        a, b = full.collect(), rest.collect()
        np.testing.assert_array_equal(a.globals[len(a.time) - len(b.time) :], b.globals)
        assert full.complete
        return ckpts, rest

    for engine, onchip in (("general", 0), ("auto", 1)):
        ckpts, _ = resumed(engine)
        assert [c.counters["onchip"] for c in ckpts] == [onchip] * len(ckpts) and len(ckpts) >= 2
    if not growth:
        _, rest = resumed("general", forget=True)
        assert "step:strang:onchip" in rest.stages


@pytest.mark.parametrize(("cap", "launches"), [(None, 1), (60 * 300, 4), (10, 10)])
def test_a_cpu_launch_covers_at_most_the_patch_step_cap(cap, launches, monkeypatch):
    """On the CPU a launch covers at most ``_CPU_PATCH_STEPS_PER_LAUNCH`` patch-steps in whole sample intervals and at
    least one interval (a pad larger than the cap: one per launch): 60 patches, 100 steps per sample, 10 samples in 1,
    ceil(10 / 3) or 10 launches; the samples are the same bits in every case."""
    from aca_warp.hf import onchip

    if cap is not None:
        monkeypatch.setattr(onchip, "_CPU_PATCH_STEPS_PER_LAUNCH", cap)
    calls = []
    real = onchip.OnchipEngine._launch

    def counted(self, *a):
        calls.append(a[1])  # sample intervals of the launch
        return real(self, *a)

    monkeypatch.setattr(onchip.OnchipEngine, "_launch", counted)
    s = _small_pad(False)
    model = build_model([s], device="cpu", precision="fp64")
    res = run_hf(
        model,
        initial_state(model),
        RunOptions(integrator="strang", crossing="point", dt=1e-8, duration=1e-5, engine="onchip"),
    )
    assert res.complete and len(calls) == launches and sum(calls) == 10
    ref = _small_pad_reference()
    np.testing.assert_array_equal(res.collect().globals, ref)


def _small_pad_reference() -> np.ndarray:
    """The global outputs of the 60-patch pad over 10 µs at 1e-8 s on the general engine."""
    s = _small_pad(False)
    model = build_model([s], device="cpu", precision="fp64")
    opts = RunOptions(integrator="strang", crossing="point", dt=1e-8, duration=1e-5, engine="general")
    return run_hf(model, initial_state(model), opts).collect().globals


def test_thread_links_per_block_and_thread_as_a_loop_counts_them():
    """The links each thread of each block gathers (:func:`thread_links`) equal every ``threads``-th patch's links of
    the block summed by slicing, for pads of unequal size split over clusters larger than some pads (empty blocks);
    the model keeps one read-only host copy of its neighbour lists, made once, and the tile sizes worked out from
    them."""
    from aca_warp.hf.onchip_layout import thread_links, tile_sizes
    from aca_warp.sweep import load_spec

    def loop(model: object, cluster: int, threads: int) -> np.ndarray:
        start, deg = model.pad_patch_start_host, np.diff(model.host("nbr_start"))
        rows = []
        for p in range(model.pad_count):
            n = start[p + 1] - start[p]
            for r in range(cluster):
                part = deg[start[p] + n * r // cluster : start[p] + n * (r + 1) // cluster]
                rows.append([int(part[t::threads].sum()) for t in range(threads)])
        return np.array(rows, dtype=np.int64)

    spec = load_spec({"sweep": {"name": "sizes", "base": "hf1"}, "parameters": {"patches.count": [3, 50, 7, 200]}})
    model = build_model(spec.scenes(spec.shard_pads(0)))
    for cluster in (1, 2, 8, 16):
        for threads in (1, 5, 32, 96):
            got = thread_links(model, cluster, threads)
            assert got.dtype == np.int64 and np.array_equal(got, loop(model, cluster, threads)), (cluster, threads)
    start = model.host("nbr_start")
    assert start is model.host("nbr_start") and not start.flags.writeable
    assert model.host("area") is not model.host("area")  # arrays a run changes: a fresh copy each time
    assert tile_sizes(model, 2, 32) is tile_sizes(model, 2, 32) and ("tile_sizes", 2, 32) in model.memo


@pytest.mark.parametrize("cluster", [1, 2])
def test_sample_rows_combine_parts_in_order(cluster):
    """The rows and verdicts of a launch from hand-made parts (the cluster path runs on the CPU here, where no kernel
    makes parts for clusters): a block's warps added in order (1, 2⁵³, −2⁵³ gives 0; any other order 1), a cluster's
    blocks added to zero in rank order (two blocks of −0.0 give +0.0, one block keeps its −0.0), the pad's first
    non-finite patch, and the pad's first runaway patch with the energy speed its part carries. A pad is broken where
    a patch is not finite, whether or not its sums are (the general engine's rule): sample 2 has a non-finite patch
    under finite sums in pad 1 (broken) and sums that overflowed with every patch finite in pad 0 (not broken)."""
    from aca_warp.kernels.hf_onchip import PART, Verdict, pad_samples_kernel

    from aca_warp.hf.recorder import Recorder

    scene = preset("hf1").replace(record=Record(sample_dt=1e-7))
    model = build_model([scene, scene], device="cpu", precision="fp64")
    n = int(np.diff(model.pad_patch_start_host)[0])
    rec = Recorder(model, scene.record, 4, 4)
    samples, warps = 3, 3
    p = np.zeros((samples, 2 * cluster, warps, PART))
    p[..., 7] = n  # no non-finite patch
    p[..., 8] = n  # no runaway patch
    first = 0  # pad 0's first block
    p[0, first, :, 2] = [1.0, 2.0**53, -(2.0**53)]  # Σu̇ of pad 0, sample 0: 0 in warp order
    p[0, :, :, 3] = -0.0  # Σ|u̇| of every part of sample 0: −0.0
    p[0, first, 0, 10:12] = [3.0, 0.1]  # the pad's matrix force [N] and radius [m] at the sample
    p[1, first, 1, 8:10] = [12, 5.0]  # sample 1: runaway patch 12 (energy speed 5 m/s) in pad 0's first block
    last = cluster - 1  # pad 0's last block: the first runaway patch (9) lies there when cluster = 2
    p[1, last, 2, 8:10] = [9, 7.0] if cluster == 2 else [12, 5.0]
    p[1, last, 2, 7] = 30  # its first non-finite patch (its sums not finite too)
    p[1, last, 2, 6] = np.nan
    p[2, 2 * cluster - 1, 1, 7] = 44  # pad 1's last block: a non-finite patch, its sums finite
    p[2, first, 0, 6] = np.inf  # pad 0: an overflowed sum, every patch finite
    parts = wp.array(p, dtype=wp.float64, device="cpu")
    verdicts = wp.zeros((samples, 2), dtype=Verdict, device="cpu")
    sample_rows, _ = pad_samples_kernel(wp.float64)
    wp.launch(
        sample_rows, dim=(samples, 2), inputs=[model.struct(), rec.struct, parts, cluster, warps, 1, verdicts],
        device="cpu",
    )  # fmt: skip
    g, v = rec.globals.numpy(), verdicts.numpy()
    assert g[1, 0, 3] == 0.0  # Σu̇, row0 = 1
    assert g[1, 0, 2] == pytest.approx(0.1) and g[1, 1, 2] == 0.0  # friction radius: the matrix's, from pad 0's part
    assert np.signbit(g[1, 0, 4]) == (cluster == 1)  # Σ|u̇|: −0.0 kept by one block, +0.0 from a cluster's sum
    assert np.signbit(g[1, 1, 4]) == (cluster == 1)
    np.testing.assert_array_equal(v[0, 0], [0.0, -1.0, n, 0.0])
    np.testing.assert_array_equal(v[1, 0], [1.0, 30.0, 9.0, 7.0] if cluster == 2 else [1.0, 30.0, 12.0, 5.0])
    np.testing.assert_array_equal(v[1, 1], [0.0, -1.0, n, 0.0])
    np.testing.assert_array_equal(v[2, 0], [0.0, -1.0, n, 0.0])
    np.testing.assert_array_equal(v[2, 1], [1.0, 44.0, n, 0.0])


@pytest.mark.parametrize(("arch", "cluster"), [(75, 1), (90, 2)])
def test_onchip_kernels_build_for_cuda_architectures(arch, cluster):
    """The on-chip kernels and the samples' kernels compile for CUDA from sm_75 (Warp's NVRTC, no GPU needed): what
    a newer architecture adds (the warp's own min from sm_80, clusters from sm_90) is compiled only there."""
    from aca_warp.kernels.hf_onchip import onchip_kernel, pad_samples_kernel
    from aca_warp.kernels.hf_onchip_adaptive import onchip_dp5_kernel

    if arch not in wp.get_cuda_supported_archs():
        pytest.skip(f"this Warp build compiles no CUDA code for sm_{arch}")
    strang = onchip_kernel(wp.float32, 64, 512, True, 64, cluster=cluster)
    dp5 = onchip_dp5_kernel(wp.float64, cluster, 64, 1, 64, 0, frozenset(), False)
    kernels = (strang, dp5, *pad_samples_kernel(wp.float32))  # cached: other tests launch them as they were
    options = [dict(k.module.options) for k in kernels]
    try:
        for kernel in (strang, dp5):  # launched with blocks of 64 threads
            kernel.module.options["block_dim"] = 64
        for kernel in kernels:
            assert wp.compile_aot_module(kernel.module, arch=arch, use_ptx=False), kernel.key
    finally:
        for kernel, before in zip(kernels, options, strict=True):
            kernel.module.options.clear()
            kernel.module.options.update(before)
