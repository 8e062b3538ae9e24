"""Figures of LF run files (``aca-warp plot LF.h5``) and the refusal of ``aca-warp analyze`` on them.

A tiny LF run (10 mm × ~14 mm pad, 150 cells, 40 steps, 4 snapshots) takes well under a second on the CPU.
"""

from __future__ import annotations

import argparse
import hashlib

import h5py
import numpy as np
import pytest

from aca_warp import plots
from aca_warp.analysis.commands import FIGURE_NAMES, LF_FIGURE_NAMES, LF_QUANTITIES, add_parsers
from aca_warp.common.errors import SceneError
from aca_warp.plots import lf as plots_lf

DOC = {
    "scene": {"name": "tiny"},
    "pad": {"r_inner": 0.100, "r_outer": 0.110, "span_deg": 8.0},
    "patches": {"count": 40, "area_min": 2e-8, "area_max": 8e-8, "height": 3e-6, "seed": 3},
    "lf": {"capacity": 1024, "wear_m": 2e-12, "p_store": 0.3, "p_birth": 1.0, "p_comp": 1e4, "lam0": 2.0},
    "snapshots": {"applications": True, "times": [0.1]},
    "schedule": [
        {"kind": "application", "duration": 0.2, "normal_force": 300.0, "ramp": 0.05},
        {"kind": "pause", "duration": 0.05},
        {"kind": "application", "duration": 0.15, "normal_force": 1500.0},
    ],
}


@pytest.fixture(scope="module")
def lf_run(tmp_path_factory):
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.scene import lf_scene_from_dict

    out = tmp_path_factory.mktemp("lf") / "lf.h5"
    run_lf(lf_scene_from_dict(DOC), out)
    return out


@pytest.fixture(scope="module")
def hf_run(tmp_path_factory):
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.runner import run_scene
    from aca_warp.scene import Pad, PatchGenerator, Record, Scene

    pad = Pad()
    scene = Scene(
        name="small", pad=pad, patches=PatchGenerator(count=20, seed=4).generate(pad), normal_force=20.0,
        record=Record(sample_dt=1e-7), duration=2e-6,
    )  # fmt: skip
    out = tmp_path_factory.mktemp("hf") / "hf.h5"
    run_scene(scene, out, RunOptions(integrator="strang", dt=2e-8), device="cpu")
    return out


def _check_files(files, expected):
    assert sorted(p.name for p in files) == sorted(expected)
    for p in files:
        assert p.stat().st_size > 1000, p
        assert p.read_bytes()[:8].startswith({".png": b"\x89PNG", ".pdf": b"%PDF"}[p.suffix]), p


def _cli(argv):
    parser = argparse.ArgumentParser(prog="aca-warp")
    add_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.handler(args)
    except SceneError as e:
        print(f"aca-warp: error: {e}")
        return 2


def test_plot_writes_every_lf_figure(lf_run, tmp_path):
    """An LF file is recognised by kind = "lf": the three LF figures, PNG + PDF, none of the HF ones."""
    notes = []
    files = plots.plot_run(lf_run, tmp_path / "fig", log=notes.append)
    _check_files(files, [f"lf_{n}.{ext}" for n in plots_lf.LF_FIGURES for ext in ("png", "pdf")])
    assert notes == []


def test_a_damaged_lf_file_skips_or_refuses_the_figure_it_breaks(lf_run, tmp_path, capsys):
    """A snapshot group damaged after the global series: the figure that reads it is skipped with a note naming the
    file (exit 0, the others drawn), or, named with --only, refused in one line (exit 2) with the figures of the
    call removed again and the earlier figures they replaced put back (all or nothing), as for HF run files; --times
    on an LF file names --snapshots."""
    import shutil

    damaged = tmp_path / "damaged.h5"
    shutil.copy(lf_run, damaged)
    with h5py.File(damaged, "a") as f:
        for name in f["snapshots"]:
            del f[f"snapshots/{name}/matrix"]
    out = tmp_path / "fig"
    assert _cli(["plot", str(damaged), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "skipped lf_population: cannot read run file" in err and "damaged or incomplete" in err
    assert (out / "damaged_lf_global.png").exists() and not (out / "damaged_lf_population.png").exists()
    out2 = tmp_path / "fig2"
    assert _cli(["plot", str(damaged), "-o", str(out2), "--only", "lf_global", "lf_population"]) == 2
    assert "damaged or incomplete" in capsys.readouterr().out
    assert not out2.exists() or not list(out2.iterdir())
    # an earlier plot's figure that this call replaced before it failed is put back, byte for byte
    earlier = {p.name: p.read_bytes() for p in out.iterdir()}
    assert _cli(["plot", str(damaged), "-o", str(out), "--only", "lf_global", "lf_population"]) == 2
    capsys.readouterr()
    assert {p.name: p.read_bytes() for p in out.iterdir()} == earlier  # nothing left beside them, hidden or not
    assert _cli(["plot", str(lf_run), "-o", str(out), "--times", "0.1"]) == 2
    assert "panels with snapshots=[…], not times=[…]" in capsys.readouterr().out  # the Python API's names here


def test_only_selects_among_the_lf_figures(lf_run, hf_run, tmp_path, capsys):
    out = tmp_path / "fig"
    argv = ["plot", str(lf_run), "-o", str(out), "--only", "lf_patch_map", "--quantity", "thickness"]
    assert _cli([*argv, "--snapshots", "app1_end", "app2_end"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["lf_lf_patch_map.pdf", "lf_lf_patch_map.png"]
    assert _cli(["plot", str(lf_run), "-o", str(out), "--only", "lf_global", "lf_population"]) == 0
    assert len(list(out.iterdir())) == 6
    capsys.readouterr()
    # HF figures on an LF file, LF figures on an HF file, unknown snapshots, HF options: one line, exit 2
    for argv, message in (
        (["plot", str(lf_run), "-o", str(out), "--only", "global"], "is an LF run file"),
        (["plot", str(hf_run), "-o", str(out), "--only", "lf_global"], "LF figures need an LF run file"),
        (["plot", str(lf_run), "-o", str(out), "--snapshots", "app9_end"], "no snapshot app9_end"),
        (["plot", str(lf_run), "-o", str(out), "--times", "0.1"], "not times"),
        (["plot", str(hf_run), "-o", str(out), "--quantity", "age"], "not an LF run file"),
    ):
        assert _cli(argv) == 2
        lines = capsys.readouterr().out.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], lines
    assert len(list(out.iterdir())) == 6


def test_plot_help_lists_the_lf_figures(capsys):
    assert LF_FIGURE_NAMES == plots_lf.LF_FIGURES and FIGURE_NAMES == plots.FIGURES
    assert LF_QUANTITIES == tuple(plots_lf.QUANTITIES)
    with pytest.raises(SystemExit):
        _cli(["plot", "--help"])
    text = capsys.readouterr().out
    for name in LF_FIGURE_NAMES + LF_QUANTITIES:
        assert name in text, name


def test_patch_map_draws_every_patch_at_its_place_and_value(lf_run):
    """Disc centres, diameters (∝ √A, one magnification) and colours are the snapshot's, with units on the axes."""
    fig = plots_lf.lf_figure(lf_run, "lf_patch_map", quantity="pressure", snapshots=["app2_end", "app1_start"])
    maps = [ax for ax in fig.axes if ax.collections and ax.get_label() != "<colorbar>"]
    assert len(maps) == 2
    grow = None
    with h5py.File(lf_run, "r") as f:
        for ax, name in zip(maps, ("app2_end", "app1_start"), strict=True):
            p = f[f"snapshots/{name}/patches"]
            (coll,) = ax.collections
            np.testing.assert_allclose(coll.get_offsets(), 1e3 * np.column_stack([p["x"][()], p["y"][()]]))
            np.testing.assert_allclose(coll.get_array(), 1e-6 * p["normal_force"][()] / p["area"][()], rtol=1e-12)
            ratio = coll.get_widths() / (2e3 * np.sqrt(p["area"][()] / np.pi))
            grow = ratio[0] if grow is None else grow
            np.testing.assert_allclose(ratio, grow, rtol=1e-12)
            assert name in ax.get_title() and ax.get_xlabel() == "x [mm]" and ax.get_ylabel() == "y [mm]"
    assert grow >= 1.0
    (bar,) = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert bar.get_xlabel() == "patch contact pressure F_N,i / A_i [MPa]"


def test_time_series_hide_pauses_and_label_units(lf_run):
    fig = plots_lf.lf_figure(lf_run, "lf_global")
    axes = [ax for ax in fig.axes if ax.get_ylabel()]
    labels = [ax.get_ylabel() for ax in axes]
    assert labels == ["clamp force F_N [kN]", "μ [1]", "friction torque T [N m]", "r_eff [mm]", "temperature [K]"]
    with h5py.File(lf_run, "r") as f:
        mu, load = f["global/mu"][()], f["global/normal_force"][()]
    drawn = axes[1].lines[0].get_ydata()
    assert np.count_nonzero(load == 0) == 5
    np.testing.assert_array_equal(np.isnan(drawn), load == 0)  # μ = 0 in pauses is not drawn
    np.testing.assert_array_equal(drawn[load > 0], mu[load > 0])
    pop = plots_lf.lf_figure(lf_run, "lf_population")
    ylabels = [ax.get_ylabel() for ax in pop.axes if ax.get_ylabel()]
    assert ylabels == ["alive patches [1]", "[%]", "cumulative count [1]", "mass [µg]", "mean patch\nthickness [µm]"]


def test_analyze_refuses_an_lf_file_in_one_line(lf_run, capsys):
    before = hashlib.sha256(lf_run.read_bytes()).hexdigest()
    assert _cli(["analyze", str(lf_run)]) == 2
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and "HF run files" in lines[0] and f"aca-warp plot {lf_run}" in lines[0], lines
    assert hashlib.sha256(lf_run.read_bytes()).hexdigest() == before


def test_hf_and_lf_footers_name_the_processor_alike(lf_run, hf_run):
    """Both footers name the CPU the run ran on the same way: "device cpu (<processor>, <n> cores)"."""
    from aca_warp.common.files import host_cpu
    from aca_warp.plots.hf import _Run

    want = f" · device cpu ({host_cpu()}) · "
    with _Run(hf_run) as run:
        assert want in run.footer, run.footer
    with plots_lf._LFRun(lf_run) as run:
        assert want in run.footer, run.footer


def test_a_run_without_snapshots_names_both_reasons(tmp_path, capsys):
    """An LF run that ends before its first snapshot (the tiny scene's first is due at 0.1 s): the patch map is
    skipped with a line naming both reasons a file can hold none, not only a scene that asked for none."""
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.scene import lf_scene_from_dict

    short = tmp_path / "short.h5"
    run_lf(lf_scene_from_dict(DOC), short, duration=0.05)
    with h5py.File(short) as f:
        assert len(f["snapshots"]) == 0
    capsys.readouterr()
    assert _cli(["plot", str(short), "-o", str(tmp_path / "fig")]) == 0
    err = capsys.readouterr().err
    assert "skipped lf_patch_map: short.h5 holds no snapshots (the run ended before its first snapshot was due" in err
