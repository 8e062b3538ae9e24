"""The spacing of growth events (``RunOptions.growth_dt``, ``aca-warp hf --growth-dt``): the growth rate kept at any
spacing, the same bits at the scene's own spacing, every engine and the adaptive integrator alike, and its refusals
(CPU)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from procs import interrupted_at_second_checkpoint, nine_patch_scene

from aca_warp.common.errors import SceneError
from aca_warp.hf.loop import run_hf
from aca_warp.hf.model import build_model
from aca_warp.hf.options import RunOptions
from aca_warp.hf.runner import run_scene
from aca_warp.hf.state import initial_state
from aca_warp.studies.work_precision_stats import parse_setting

INTERVAL = 2.02e-7  # s: the scene's growth interval (the paper's clock)


def grow(
    growth_dt: float | None,
    *,
    integrator: str = "strang",
    engine: str = "general",
    dt: float = 1e-8,
    device: str = "cpu",
    precision: str = "fp64",
) -> tuple[np.ndarray, np.ndarray]:
    """(μ samples, final areas [m²]) of the 9-patch scene growing 1000× faster than Eq. 10 over 40 µs."""
    scene = nine_patch_scene(increment=1e-6, interval=INTERVAL, sample_dt=1e-6, duration=4e-5)
    model = build_model([scene], device=device, precision=precision)
    options = RunOptions(integrator=integrator, engine=engine, dt=dt, growth_dt=growth_dt, checkpoint_interval=0)
    res = run_hf(model, initial_state(model), options)
    assert res.complete, res.fault
    return res.collect().globals[:, 0, 0], model.host("area")


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
@pytest.mark.parametrize("engine", ["general", "onchip"])
def test_the_scenes_spacing_gives_the_same_bits(engine, precision, device):
    """growth_dt equal to the scene's interval is the run without it, bit for bit (on every device)."""
    mu, area = grow(None, engine=engine, device=device, precision=precision)
    mu2, area2 = grow(INTERVAL, engine=engine, device=device, precision=precision)
    np.testing.assert_array_equal(mu2, mu)
    np.testing.assert_array_equal(area2, area)


def test_coarser_events_keep_the_growth_rate():
    """Events every 1 and 2 µs (every 100 and 200 steps of 1e-8 s, each adding 4.95 and 9.9 increments) end, at a
    multiple of every spacing, at the areas of the scene's clock (every 20 steps, 0.99 increments) up to the
    bigger increments' second-order terms: on this scene, whose areas grow 1000× faster than Eq. 10 (by 90-170 %
    in 40 µs), the growth differs by less than a quarter of the largest relative increment per event (0.065 at
    2 µs), and the difference is of first order in the spacing (halved with it)."""
    _, area = grow(None)
    a0 = nine_patch_scene(increment=1e-6, interval=INTERVAL, sample_dt=1e-6, duration=4e-5).patches.area
    assert np.all(area > 1.8 * a0)
    err = {}
    for spacing in (1e-6, 2e-6):
        _, coarse = grow(spacing)
        err[spacing] = np.abs(coarse - area) / (area - a0)
        per_event = 1e-6 * (spacing / INTERVAL) / np.sqrt(a0)  # ΔA/A of one event at the start
        assert np.all(err[spacing] < 0.25 * per_event.max()) and np.all(err[spacing] > 0)
    assert 1.7 < np.min(err[2e-6] / err[1e-6]) and np.max(err[2e-6] / err[1e-6]) < 2.8


def test_engines_and_the_adaptive_integrator_agree_on_the_events():
    """At events every 1 µs the on-chip engine gives the general engine's bits; the adaptive integrator lands on
    the same event times and ends at the same areas (growth does not depend on the motion)."""
    mu_g, area_g = grow(1e-6)
    mu_o, area_o = grow(1e-6, engine="onchip")
    np.testing.assert_array_equal(mu_o, mu_g)
    np.testing.assert_array_equal(area_o, area_g)
    _, area_a = grow(1e-6, integrator="adaptive", dt=1e-9)
    np.testing.assert_allclose(area_a, area_g, rtol=1e-13)
    _, area_scene = grow(None, integrator="adaptive", dt=1e-9)
    assert not np.array_equal(area_scene, area_a)


@pytest.mark.parametrize("bad", [0.0, -1e-6, float("nan"), float("inf")])
def test_bad_spacing_is_refused(bad):
    with pytest.raises(SceneError, match="growth_dt must be a positive number of seconds"):
        RunOptions(growth_dt=bad)


def test_spacing_for_a_scene_that_does_not_grow_is_refused(tmp_path):
    """Nothing is written: the refusal comes before the run file."""
    scene = nine_patch_scene(sample_dt=1e-6, duration=4e-6)
    out = tmp_path / "run.h5"
    with pytest.raises(SceneError, match="the scene does not grow"):
        run_scene(scene, out, RunOptions(growth_dt=1e-6))
    assert list(tmp_path.iterdir()) == []


def test_run_file_keeps_the_spacing_and_rerun_repeats_it(tmp_path):
    from aca_warp.hf.rerun import read_settings

    scene = nine_patch_scene(increment=1e-6, interval=INTERVAL, sample_dt=1e-6, duration=4e-6)
    out = tmp_path / "run.h5"
    run_scene(scene, out, RunOptions(growth_dt=1e-6, checkpoint_interval=0))
    assert read_settings(out).options.growth_dt == 1e-6
    with h5py.File(out) as f:
        assert '"growth_dt": 1e-06' in f.attrs["run_options"]


def test_strang_spaces_growth_events_5_us_apart_by_default(tmp_path, capsys):
    """``aca-warp hf`` and ``run_scene`` without a spacing: strang's events every 5 µs (the statistics' spacing),
    written out in the file and named in the summary line; a shorter run, and a scene whose interval is longer, keep
    the scene's interval; ``adaptive`` keeps it too (None); ``--growth-dt scene`` names it."""
    import json

    from aca_warp.cli import main

    for extra, spacing in (([], 5e-6), (["--integrator", "adaptive"], None)):
        out = tmp_path / f"run{len(extra)}.h5"
        assert main(["hf", "varying_area", "--duration", "1e-5", "-o", str(out), "--no-progress", *extra]) == 0
        with h5py.File(out) as f:
            assert json.loads(f.attrs["run_options"])["growth_dt"] == spacing
        assert ("growth events every 5e-06 s" in capsys.readouterr().out) == (spacing is not None)
    out = tmp_path / "short.h5"  # a run shorter than 5 µs grows at the scene's clock, without a warning
    assert main(["hf", "varying_area", "--duration", "2e-6", "-o", str(out), "--no-progress"]) == 0
    with h5py.File(out) as f:
        assert json.loads(f.attrs["run_options"])["growth_dt"] == INTERVAL
    assert "warning" not in capsys.readouterr().err
    out = tmp_path / "clock.h5"  # --growth-dt scene: the scene's clock, written out
    assert (
        main(["hf", "varying_area", "--duration", "1e-5", "--growth-dt", "scene", "-o", str(out), "--no-progress"]) == 0
    )
    with h5py.File(out) as f:
        assert json.loads(f.attrs["run_options"])["growth_dt"] == INTERVAL
    none = tmp_path / "none.h5"
    assert main(["hf", "hf1", "--duration", "1e-6", "--growth-dt", "scene", "-o", str(none), "--no-progress"]) == 2
    assert "the scene does not grow" in capsys.readouterr().err and not none.exists()
    slow = nine_patch_scene(increment=1e-6, interval=1e-5, sample_dt=1e-6, duration=2e-5)
    run_scene(slow, tmp_path / "slow.h5", RunOptions(checkpoint_interval=0))
    with h5py.File(tmp_path / "slow.h5") as f:
        assert json.loads(f.attrs["run_options"])["growth_dt"] == 1e-5


def test_the_summary_gives_the_spacing_taken_in_whole_steps(tmp_path, capsys):
    """A spacing that whole steps do not fill: the summary line gives the spacing the events took beside the one
    asked; one below half the step warns that an event follows every step."""
    from aca_warp.cli import main

    for asked, taken, warned in (
        ("1e-9", "every 1e-07 s (1e-09 s asked", True),
        ("scene", "every 2e-07 s (2.02e-07 s asked", False),
        ("1e-6", "every 1e-06 s)", False),
    ):
        out = tmp_path / f"r{asked}.h5"
        argv = ["hf", "varying_area", "--duration", "4e-6", "--dt", "1e-7", "--growth-dt", asked, "-o", str(out)]
        argv += ["--no-progress"]
        assert main(argv) == 0
        captured = capsys.readouterr()
        assert f"growth events {taken}" in captured.out, captured.out
        assert ("one event per step, every 1e-07 s" in captured.err) == warned, captured.err


def test_a_file_without_a_stored_spacing_is_repeated_at_the_scene_s_interval(tmp_path):
    """A run file that stores no spacing (written while the events came at the scene's interval by default) is
    rerun at that interval, not at today's default: the same samples, bit for bit."""
    import json

    from aca_warp.cli import main

    scene = nine_patch_scene(increment=1e-6, interval=INTERVAL, sample_dt=1e-6, duration=4e-6)
    out = tmp_path / "old.h5"
    run_scene(scene, out, RunOptions(growth_dt=INTERVAL, checkpoint_interval=0))
    with h5py.File(out, "r+") as f:
        options = json.loads(f.attrs["run_options"])
        f.attrs["run_options"] = json.dumps({**options, "growth_dt": None})
    assert main(["rerun", str(out), "-o", str(tmp_path / "again.h5"), "--no-progress"]) == 0
    with h5py.File(out) as a, h5py.File(tmp_path / "again.h5") as b:
        assert np.array_equal(a["global/mu"][()], b["global/mu"][()])
        assert json.loads(b.attrs["run_options"])["growth_dt"] == INTERVAL


def test_study_settings_parse_the_spacing():
    settings = parse_setting("strang@fp32:dt=1e-7:growth_dt=1e-6,5e-6")
    assert [s.growth_dt for s in settings] == [1e-6, 5e-6]
    assert settings[0].label == "strang@fp32:dt=1e-07:growth_dt=1e-06"
    assert parse_setting(settings[0].label) == [settings[0]]
    assert parse_setting("strang@fp32:dt=1e-7")[0].label == "strang@fp32:dt=1e-07"  # labels of earlier files
    with pytest.raises(ValueError, match="growth_dt must be positive"):
        parse_setting("strang@fp32:growth_dt=0")


def test_cli_refuses_the_spacing_for_a_scene_that_does_not_grow(tmp_path, capsys):
    from aca_warp.cli import main

    out = tmp_path / "run.h5"
    assert main(["hf", "hf1", "--growth-dt", "1e-6", "--duration", "1e-6", "-o", str(out), "--no-progress"]) == 2
    assert "--growth-dt sets the spacing of growth events; the scene does not grow" in capsys.readouterr().err
    assert not out.exists()


def test_sweep_spec_takes_the_spacing_for_growing_pads_only(tmp_path):
    """A growing sweep's spacing: the asked one, kept as asked (the scenes' interval too); by default with strang the
    statistics' 5 µs, written out; ``scene``, and the default of the other integrators, leave it out of the run
    settings, as sweeps at the scenes' interval did before the default: such a sweep continues with
    ``--growth-dt scene``, which its refusal names."""
    from aca_warp.sweep.manifest import prepare_dir
    from aca_warp.sweep.prepare import run_options
    from aca_warp.sweep.spec import SweepError, load_spec

    doc = {"sweep": {"base": "varying_area"}, "run": {"duration": 1e-5, "growth_dt": 1e-6}, "parameters": {}}
    spec = load_spec(doc, base_dir=tmp_path)
    assert run_options(spec).growth_dt == 1e-6 and spec.run_settings()["growth_dt"] == 1e-6
    asked = load_spec(doc, base_dir=tmp_path, growth_dt=INTERVAL)
    assert run_options(asked).growth_dt == INTERVAL and asked.run_settings()["growth_dt"] == INTERVAL
    default = load_spec({**doc, "run": {"duration": 1e-5}}, base_dir=tmp_path)
    assert run_options(default).growth_dt == 5e-6 and default.run_settings()["growth_dt"] == 5e-6
    clock = load_spec({**doc, "run": {"duration": 1e-5}}, base_dir=tmp_path, growth_dt="scene")
    adaptive = load_spec({**doc, "run": {"duration": 1e-5, "integrator": "adaptive"}}, base_dir=tmp_path)
    for s in (clock, adaptive):
        assert run_options(s).growth_dt is None and "growth_dt" not in s.run_settings()
    assert len({spec.hash, asked.hash, default.hash, clock.hash}) == 4
    prepare_dir(clock, tmp_path / "sw")  # a sweep begun with its events at the scenes' interval
    with pytest.raises(SweepError, match=r"growth_dt unset there, 5e-06 here\) \(to continue it: --growth-dt scene\)"):
        prepare_dir(default, tmp_path / "sw")
    odd = load_spec({**doc, "run": {"duration": 1e-5, "dt": 1.2345678e-8}}, base_dir=tmp_path)
    prepare_dir(odd, tmp_path / "odd")  # the hint gives every digit of the stored value
    with pytest.raises(SweepError, match=r"to continue it: --dt 1.2345678e-08 --growth-dt 5e-06\)"):
        prepare_dir(spec, tmp_path / "odd")
    with pytest.raises(SweepError, match="the base scene does not grow"):
        load_spec({**doc, "sweep": {"base": "hf1"}}, base_dir=tmp_path)
    with pytest.raises(SweepError, match="run.growth_dt must be a positive number"):
        load_spec({**doc, "run": {"growth_dt": 0}}, base_dir=tmp_path)


def test_onchip_adaptive_lands_on_the_spacing_as_the_general_engine():
    """The adaptive integrator on chip (CPU) with events every 1 µs: the general engine's samples and areas, bit for
    bit, and not those at the scene's own spacing."""
    mu_g, area_g = grow(1e-6, integrator="adaptive", dt=1e-9)
    mu_o, area_o = grow(1e-6, integrator="adaptive", engine="onchip", dt=1e-9)
    np.testing.assert_array_equal(mu_o, mu_g)
    np.testing.assert_array_equal(area_o, area_g)
    _, area_scene = grow(None, integrator="adaptive", engine="onchip", dt=1e-9)
    assert not np.allclose(area_scene, area_o, rtol=1e-9, atol=0)


@pytest.mark.parametrize(
    ("integrator", "engine"), [("strang", "general"), ("strang", "onchip"), ("adaptive", "general")]
)
def test_resume_keeps_the_spacing(integrator, engine, tmp_path, monkeypatch):
    """``aca-warp hf --growth-dt 1.5e-6`` stopped by Ctrl-C after its second checkpoint (4 µs: between the events at
    3 and 4.5 µs, each 150 steps of 1e-8 s across 15 samples) and resumed with ``--resume`` (the spacing read from
    the file) ends equal to the uninterrupted run, bit for bit, and not to the run at the scene's own spacing."""
    from procs import small_scene_toml

    from aca_warp.cli import main

    scene = tmp_path / "s.toml"
    scene.write_text(
        small_scene_toml("g", count=40, duration=1e-5, perturbation=1e-3)
        + f"\n[growth]\nincrement = 1.0e-6\ninterval = {INTERVAL!r}\n"
    )
    opts = ["--integrator", integrator, "--engine", engine, "--dt", "1e-8", "--no-progress"]
    ref, scene_clock, out = tmp_path / "ref.h5", tmp_path / "scene.h5", tmp_path / "run.h5"
    assert main(["hf", str(scene), "-o", str(ref), *opts, "--growth-dt", "1.5e-6", "--no-checkpoint"]) == 0
    assert main(["hf", str(scene), "-o", str(scene_clock), *opts, "--no-checkpoint"]) == 0
    argv = ["hf", str(scene), "-o", str(out), *opts, "--growth-dt", "1.5e-6", "--checkpoint-interval", "2e-6"]
    with interrupted_at_second_checkpoint(monkeypatch):
        assert main(argv) == 130
    with h5py.File(out) as f:
        assert not f.attrs["complete"] and 4e-6 <= f["checkpoint"].attrs["sim_time"] < 4.5e-6
    assert main(["hf", "--resume", str(out), "--no-progress"]) == 0
    with h5py.File(out) as f, h5py.File(ref) as g, h5py.File(scene_clock) as h:
        assert f.attrs["complete"]
        np.testing.assert_array_equal(f["global/mu"][()], g["global/mu"][()])
        assert not np.array_equal(f["global/mu"][()], h["global/mu"][()])


def test_a_pad_of_a_sweep_keeps_the_spacing(tmp_path):
    """A pad taken out of a shard of a sweep with ``run.growth_dt`` (``aca-warp analyze SHARD --pad K``) stores the
    spacing, so that ``aca-warp rerun`` of it repeats the pad's run: the same μ as in the shard."""
    from aca_warp.analysis.pads import write_pad_run
    from aca_warp.cli import main
    from aca_warp.hf.rerun import read_settings

    spec = tmp_path / "s.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 2\n[run]\nduration = 4e-6\nsample_dt = 1e-6\ngrowth_dt = 1e-6\n'
        f"[base.patches]\ncount = 12\n[base.growth]\nincrement = 1e-6\ninterval = {INTERVAL!r}\n"
        '[parameters]\n"friction.M" = [0.7, 0.8]\n'
    )
    assert main(["sweep", str(spec), "-o", str(tmp_path / "sw"), "--workers", "0", "--quiet"]) == 0
    shard = tmp_path / "sw" / "shard-00000.h5"
    pad = write_pad_run(shard, 1, tmp_path / "pad1.h5")
    assert read_settings(pad).options.growth_dt == 1e-6
    again = tmp_path / "again.h5"
    assert main(["rerun", str(pad), "-o", str(again), "--no-progress"]) == 0
    with h5py.File(pad) as f, h5py.File(again) as g:
        np.testing.assert_allclose(g["global/mu"][()], f["global/mu"][()], rtol=1e-12, atol=0)


def test_a_spacing_beyond_the_run_warns_that_nothing_grows(capsys):
    from aca_warp.hf.sanity import _WARNED

    _WARNED.clear()
    scene = nine_patch_scene(increment=1e-6, interval=INTERVAL, sample_dt=1e-6, duration=4e-6)
    model = build_model([scene], device="cpu", precision="fp64")
    area = model.host("area").copy()
    res = run_hf(model, initial_state(model), RunOptions(growth_dt=1e-5, checkpoint_interval=0))
    assert res.complete
    assert "no growth event in the run" in capsys.readouterr().err
    np.testing.assert_array_equal(model.host("area"), area)


def test_sweep_command_takes_the_spacing(tmp_path, capsys):
    from aca_warp.cli import main

    spec = tmp_path / "va.toml"
    spec.write_text('[sweep]\nbase = "varying_area"\nshard_size = 2\n[run]\nduration = 2e-6\nsample_dt = 1e-6\n'
                    '[parameters]\n"initial.perturbation" = [0.0, 0.01]\n')  # fmt: skip
    out = tmp_path / "sweep"
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0", "--growth-dt", "1e-6", "--quiet"]) == 0
    import json

    import h5py

    shard = next(out.glob("*.h5"))
    with h5py.File(shard) as f:
        assert json.loads(f.attrs["run"])["growth_dt"] == 1e-6
