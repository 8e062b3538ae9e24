"""``aca_warp.studies.varying_area`` (``scripts/varying_area.py``): segment/resume logic and the growth trends on a
9-patch growing scene, and the contact re-solve of growth events (CPU)."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from aca_warp.kernels.hf import contact_flat
from aca_warp.kernels.hf_types import HFModel
from aca_warp.kernels.physics import contact_block
from procs import nine_patch_scene

from aca_warp.scene import Scene
from aca_warp.studies import varying_area as va


def growing_scene() -> Scene:
    """The 9-patch scene growing 1000× faster than Eq. 10 (an event every 2.02e-7 s), over 40 µs."""
    return nine_patch_scene(increment=1e-6, interval=2.02e-7, sample_dt=1e-6, duration=4e-5)


@pytest.mark.parametrize("integrator", ["strang", "implicit-friction"])
def test_resume_equals_one_go(tmp_path, integrator):
    """Stopping at 20 µs, saving and resuming in a fresh model gives the one-go record bit for bit."""
    s = growing_scene()
    kw = {"chunk": 1e-5, "integrator": integrator, "dt": 1e-8, "max_wall": np.inf}
    one = va.Segment(s, "cpu", "fp64")
    one.advance(4e-5, **kw)
    a = va.Segment(s, "cpu", "fp64")
    a.advance(2e-5, **kw)
    a.save(tmp_path / "state.npz", {"x": 1})
    b = va.Segment(s, "cpu", "fp64")
    assert b.load(tmp_path / "state.npz") == {"x": 1}
    b.advance(4e-5, **kw)
    g1, g2 = np.concatenate(one.globals), np.concatenate(b.globals)
    assert g1.shape == (41, 6) and np.array_equal(np.concatenate(one.time), np.concatenate(b.time))
    np.testing.assert_array_equal(g1, g2)
    np.testing.assert_array_equal(one.state.numpy()[1], b.state.numpy()[1])
    assert [x["patch_share"] for x in one.snaps] == [x["patch_share"] for x in b.snaps]
    # a different chunking only moves where strang closes and reopens its staggered velocity: O(dt³) per chunk
    c = va.Segment(s, "cpu", "fp64")
    c.advance(4e-5, **{**kw, "chunk": 4e-5})
    assert np.max(np.abs(np.concatenate(c.globals)[:, 0] - g1[:, 0])) < 1e-6
    assert c.snaps[-1]["area_total"] == pytest.approx(one.snaps[-1]["area_total"], rel=1e-12)


def test_growth_dt_reaches_the_runs_and_keeps_the_growth():
    """``Segment.advance(growth_dt=…)`` spaces the events as asked: in 4 chunks of 10 µs with events every 2 µs
    (a whole number per chunk) the areas end where the scene's clock puts them, up to the bigger increments'
    second-order terms, and not at the same bits."""
    s = growing_scene()
    kw = {"chunk": 1e-5, "integrator": "strang", "dt": 1e-8, "max_wall": np.inf}
    paper, coarse = va.Segment(s, "cpu", "fp64"), va.Segment(s, "cpu", "fp64")
    paper.advance(4e-5, **kw)
    coarse.advance(4e-5, growth_dt=2e-6, **kw)
    a, b = paper.model.host("area"), coarse.model.host("area")
    assert not np.array_equal(a, b)
    np.testing.assert_allclose(b, a, rtol=0.02)
    assert coarse.snaps[-1]["area_total"] == pytest.approx(paper.snaps[-1]["area_total"], rel=0.02)


def test_resume_refuses_another_growth_spacing(tmp_path):
    """A state saved without a spacing (as before the option was recorded) resumed with --growth-dt is refused,
    naming both values."""
    s = growing_scene()
    seg = va.Segment(s, "cpu", "fp64")
    seg.advance(2e-6, chunk=2e-6, integrator="strang", dt=1e-8, max_wall=np.inf)
    meta = {"speedup": 1.0, "duration": s.duration, "integrator": "strang", "dt": 1e-8, "precision": "fp64",
            "chunk": 2e-6, "calls": []}  # fmt: skip
    seg.save(tmp_path / "state.npz", meta)
    with pytest.raises(SystemExit, match="made with growth_dt = None, this call has 1e-06"):
        va._resume(va.Segment(s, "cpu", "fp64"), tmp_path / "state.npz", {**meta, "growth_dt": 1e-6})
    va._resume(va.Segment(s, "cpu", "fp64"), tmp_path / "state.npz", {**meta, "growth_dt": None})


def test_onchip_engine_equals_general():
    """``--engine onchip`` (growth inside the on-chip kernel) gives the general engine's record bit for bit on the
    CPU, over several run calls (the growth counter restarts with each call in both)."""
    s = growing_scene()
    kw = {"chunk": 1e-5, "integrator": "strang", "dt": 1e-8, "max_wall": np.inf}
    segs = {}
    for engine in ("general", "onchip"):
        segs[engine] = va.Segment(s, "cpu", "fp64")
        segs[engine].advance(4e-5, engine=engine, **kw)
    g, o = segs["general"], segs["onchip"]
    np.testing.assert_array_equal(np.concatenate(o.globals), np.concatenate(g.globals))
    np.testing.assert_array_equal(o.state.numpy()[1], g.state.numpy()[1])
    np.testing.assert_array_equal(o.model.host("normal_force"), g.model.host("normal_force"))
    assert o.snaps == g.snaps


def test_growth_moves_load_to_patches():
    """Areas follow Eq. 10 (√A grows linearly); the patch share of the load and μ rise as they grow."""
    s = growing_scene()
    seg = va.Segment(s, "cpu", "fp64")
    seg.advance(4e-5, chunk=1e-5, integrator="strang", dt=1e-8, max_wall=np.inf)
    sq0 = np.sqrt(s.patches.area)
    # 200 growth events (every 20 steps of 1e-8 s, scaled to 2.02e-7 s each): √A += g/2 per event to O(g²/A)
    events = 4e-5 / 2e-7
    sq1 = np.sqrt(seg.model.host("area"))
    np.testing.assert_allclose(sq1 - sq0, 0.5e-6 * events * (2e-7 / 2.02e-7), rtol=2e-2)
    share = [x["patch_share"] for x in seg.snaps]
    assert share[0] < 0.7 and all(np.diff(share) > 0) and share[-1] > share[0] + 0.1
    assert seg.snaps[-1]["matrix_share"] == pytest.approx(1 - share[-1], abs=1e-9)
    mu = np.concatenate(seg.globals)[:, 0]
    assert mu[-10:].mean() > mu[5:15].mean()


def test_growth_contact_block_threads_agree():
    """The growth events' contact re-solve (one thread block per pad) gives the same forces with one CPU thread
    per block and with Warp's cooperative CPU fibers (256 threads, real barriers), to rounding, in force balance."""
    import warp as wp

    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state

    s = growing_scene()
    out = []
    old = wp.config.enable_cpu_blocks
    try:
        for fibers in (False, True):
            wp.config.enable_cpu_blocks = fibers
            model = build_model([s, s.replace(normal_force=35.0)], device="cpu", precision="fp64")
            res = run_hf(model, initial_state(model), RunOptions(integrator="strang", duration=4e-6, dt=1e-8))
            assert res.complete and "growth" in res.stages
            fn = model.host("normal_force")
            total = fn.reshape(2, -1).sum(axis=1) + model.host("pad_matrix_force")
            np.testing.assert_allclose(total, [20.0, 35.0], rtol=1e-12)
            out.append((fn, model.host("pad_matrix_force"), model.host("area")))
    finally:
        wp.config.enable_cpu_blocks = old
    for a, b in zip(out[0], out[1], strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)


@wp.kernel
def _contact_part(part: int, parts: int, model: HFModel(wp.float64), gap_out: wp.array(dtype=wp.float64)):
    """Block ``part`` of ``parts`` of a (one-thread CPU) cluster: the pad's whole contact, its own forces only."""
    pad, lane = wp.tid()
    s = model.pad_patch_start[pad]
    n = model.pad_patch_start[pad + 1] - s
    g = contact_block(
        pad, lane, 1, model, model.pad_gap[pad], s + n * part // parts, s + n * (part + 1) // parts, part == 0
    )
    if lane == 0:
        gap_out[pad * parts + part] = g


def test_contact_block_parts_compose():
    """What a growth event on a thread-block cluster relies on (kernels/hf_onchip.py): every block re-solves the
    pad's contact with the same gap, writes only its own range of normal forces, and only the writer block the
    matrix force and radius; the parts together give the general path's contact_flat result exactly."""
    from aca_warp.hf.model import build_model

    s = growing_scene()
    parts = 3
    model = build_model([s, s.replace(normal_force=35.0)], device="cpu", precision="fp64")
    m = model.arrays
    m["pad_load"].assign(m["pad_load"].numpy() * 1.3)  # a new load: the contact must move
    gap0 = m["pad_gap"].numpy().copy()
    ref = {k: wp.zeros_like(m[k]) for k in ("normal_force", "pad_matrix_force", "pad_matrix_radius")}
    ref_gap = wp.array(gap0, dtype=wp.float64, device="cpu")
    wp.launch_tiled(
        contact_flat, dim=[model.pad_count], block_dim=1, device="cpu",
        inputs=[HFModel.of(wp.float64, {**m, **ref, "pad_gap": ref_gap}), wp.zeros(1, dtype=wp.int64, device="cpu"),
                1, 1],
    )  # fmt: skip
    out = {k: wp.full(v.shape, np.nan, dtype=wp.float64, device="cpu") for k, v in ref.items()}
    parted = HFModel.of(wp.float64, {**m, **out})
    gaps = wp.zeros(model.pad_count * parts, dtype=wp.float64, device="cpu")
    for part in (2, 1, 0):  # the writer last: the others must leave the pad's matrix outputs alone
        if part == 0:  # parts 1 and 2 wrote their own forces and nothing else
            assert np.isnan(out["pad_matrix_force"].numpy()).all() and np.isnan(out["pad_matrix_radius"].numpy()).all()
            start = model.pad_patch_start_host
            own0 = np.concatenate([np.arange(a, a + (b - a) // parts) for a, b in zip(start, start[1:], strict=False)])
            fn = out["normal_force"].numpy()
            assert np.isnan(fn[own0]).all() and not np.isnan(np.delete(fn, own0)).any()
        wp.launch_tiled(
            _contact_part, dim=[model.pad_count], block_dim=1, device="cpu", inputs=[part, parts, parted, gaps]
        )
    np.testing.assert_array_equal(m["pad_gap"].numpy(), gap0)  # the gap is returned, not stored
    g = gaps.numpy().reshape(model.pad_count, parts)
    np.testing.assert_array_equal(g, np.repeat(ref_gap.numpy()[:, None], parts, axis=1))
    assert not np.array_equal(ref_gap.numpy(), gap0)  # the contact moved, so the test compares something
    for k in ref:
        np.testing.assert_array_equal(out[k].numpy(), ref[k].numpy())


def test_report_of_a_compressed_record(tmp_path):
    """A --quick record (growth ×100, 3.6 ms) gets its figures, summary and docs section: the report reads the
    frame at 10 ms of growth and the μ spread over 10 ms of growth compressed 100× (0.1 ms), as the growth is."""
    import json

    t = np.arange(3601) * 1e-6
    mu = 0.4 + 0.004 * np.sin(2 * np.pi * 70e3 * t) + 0.002 * (t < 1e-4) * np.sin(2 * np.pi * 20e3 * t)
    g = np.zeros((t.size, 5))
    g[:, 0] = mu
    st = np.linspace(0.0, 3.6e-3, 5)
    call = {"machine": {"device_name": "Test CPU"}, "warp": "1.19.0", "sim_time": 3.6e-3, "engine": "general"}
    meta = {"speedup": 100.0, "duration": 3.6e-3, "integrator": "strang", "dt": 1e-8, "precision": "fp64"}
    meta.update(chunk=1e-3, calls=[{**call, "wall_s": 1.0}], complete=True, steps=360000, wall_s=1.0)
    snaps = {f"snap_{k}": st for k in ("time", "area_total", "patch_force", "matrix_force", "patches_loaded")}
    snaps.update(snap_patch_share=0.5 + st, snap_matrix_share=0.5 - st, snap_area_mean=5e-8 * (1 + 100 * st))
    record = tmp_path / "varying_area.npz"
    np.savez_compressed(record, time=t, globals=g, meta=json.dumps(meta), **snaps)
    page, figdir = tmp_path / "page.md", tmp_path / "figures" / "va"
    page.write_text(f"# Varying area\n\nhand-written\n\n{va.BEGIN}\nold\n{va.END}\n\nafter\n")
    va.report(record, page, figdir)
    text = page.read_text()
    assert "hand-written" in text and "after" in text and "old" not in text
    assert "growth ×100 compressed (--quick)" in text and "over the first and the last 0.1 ms" in text
    assert "![va_stft](figures/va/va_stft.png)" in text
    summary = json.loads((figdir / "summary.json").read_text())
    frame, hz, amp = summary["peak_at_10ms"]
    frames = va.analyse(record)["stft"][0]
    hop = frames[1] - frames[0]
    assert 1e-4 <= frame < 1e-4 + hop and 60e3 <= hz <= 80e3 and amp == pytest.approx(0.004, rel=0.25)
    np.testing.assert_allclose(summary["mu_std_first_last_10ms"], [mu[:100].std(), mu[-100:].std()], rtol=1e-12)
    assert summary["patch_share"] == [0.5, pytest.approx(0.5036)]
    for stem in ("va_mu", "va_load_share", "va_stft", "va_cwt"):
        assert (figdir / f"{stem}.png").stat().st_size > 0 and (figdir / f"{stem}.pdf").stat().st_size > 0
