"""``analyze_run`` (/analysis group of a run file), the figures of ``aca_warp.plots`` and their subcommands."""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from procs import one_shard_sweep

from aca_warp import plots
from aca_warp.analysis import report, sync_index_from_signals
from aca_warp.analysis.commands import FIGURE_NAMES, add_parsers
from aca_warp.analysis.report import analyze_run
from aca_warp.common.errors import AcaError, SceneError
from aca_warp.hf.options import RunOptions
from aca_warp.hf.runner import run_scene
from aca_warp.scene import Material, Pad, Patches, PatchGenerator, Record, Scene

SAMPLE_DT = 1.0e-7  # s
SYNC_KEYS = ("rule", "eta", "n_bins", "tau_ab", "tau_bc", "w", "smooth", "null_trials", "seed", "smoothing_weights")


def _small_scene(*, patches: tuple[str, ...]) -> Scene:
    pad = Pad()
    return Scene(
        name="small",
        pad=pad,
        patches=PatchGenerator(count=60, seed=4).generate(pad),
        normal_force=20.0,
        record=Record(sample_dt=SAMPLE_DT, patches=patches),
        duration=1.0e-4,
    )


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Three run files: 60 patches with and without per-patch velocities, and one isolated 0.05 mm² patch."""
    d = tmp_path_factory.mktemp("runs")
    out = {"patches": d / "patches.h5", "globals": d / "globals.h5", "single": d / "single.h5"}
    for key, rec in (("patches", ("velocity",)), ("globals", ())):
        run_scene(
            _small_scene(patches=rec), out[key], RunOptions(integrator="strang", dt=2e-8), device="cpu", overwrite=True
        )
    one = Patches(np.array([0.0]), np.array([0.13]), np.array([5.0e-8]), np.array([3.0e-6]))
    single = Scene(
        name="single",
        pad=Pad(),
        patches=one,
        normal_force=1.0,
        record=Record(sample_dt=SAMPLE_DT, patches=("velocity",)),
        duration=2.0e-4,
    )
    opts = RunOptions(integrator="strang", dt=1e-7)  # the figures need no accuracy
    run_scene(single, out["single"], opts, device="cpu", overwrite=True)
    return out


def _copy(src, tmp_path, name="run.h5"):
    dst = tmp_path / name
    shutil.copy(src, dst)
    return dst


def _snapshot(path, group="analysis"):
    """{dataset: (data, attrs)} and {group: attrs} under ``group`` of an HDF5 file."""
    data, groups = {}, {}
    with h5py.File(path, "r") as f:
        if group not in f:
            return None

        def visit(name, obj):
            attrs = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in obj.attrs.items()}
            if isinstance(obj, h5py.Dataset):
                data[name] = (obj[()], attrs)
            else:
                groups[name] = attrs

        groups[""] = dict(f[group].attrs)
        f[group].visititems(visit)
    return data, groups


def _assert_same(a, b):
    assert a is not None and b is not None
    assert sorted(a[0]) == sorted(b[0]) and sorted(a[1]) == sorted(b[1])
    for name, (arr, attrs) in a[0].items():
        np.testing.assert_array_equal(arr, b[0][name][0], err_msg=name)
        assert attrs == b[0][name][1], name
    for name, attrs in a[1].items():
        assert set(attrs) == set(b[1][name]), name


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


# ---------------------------------------------------------------------------------------------- analyze


def test_analyze_writes_every_group_with_units(runs, tmp_path):
    """/analysis holds spectra, patch spectrum, STFT, CWT, sync, peaks and saturation; every dataset has a unit."""
    path = _copy(runs["patches"], tmp_path)
    groups = analyze_run(path)
    assert set(groups) == {"spectra", "patch_spectrum", "stft", "cwt", "sync", "peaks", "saturation"}
    with h5py.File(path, "r") as f:
        a = f["analysis"]
        assert set(a) == set(groups) and report.TMP_GROUP not in f
        units = {}
        a.visititems(lambda n, o: units.__setitem__(n, o.attrs.get("unit")) if isinstance(o, h5py.Dataset) else None)
        assert units and all(u is not None for u in units.values()), units
        for name in ("freq", *report.GLOBAL_OUTPUTS):
            assert f"spectra/{name}" in a
        for name in report.GLOBAL_OUTPUTS:
            attrs = a[f"spectra/{name}"].attrs
            assert {"window", "scaling", "normalisation", "unit"} <= set(attrs)
        assert a["spectra/mu"].attrs["unit"] == "1" and a["spectra/mu"][0] == pytest.approx(1.0, rel=1e-3)
        assert a["spectra/sum_abs_velocity"].attrs["normalised"]
        assert not a["spectra/sum_velocity"].attrs["normalised"]  # Σu̇ changes sign: physical units
        assert a["spectra/sum_velocity"].attrs["unit"] == "m s-1"
        for tf in ("stft", "cwt"):
            assert {"time", "freq", "amplitude"} <= set(a[tf]) and "caption" in a[tf].attrs
            assert a[f"{tf}/amplitude"].shape == (a[f"{tf}/freq"].size, a[f"{tf}/time"].size)
        assert a["cwt/time"].size <= 2048
        for key in SYNC_KEYS:
            assert key in a["sync"].attrs, key
        assert {"freq", "S", "Phi", "S_null", "R_w"} <= set(a["sync"])
        assert list(a["sync"].attrs["band"]) == [10.0, 200e3]
        peaks = a["peaks"].attrs
        assert peaks["first_velocity_peak_frequency_unit"] == "Hz" and "patch" in peaks["first_velocity_peak_source"]
        assert peaks["first_velocity_peak_amplitude"] > 0
        v = f["patches/velocity"]
        ref = sync_index_from_signals(v, SAMPLE_DT, freq_range=(10.0, 200e3))
        np.testing.assert_array_equal(a["sync/S"][()], ref.S)
        np.testing.assert_array_equal(a["sync/Phi"][()], ref.Phi)
        np.testing.assert_array_equal(a["sync/R_w"][()], ref.R_w)


def test_sync_in_several_passes_is_identical(runs):
    """A band array over the memory budget falls back to sync_index_from_signals: same S, Φ, R_w."""
    with h5py.File(runs["patches"], "r") as f:
        one = report.compute_sync(f, freq_range=(1e3, 1e6))
        many = report.compute_sync(f, freq_range=(1e3, 1e6), max_bytes=4096)
    for key in ("S", "Phi", "R_w", "S_null"):
        np.testing.assert_array_equal(one[key], many[key])


def test_rerun_replaces_the_group(runs, tmp_path):
    """Re-running rewrites /analysis: same content, no duplicates; other options replace, never merge."""
    path = _copy(runs["patches"], tmp_path)
    analyze_run(path)
    first = _snapshot(path)
    analyze_run(path)
    _assert_same(first, _snapshot(path))
    analyze_run(path, sync=False, freq_range=(20e3, 150e3), rule="snr")
    with h5py.File(path, "r") as f:
        assert "sync" not in f["analysis"] and "patch_spectrum" not in f["analysis"]
        assert "Σu̇" in f["analysis/peaks"].attrs["first_velocity_peak_source"]
        assert [k for k in f if "analysis" in k] == ["analysis"]
        assert f["analysis/peaks"].attrs["band"][0] >= 20e3 and f["analysis/peaks"].attrs["band"][1] == 150e3
        assert f["analysis/cwt/freq"][0] >= 20e3 and f["analysis/cwt/freq"][-1] <= 150e3 * (1 + 1e-12)


def test_non_run_files_are_refused_and_left_unchanged(tmp_path):
    """A plain HDF5 file, a text file and a missing path raise SceneError; files keep every byte."""
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["data"] = np.arange(10.0)
    text = tmp_path / "notes.h5"
    text.write_text("not HDF5\n")
    for p, message in ((plain, "not an aca_warp run file"), (text, "not an HDF5 file")):
        before = _sha(p)
        with pytest.raises(SceneError, match=message):
            analyze_run(p)
        assert _sha(p) == before
    with pytest.raises(SceneError, match="not found"):
        analyze_run(tmp_path / "missing.h5")
    with pytest.raises(SceneError, match="not an aca_warp run file"):
        plots.plot_run(plain, tmp_path / "fig")


def test_a_run_file_that_cannot_be_opened_for_writing_says_so(runs, tmp_path, monkeypatch):
    """A run file HDF5 will not open for writing because another process holds it (here a simulated lock error for
    mode "r+"): one SceneError naming the file and HDF5's file lock, with what to do; opening it to read still works.
    Another cause keeps HDF5's first line."""
    from aca_warp.analysis.report import open_run_file

    path = _copy(runs["globals"], tmp_path)
    real = h5py.File

    def refusing(name, mode="r", *args, **kwargs):
        if mode != "r":
            raise OSError("unable to lock file, errno = 11 (simulated)\nsecond line")
        return real(name, mode, *args, **kwargs)

    monkeypatch.setattr(h5py, "File", refusing)
    with pytest.raises(SceneError, match=rf"^another process has {path} open \(HDF5's file lock\): close it there"):
        open_run_file(path, "r+")
    open_run_file(path, "r").close()

    def failing(name, mode="r", *args, **kwargs):
        if mode != "r":
            raise OSError("unable to open file (simulated)\nsecond line")
        return real(name, mode, *args, **kwargs)

    monkeypatch.setattr(h5py, "File", failing)
    with pytest.raises(
        SceneError, match=rf"cannot open run file {path} for writing: unable to open file \(simulated\)$"
    ):
        open_run_file(path, "r+")


def test_a_failed_write_keeps_the_previous_analysis(runs, tmp_path, monkeypatch):
    """If writing fails half-way, the earlier /analysis survives untouched and no temporary group remains."""
    path = _copy(runs["globals"], tmp_path)
    analyze_run(path)
    before = _snapshot(path)
    calls = {"n": 0}
    real = report._write_dataset

    def failing(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 5:
            raise OSError("disk full (simulated)")
        return real(*args, **kwargs)

    monkeypatch.setattr(report, "_write_dataset", failing)
    with pytest.raises(OSError, match="simulated"):
        analyze_run(path, freq_range=(1e3, 1e5))
    _assert_same(before, _snapshot(path))
    with h5py.File(path, "r") as f:
        assert report.TMP_GROUP not in f


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"rule": "majority"}, "rule"),
        ({"eta": 0.0}, "eta"),
        ({"snr": -1.0}, "snr"),
        ({"n_bins": 1}, "n_bins"),
        ({"freq_range": (5e4, 1e4)}, r"0 <= freq_range\[0\] < freq_range\[1\], got 50000 and 10000 Hz$"),
        ({"cwt_count": 0}, "cwt_count must be an integer >= 1, got 0"),
        ({"cwt_columns": 1}, "cwt_columns must be an integer >= 2, got 1"),
        ({"null_trials": -5}, "null_trials must be an integer >= 0, got -5"),
        ({"stft_window_s": -1.0}, "stft_window_s must be a positive window length in s"),
        ({"stft_window_s": 2e-7}, r"STFT of mu: stft_window_s 2e-07 s is 2 samples .* at least 4 samples \(4e-07 s\)"),
        ({"stft_window_s": 1e-4}, r"stft_window_s 0.0001 s is 1000 samples .* holds 1 window of it, .* 2 windows"),
    ],
)
def test_bad_options_are_refused(runs, tmp_path, kwargs, message):
    path = _copy(runs["globals"], tmp_path)
    before = _sha(path)
    with pytest.raises(SceneError, match=message):
        analyze_run(path, **kwargs)
    assert _sha(path) == before


def test_single_patch_peak_is_the_isolated_patch_frequency(runs, tmp_path):
    """One 0.05 mm² patch: the first velocity peak is √(k_T/m)/2π = 75.2 kHz (docs/model.md §2.2) within 2 %.

    Σ|u̇| peaks at twice that frequency (|sin| rectifies), which is why it is not the velocity peak.
    """
    mat, area = Material(), 5.0e-8
    f0 = math.sqrt(mat.K_T * math.sqrt(area) / (mat.mass_per_area * area)) / (2 * math.pi)
    assert f0 == pytest.approx(75.2e3, rel=1e-3)
    path = _copy(runs["single"], tmp_path)
    peaks = analyze_run(path)["peaks"].attrs
    assert "patch" in peaks["first_velocity_peak_source"]
    assert peaks["first_velocity_peak_frequency"] == pytest.approx(f0, rel=0.02)
    assert peaks["sum_velocity_peak_frequency"] == pytest.approx(f0, rel=0.02)
    assert peaks["sum_abs_velocity_peak_frequency"] == pytest.approx(2 * f0, rel=0.02)
    with h5py.File(path, "r") as f:
        assert f["analysis/peaks"].attrs["first_velocity_peak_frequency"] == peaks["first_velocity_peak_frequency"]


# ------------------------------------------------------------------------------------------------ plots


def _check_files(files, expected):
    assert sorted(p.name for p in files) == sorted(expected)
    for p in files:
        head = p.read_bytes()[:8]
        assert p.stat().st_size > 1000, p
        assert head.startswith({".png": b"\x89PNG", ".pdf": b"%PDF", ".gif": b"GIF8"}[p.suffix]), p


def test_plot_run_with_per_patch_velocities(runs, tmp_path):
    """Every figure is made (computing on the fly: the file has no /analysis), PNG + PDF, and the GIF."""
    from matplotlib import animation

    notes = []
    files = plots.plot_run(runs["patches"], tmp_path / "fig", frames=4, log=notes.append)
    names = [n for n in plots.FIGURES if n != "animation"]
    expected = [f"patches_{n}.{ext}" for n in names for ext in ("png", "pdf")]
    if animation.writers.is_available("pillow"):
        expected.append("patches_patch_map.gif")
    else:  # pragma: no cover
        assert any("Pillow" in n for n in notes)
    _check_files(files, expected)
    assert not any("patch_map" in n or "sync" in n for n in notes), notes


def test_plot_run_without_per_patch_velocities(runs, tmp_path):
    """Figures needing per-patch velocities are skipped with a note; asking for one explicitly is an error."""
    path = _copy(runs["globals"], tmp_path, "globals.h5")
    analyze_run(path)  # the figures then read /analysis
    notes = []
    files = plots.plot_run(path, tmp_path / "fig", log=notes.append)
    _check_files(files, [f"globals_{n}.{ext}" for n in ("global", "spectra", "stft", "cwt") for ext in ("png", "pdf")])
    assert sorted(n.split(":")[0] for n in notes) == ["skipped animation", "skipped patch_map", "skipped sync"]
    with pytest.raises(SceneError, match="per-patch velocities"):
        plots.plot_run(path, tmp_path / "fig2", which=["spectra", "sync"])
    assert not (tmp_path / "fig2").exists()
    with pytest.raises(SceneError, match="unknown figure"):
        plots.plot_run(path, tmp_path / "fig2", which=["bode"])


# -------------------------------------------------------------------------------------------------- CLI


def _cli(argv):
    """The dispatch aca_warp.cli.main applies: subcommand handler, AcaError -> one line and 2."""
    parser = argparse.ArgumentParser(prog="aca-warp")
    sub = parser.add_subparsers(dest="command", required=True)
    add_parsers(sub)
    args = parser.parse_args(argv)
    assert args.command in ("analyze", "plot")
    try:
        return args.handler(args)
    except AcaError:
        return 2


def test_a_band_past_either_record_says_where_each_spectrum_ends(tmp_path, capsys):
    """Per-patch velocities every 4th sample (global Nyquist frequency 5 MHz, per-patch 1.25 MHz): a --freq-max above
    either is said with the spectra that end there, S(f)'s band clipped to the per-patch one; a --freq-min that
    empties the peak search's band is named, as is one past the per-patch record."""
    from aca_warp.cli import main

    record = Record(sample_dt=SAMPLE_DT, patches=("velocity",), decimation=4)
    scene = dataclasses.replace(_small_scene(patches=("velocity",)), record=record)
    path = tmp_path / "dec.h5"
    run_scene(scene, path, RunOptions(integrator="strang", dt=1e-7), device="cpu", overwrite=True)
    said = "lies above the Nyquist frequency (half the sampling rate)"
    cases = {
        "1e6": None,
        "2e6": f"--freq-max 2e+06 Hz {said} of the per-patch record, 1250 kHz: S(f) and the per-patch spectrum end "
        "there (the global spectra at 5000 kHz)",
        "6e6": f"--freq-max 6e+06 Hz {said} of the global record, 5000 kHz, and of the per-patch record, 1250 kHz: "
        "the global spectra end at the first, S(f) and the per-patch spectrum at the second",
    }
    for freq_max, line in cases.items():
        assert main(["analyze", str(path), "--freq-max", freq_max]) == 0
        out = capsys.readouterr().out
        assert (line in out) if line else ("Nyquist" not in out), out
        with h5py.File(path, "r") as f:
            assert list(f["analysis/sync"].attrs["band"]) == [10.0, min(float(freq_max), 1.25e6)]
    assert main(["analyze", str(path), "--no-sync", "--freq-min", "6e6", "--freq-max", "7e6"]) == 0
    out = capsys.readouterr().out
    assert f"--freq-max 7e+06 Hz {said} of the global record, 5000 kHz: the global spectra end there\n" in out
    assert (
        "no velocity-spectrum peak: --freq-min 6e+06 Hz lies at or above the global spectra's last bin, 4995 kHz, so "
        "the peak search's band is empty: lower --freq-min\n"
    ) in out
    assert main(["analyze", str(path), "--freq-min", "2e6", "--freq-max", "3e6"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "empty frequency band 2e+06-1.25e+06 Hz for the per-patch velocities (the Nyquist frequency of their "
        "record is 1.25e+06 Hz): lower the band's start, or leave them out (--no-sync)"
    )


def test_commands(runs, tmp_path, capsys):
    """analyze and plot exit 0 and say what they did; bad input exits 2 (argparse or AcaError)."""
    assert FIGURE_NAMES == plots.FIGURES
    path = _copy(runs["patches"], tmp_path)
    assert _cli(["analyze", str(path), "--freq-min", "1e3", "--freq-max", "3e5", "--rule", "snr", "--snr", "4"]) == 0
    out = capsys.readouterr().out
    assert "/analysis written" in out and "first velocity-spectrum peak" in out and "Nyquist" not in out
    with h5py.File(path, "r") as f:
        assert f["analysis/sync"].attrs["rule"] == "snr" and f["analysis/sync"].attrs["snr"] == 4.0
        assert list(f["analysis/sync"].attrs["band"]) == [1e3, 3e5]
    assert _cli(["analyze", str(path), "--no-sync"]) == 0
    assert "not read (--no-sync)" in capsys.readouterr().out
    # a band below 4 periods of the record (1001 samples of 0.1 µs): the CWT keeps to it and says so; the peak
    # search's band, which starts at 3 bins (29.97 kHz), is empty, said too
    assert _cli(["analyze", str(path), "--no-sync", "--freq-min", "5e3", "--freq-max", "2e4"]) == 0
    out = capsys.readouterr().out
    assert "CWT over 5-20 kHz: the record (0.0001001 s) holds fewer than 4 periods below 39.96 kHz" in out
    assert "no velocity-spectrum peak: the peak search's band 29.97-20 kHz is empty" in out
    with h5py.File(path, "r") as f:
        assert f["analysis/cwt/freq"][0] == pytest.approx(5e3) and f["analysis/cwt/freq"][-1] == pytest.approx(2e4)
    # a band above the CWT's top (0.45/Δt = 4.5 MHz, below the Nyquist frequency): the decade below that top, said
    assert _cli(["analyze", str(path), "--no-sync", "--freq-min", "4.6e6", "--freq-max", "4.9e6"]) == 0
    assert "CWT over 450-4500 kHz: the band lies above the CWT's top, 0.45/Δt = 4500 kHz" in capsys.readouterr().out
    assert _cli(["analyze", str(path), "--no-sync", "--freq-max", "1e9"]) == 0  # a band past the samples: said
    said = (
        "--freq-max 1e+09 Hz lies above the Nyquist frequency (half the sampling rate) of the global record, 5000 kHz"
    )
    assert f"{said}: the global spectra end there\n" in capsys.readouterr().out
    assert _cli(["analyze", str(tmp_path / "missing.h5")]) == 2
    assert _cli(["analyze", str(path), "--freq-min", "5e4", "--freq-max", "1e4"]) == 2
    with pytest.raises(SystemExit) as e:
        _cli(["analyze", str(path), "--eta", "1.5"])
    assert e.value.code == 2
    capsys.readouterr()
    from aca_warp.cli import main

    for argv, said in (  # an option that would not act: one line, exit 2, before the file is touched
        (["--snr", "8"], "add --rule snr"),
        (["--rule", "relative", "--snr", "8"], "add --rule snr"),
        (["--rule", "snr", "--eta", "0.2"], "the snr rule takes --snr"),
        (["--no-sync", "--n-bins", "90", "--rule", "snr"], "--rule, --n-bins would not act"),
    ):
        assert main(["analyze", str(path), *argv]) == 2, argv
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and said in lines[0], (argv, lines)
    out_dir = tmp_path / "fig"
    assert _cli(["plot", str(path), "-o", str(out_dir), "--only", "patch_map", "--times", "5e-5", "9e-5"]) == 0
    assert sorted(p.name for p in out_dir.iterdir()) == ["run_patch_map.pdf", "run_patch_map.png"]
    assert _cli(["plot", str(path), "-o", str(out_dir), "--only", "patch_map", "--times", "1.0"]) == 2
    capsys.readouterr()  # an instant outside the record: refused before any figure, the other figures included
    assert main(["plot", str(path), "-o", str(tmp_path / "fig2"), "--times", "5e-5", "1.0"]) == 2
    assert "--times: instant 1 s lies outside the per-patch record" in capsys.readouterr().err
    assert not (tmp_path / "fig2").exists()


def test_analyze_summary_uses_the_figures_band(runs, tmp_path, capsys):
    """The printed largest excess S − S_null (with S and S_null beside it) skips the bins below max(10 Hz, 2 Δf), as
    the figures do, and names that band.

    On this 0.1 ms record (Δf ≈ 10 kHz) bin 1, the Hann leakage of the mean, has the largest S − S_null.
    """
    path = _copy(runs["patches"], tmp_path)
    assert _cli(["analyze", str(path)]) == 0
    out = capsys.readouterr().out
    with h5py.File(path, "r") as f:
        freq, S, s0, phi = (f[f"analysis/sync/{k}"][()] for k in ("freq", "S", "S_null", "Phi"))
    df = (freq[-1] - freq[0]) / (freq.size - 1)
    excess = np.where(np.isfinite(S), S - s0, -np.inf)
    assert freq[np.argmax(excess)] == pytest.approx(df, rel=1e-6), "bin 1 must win without the rule"
    shown = freq > 1.5 * df
    k = int(np.argmax(np.where(shown, excess, -np.inf)))
    assert freq[k] >= 2 * df * (1 - 1e-9)
    said = f"largest excess S - S_null = {S[k] - s0[k]:.3f} (S {S[k]:.3f}, S_null {s0[k]:.3f}, Phi {phi[k]}) at "
    assert said + f"{freq[k] / 1e3:.4g} kHz" in out
    assert f"over {2 * df / 1e3:.4g}-200 kHz" in out and "leakage of the mean" in out
    above = np.count_nonzero((S > s0)[shown & np.isfinite(S)])
    assert f"S > S_null in {above} of {np.count_nonzero(shown & np.isfinite(S))} bins" in out
    lowest = k == int(np.flatnonzero(shown & np.isfinite(S))[0])  # there the record's start-up can win: said so
    assert lowest and freq[k] / df <= 20  # this record: the remark's case
    assert f"(the lowest bin counted, {freq[k] / df:.3g} periods in the record" in out
    band = ["--freq-min", f"{freq[k] * 1.01:.6g}"]  # the winning bin left out: another wins, lowest or not
    assert _cli(["analyze", str(path), *band]) == 0
    out = capsys.readouterr().out
    with h5py.File(path, "r") as f:
        freq, S, s0 = (f[f"analysis/sync/{k}"][()] for k in ("freq", "S", "S_null"))
    counted = (freq >= float(band[1])) & np.isfinite(S)
    k = int(np.argmax(np.where(counted, S - s0, -np.inf)))
    remark = k == int(np.flatnonzero(counted)[0]) and freq[k] / df <= 20
    assert (f"(the lowest bin counted, {freq[k] / df:.3g} periods" in out) == remark


@pytest.mark.parametrize(("lowest", "periods", "said"), [(True, 2.0, True), (True, 20.0, True), (True, 21.0, False),
                                                        (False, 2.0, False)])  # fmt: skip
def test_the_lowest_bin_remark_needs_few_periods(lowest, periods, said):
    """The remark on a shared start-up or drift comes only at the lowest bin counted and with at most 20 periods of
    its frequency in the record (beyond, a Hann-windowed drift has faded)."""
    from aca_warp.analysis.report import lowest_bin_remark

    remark = lowest_bin_remark({"lowest": lowest, "periods": periods})
    assert bool(remark) == said and (not said or f"{periods:.3g} periods in the record" in remark)


def test_a_one_bin_band_names_its_floor_and_plots_no_sync(runs, tmp_path, capsys):
    """A band holding one frequency bin: the summary's floor 2 Δf is the record's (Δf = 1 / (N dt) ≈ 10 kHz, not
    the 10 Hz of a band without a second bin), and the Synchronization Index figure is refused with the note plot
    prints when it skips it (instead of an IndexError); asked for with others, nothing is left behind."""
    path = _copy(runs["patches"], tmp_path)
    assert _cli(["analyze", str(path), "--freq-min", "95e3", "--freq-max", "105e3"]) == 0
    with h5py.File(path, "r") as f:
        assert f["analysis/sync/freq"].shape == (1,)
        n, dt = f["analysis/sync"].attrs["samples"], f["analysis/sync"].attrs["sample_interval"]
    assert f"max(10 Hz, 2 df) = {2 / (n * dt) / 1e3:.4g} kHz" in capsys.readouterr().out
    with pytest.raises(SceneError, match="holds 1 frequency bin.* too few to draw"):  # skipped with this note
        plots.plot_sync(path, tmp_path / "fig")
    assert not (tmp_path / "fig").exists()
    with pytest.raises(SceneError, match="sync: the Synchronization Index holds 1 frequency bin"):
        plots.plot_run(path, tmp_path / "fig2", which=["global", "sync"])
    assert not (tmp_path / "fig2").exists() or not any((tmp_path / "fig2").iterdir())


def test_plot_of_a_ten_sample_run(tmp_path):
    """A run of 10 samples with per-patch velocities: every figure it supports is made, the Synchronization Index
    (no bin above 2 Δf) skipped with a note; no traceback."""
    path = tmp_path / "short.h5"
    scene = _small_scene(patches=()).replace(duration=9e-6, record=Record(sample_dt=1e-6, patches=("velocity",)))
    run_scene(scene, path, RunOptions(integrator="strang", dt=2e-8), device="cpu")
    notes = []
    files = plots.plot_run(path, tmp_path / "fig", frames=2, log=notes.append)
    assert [n.split(":")[0] for n in notes] == ["skipped sync"]
    assert {p.stem.removeprefix("short_") for p in files} == {"patch_map", "global", "spectra", "stft", "cwt"}


def test_the_animation_footer_is_readable_in_its_frame(runs):
    """The GIF's frames are 512 × 288 px; its footer (what the run is, the device) has letters of at least 7 px and
    lies wholly inside the frame, clear of the map's x label."""
    from matplotlib.text import Text

    from aca_warp.plots.hf import GIF_DPI, _Run, animation_figure

    with _Run(runs["patches"]) as run:
        fig, _, count = animation_figure(run, None, None, 3)
        footer = run.footer
    assert count == 3
    fig.canvas.draw()
    w, h = fig.canvas.get_width_height()
    assert (w, h) == (512, 288)
    renderer = fig.canvas.get_renderer()
    (foot,) = [t for t in fig.findobj(Text) if t.get_text().startswith("marker area")]
    assert foot.get_fontsize() * GIF_DPI / 72 >= 7.0
    box = foot.get_window_extent(renderer)
    assert 0 <= box.x0 and box.x1 <= w and 0 <= box.y0 and box.y1 <= h
    assert " ".join(foot.get_text().split()) == " ".join(f"marker area ∝ patch area · {footer}".split())
    xlabel = fig.axes[0].xaxis.label.get_window_extent(renderer)
    assert box.y1 <= xlabel.y0


def test_default_patch_map_instants_are_evenly_spaced_when_decimated(runs, tmp_path):
    """Per-patch histories of every 3rd sample: the default instants stay evenly spaced (a whole number of the
    record's intervals), and the caption gives that spacing against the quarter period it stands for."""
    from aca_warp.plots.hf import _patch_rows, _Run

    path = _copy(runs["patches"], tmp_path)
    with h5py.File(path, "r+") as f:
        for name in ("time", "velocity"):
            data, attrs = f[f"patches/{name}"][::3], dict(f[f"patches/{name}"].attrs)
            del f[f"patches/{name}"]
            f.create_dataset(f"patches/{name}", data=data).attrs.update(attrs)
    with _Run(path) as run:
        rows, how = _patch_rows(run, None)
        pt, fp = run.f["patches/time"][()], run.first_peak()
    gaps = np.diff(pt[rows])
    assert rows.size == 4 and rows[-1] == pt.size - 1 and np.allclose(gaps, gaps[0], rtol=1e-9, atol=0)
    quarter = 0.25 / fp
    assert abs(gaps[0] - quarter) <= 0.5 * 3e-7 + 1e-12
    if abs(gaps[0] - quarter) > 0.02 * quarter:
        assert f"{gaps[0] * 1e6:.4g} µs apart" in how and f"{quarter * 1e6:.4g} µs" in how


def test_analyze_of_an_interrupted_run_says_where_its_record_ends(runs, tmp_path, capsys):
    """An incomplete run (here cut to its first 500 samples and marked interrupted): the summary says the record
    ends early, where, and of what duration; a complete run's summary says nothing of it."""
    path = _copy(runs["globals"], tmp_path)
    assert _cli(["analyze", str(path), "--no-sync"]) == 0
    assert "ends early" not in capsys.readouterr().out
    with h5py.File(path, "r+") as f:
        for d in f["global"].values():
            d.resize(500, axis=0)
        f.attrs["complete"] = False
        f.attrs["status"] = "interrupted by the user"
        end = float(f["global/time"][-1])
    assert _cli(["analyze", str(path), "--no-sync"]) == 0
    out = capsys.readouterr().out
    assert f"the run is incomplete (interrupted by the user): its record ends early, at t = {end:.4g} s of the " in out
    assert "0.0001 s asked" in out


def test_one_pad_of_a_sweep_shard(tmp_path, capsys):
    """analyze/plot of a sweep shard: without --pad one line naming --pad and the shard's pads; with --pad K the
    pad's run file SHARD_padK.h5 (its global series and scene) gets its /analysis, plot draws its global figures
    (the per-patch ones skipped: a shard holds no per-patch data), and rerun of that file repeats the pad; the pad
    file has the predicted growth rates a run of its scene writes. rerun of the shard itself says what to do
    instead."""
    from aca_warp.cli import main

    shard = one_shard_sweep(tmp_path, [0.7, 0.8, 0.9], duration=2e-5)
    capsys.readouterr()
    for argv, said in (
        (["analyze", str(shard)], "is a sweep shard of pads 0-2: analyze one of them with --pad K"),
        (["plot", str(shard), "-o", str(tmp_path / "f")], "is a sweep shard of pads 0-2: plot one of them with --pad"),
        (["analyze", str(shard), "--pad", "3"], "holds pads 0-2; pad 3 is not one of them"),
        (["rerun", str(shard), "-o", str(tmp_path / "r.h5")], "is a sweep shard (pads 0-2), not a run"),
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and said in err[0], err
    assert not (tmp_path / "f").exists() and not (tmp_path / "r.h5").exists()
    assert main(["analyze", str(shard), "--pad", "1"]) == 0
    pad = tmp_path / "sw" / "shard-00000_pad1.h5"
    assert f"{pad} (pad 1 of {shard}): /analysis written" in capsys.readouterr().out
    with h5py.File(shard, "r") as s, h5py.File(pad, "r") as p:
        assert np.array_equal(p["global/mu"][()], s["global/mu"][1]) and "analysis/spectra" in p
        assert json.loads(p.attrs["scene"])["friction"]["M"] == 0.8 and p.attrs["complete"]
    assert main(["plot", str(shard), "--pad", "1", "-o", str(tmp_path / "f"), "--only", "global", "spectra"]) == 0
    names = sorted(f.name for f in (tmp_path / "f").iterdir())
    assert names == [f"shard-00000_pad1_{n}.{e}" for n in ("global", "spectra") for e in ("pdf", "png")]
    assert main(["plot", str(shard), "--pad", "2", "-o", str(tmp_path / "g")]) == 0  # pad 2: a temporary pad file
    err = capsys.readouterr().err  # its skip notes name the pad as given, not the file no one saw
    assert f"skipped patch_map: pad 2 of {shard} holds no per-patch velocities" in err
    assert "shard-00000_pad2.h5" not in err, err
    again = tmp_path / "again.h5"
    assert main(["rerun", str(pad), "-o", str(again), "--no-progress"]) == 0
    with h5py.File(again, "r") as a, h5py.File(pad, "r") as p:
        assert np.allclose(a["global/mu"][()], p["global/mu"][()], rtol=1e-5)
        # the pad's predicted growth rates, as a run of its scene writes them, and the analysis read them
        sigma = p["patches/predicted_growth_rate"][()]
        assert sigma.shape == p["patches/x"].shape and np.array_equal(sigma, a["patches/predicted_growth_rate"][()])
        assert p.attrs["predicted_growth_rate_median"] == a.attrs["predicted_growth_rate_median"]
        assert p["analysis/saturation"].attrs["predicted_source"] == "/patches/predicted_growth_rate"


def test_figures_are_named_for_the_run_also_when_unfinished(runs, tmp_path):
    from aca_warp.plots.figure import run_stem

    assert run_stem("out/k.h5") == run_stem("out/k.h5.partial") == "k"
    assert run_stem("lf.h5") == "lf"
    path = _copy(runs["patches"], tmp_path, "k.h5.partial")
    assert _cli(["plot", str(path), "-o", str(tmp_path / "fig"), "--only", "global"]) == 0
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == ["k_global.pdf", "k_global.png"]


@pytest.mark.parametrize("axis", ["group", "scalar", "text", "2-D"])
def test_times_with_a_crafted_patch_time_axis_give_one_line(runs, tmp_path, capsys, axis):
    """A /patches/time that is no 1-D axis of numbers: `plot --times` ends in one line, as `plot` does without it."""
    from aca_warp.cli import main

    path = _copy(runs["patches"], tmp_path)
    with h5py.File(path, "r+") as f:
        del f["patches/time"]
        if axis == "group":
            f.create_group("patches/time")
        else:
            data = {"scalar": 1e-5, "text": np.array([b"a", b"b"]), "2-D": np.zeros((2, 2))}[axis]
            f["patches/time"] = data
    capsys.readouterr()
    code = main(["plot", str(path), "-o", str(tmp_path / "fig"), "--times", "1e-5"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1 and "patches/" in err[0], err


def test_one_pad_of_a_packed_shard_is_that_pad(tmp_path, capsys, monkeypatch):
    """A sweep packed by size holds pads from anywhere in the sweep in a shard: --pad K takes the row /pads/index
    names (the pad's own series, as load_sweep reads it), refuses a pad the shard does not hold naming those it
    does, finds its earlier extraction however the shard's path is spelled, refuses a pad whose base scene file
    changed since the sweep, and a file system that refuses the write gives one line and exit 4."""
    import errno

    from aca_warp.analysis import pads as pads_module
    from aca_warp.cli import main
    from aca_warp.sweep import load_sweep

    base = tmp_path / "small.toml"
    base.write_text('[scene]\nname = "small"\n[patches]\ncount = 20\n[run]\nduration = 2e-6\n')
    spec = tmp_path / "pack.toml"
    spec.write_text(
        '[sweep]\nbase = "small.toml"\nmode = "zip"\nshard_size = 2\n[run]\nduration = 2e-5\nsample_dt = 1e-6\n'
        '[parameters]\n"patches.count" = [30, 10, 30, 10]\n"patches.seed" = [1, 2, 3, 4]\n'
    )
    out = tmp_path / "sw"
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "0", "--quiet"]) == 0
    shard = out / "shard-00000.h5"
    with h5py.File(shard, "r") as f:
        assert f["pads/index"][()].tolist() == [1, 3]  # the two pads of 10 patches
    capsys.readouterr()
    assert main(["analyze", str(shard), "--pad", "0"]) == 2
    assert f"holds pads 1, 3; pad 0 is not one of them: it is in {out / 'shard-00001.h5'}" in capsys.readouterr().err
    assert main(["analyze", str(shard), "--pad", "3", "--no-sync"]) == 0
    capsys.readouterr()
    mu = load_sweep(out)["mu"]  # (pads, samples) in the sweep's pad order
    with h5py.File(out / "shard-00000_pad3.h5", "r") as p:
        assert np.array_equal(p["global/mu"][()], mu[3]) and json.loads(p.attrs["scene"])["patches"]
        assert len(p["patches/x"]) == 10
    monkeypatch.chdir(out)  # the same shard spelled another way: its extraction is found, not refused
    assert main(["analyze", "shard-00000.h5", "--pad", "3", "--no-sync"]) == 0
    monkeypatch.chdir(tmp_path)

    def refused(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(pads_module, "_write", refused)
    capsys.readouterr()
    assert main(["analyze", str(shard), "--pad", "1", "--no-sync"]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "read-only" in err[0] and not (out / "shard-00000_pad1.h5").exists()
    monkeypatch.undo()
    (tmp_path / "other").mkdir()
    other = one_shard_sweep(tmp_path / "other", [0.7, 0.8], duration=2e-5)  # another sweep, a shard of that name
    shutil.copy(out / "shard-00000_pad3.h5", other.parent / "shard-00000_pad1.h5")
    capsys.readouterr()
    assert main(["analyze", str(other), "--pad", "1", "--no-sync"]) == 2  # not taken for this shard's pad
    assert "is not a pad extracted from" in capsys.readouterr().err
    base.write_text(base.read_text().replace("count = 20", "count = 21"))  # the spec's base file changed
    assert main(["analyze", str(shard), "--pad", "1", "--no-sync"]) == 2
    assert "is not the one it ran" in capsys.readouterr().err


def test_a_failed_analysis_of_a_pad_leaves_no_pad_file(tmp_path, capsys):
    """analyze SHARD --pad K on a pad whose record is too short for the analysis: one line, exit 2, and no
    SHARD_padK.h5 left beside the shard (bad input writes nothing)."""
    from aca_warp.cli import main

    shard = one_shard_sweep(tmp_path, [0.7], duration=2e-6)
    capsys.readouterr()
    assert main(["analyze", str(shard), "--pad", "0"]) == 2
    assert "needs at least" in capsys.readouterr().err
    assert not (shard.parent / "shard-00000_pad0.h5").exists()
    assert main(["plot", str(shard), "--pad", "0", "-o", str(tmp_path / "f"), "--only", "spectra"]) == 2
    err = capsys.readouterr().err
    assert f"pad 0 of {shard}" in err and "tmp" not in err.replace(str(tmp_path), ""), err
    assert main(["analyze", str(tmp_path / "none.h5"), "--pad", "1"]) == 2
    assert "none.h5 not found" in capsys.readouterr().err
    for command in (["analyze"], ["plot", "-o", str(tmp_path / "f")]):  # in a folder that is not there either
        assert main([command[0], str(tmp_path / "nodir" / "run.h5"), *command[1:]]) == 2
        assert f"run file not found: {tmp_path / 'nodir' / 'run.h5'}" in capsys.readouterr().err


def test_a_shard_without_samples_gives_one_line_and_no_pad_file(tmp_path, capsys):
    """analyze/plot SHARD --pad K on the .partial of a sweep stopped before its first samples (an empty /global/time):
    one line saying so and how to complete it, exit 2, nothing written; a pad whose μ is finite nowhere: likewise."""
    from aca_warp.cli import main

    done = one_shard_sweep(tmp_path, [0.7, 0.8], duration=2e-5)
    shard = done.with_name("shard-00000.h5.partial")
    done.rename(shard)
    with h5py.File(shard, "r+") as f:  # as a killed sweep leaves it: the datasets made, no sample appended yet
        for data in f["global"].values():
            data.resize(0, axis=data.ndim - 1)
        f.attrs["complete"] = False
    before = sorted(shard.parent.iterdir())
    capsys.readouterr()
    said = (
        f"aca-warp: error: {shard} holds no sample yet (its sweep stopped before writing any): run the same sweep "
        "command again; it continues the sweep and completes the shard"
    )
    for command in (["analyze"], ["plot", "-o", str(tmp_path / "figs")]):
        assert main([command[0], str(shard), "--pad", "1", *command[1:]]) == 2
        assert capsys.readouterr().err.strip().splitlines() == [said]
        assert sorted(shard.parent.iterdir()) == before and not (tmp_path / "figs").exists()
    with h5py.File(shard, "r+") as f:  # one sample, at which pad 1's μ is not finite
        for data in f["global"].values():
            data.resize(1, axis=data.ndim - 1)
        f["global/mu"][1, 0] = np.nan
    assert main(["analyze", str(shard), "--pad", "1"]) == 2
    said = f"aca-warp: error: pad 1 of {shard} holds no finite sample (μ is not finite from the first one on)"
    assert capsys.readouterr().err.strip() == f"{said}: nothing to take out"
    assert sorted(shard.parent.iterdir()) == before


def test_pad_list_compresses_runs_and_counts_the_rest():
    """One wording of a list of pads, for a shard's refusals and for the pads a fault stopped."""
    from aca_warp.sweep.spec import pad_list

    assert pad_list(np.array([2, 0, 1])) == "0-2"
    assert pad_list(np.array([7, 1, 2, 3, 9, 10, 11, 12])) == "1-3, 7, 9-12"
    many = pad_list(np.arange(1, 60, 2))
    assert many.startswith("1, 3, 5") and many.endswith("… (30 pads; the shard's /pads/index lists them)")
    assert "-." not in many


def test_a_shard_written_before_the_run_settings_were_spelled_out_gives_its_pads(tmp_path, capsys):
    """A shard whose stored spec lacks the step and precision (written before they were spelled out, when the defaults
    were others): its pad is rebuilt with the run settings the shard ran, and extracted; a crafted /pads/index (of
    another length, or a link) makes the file no shard, in one line."""
    from aca_warp.cli import main

    spec = tmp_path / "s.toml"  # run in fp64: today's default for strang is fp32
    spec.write_text(
        '[sweep]\nbase = "hf1"\nshard_size = 2\n[run]\nduration = 2e-5\nsample_dt = 1e-6\nprecision = "fp64"\n'
        '[base.patches]\ncount = 12\n[parameters]\n"friction.M" = [0.7, 0.8]\n'
    )
    assert main(["sweep", str(spec), "-o", str(tmp_path / "sw"), "--workers", "0", "--quiet"]) == 0
    shard = tmp_path / "sw" / "shard-00000.h5"
    with h5py.File(shard, "r+") as f:  # the spec as stored before the run settings were written out
        doc = json.loads(f.attrs["spec"])
        doc["run"].pop("dt", None)
        doc["run"].pop("precision", None)
        f.attrs["spec"] = json.dumps(doc)
    capsys.readouterr()
    assert main(["analyze", str(shard), "--pad", "1", "--no-sync"]) == 0
    with h5py.File(shard, "r+") as f:
        del f["pads/index"]
        f["pads/index"] = np.arange(5)
    assert main(["analyze", str(shard), "--pad", "1", "--no-sync"]) == 2  # no shard now: a run file it is not
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_read_only_folder_refusing_even_the_clean_up_gives_one_line(tmp_path, capsys, monkeypatch):
    """On a read-only file system the write of the pad file fails and so does the removal of its temporary name:
    still one line and exit 4."""
    import errno

    from aca_warp.analysis import pads as pads_module
    from aca_warp.cli import main

    shard = one_shard_sweep(tmp_path, [0.7], duration=2e-5)

    def refused(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    real_unlink = Path.unlink

    def unlink(self, missing_ok=False):
        if self.name.endswith(".new"):
            raise OSError(errno.EROFS, "Read-only file system")
        return real_unlink(self, missing_ok=missing_ok)

    monkeypatch.setattr(pads_module, "_write", refused)
    monkeypatch.setattr(Path, "unlink", unlink)
    capsys.readouterr()
    assert main(["analyze", str(shard), "--pad", "0", "--no-sync"]) == 4
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "read-only" in err[0], err


@pytest.mark.parametrize(("freq", "said"), [(3e6, True), (2e7, True), (2.1e7, False)])
def test_a_peak_with_few_periods_in_the_record_says_so(freq, said):
    """analyze's peak lines: a peak of which a 1 µs record holds at most 20 periods names the bins' width and the
    periods; beyond, nothing is added."""
    from aca_warp.analysis.commands import _few_periods

    clause = _few_periods(freq, 1.0 / (10 * 1e-7))  # the bins of 10 samples 1e-7 s apart
    assert bool(clause) == said
    if said:
        assert clause == f" (bins 1e+03 kHz wide: {freq * 1e-6:.3g} periods in the record)"


def test_numpy_numbers_in_options_are_stored_as_json(runs, tmp_path):
    """NumPy scalars pass the option checks and are stored in ``parameters`` as plain JSON numbers."""
    path = _copy(runs["globals"], tmp_path)
    analyze_run(path, n_bins=np.int64(90), eta=np.float64(0.2), null_trials=np.int64(3), stft_window_s=np.float64(2e-6))
    with h5py.File(path, "r") as f:
        params = json.loads(f["analysis"].attrs["parameters"])
    assert params["n_bins"] == 90 and params["eta"] == 0.2 and params["null_trials"] == 3
    assert params["stft_window_s"] == 2e-6


def test_plot_api_refuses_bad_animation_counts_and_takes_one_name_as_a_string(runs, tmp_path):
    from aca_warp.plots.hf import animate_patch_map

    with pytest.raises(SceneError, match="fps must be an integer >= 1, got 0"):
        animate_patch_map(runs["patches"], tmp_path / "a", fps=0)
    with pytest.raises(SceneError, match="frames must be an integer >= 2, got 0"):
        animate_patch_map(runs["patches"], tmp_path / "a", frames=0)
    files = plots.plot_run(runs["globals"], tmp_path / "s", which="spectra")
    assert sorted(p.name for p in files) == ["globals_spectra.pdf", "globals_spectra.png"]


def test_a_band_edge_is_no_peak_and_is_said_to_be_one(monkeypatch, tmp_path):
    """The largest bin of a band that sits on its lower edge of a falling spectrum is flagged in /analysis/peaks, in
    the summary line and in the spectra figure's caption; an interior maximum is not."""
    from matplotlib.figure import Figure

    from aca_warp.analysis.commands import peak_lines
    from aca_warp.plots import hf

    freq = np.arange(0, 401) * 5.0e3
    falling = 1.0 / (1.0 + freq / 1e4)
    bump = falling + 0.5 * np.exp(-(((freq - 150e3) / 8e3) ** 2))
    spectra = report.Group(attrs={"samples": 800, "sample_interval": 2.5e-7})
    spectra.add("freq", freq, "Hz")
    for name, a in (("mu", falling), ("sum_velocity", falling), ("sum_abs_velocity", bump)):
        spectra.add(name, a, "1")
    peaks = report.compute_peaks(spectra, freq_range=(1.2e5, 2e5))
    a = peaks.attrs
    assert a["first_velocity_peak_frequency"] == 120e3 and a["first_velocity_peak_at_band_edge"] == "lower"
    assert a["mu_peak_at_band_edge"] == "lower" and a["sum_abs_velocity_peak_at_band_edge"] == "no"
    lines = peak_lines({"peaks": peaks, "spectra": spectra})
    assert lines[0] == (
        "first velocity-spectrum peak 120 kHz (at the band's lower edge: no peak inside the band), of the Σu̇ spectrum "
        "(the paper's Fig. 8)"
    )
    assert lines[1].startswith("largest mu peak 120 kHz (at the band's lower edge: no peak inside the band)")
    axes = Figure().subplots(2, 1)
    text = hf._mark_velocity_peak(axes, peaks)
    assert "120 kHz, at the band's lower edge: no peak inside the band" in text
    assert "(120 kHz – 200 kHz)" in text
    inside = report.compute_peaks(spectra, freq_range=(1e5, 2e5))  # the bump is the Σ|u̇| peak, not an edge
    assert inside.attrs["sum_abs_velocity_peak_frequency"] == pytest.approx(150e3, rel=1e-3)
    assert inside.attrs["sum_abs_velocity_peak_at_band_edge"] == "no"


def test_the_per_patch_peak_line_uses_the_per_patch_bin_width():
    """A per-patch spectrum coarser than the global one (``--patch-window``/``--patch-decimation``): the summary's bin
    width and period count are those of the per-patch spectrum the peak comes from."""
    from aca_warp.analysis.commands import peak_lines

    spectra = report.Group(attrs={"samples": 1001, "sample_interval": 2e-7})  # Δf 4995 Hz
    spectra.add("freq", np.arange(501) * 4995.0, "Hz")
    patch = report.Group(attrs={"sample_interval": 6e-7})
    patch.add("freq", np.arange(84) * 9980.0, "Hz")  # Δf 9980 Hz
    peaks = report.Group(
        attrs={
            "first_velocity_peak_frequency": 73.73e3,
            "first_velocity_peak_source": "mean per-patch velocity amplitude spectrum (/analysis/patch_spectrum)",
            "first_velocity_peak_at_band_edge": "no",
            "sum_velocity_peak_frequency": 71.9e3,
            "sum_velocity_peak_at_band_edge": "lower",
            "mu_peak_frequency": 72.22e3,
            "mu_peak_at_band_edge": "no",
        }
    )
    lines = peak_lines({"peaks": peaks, "spectra": spectra, "patch_spectrum": patch})
    assert lines[0] == (
        "first velocity-spectrum peak 73.73 kHz (bins 9.98 kHz wide: 7.39 periods in the record), of the mean "
        "per-patch velocity spectrum; the Σu̇ spectrum's (the paper's Fig. 8): 71.9 kHz (at the band's lower edge: no "
        "peak inside the band) (bins 5 kHz wide: 14.4 periods in the record)"
    )
    assert lines[1] == "largest mu peak 72.22 kHz (bins 5 kHz wide: 14.5 periods in the record)"
    alone = peak_lines({"peaks": peaks, "spectra": spectra})[0]  # without the per-patch group: named by its source
    assert "of the mean per-patch velocity spectrum; the Σu̇ spectrum's" in alone, alone


def test_the_sync_caption_gives_the_band_with_units(runs, monkeypatch, tmp_path):
    """The band of the sync figure's caption carries a unit on each edge: 10 Hz – 200 kHz, not "10–200 kHz"."""
    from aca_warp.plots import hf

    assert (hf._hz(10.0), hf._hz(2.0e4), hf._hz(2.0e5), hf._hz(2.5e6)) == ("10 Hz", "20 kHz", "200 kHz", "2.5 MHz")
    captions = []
    monkeypatch.setattr(hf._Run, "save", lambda self, fig, caption, outdir, name: captions.append(caption) or [])
    hf.plot_sync(runs["patches"], tmp_path)
    assert "Band 10 Hz – 200 kHz, Δf" in captions[0]


def test_a_run_named_without_its_partial_says_where_it_is(runs, tmp_path, capsys):
    """``analyze RUN.h5``/``plot RUN.h5`` where only RUN.h5.partial exists: one line naming the .partial and what to
    do; a folder is called one."""
    from aca_warp.cli import main

    _copy(runs["globals"], tmp_path, "cut.h5.partial")
    run = tmp_path / "cut.h5"
    for argv in (["analyze", str(run)], ["plot", str(run), "-o", str(tmp_path / "fig")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"{run}.partial exists (a run still being written, or one stopped or killed" in err
        said = f"analyse or plot {run}.partial itself, or continue it from t = 0 with 'aca-warp hf --resume {run}'"
        assert said in err
    assert main(["analyze", str(tmp_path)]) == 2
    assert f"{tmp_path} is a folder, not a run file" in capsys.readouterr().err
    sweep = tmp_path / "sw"  # a sweep's folder: how to read it
    sweep.mkdir()
    (sweep / "manifest.json").write_text("{}")
    (sweep / "shard-00003.h5").touch()
    for argv in (["analyze", str(sweep)], ["plot", str(sweep), "-o", str(tmp_path / "fig")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert (
            f"{sweep} is a sweep's folder, not a run file: take one pad of a shard (e.g. {sweep}/shard-00003.h5 " in err
        )
        assert f"--pad K), or read the whole sweep in Python with aca_warp.sweep.load_sweep('{sweep}')" in err


@pytest.mark.parametrize("slash", ["", "/"])
def test_analyze_run_calls_a_folder_no_run_file(tmp_path, slash):
    """The Python API says of a folder what the command line says: it is no run file (not an output to rename)."""
    said = f"{tmp_path} is a folder, not a run file: name the run file (RUN.h5) inside it"
    with pytest.raises(SceneError) as e:
        analyze_run(f"{tmp_path}{slash}")
    assert str(e.value) == said
    assert list(tmp_path.iterdir()) == []


def test_one_per_patch_sample_is_said_in_the_singular(tmp_path, capsys):
    """A per-patch record of one row (decimation beyond the record): plot --only patch_map says "1 per-patch sample"."""
    from aca_warp.cli import main

    record = Record(sample_dt=SAMPLE_DT, patches=("velocity",), decimation=100)
    scene = dataclasses.replace(_small_scene(patches=("velocity",)), record=record, duration=10 * SAMPLE_DT)
    run = tmp_path / "one.h5"
    run_scene(scene, run, RunOptions(integrator="strang", dt=2e-8), device="cpu", overwrite=True)
    assert main(["plot", str(run), "-o", str(tmp_path / "f"), "--only", "patch_map"]) == 2
    said = f"patch_map: {run} holds 1 per-patch sample; the per-patch figures need at least 8"
    assert capsys.readouterr().err.strip().endswith(said)


def test_a_record_too_short_for_the_transforms_still_plots_its_series(tmp_path, capsys):
    """A run of 6 samples: analyze refuses it (the transforms need 8), plot draws its global series and skips the
    transforms' and the per-patch figures saying why; --only naming a transform is refused in one line with nothing
    written (all or nothing); a run of 1 sample gives no figure at all."""
    from dataclasses import replace

    from aca_warp.cli import main

    short = tmp_path / "short.h5"
    scene = replace(_small_scene(patches=("velocity",)), duration=5 * SAMPLE_DT)
    run_scene(scene, short, RunOptions(integrator="strang", dt=2e-8), device="cpu", overwrite=True)
    assert main(["analyze", str(short)]) == 2
    assert "holds 6 samples; the analysis needs at least 8" in capsys.readouterr().err
    out = tmp_path / "fig"
    assert main(["plot", str(short), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["short_global.pdf", "short_global.png"]
    for name in ("spectra", "sync", "stft", "cwt"):
        assert f"skipped {name}: {short} holds 6 samples; spectra, time-frequency maps and S(f) need at least 8" in err
    for name in ("patch_map", "animation"):  # its per-patch velocities are there, too few for the default instants
        assert f"skipped {name}: {short} holds 6 per-patch samples; the per-patch figures need at least 8" in err
    assert main(["plot", str(short), "-o", str(tmp_path / "only"), "--only", "global"]) == 0
    assert main(["plot", str(short), "-o", str(tmp_path / "two"), "--only", "global", "stft"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[-1].endswith(f"stft: {short} holds 6 samples; spectra, time-frequency maps and S(f) need at least 8")
    assert not (tmp_path / "two").exists() or not list((tmp_path / "two").iterdir())
    assert main(["plot", str(short), "-o", str(tmp_path / "two"), "--only", "stft", "patch_map"]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]  # each reason with the figures it keeps out
    assert f"stft: {short} holds 6 samples;" in line and f"; patch_map: {short} holds 6 per-patch samples;" in line
    for draw in (plots.plot_spectra, plots.plot_stft, plots.plot_cwt):  # the figures' own API refuses it too
        with pytest.raises(SceneError, match="holds 6 samples; the analysis needs at least 8"):
            draw(short, tmp_path / "api")
    one = _copy(short, tmp_path, "one.h5")
    with h5py.File(one, "a") as f:  # its global series cut to the first sample
        for k in list(f["global"]):
            first = f["global"][k][:1]
            del f["global"][k]
            f["global"][k] = first
    assert main(["plot", str(one), "-o", str(tmp_path / "none")]) == 2
    assert "holds 1 sample; a figure needs at least 2" in capsys.readouterr().err


def _digests(folder: Path) -> dict[str, str]:
    """{file name: MD5} of every file in ``folder``, hidden ones included."""
    return {p.name: hashlib.md5(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def _interrupt_after_global(monkeypatch) -> None:
    """Ctrl-C in the spectra's figure maker, the one drawn after ``global``: it raises KeyboardInterrupt."""

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, "plot_spectra", stopped)


def test_an_interrupted_plot_keeps_the_figures_finished_before_it(runs, tmp_path, monkeypatch, capsys):
    """Ctrl-C while the second figure is drawn, without --only: exit 130, one line saying that the figures finished
    before it are in the folder, and there they are (global's), nothing half written."""
    from aca_warp.cli import main

    _interrupt_after_global(monkeypatch)
    figs = tmp_path / "figs"
    assert main(["plot", str(runs["globals"]), "-o", str(figs)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    finished = f"the figures finished before it are in {figs}, each whole, its PNG and PDF together"
    assert err[-1] == f"aca-warp: interrupted (Ctrl-C); {finished}"
    assert sorted(_digests(figs)) == ["globals_global.pdf", "globals_global.png"]


def test_an_interrupt_while_the_pdf_is_drawn_leaves_neither_file(tmp_path, monkeypatch):
    """A figure's PNG and PDF come together: Ctrl-C while the PDF is drawn leaves neither (before, the PNG was
    already in place), nor a temporary file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from aca_warp.plots import figure

    fig = plt.figure()
    real = fig.savefig

    def stopped(fh, format, **kw):  # noqa: A002
        if format == "pdf":
            raise KeyboardInterrupt
        real(fh, format=format, **kw)

    monkeypatch.setattr(fig, "savefig", stopped)
    with pytest.raises(KeyboardInterrupt):
        figure.save(fig, tmp_path / "figs", "x")
    assert list((tmp_path / "figs").iterdir()) == []
    monkeypatch.setattr(fig, "savefig", real)
    assert [p.name for p in figure.save(fig, tmp_path / "figs", "x")] == ["x.png", "x.pdf"]
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == ["x.pdf", "x.png"]
    plt.close(fig)


def test_an_interrupted_plot_only_puts_back_the_earlier_figures(runs, tmp_path, monkeypatch, capsys):
    """Ctrl-C while the second figure named with --only is drawn: exit 130, one line saying that none of its figures
    is left, and the folder as an earlier plot left it, byte for byte (its global figures put back, no hidden copy)."""
    from aca_warp.cli import main

    figs = tmp_path / "figs"
    assert main(["plot", str(runs["globals"]), "-o", str(figs), "--only", "global"]) == 0
    earlier = _digests(figs)
    _interrupt_after_global(monkeypatch)
    capsys.readouterr()
    assert main(["plot", str(runs["globals"]), "-o", str(figs), "--only", "global", "spectra"]) == 130
    assert capsys.readouterr().err.strip().splitlines() == [
        f"aca-warp: interrupted (Ctrl-C); none of its figures is left in {figs} (--only: all or nothing; an earlier "
        "plot's figures it had replaced are back)"
    ]
    assert _digests(figs) == earlier


@pytest.mark.parametrize("after", [1, 2], ids=["while-letting-go", "after-letting-go"])
def test_a_signal_once_plot_only_has_written_its_figures_does_not_undo_them(runs, tmp_path, monkeypatch, capsys, after):
    """SIGINT while ``plot --only`` lets go the two earlier figures its own replaced (after the first), or once it
    has: its figures are final, so the signal does not stop the command (exit 0, no "none of its figures is left";
    the signal recorded for the exit's line) and no earlier figure is left under a hidden name."""
    import os
    import signal
    import time

    from aca_warp.cli import main
    from aca_warp.common import files, interrupts

    figs = tmp_path / "figs"
    assert main(["plot", str(runs["globals"]), "-o", str(figs), "--only", "global"]) == 0
    capsys.readouterr()

    def commit(book) -> None:  # _Writes.commit, with SIGINT after the ``after``-th earlier file is let go
        for i, kept in enumerate(book.earlier.values(), start=1):
            kept.unlink()
            if i == after:
                os.kill(os.getpid(), signal.SIGINT)
                end = time.monotonic() + 0.05
                while time.monotonic() < end:  # ordinary code, where the signal's handler runs
                    time.sleep(0.001)

    monkeypatch.setattr(files._Writes, "commit", commit)
    try:
        code = main(["plot", str(runs["globals"]), "-o", str(figs), "--only", "global"])
        err = capsys.readouterr().err
        assert code == 0 and "interrupted" not in err, err
        assert interrupts._late == [signal.SIGINT]
    finally:
        interrupts._late.clear()
    assert sorted(_digests(figs)) == ["globals_global.pdf", "globals_global.png"]  # no hidden copy
