"""``aca_warp.studies.hf_study`` (``scripts/hf_study.py``): the HF1-HF4 study and the area sweep, end to end on a
tiny configuration (CPU)."""

from __future__ import annotations

import json
import math

import pytest
from scriptload import load_script

from aca_warp.studies.hf_study.base import fit_power_law, isolated_frequency
from aca_warp.studies.hf_study.cli import main


def test_fit_power_law():
    """The exponent of an exact power law is recovered; two points give no standard error."""
    import numpy as np

    a = np.array([5e-8, 1.25e-7, 3e-7, 6e-7, 1.25e-6])
    fit = fit_power_law(a, 2.0 * a**-0.25)
    assert fit["exponent"] == pytest.approx(-0.25, abs=1e-12)
    assert fit["stderr"] == pytest.approx(0.0, abs=1e-9)
    two = fit_power_law(a[:2], np.array([73e3, 60e3]))
    assert math.isfinite(two["exponent"]) and two["stderr"] is None


def test_isolated_frequency():
    """sqrt(K_T sqrt(A) / (rho_A A)) / 2 pi of the default material: 75.2 kHz at 0.05 mm², 33.6 kHz at 1.25 mm²;
    an explicit material and arrays of areas give the same."""
    import numpy as np

    from aca_warp.scene import Material

    assert isolated_frequency(5e-8, Material()) == pytest.approx(75.2e3, rel=2e-3)
    assert isolated_frequency(1.25e-6) == pytest.approx(33.6e3, rel=2e-3)
    both = isolated_frequency(np.array([5e-8, 1.25e-6]))
    np.testing.assert_allclose(both, [isolated_frequency(5e-8), isolated_frequency(1.25e-6)])
    stiffer = Material(K_T=4 * Material().K_T)
    assert isolated_frequency(5e-8, stiffer) == pytest.approx(2 * isolated_frequency(5e-8))


def test_script_help(capsys):
    """``scripts/hf_study.py`` (loaded as the script, run in this process) is the study's command line."""
    with pytest.raises(SystemExit) as done:
        load_script("hf_study").main(["--help"])
    out = capsys.readouterr().out
    assert done.value.code == 0 and "--sweep-areas" in out and "--archive" in out


def test_tiny_study(tmp_path, capsys):
    """Four presets with 30 patches and two sweep points: summaries, page and the figures asked for are written (one
    kind, the Synchronization Index: every kind of plot_run is drawn by tests/test_report_plots.py; the study passes
    its --figures through and lists and links what plot_run wrote)."""
    out = tmp_path / "study"
    rc = main(
        [
            "--device", "cpu", "--quick", "--duration", "1.2e-4", "--transient", "2e-5", "--dt", "2e-8",
            "--patches", "30", "--sweep-areas", "0.05", "1.25", "--figures", "sync",
            "--outdir", str(out), "--archive", str(tmp_path / "study.tar.gz"),
        ]
    )  # fmt: skip
    assert rc == 0
    assert "hf1: simulating" in capsys.readouterr().out
    study = json.loads((out / "study.json").read_text())
    for key in ("machine", "versions", "settings", "presets", "sweep", "comparisons", "paper", "complete", "command"):
        assert key in study
    assert study["complete"] is True
    assert study["machine"]["device"] == "cpu" and study["versions"]["warp-lang"]
    assert sorted(study["presets"]) == ["hf1", "hf2", "hf3", "hf4"]
    for name, p in study["presets"].items():
        for key in (
            "first_velocity_peak_hz",
            "first_velocity_peak_amplitude",
            "mu_peak_hz",
            "mu_peak_amplitude",
            "mu_mean",
            "S_median_phi_min",
            "S_max_phi_min",
            "S_bins_above_null",
            "S_bins_phi_min",
        ):
            assert key in p, (name, key)
        assert p["scene"]["patches"] == 30
        assert p["first_velocity_peak_hz"] > 0 and 0 < p["mu_mean"] < 1
        for f in p["figures"]:
            assert (out / f).is_file()
        assert sorted(p["figures"]) == [f"{name}_sync.pdf", f"{name}_sync.png"]
    # the large patches (hf2) oscillate lower than the small ones (hf1)
    assert study["presets"]["hf2"]["first_velocity_peak_hz"] < study["presets"]["hf1"]["first_velocity_peak_hz"]
    sweep = study["sweep"]
    assert len(sweep["points"]) == 2
    assert math.isfinite(sweep["fit"]["exponent"]) and -0.6 < sweep["fit"]["exponent"] < 0.0
    assert (out / "area_sweep.png").is_file() and (out / "area_sweep.pdf").is_file()
    claims = [c["claim"] for c in study["comparisons"]]
    assert any("lower M raises S" in c for c in claims) and any("spread S" in c for c in claims)
    page = (out / "results.md").read_text()
    assert "scripts/hf_study.py" in page and "Warp" in page and "73.0 kHz" in page
    assert "](area_sweep.png)" in page and "](hf1_sync.png)" in page
    assert (tmp_path / "study.tar.gz").stat().st_size > 0
