"""``aca_warp.studies.work_precision_stats`` (``scripts/work_precision_stats.py``) with its rule and report modules:
the error/σ bookkeeping on ensembles whose answer is known, the rule's choice, the grid syntax (a new integrator
name enters without a change), the per-pad measures, the page from a synthetic result, and one tiny run on the
CPU end to end."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
import scipy.stats

from aca_warp.studies import work_precision_stats as wps
from aca_warp.studies import work_precision_stats_report as wps_report
from aca_warp.studies import work_precision_stats_rule as rule


def test_compare_known_ensemble():
    """A setting whose every seed is the reference's + 0.3: error 0.3 with no noise (bound = low = 0.3), σ the
    reference's sample std, the 95 % half-width t·σ/√n; seed-by-seed noise of zero mean leaves no error but a bound
    of t·sd/√n; a vector measure gives the rms over its components; a seed missing in either ensemble is left out."""
    rng = np.random.default_rng(4)
    ref = rng.normal(5.0, 2.0, 40)
    t = scipy.stats.t.ppf(0.975, 39)
    c = rule.compare(ref, ref + 0.3)
    sd = ref.std(ddof=1)
    assert c.n == 40
    assert c.error == pytest.approx(0.3, rel=1e-12) and c.bound == pytest.approx(0.3) and c.low == pytest.approx(0.3)
    assert c.sigma == pytest.approx(sd, rel=1e-12)
    assert c.ratio == pytest.approx(0.3 / sd, rel=1e-12)
    assert c.half_width == pytest.approx(t * sd / math.sqrt(40), rel=1e-9)
    assert c.paired_se == pytest.approx(0.0, abs=1e-12)
    assert c.reference_mean == pytest.approx(ref.mean(), rel=1e-12)
    noise = np.tile([0.5, -0.5], 20)
    d = rule.compare(ref, ref + noise)
    se = 0.5 * math.sqrt(40 / 39) / math.sqrt(40)
    assert d.error == pytest.approx(0.0, abs=1e-12) and d.paired_se == pytest.approx(se, rel=1e-12)
    assert d.bound == pytest.approx(t * se, rel=1e-9) and d.low == 0.0
    vec = np.stack([ref, 2 * ref], axis=1)
    v = rule.compare(vec, vec + [0.3, 0.4])
    assert v.error == pytest.approx(math.sqrt((0.09 + 0.16) / 2), rel=1e-12)
    assert v.sigma == pytest.approx(math.sqrt((sd**2 + 4 * sd**2) / 2), rel=1e-12)
    assert v.reference_mean == pytest.approx(1.5 * ref.mean(), rel=1e-12)
    bad = ref + 0.3
    bad[0] = np.nan
    e = rule.compare(ref, bad)
    assert e.n == 39 and e.sigma == pytest.approx(ref[1:].std(ddof=1), rel=1e-12)
    assert math.isnan(rule.compare(ref[:1], ref[:1]).ratio)


def _setting(label: str, role: str, wall: float, values: dict, complete: bool = True) -> dict:
    name, _, rest = label.partition("@")
    return {"label": label, "role": role, "integrator": name, "precision": rest.split(":")[0], "wall_s": wall,
            "complete": complete, "values": values if complete else None, "steps": 1}  # fmt: skip


T29 = scipy.stats.t.ppf(0.975, 29)


def synthetic_regime(seeds: int = 30) -> dict:
    """A regime with μ std (σ ≈ 1) and Φ (σ ≈ 2) over ``seeds`` pads. A setting's values are the reference's +
    bias·σ + c·σ·z (z of mean 0 and standard deviation 1 over the seeds), so its bound/σ is bias + c·t/√n. Settings
    (wall; μ std bias, c; Φ bias): cheap (1; 0.5, 0; 0) moves μ std, noisy (1.5; 0, 1; 0) leaves it undecided
    (bound 0.37), mid (2; 0.1, 0.2; 0) keeps it (bound 0.17), dear (3; 0, 0; 0.3) moves Φ, fast (0.5) did not
    complete."""
    rng = np.random.default_rng(7)
    a = rng.normal(0.0, 1.0, seeds)
    b = rng.normal(10.0, 2.0, seeds)
    z = rng.normal(0.0, 1.0, seeds)
    z = (z - z.mean()) / z.std(ddof=1)
    sa, sb = a.std(ddof=1), b.std(ddof=1)

    def vals(bias: float, c: float, bias_b: float) -> dict:
        return {"mu_std": (a + bias * sa + c * sa * z).tolist(), "phi": (b + bias_b * sb).tolist()}

    return {
        "name": "syn", "description": "synthetic", "kind": "saturated", "measures": ["mu_std", "phi"],
        "pads": [{"seed": s + 1, "member": None, "patches": 10} for s in range(seeds)],
        "config": {"perturbation": 0.01}, "duration_s": 0.03, "window_start_s": 0.02,
        "settings": [
            _setting("strang@fp64:dt=1e-08", "reference", 10.0, vals(0, 0, 0)),
            _setting("strang@fp32:dt=5e-07", "grid", 1.0, vals(0.5, 0, 0)),
            _setting("adaptive@fp64:tol=0.001", "grid", 1.5, vals(0, 1, 0)),
            _setting("strang@fp32:dt=1e-07", "grid", 2.0, vals(0.1, 0.2, 0)),
            _setting("strang@fp32:dt=2e-08", "grid", 3.0, vals(0, 0, 0.3)),
            _setting("implicit-friction@fp32:dt=5e-07", "grid", 0.5, {}, complete=False),
        ],
    }  # fmt: skip


def test_verdicts_are_an_equivalence_test():
    """keeps: the 95 % interval of the bias within ± rule·σ; moves: wholly beyond; undecided: across; an incomplete
    run keeps nothing."""
    reg = synthetic_regime()
    cheap, noisy, mid, dear, fast = reg["settings"][1:]
    c = rule.compare_setting(reg, mid, "mu_std")
    assert c.ratio == pytest.approx(0.1) and c.bound_ratio == pytest.approx(0.1 + 0.2 * T29 / math.sqrt(30))
    assert [rule.verdict(reg, s, "mu_std", 0.25) for s in (cheap, noisy, mid, dear, fast)] == [
        "moves", "undecided", "keeps", "keeps", "no run"]  # fmt: skip
    assert rule.verdict(reg, dear, "phi", 0.25) == "moves" and rule.verdict(reg, dear, "phi", 0.31) == "keeps"
    assert rule.verdict(reg, noisy, "mu_std", 0.4) == "keeps"  # bound 0.373
    assert rule.verdict(reg, reg["settings"][0], "phi", 0.0) == "keeps"


def test_rule_picks_the_cheapest_setting_that_keeps_every_measure():
    """mid is the cheapest setting that keeps both (cheap moves μ std, noisy leaves it undecided); μ std binds it;
    a tighter rule leaves the reference, a looser one takes the cheaper settings; one measure alone its cheapest;
    an incomplete run is never chosen."""
    doc = {"regimes": {"syn": synthetic_regime()}}
    ch = rule.settings_for(doc, "syn")
    assert ch.setting == "strang@fp32:dt=1e-07" and ch.wall_s == 2.0 and ch.speedup == pytest.approx(5.0)
    assert ch.passing == ["strang@fp32:dt=1e-07", "strang@fp64:dt=1e-08"]
    assert ch.cheapest == {"mu_std": "strang@fp32:dt=1e-07", "phi": "strang@fp32:dt=5e-07"}
    assert rule.settings_for(doc, "syn", rule=0.1).setting == "strang@fp64:dt=1e-08"
    assert rule.settings_for(doc, "syn", rule=0.4).setting == "adaptive@fp64:tol=0.001"
    assert rule.settings_for(doc, "syn", rule=0.6).setting == "strang@fp32:dt=5e-07"
    assert rule.settings_for(doc, "syn", ["phi"]).setting == "strang@fp32:dt=5e-07"
    with pytest.raises(KeyError):
        rule.settings_for(doc, "syn", ["f1"])
    with pytest.raises(KeyError):
        rule.settings_for(doc, "other")


def test_members_take_the_worst():
    """A regime with two members (LF states): the regime's figure is the member with the larger bound/σ."""
    reg = synthetic_regime(20)
    for i, p in enumerate(reg["pads"]):
        p["member"] = "s1" if i < 10 else "s2"
    mid = reg["settings"][3]
    mid["values"]["mu_std"] = [x + (2.0 if i >= 10 else 0.0) for i, x in enumerate(mid["values"]["mu_std"])]
    c = rule.compare_setting(reg, mid, "mu_std")
    ref_a = np.array(reg["settings"][0]["values"]["mu_std"][10:])
    assert c.member == "s2" and c.n == 10
    assert c.sigma == pytest.approx(ref_a.std(ddof=1), rel=1e-12)
    assert c.error == pytest.approx(np.mean(mid["values"]["mu_std"][10:]) - ref_a.mean(), rel=1e-9)


def test_grid_syntax_and_new_integrators(monkeypatch):
    """Specs expand to products and labels parse back; bad specs are refused with the reason; a name added to
    INTEGRATORS enters the default grid at its defaults and is accepted in a spec."""
    s = wps.parse_setting("strang@fp32,fp64:dt=1e-8,5e-7")
    assert [x.label for x in s] == ["strang@fp32:dt=1e-08", "strang@fp32:dt=5e-07", "strang@fp64:dt=1e-08",
                                    "strang@fp64:dt=5e-07"]  # fmt: skip
    for x in s:
        assert wps.parse_setting(x.label) == [x]
    a = wps.parse_setting("adaptive@fp64:tol=1e-4:dt=1e-9")
    assert a == [wps.Setting("adaptive", "fp64", 1e-9, 1e-4)]
    assert math.isinf(a[0].cost(1e-3)) and s[0].cost(1e-3) == pytest.approx(1e5)
    for bad in ("rk4@fp32", "strang@fp16", "strang@fp32:h=1e-8", "strang@fp32:dt=-1", "strang@fp32:dt=x"):
        with pytest.raises(ValueError):
            wps.parse_setting(bad)
    assert not any(spec.startswith("lstable") for spec in wps.default_grid(False))
    monkeypatch.setattr(wps, "INTEGRATORS", (*wps.INTEGRATORS, "lstable"))
    assert "lstable@fp32,fp64" in wps.default_grid(False) and "lstable@fp32,fp64" in wps.default_grid(True)
    assert [x.label for x in wps.parse_setting("lstable@fp32:tol=1e-3")] == ["lstable@fp32:tol=0.001"]
    g = wps.grid(wps.default_grid(True), ["lstable", "adaptive"], ["fp64"])
    assert {x.integrator for x in g} == {"lstable", "adaptive"} and {x.precision for x in g} == {"fp64"}


def test_pad_measures_read_from_the_validation_pad():
    """Band spectra are log10 of band means (NaN above the record's Nyquist), the velocity-sum peak is the largest
    peak above 5 kHz, the STFT and tonality measures read their entries, a pad without measures is NaN."""
    freq = np.arange(0, 100_001, 250.0)
    amp = np.full(freq.size, 10.0)
    amp[(freq > 40e3) & (freq < 60e3)] = 0.1
    velocity = np.exp(-0.5 * ((freq - 51e3) / 1e3) ** 2) + 2.0 * (freq < 4e3)  # the largest bins below 5 kHz
    bands = rule.band_log10(freq, amp)
    assert bands[0] == pytest.approx(1.0) and bands[8] == pytest.approx(-1.0)  # 5–10 kHz and 45–50 kHz
    assert np.isnan(bands[-1]) and np.isfinite(bands[18])  # 145–150 kHz beyond 100 kHz; 95–100 kHz in
    pad = {
        "growth_rate": 812.0,
        "measures": {
            "mu_std": 0.02, "sync_relative": {"median_excess_phi10": 0.07},
            "stft": [{"samples": 2048, "amplitude": 9.0}, {"samples": 4096, "amplitude": 0.004, "frequency": 7e4}],
            "tonality": {"peak_to_median": [2.0, 3.0, 2.0 * math.e]},
        },
    }  # fmt: skip
    spectra = {"freq": freq, "mu": amp, "velocity": velocity}
    names = ["mu_std", "vsum_peak", "mu_spectrum", "sync_excess", "growth_rate", "stft_amplitude", "tonality", "f1"]
    vals = rule.pad_values([pad, {"seed": 2}], [spectra, None], names)
    assert vals["mu_std"][0] == 0.02
    assert vals["vsum_peak"][0] == pytest.approx(51e3, abs=10)
    assert vals["mu_spectrum"][0][0] == pytest.approx(1.0)
    assert vals["sync_excess"][0] == 0.07 and vals["growth_rate"][0] == 812.0
    assert vals["stft_amplitude"][0] == 0.004 and vals["tonality"][0] == pytest.approx(1.0)
    assert math.isnan(vals["f1"][0])
    assert all(math.isnan(vals[k][1]) for k in names)


def test_report_page_from_a_synthetic_result(tmp_path):
    """The page names the machine and the choice, gives every setting's error/σ with its bound and verdict, and
    the cheapest setting per measure; the figure is written; a regime named in two files is refused."""
    doc = {
        "machine": {"device": "cpu", "device_name": "CPU", "host": "Test CPU, 2 cores"},
        "tag": "cpu_quick", "quick": True, "commands": ["python3 scripts/work_precision_stats.py --quick"],
        "regimes": {"syn": synthetic_regime()},
    }  # fmt: skip
    path = tmp_path / "wps_cpu_quick_syn.json"
    path.write_text(json.dumps(doc))
    page, figs = tmp_path / "docs" / "page.md", tmp_path / "docs" / "fig"
    page.parent.mkdir()
    wps_report.report([path], page, figs, 0.25, None)
    text = page.read_text()
    assert "Test CPU, 2 cores" in text and "(the quick CPU variant)" in text
    assert (
        "| syn | 30 × 10 | 30.0 ms | `strang@fp64:dt=1e-08` (10 s) | `strang@fp32:dt=1e-07` | 2 | 5 | μ std |" in text
    )
    assert "| `strang@fp32:dt=5e-07` | 1 | 10 | **0.5 (0.5)** | 0 (0) ✓ | no |" in text
    assert "| `adaptive@fp64:tol=0.001` | 1.5 | 6.7 | < 0.001 (0.37) | 0 (0) ✓ | no |" in text
    assert "| `strang@fp32:dt=1e-07` | 2 | 5 | 0.1 (0.17) ✓ | 0 (0) ✓ | yes |" in text
    assert "| `implicit-friction@fp32:dt=5e-07` | 0.5 | 20 | – | – | no (incomplete) |" in text
    assert "`strang@fp32:dt=5e-07` (1 s) |" in text  # Φ: the cheapest setting keeping it
    assert (figs / "wps_cpu_quick.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="both"):
        wps_report.report([path, path], page, figs, 0.25, None)


def test_bad_input_exits_2(capsys):
    """A bad grid spec, reference or size: argparse's exit code 2 with the reason, nothing run."""
    for argv in (["--grid", "rk4@fp32"], ["--reference", "strang@fp32,fp64"], ["--seeds", "1"]):
        with pytest.raises(SystemExit) as e:
            wps.main(argv)
        assert e.value.code == 2
    assert "rk4" in capsys.readouterr().err
    assert wps.main(["--report", "missing.json"]) == 2


def test_tiny_run_end_to_end(tmp_path, capsys):
    """Two 10-patch hf1 sectors for 1 ms (linear growth: not chaotic yet): strang at 1e-8 s stays within 1e-3 σ of
    the 2e-8 s reference, at 5e-7 s forced it moves the measures by more than 0.1 σ; the file holds every pad's
    value. A second call with another grid continues the file (the reference kept, not rerun); a call with other
    pads is refused."""
    out = tmp_path / "wps"
    argv = ["--quick", "--regimes", "hf1", "--seeds", "2", "--patches", "10", "--duration", "1e-3", "--window",
            "5e-4", "--out", str(out)]  # fmt: skip
    assert wps.main([*argv, "--grid", "strang@fp64:dt=5e-7,1e-8"]) == 0
    path = out / "wps_cpu_quick_hf1.json"
    first = json.loads(path.read_text())
    reg = first["regimes"]["hf1"]
    assert [s["label"] for s in reg["settings"]] == ["strang@fp64:dt=2e-08", "strang@fp64:dt=5e-07",
                                                     "strang@fp64:dt=1e-08"]  # fmt: skip
    assert all(s["complete"] for s in reg["settings"])
    assert len(reg["settings"][0]["values"]["mu_mean"]) == 2 and reg["settings"][0]["role"] == "reference"
    fine = [rule.compare_setting(reg, reg["settings"][2], m).ratio for m in ("mu_mean", "mu_std", "f1", "phi")]
    assert max(fine) < 1e-3, fine
    coarse = [rule.compare_setting(reg, reg["settings"][1], m).ratio for m in ("mu_std", "f1", "phi", "top_excess")]
    assert max(coarse) > 0.1, coarse
    assert wps.main([*argv, "--grid", "implicit-friction@fp64:dt=2.5e-7"]) == 0
    doc = json.loads(path.read_text())
    again = doc["regimes"]["hf1"]["settings"]
    assert [s["label"] for s in again] == [*(s["label"] for s in reg["settings"]), "implicit-friction@fp64:dt=2.5e-07"]
    assert again[0] == reg["settings"][0] and len(doc["commands"]) == 2
    assert doc["regime_wall_s"] > first["regime_wall_s"] + again[-1]["wall_s"]
    capsys.readouterr()
    assert wps.main([*argv[:4], "3", *argv[5:], "--grid", "strang@fp64:dt=5e-7"]) == 2
    assert "choose another --out" in capsys.readouterr().err


def test_committed_page_is_what_the_report_writes():
    """The generated section of docs/work_precision_statistics.md is what ``--report`` writes from the committed
    result files (every number on the page traceable to them)."""
    from pathlib import Path

    repo = Path(__file__).resolve().parent.parent
    page = repo / "docs" / "work_precision_statistics.md"
    folder = repo / "docs" / "figures" / "work_precision_statistics"
    text = page.read_text()
    names = [n for n in re.findall(r"`(docs/figures/work_precision_statistics/wps_[^`]+\.json)`", text)]
    assert names, "the page names no result file"
    docs = [rule.load_results(repo / n) for n in names]
    tags = list(dict.fromkeys(d["tag"] for d in docs))
    body = wps_report.render(docs, names, [folder / f"wps_{t}.png" for t in tags], page, 0.25, None)
    begin, end = wps_report.generated_markers(wps_report.MARKER)
    assert text.split(begin, 1)[1].split(end, 1)[0] == "\n" + "\n".join(body) + "\n"
    for t in tags:
        assert (folder / f"wps_{t}.png").is_file()
