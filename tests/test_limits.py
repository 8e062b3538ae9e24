"""Sizes and counts against the integers and the memory they land in (aca_warp/hf/limits.py): refused with one line
before anything is allocated or written, never a segmentation fault, SIGFPE or traceback."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import h5py
import numpy as np
import pytest
from procs import small_scene_toml

from aca_warp.cli import main
from aca_warp.common.errors import SceneError
from aca_warp.hf import limits
from aca_warp.hf import model as model_module
from aca_warp.hf.model import build_model
from aca_warp.scene import Pad, PatchGenerator, load_scene

TINY = small_scene_toml("limits", count=40, disc=False)


def run_cli(capsys, argv: list[str]) -> tuple[int, list[str]]:
    capsys.readouterr()
    code = main(argv)
    return code, [line for line in capsys.readouterr().err.splitlines() if line.strip()]


def no_output(tmp_path: Path) -> bool:
    return not any(p.name.startswith("run.h5") for p in tmp_path.iterdir())


def test_overflowing_neighbour_scene_refused_before_allocation(tmp_path, capsys, monkeypatch) -> None:
    """50 000 patches of 1e-9 m² with a 0.5 m coupling radius (2.5e9 links: the int32 CSR offsets overflowed into a
    segmentation fault): refused from the cheap lower bound (exact here: one cell), before the neighbour search
    runs, with one line naming the memory estimate."""

    def no_search(*args, **kw):
        raise AssertionError("the neighbour search ran")

    monkeypatch.setattr(model_module, "build_neighbours", no_search)
    s = tmp_path / "big.toml"
    s.write_text("[patches]\ncount = 50000\narea_min = 1e-9\narea_max = 1e-9\n[material]\ncoupling_radius = 0.5\n")
    code, err = run_cli(capsys, ["hf", str(s), "-o", str(tmp_path / "run.h5"), "--no-progress"])
    assert code == 2 and len(err) == 1, err
    assert "the model needs about" in err[0] and "GB (50000 patches, at least 2.5e+09 neighbour links" in err[0]
    assert no_output(tmp_path)


def test_link_count_checked_before_the_offsets(monkeypatch) -> None:
    """The exact link count (summed in int64) reaches the check before the int32 offsets are made; the int32 limit
    and the memory estimate are one line each."""
    scene = load_scene("hf1")
    seen = []
    real = model_module.limits.check_model_memory

    def spy(patches, links, device, radius, *, exact):
        seen.append((links, exact))
        return real(patches, links, device, radius, exact=exact)

    monkeypatch.setattr(model_module.limits, "check_model_memory", spy)
    m = build_model([scene])
    assert seen[-1] == (m.nnz, True) and seen[0][1] is False and seen[0][0] <= m.nnz
    monkeypatch.setattr(limits, "available_memory", lambda device: 10**15)
    with pytest.raises(SceneError, match=r"exceeds 2147483647 \(2\^31 - 1, the kernels count it in int32\)"):
        limits.check_model_memory(10, 2**31, "cpu", 0.5, exact=True)
    monkeypatch.setattr(limits, "available_memory", lambda device: 10**9)
    with pytest.raises(SceneError, match=r"needs about 1.6 GB .* more than the 1 GB available"):
        limits.check_model_memory(10, 2 * 10**7, "cpu", 0.5, exact=True)


def test_links_lower_bound_is_a_lower_bound() -> None:
    """The r/√2-cell bound never exceeds the exact count (random pads, radii from tiny to the whole pad) and is exact
    when one cell holds the pad."""
    pad = Pad()
    for seed, (count, radius) in enumerate([(300, 1e-3), (300, 5e-3), (500, 2e-2), (200, 1.0)]):
        p = PatchGenerator(count=count, area_min=2e-8, area_max=8e-8, seed=seed).generate(pad)
        scene = load_scene("hf1").replace(patches=p)
        scene = scene.replace(material=dataclasses.replace(scene.material, coupling_radius=radius))
        m = build_model([scene])
        lb = limits.links_lower_bound(p.x, p.y, np.zeros(count, int), np.array([radius]))
        assert lb <= m.nnz
        if radius == 1.0:
            assert lb == m.nnz == count * (count - 1)


@pytest.mark.parametrize(
    ("how", "value"),
    [("cli", "4294967296"), ("cli", "2147483648"), ("toml", "9223372036854775807")],
)
def test_decimation_beyond_int32_is_refused(tmp_path, capsys, how, value) -> None:
    """--patch-decimation 2^32 (was SIGFPE, a .partial left) and 2^31, decimation = 2^63 − 1 in TOML (was an
    AssertionError and a 'failed' file): exit 2, one line naming the limit, nothing written."""
    s = tmp_path / "s.toml"
    text = small_scene_toml("limits", count=40, disc=False, patches=("velocity",))
    argv = ["hf", str(s), "-o", str(tmp_path / "run.h5"), "--no-progress"]
    if how == "toml":
        text = text.replace("[record]\n", f"[record]\ndecimation = {value}\n")
    else:
        argv += ["--patch-decimation", value]
    s.write_text(text)
    code, err = run_cli(capsys, argv)
    assert code == 2 and len(err) == 1 and f"record.decimation = {value} exceeds 2147483647" in err[0], err
    assert no_output(tmp_path)


def test_largest_int32_decimation_runs(tmp_path, capsys) -> None:
    """2^31 − 1 is accepted: the per-patch history holds the first sample of its window only."""
    s = tmp_path / "s.toml"
    s.write_text(small_scene_toml("limits", count=40, disc=False, patches=("velocity",)))
    out = tmp_path / "run.h5"
    code, err = run_cli(capsys, ["hf", str(s), "-o", str(out), "--no-progress", "--patch-decimation", str(2**31 - 1)])
    assert code == 0 and not err, err
    with h5py.File(out, "r") as f:
        assert f["patches/velocity"].shape == (1, 40) and f["patches/time"][()].tolist() == [0.0]


@pytest.mark.parametrize(
    ("extra", "message"),
    [  # radii are refused first as implausible (a unit mistake), then, allowed, as too large
        ("[pad]\nr_outer = 1e308\n", "pad.r_outer = 1e+308 m — beyond 2 m"),
        ("[pad]\nr_outer = 1e150\n", "pad.r_outer = 1e+150 m — beyond 2 m"),
        ("[scene]\nallow_implausible = true\n[pad]\nr_outer = 1e308\n", "pad.r_outer = 1e+308 m is too large"),
        ("[scene]\nallow_implausible = true\n[pad]\nr_outer = 1e150\n", "pad.r_outer = 1e+150 m is too large"),
        ('[patches]\nfile = "folder"\n', "is a folder"),
    ],
    ids=["r_outer-1e308", "r_outer-1e150", "r_outer-1e308-allowed", "r_outer-1e150-allowed", "patch-file-folder"],
)
def test_scene_values_one_line(tmp_path, capsys, extra, message) -> None:
    (tmp_path / "folder").mkdir()
    s = tmp_path / "s.toml"
    s.write_text(extra)
    code, err = run_cli(capsys, ["hf", str(s), "-o", str(tmp_path / "run.h5"), "--no-progress"])
    assert code == 2 and len(err) == 1 and message in err[0], err
    assert no_output(tmp_path)


def test_step_counts_beyond_int32(tmp_path, capsys) -> None:
    """A sample interval of more than 2^31 − 1 steps (the on-chip kernel takes it as an int32): one line."""
    s = tmp_path / "s.toml"
    s.write_text(small_scene_toml("limits", count=40, disc=False, duration=1.0e-2, sample_dt=1.0e-2))
    argv = ["hf", str(s), "-o", str(tmp_path / "run.h5"), "--dt", "1e-12", "--no-progress"]
    code, err = run_cli(capsys, argv)  # 1e-2 s samples are implausible for HF (docs/scenes.md)
    assert code == 2 and len(err) == 1 and "record.sample_dt = 0.01 s — beyond 0.001 s" in err[0]
    code, err = run_cli(capsys, [*argv, "--allow-implausible"])
    assert code == 2 and len(err) == 1 and "steps per sample interval = 10000000000 exceeds 2147483647" in err[0]


def test_sample_interval_shorter_than_the_step(tmp_path, capsys) -> None:
    """A sample interval below the step: `[record] sample_dt = 5e-10` (with strang's default 5e-8 s step), `--sample-dt
    5e-10` and a sweep's `run.sample_dt = 5e-10`: one line each, nothing written (before: the step shrank to the
    sample interval, 20 or 1e4 times the steps; sample_dt = 1e-12 hung); `[record] sample_dt = 1e-12`, with or
    without that step asked for (`--dt 1e-12`: 2e8 samples), is refused as implausible (below 1e-10 s,
    docs/scenes.md) unless --allow-implausible."""
    out = ["-o", str(tmp_path / "run.h5"), "--no-progress"]
    for name, sample_dt in (("short", 5.0e-10), ("tiny", 1.0e-12), ("ok", 1.0e-7)):
        (tmp_path / f"{name}.toml").write_text(small_scene_toml(name, count=10, duration=2.0e-4, sample_dt=sample_dt))
    spec = tmp_path / "spec.toml"
    spec.write_text(
        '[sweep]\nbase = "hf1"\n[run]\nsample_dt = 5e-10\nduration = 1e-6\n[parameters]\n"friction.M" = [0.6]'
    )
    for argv, message in (
        (
            ["hf", str(tmp_path / "short.toml"), *out],
            "(--sample-dt, or record.sample_dt in the scene) = 5e-10 s is shorter than the step 5e-08 s",
        ),
        (["hf", str(tmp_path / "ok.toml"), "--sample-dt", "5e-10", *out], "5e-10 s is shorter than the step 5e-08"),
        (["sweep", str(spec), "-o", str(tmp_path / "sweep"), "--workers", "0"], "5e-10 s is shorter than the step"),
        (["hf", str(tmp_path / "tiny.toml"), *out], "record.sample_dt = 1e-12 s — below 1e-10 s"),
        (["hf", str(tmp_path / "tiny.toml"), *out, "--dt", "1e-12"], "record.sample_dt = 1e-12 s — below 1e-10 s"),
    ):
        code, err = run_cli(capsys, argv)
        assert code == 2 and len(err) == 1 and message in err[0], (argv, err)
        assert no_output(tmp_path) and not (tmp_path / "sweep").exists()
