"""``aca_warp.studies.multiscale`` (``scripts/multiscale_study.py``) end to end on a tiny pad: LF, HF on both
snapshots, figures, the docs page."""

from __future__ import annotations

import json
import math

from aca_warp.studies import multiscale as ms

TOML = """
[pad]
r_inner = 0.1
r_outer = 0.11
span_deg = 8.0
[patches]
count = 20
seed = 2
[[schedule]]
kind = "application"
duration = 0.2
pressure_bar = 0.5
"""


def test_tiny_study_with_hf_table(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TOML)
    out, page = tmp_path / "study", tmp_path / "page.md"
    figs = tmp_path / "docs" / "figures"
    argv = ["--scene", str(scene), "--outdir", str(out), "--hf-duration", "5e-5", "--docs", str(page)]
    argv += ["--figures", str(figs)]
    assert ms.main(argv) == 0
    study = json.loads((out / "study.json").read_text())
    assert sorted(study["hf_summary"]) == ["app1_end", "app1_start"]
    for h in study["hf_summary"].values():
        assert h["patches"] > 0 and 0.0 < h["mu_mean"] < 1.0 and h["mu_std"] >= 0.0
        assert h["peak_band_hz"][0] <= h["mu_peak_hz"] <= h["peak_band_hz"][1] and h["mu_peak_amplitude"] > 0
        assert h["S_max"] is None or 0.0 <= h["S_max"] <= 1.0 + 1e-9
    text = page.read_text()
    assert "## HF on the states (paper Fig. 13)" in text and text.count("| app1_") >= 4  # states + HF tables
    assert (figs / "fig13_panel.png").stat().st_size > 0 and (figs / "lf_timeseries.png").stat().st_size > 0
    assert "![fig13_panel.png](docs/figures/fig13_panel.png)" in text
    assert not any(math.isnan(v) for h in study["hf_summary"].values() for v in h.values() if isinstance(v, float))
