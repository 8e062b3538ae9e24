"""Determinism of the HF engine on the CPU: repeated runs, graph replay against eager launches, and batching.

Same scene and seed must give bit-identical recorded outputs; a pad must not feel the other pads of its
batch (fixed-step schemes, where all pads take the same steps anyway).
"""

from __future__ import annotations

import numpy as np
import pytest

from aca_warp.hf.loop import EngineTuning, run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import INTEGRATORS, RunOptions
from aca_warp.hf.state import initial_state
from aca_warp.scene import Friction, Initial, Material, Pad, Patches, Record, Scene

FIXED_STEP = [i for i in INTEGRATORS if i != "adaptive"]
# the fixed step, or the tolerances of the step-controlled integrators
SETTINGS = {
    "symplectic-euler": {"dt": 5e-9},
    "implicit-friction": {"dt": 1e-8},
    "strang": {"dt": 1e-8},
    "adaptive": {"tolerance": 1e-6},
    "controlled": {"split_tolerance": 1e-3},
    "auto": {"tolerance": 1e-6, "split_tolerance": 1e-3},
}
GRAPH_STEPS = 32  # short graphs: a CPU capture costs more per step the longer the graph (5000 steps of 30 patches
# sampled every 10 steps: 0.08 s of CPU in graphs of 32 steps, 0.38 s in graphs of 256)


def cluster(seed: int, n: int, centre: tuple[float, float], spacing: float = 1.0e-3) -> Patches:
    """``n`` HF1-size patches jittered on a square grid around ``centre`` (all within coupling range)."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    ij = np.array([(i, j) for i in range(side) for j in range(side)][:n], dtype=float)
    xy = (ij - (side - 1) / 2) * spacing + rng.uniform(-0.15, 0.15, (n, 2)) * spacing
    return Patches(
        x=centre[0] + xy[:, 0],
        y=centre[1] + xy[:, 1],
        area=rng.uniform(2e-8, 8e-8, n),
        height=rng.uniform(2.8e-6, 3.2e-6, n),
    )


RECORD = Record(sample_dt=1e-7, patches=("velocity", "displacement"))


def scene_a() -> Scene:
    """Twelve patches near r = 0.13 m, M = 0.8, part of the load on the matrix, perturbed velocities."""
    return Scene(
        name="a",
        pad=Pad(),
        patches=cluster(1, 12, (0.0, 0.13)),
        friction=Friction(M=0.8),
        normal_force=15.0,
        initial=Initial(perturbation=0.05, seed=3),
        record=RECORD,
        duration=5e-6,
    )


def scene_b() -> Scene:
    """Seven patches on the same pad region (overlapping coordinates with scene a), other load, M, material."""
    return Scene(
        name="b",
        pad=Pad(),
        patches=cluster(2, 7, (0.0005, 0.1305), spacing=1.3e-3),
        material=Material(damping_ratio=1e-4),
        friction=Friction(M=0.4),
        normal_force=3.0,
        initial=Initial(state="equilibrium", perturbation=0.02, seed=9),
        record=RECORD,
        duration=5e-6,
    )


def run(scenes, integrator, *, use_graph=True, device="cpu", engine="auto"):
    """Run a batch from its initial state for 5 µs on ``engine``; returns the collected chunk and the final (u, v)."""
    model = build_model(scenes, device=device, precision="fp64")
    state = initial_state(model)
    kw = SETTINGS[integrator]
    tuning = EngineTuning(use_graph=use_graph, max_graph_steps=GRAPH_STEPS)
    res = run_hf(model, state, RunOptions(duration=5e-6, integrator=integrator, engine=engine, **kw), tuning=tuning)
    assert res.complete
    return res.collect(), state.numpy(), res


def assert_identical(c1, c2):
    """Bit-identical recorded times, globals and per-patch histories."""
    np.testing.assert_array_equal(c1.time, c2.time)
    np.testing.assert_array_equal(c1.globals, c2.globals)
    np.testing.assert_array_equal(c1.patch_time, c2.patch_time)
    np.testing.assert_array_equal(c1.velocity, c2.velocity)
    np.testing.assert_array_equal(c1.displacement, c2.displacement)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_repeated_runs_are_bit_identical(integrator):
    """Two runs of the same scene and seed record exactly the same numbers (and end in the same state)."""
    c1, (u1, v1), r1 = run([scene_a()], integrator)
    c2, (u2, v2), r2 = run([scene_a()], integrator)
    assert_identical(c1, c2)
    np.testing.assert_array_equal(u1, u2)
    np.testing.assert_array_equal(v1, v2)
    assert r1.steps == r2.steps and r1.rejected == r2.rejected
    assert np.ptp(c1.velocity) > 0.01  # the patches do move


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_graph_and_eager_are_bit_identical(integrator, monkeypatch):
    """Replaying captured graphs gives exactly what eager launches give (every graph captured: on the CPU a short
    run would otherwise launch eagerly, :func:`test_cpu_captures_only_graphs_that_pay`)."""
    from aca_warp.hf import general

    monkeypatch.setattr(general, "CPU_CAPTURE_REPLAYS", 0)
    c1, (u1, v1), r1 = run([scene_a()], integrator, use_graph=True, engine="general")  # the engine with graphs
    c2, (u2, v2), r2 = run([scene_a()], integrator, use_graph=False, engine="general")
    assert_identical(c1, c2)
    np.testing.assert_array_equal(u1, u2)
    np.testing.assert_array_equal(v1, v2)
    assert r1.steps == r2.steps


def test_graph_size_does_not_change_results():
    """The split of the run into graph replays (max_graph_steps) does not change a single bit."""
    s = scene_a()
    out = []
    for steps in (30, 200, 1000):
        model = build_model([s])
        res = run_hf(
            model,
            initial_state(model),
            RunOptions(duration=5e-6, integrator="strang", dt=1e-8, engine="general"),  # the engine with graphs
            tuning=EngineTuning(max_graph_steps=steps),
        )
        out.append(res.collect())
    assert_identical(out[0], out[1])
    assert_identical(out[0], out[2])


def _pad_slice(c, pad, start, stop):
    """The part of a batch chunk that belongs to one pad."""
    return c.globals[:, pad], c.velocity[:, start:stop], c.displacement[:, start:stop]


def _batch_and_singles(integrator):
    """Chunks of the batch [a, b] and of a and b run alone; the patch count of a."""
    a, b = scene_a(), scene_b()
    cab, _, _ = run([a, b], integrator)
    ca, _, _ = run([a], integrator)
    cb, _, _ = run([b], integrator)
    np.testing.assert_array_equal(cab.time, ca.time)
    return cab, ca, cb, a.patches.count


@pytest.mark.parametrize("integrator", FIXED_STEP)
def test_batch_matches_single_pads(integrator):
    """A batch of two different pads gives each pad what running it alone gives (to 1e-12: no cross-talk)."""
    cab, ca, cb, na = _batch_and_singles(integrator)
    for got, want in zip(_pad_slice(cab, 0, 0, na), _pad_slice(ca, 0, 0, na), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    for got, want in zip(_pad_slice(cab, 1, na, None), _pad_slice(cb, 0, 0, None), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("integrator", FIXED_STEP)
def test_batch_equals_single_pads_bitwise(integrator):
    """A batch of two different pads gives each pad bit for bit what running it alone gives."""
    cab, ca, cb, na = _batch_and_singles(integrator)
    for got, want in zip(_pad_slice(cab, 0, 0, na), _pad_slice(ca, 0, 0, na), strict=True):
        np.testing.assert_array_equal(got, want)
    for got, want in zip(_pad_slice(cab, 1, na, None), _pad_slice(cb, 0, 0, None), strict=True):
        np.testing.assert_array_equal(got, want)


def test_batch_coupling_equals_single_pad_coupling():
    """The second pad's CSR links, 1/D0 and k_ij in a batch equal those of the pad built alone, bit for bit."""
    a, b = scene_a(), scene_b()
    na = a.patches.count
    mab, mb = build_model([a, b]), build_model([b])
    start_ab, start_b = mab.host("nbr_start"), mb.host("nbr_start")
    e0, e1 = start_ab[na], start_ab[-1]
    np.testing.assert_array_equal(start_ab[na:] - e0, start_b)
    np.testing.assert_array_equal(mab.host("nbr_index")[e0:e1] - na, mb.host("nbr_index")[: start_b[-1]])
    np.testing.assert_array_equal(mab.host("nbr_inv_dist")[e0:e1], mb.host("nbr_inv_dist")[: start_b[-1]])
    np.testing.assert_array_equal(mab.host("nbr_stiffness")[e0:e1], mb.host("nbr_stiffness")[: start_b[-1]])


def test_batch_order_does_not_matter():
    """Swapping the pads of a batch swaps their outputs and nothing else (strang; to 1e-12, see the bug above)."""
    a, b = scene_a(), scene_b()
    na, nb = a.patches.count, b.patches.count
    cab, _, _ = run([a, b], "strang")
    cba, _, _ = run([b, a], "strang")
    close = dict(rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(cab.globals[:, 0], cba.globals[:, 1], **close)
    np.testing.assert_allclose(cab.globals[:, 1], cba.globals[:, 0], **close)
    np.testing.assert_allclose(cab.velocity[:, :na], cba.velocity[:, nb:], **close)
    np.testing.assert_allclose(cab.velocity[:, na:], cba.velocity[:, :nb], **close)


def test_continuing_a_run_matches_one_long_run():
    """Two consecutive 2.5 µs runs on the same state end where one 5 µs run ends (strang, to rounding)."""
    s = scene_a()
    model = build_model([s])
    st = initial_state(model)
    run_hf(
        model,
        st,
        RunOptions(duration=2.5e-6, integrator="strang", dt=1e-8),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    r2 = run_hf(
        model,
        st,
        RunOptions(duration=2.5e-6, integrator="strang", dt=1e-8),
        tuning=EngineTuning(max_graph_steps=GRAPH_STEPS),
    )
    c_long, (u, v), _ = run([s], "strang")
    c2 = r2.collect()
    np.testing.assert_allclose(st.numpy()[0], u, rtol=1e-9, atol=1e-18)
    np.testing.assert_allclose(st.numpy()[1], v, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(c2.globals[-1], c_long.globals[-1], rtol=1e-9)


def test_cpu_captures_only_graphs_that_pay():
    """On the CPU a graph is captured only when it will be replayed CPU_CAPTURE_REPLAYS times or more (known for
    fixed steps, counted for the adaptive runs); on a GPU always."""
    from types import SimpleNamespace

    from aca_warp.hf.general import CPU_CAPTURE_REPLAYS, GeneralEngine

    def engine(cpu: bool) -> SimpleNamespace:
        return SimpleNamespace(model=SimpleNamespace(device=SimpleNamespace(is_cpu=cpu)), graphs={}, _eager_uses={})

    pays = GeneralEngine._capture_pays
    cpu, gpu = engine(True), engine(False)
    assert pays(gpu, 4, 1) and pays(gpu, 4, None)
    assert not pays(cpu, 4, CPU_CAPTURE_REPLAYS - 1) and pays(cpu, 4, CPU_CAPTURE_REPLAYS)
    assert [pays(cpu, 7, None) for _ in range(CPU_CAPTURE_REPLAYS + 1)] == [False] * CPU_CAPTURE_REPLAYS + [True]
    cpu.graphs[5] = object()
    assert pays(cpu, 5, 0)  # captured already: replayed whatever is left


def test_cpu_opening_chunk_is_launched_eagerly(monkeypatch):
    """On the CPU the general engine launches the chunk that opens a fixed-step run (its first step eager, then one
    body fewer than the chunks after it: a count used once) eagerly, not captured for one replay: a 5 µs strang run
    in graphs of 3 samples (17 chunks, the last of 2 samples) captures one graph, that of the full chunks."""
    import warp as wp

    captures: list[int] = []

    class Counted(wp.ScopedCapture):
        def __enter__(self):
            captures.append(1)
            return super().__enter__()

    monkeypatch.setattr(wp, "ScopedCapture", Counted)
    run([scene_a()], "strang", engine="general")
    assert len(captures) == 1
