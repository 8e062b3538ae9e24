"""The statistical work-precision's errors against the step (``work_precision_stats.py --steps``,
:mod:`aca_warp.studies.work_precision_stats_steps`): signed errors and their 95 % half-widths on an ensemble whose
answer is known, the table and figure, refusals, and the committed page's table."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import scipy.stats
from test_work_precision_stats import _setting, synthetic_regime

from aca_warp.studies import work_precision_stats as wps
from aca_warp.studies import work_precision_stats_rule as rule
from aca_warp.studies.work_precision_stats_steps import collect, errors_by_step, step_errors

REPO = Path(__file__).resolve().parent.parent


def _doc(reg: dict) -> dict:
    """A result document of one regime."""
    machine = {"device": "cpu", "device_name": "cpu", "host": "test host"}
    return {"tag": "cpu", "machine": machine, "quick": False, "commands": [], "regimes": {reg["name"]: reg}}


def known_regime() -> dict:
    """The synthetic regime (:func:`synthetic_regime`, 30 seeds) with μ std of its 5e-7 s setting moved by −0.5 σ
    instead of +0.5 σ, and a two-component spectrum measure that every setting shifts by (−0.3, +0.4) × its
    components' σ."""
    reg = synthetic_regime()
    rng = np.random.default_rng(3)
    spec = rng.normal(0.0, [1.0, 3.0], (30, 2))
    sd = spec.std(axis=0, ddof=1)
    ref = reg["settings"][0]["values"]["mu_std"]
    cheap = reg["settings"][1]["values"]
    cheap["mu_std"] = (2 * np.array(ref) - np.array(cheap["mu_std"])).tolist()  # ref − 0.5 σ
    reg["measures"].append("mu_spectrum")
    for k, s in enumerate(reg["settings"]):
        if s["values"]:
            s["values"]["mu_spectrum"] = (spec + (0 if k == 0 else 1) * np.array([-0.3, 0.4]) * sd).tolist()
    return reg


def test_step_errors_are_signed_with_their_interval():
    """Per fixed-step setting, by family and step: the signed mean(x − x_ref)/σ (−0.5 σ, +0.1 σ, 0) and the 95 %
    half-width t₀.₉₇₅ sd(d)/(√n σ) (0.2 t/√30 for the 1e-7 s setting, whose noise is 0.2 σ); a vector measure's
    rms error over the rms σ of its components, unsigned; settings with a tolerance (error control chooses their
    steps, whatever their dt) and incomplete runs are left out."""
    reg = known_regime()
    values = reg["settings"][3]["values"]
    reg["settings"].append(_setting("controlled@fp32:dt=1e-07:tol=0.01", "grid", 1.1, values))
    got = step_errors(reg, "mu_std")
    assert [(e.family, e.dt) for e in got] == [("strang@fp32", 2e-8), ("strang@fp32", 1e-7), ("strang@fp32", 5e-7)]
    assert [e.error for e in got] == pytest.approx([0.0, 0.1, -0.5], abs=1e-12)
    t = scipy.stats.t.ppf(0.975, 29)
    assert [e.half for e in got] == pytest.approx([0.0, 0.2 * t / math.sqrt(30), 0.0], abs=1e-9)
    spec = step_errors(reg, "mu_spectrum")
    sd2 = np.square(np.array(reg["settings"][0]["values"]["mu_spectrum"]).std(axis=0, ddof=1))
    rms = math.sqrt((0.09 * sd2[0] + 0.16 * sd2[1]) / sd2.sum())  # rms of the errors over rms of the σ
    assert [e.error for e in spec] == pytest.approx([rms] * 3, rel=1e-9)
    steps = collect(_doc(reg))
    assert steps.signed == {"mu_std": True, "phi": True, "mu_spectrum": False}
    phi = {e.dt: e.error for e in step_errors(reg, "phi")}
    assert phi[2e-8] == pytest.approx(0.3) and phi[1e-7] == pytest.approx(0.0, abs=1e-12)


def test_a_regime_with_members_takes_the_sign_of_the_member_it_compares():
    """With members (the LF states) the error is the rule's, the member with the largest bound/σ, and so is its sign:
    member a moved by +0.5 σ_a, member b by −0.1 σ_b with σ_b ten times σ_a reads +0.5, where the mean over every pad
    would be negative."""
    rng = np.random.default_rng(5)
    a, b = rng.normal(0.0, 1.0, 15), rng.normal(0.0, 10.0, 15)
    ref = np.concatenate([a, b])
    moved = np.concatenate([a + 0.5 * a.std(ddof=1), b - 0.1 * b.std(ddof=1)])
    reg = {
        "name": "lf", "measures": ["mu_mean"],
        "pads": [{"seed": k % 15 + 1, "member": "a" if k < 15 else "b"} for k in range(30)],
        "settings": [_setting("strang@fp64:dt=1e-08", "reference", 9.0, {"mu_mean": ref.tolist()}),
                     _setting("strang@fp32:dt=1e-07", "grid", 1.0, {"mu_mean": moved.tolist()})],
    }  # fmt: skip
    assert np.mean(moved - ref) < 0
    (e,) = step_errors(reg, "mu_mean")
    assert e.error == pytest.approx(0.5, rel=1e-9)


def test_families_are_apart_and_the_table_lists_them():
    """A crossing treatment is a family of its own; the table has a block per family, a column per step and a row
    per measure asked for, cells "error ± half-width" and "–" where a setting has no figure for the measure; an
    unknown measure, a regime with no fixed-step setting and a file of two regimes without a name are refused."""
    reg = known_regime()
    values = reg["settings"][1]["values"]
    reg["settings"].append(_setting("strang@fp32:dt=5e-07:mean", "grid", 1.2, values))
    no_phi = {**values, "phi": [None] * 30}
    reg["settings"].append(_setting("strang@fp32:dt=2.5e-07", "grid", 1.3, no_phi))
    table = errors_by_step(collect(_doc(reg), measures=["mu_std", "phi"]))
    assert "**strang@fp32**" in table and "**strang@fp32 crossings averaged**" in table
    assert "| measure | 2e-08 s | 1e-07 s | 2.5e-07 s | 5e-07 s |" in table and "| measure | 5e-07 s |" in table
    assert re.search(r"\| μ std \| \+0\.00 ± 0\.00 \| \+0\.10 ± 0\.07 \| -0\.50 ± 0\.00 \| -0\.50 ± 0\.00 \|", table)
    assert re.search(r"\| Φ \| \+0\.30 ± 0\.00 \| [+-]0\.00 ± 0\.00 \| – \| [+-]0\.00 ± 0\.00 \|", table)
    assert table.count("| Φ |") == 2 and "μ spectrum" not in table
    with pytest.raises(ValueError, match="no measure f1"):
        collect(_doc(reg), measures=["f1"])
    bare = known_regime()
    bare["settings"] = [s for s in bare["settings"] if s["role"] == "reference" or s.get("dt") is None]
    with pytest.raises(ValueError, match="no completed fixed-step setting"):
        collect(_doc(bare))
    two = _doc(reg)
    two["regimes"]["other"] = reg
    with pytest.raises(ValueError, match="name one"):
        collect(two)
    with pytest.raises(ValueError, match="no regime hf9"):
        collect(two, "hf9")


def _drawn(png: Path, colour: tuple[float, float, float]) -> int:
    """Pixels of ``png`` within 0.02 of ``colour`` (RGB in 0–1)."""
    import matplotlib.image

    rgb = matplotlib.image.imread(png)[..., :3]
    return int((np.abs(rgb - np.array(colour)).max(axis=-1) < 0.02).sum())


def test_steps_command_prints_the_table_and_draws_the_figure(tmp_path, capsys):
    """``--steps FILE --figures DIR``: the table on stdout, ``wps_<tag>_<regime>_steps.png`` in DIR with a panel per
    measure asked for (one measure: one panel's width) and each family's errors drawn in its colour; without
    ``--figures`` beside the file; two regimes named exit 2 with one line and no figure."""
    from matplotlib import colormaps

    path = tmp_path / "wps_cpu_syn.json"
    path.write_text(json.dumps(_doc(known_regime())))
    figs = tmp_path / "figs"
    assert wps.main(["--steps", str(path), "--figures", str(figs), "--measures", "mu_std"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("syn: error / σ ± 95 % half-width") and "| μ std |" in out and "| Φ |" not in out
    one = figs / "wps_cpu_syn_steps.png"
    assert _drawn(one, colormaps["tab10"](0)[:3]) > 120  # the points, bars and line (the legend alone: ≈ 35)
    assert wps.main(["--steps", str(path)]) == 0
    capsys.readouterr()
    every = tmp_path / "wps_cpu_syn_steps.png"  # beside the file: three measures, three panels
    import matplotlib.image

    assert matplotlib.image.imread(every).shape[1] > 2.5 * matplotlib.image.imread(one).shape[1]
    assert wps.main(["--steps", str(path), "--figures", str(tmp_path / "no"), "--regimes", "hf1", "hf2"]) == 2
    assert "one regime" in capsys.readouterr().err and not (tmp_path / "no").exists()


def test_the_pages_by_step_tables_are_the_scripts_output():
    """Every ``BY STEP`` table of the docs is what ``--steps FILE --measures …`` prints from the committed result
    file it names (``BY STEP PAIRS``: with ``--precision-pairs``)."""
    folder = REPO / "docs" / "figures" / "work_precision_statistics"
    pages = [REPO / "docs" / "friction_step.md", REPO / "docs" / "work_precision_statistics.md",
             folder / "hf1_crossing" / "README.md", folder / "fp32_fp64" / "README.md"]  # fmt: skip
    pattern = r"<!-- BY STEP( PAIRS)? (\S+) ([^>]+?) -->\n(.*?)<!-- END BY STEP -->"
    blocks = [b for p in pages for b in re.findall(pattern, p.read_text(), flags=re.S)]
    assert any(pairs for pairs, *_ in blocks) and any(not pairs for pairs, *_ in blocks)
    for pairs, path, measures, table in blocks:
        printed = errors_by_step(collect(rule.load_results(REPO / path), None, measures.split(), bool(pairs)))
        assert printed.split("\n\n", 1)[1] == table, path


_MEAN = "strang@fp32:dt=2.5e-07:mean"
_FAST_MEAN = "strang@fp32:dt=2.5e-07:fast:mean"
_FAST_MEAN_FILES = (("hf1", "0"), ("hf2", "0"), ("hf3", "0"), ("hf4", "0"), ("va", "0"), ("ms_mid", "01"),
                    ("ms_app3", "0123"), ("hf1_equal", "01"), ("hf2_equal", "1"), ("hf3_equal", "0"),
                    ("hf4_equal", "1"), ("va_equal", "0"))  # fmt: skip


@pytest.mark.parametrize(
    ("page", "merged", "pads", "settings", "pick"),
    [
        ("hf1_crossing", ["wps_cuda0_hf1.json"], [160],
         {"strang@fp32:dt=1e-08:mean", "strang@fp32:dt=2.5e-08:mean", "strang@fp64:dt=5e-09"}, _MEAN),
        ("hf2_crossing", ["wps_cuda0_hf2.json"], [96], {"strang@fp32:dt=1e-07:mean", _MEAN}, _MEAN),
        ("hf3_crossing", ["wps_cuda0_hf3.json"], [128], {"strang@fp32:dt=1e-07:mean", _MEAN}, _MEAN),
        ("hf4_crossing", ["wps_cuda0_hf4.json"], [32], {"strang@fp32:dt=5e-07:mean", _MEAN}, "strang@fp32:dt=5e-07"),
        ("va_crossing", ["wps_cuda0_va.json"], [128], {"strang@fp32:dt=2.5e-07:growth_dt=5e-06:mean", _MEAN},
         "strang@fp32:dt=2.5e-07"),
        ("ms_mid_crossing", ["wps_cuda01_ms_mid.json"], [96], {"strang@fp32:dt=1e-07:mean", _MEAN}, _MEAN),
        ("ms_app3_crossing", ["wps_cuda0123_ms_app3.json"], [64], {"strang@fp32:dt=1e-07:mean", _MEAN}, _MEAN),
        ("equal_heights/crossing", [f"{r}/wps_cuda{t}_{r}.json" for r, t in (("hf1_equal", "01"), ("hf2_equal", "1"),
          ("hf3_equal", "0"), ("hf4_equal", "1"), ("va_equal", "0"))], [128, 128, 64, 64, 128], {_MEAN}, None),
        ("fast_mean", [f"{r}/wps_cuda{t}_{r}.json" for r, t in _FAST_MEAN_FILES],
         [160, 96, 128, 32, 128, 96, 64, 128, 128, 64, 64, 128],
         {_FAST_MEAN, "strang@fp32:dt=2.5e-07:growth_dt=5e-06:fast:mean"}, _FAST_MEAN),
        ("step_sample", [f"{r}/wps_cuda{t}_{r}.json" for r, t in _FAST_MEAN_FILES],
         [160, 96, 128, 32, 128, 96, 64, 128, 128, 64, 64, 128],
         {_MEAN, "strang@fp32:dt=2.5e-07:growth_dt=5e-06:mean"}, _FAST_MEAN),
    ],
)  # fmt: skip
def test_crossing_pages_are_what_merge_and_report_write(monkeypatch, page, merged, pads, settings, pick):
    """The crossing treatment's pages (docs/figures/work_precision_statistics/<regime>_crossing/ and
    equal_heights/crossing/, fast_mean/, which continues their parts with fast math, and step_sample/, which continues
    those with the default row made again on the kernels whose samples read the next step's solve): each merged file
    is the ``--merge`` of its parts (``s*/``, where it has parts: the study's own parts continued with ``mean``; hf1's,
    each setting of the steps' study), on every seed, and the page's generated section is what ``--report`` writes
    from them; the rule picks ``pick`` (the first regime's)."""
    from aca_warp.studies import work_precision_stats_report as wps_report
    from aca_warp.studies.report import clean
    from aca_warp.studies.work_precision_stats_merge import merge

    monkeypatch.chdir(REPO)  # the parts named as the page's command names them
    folder = REPO / "docs" / "figures" / "work_precision_statistics" / page
    docs = []
    for name, n in zip(merged, pads, strict=True):
        path = folder / name
        doc = rule.load_results(path)
        parts = sorted(path.parent.glob(f"s*/wps_*_{next(iter(doc['regimes']))}.json"))
        if parts:
            assert json.loads(json.dumps(clean(merge([p.relative_to(REPO) for p in parts])))) == doc
        reg = next(iter(doc["regimes"].values()))
        assert len(reg["pads"]) == n
        docs.append(doc)
    assert settings <= {s["label"] for d in docs for s in next(iter(d["regimes"].values()))["settings"]
                        if rule.usable(s)}  # fmt: skip
    readme = folder / "README.md"
    names = [(folder / m).relative_to(readme.parent.parent).as_posix() for m in merged]
    figures = [folder / f"wps_{t}.png" for t in dict.fromkeys(d["tag"] for d in docs)]
    body = wps_report.render(docs, names, figures, readme, 0.25, None, "resolution")
    begin, end = wps_report.generated_markers(wps_report.MARKER)
    generated = readme.read_text().split(begin, 1)[1].split(end, 1)[0]
    assert generated == "\n" + "\n".join(body) + "\n"
    if pick is not None:
        assert f"The rule picks `{pick}`" in generated


def test_precision_pairs_measure_fp32_against_fp64_of_its_step_and_variant(tmp_path, capsys):
    """``--precision-pairs``: each fp32 setting against the fp64 setting of its step and variant (the reference where
    that is it): an fp64 twin at 5e-7 s biased by +0.2 σ in μ std puts the 5e-7 s fp32 setting's −0.5 σ (against the
    reference) at −0.7 σ against its twin; the 2e-8 s setting has no partner and is left out; a row of an older file
    without the variant fields pairs with a new row of the defaults; a partner of another variant (a crossing
    treatment, a solve tolerance) is none."""
    from aca_warp.studies.work_precision_stats_steps import fp64_partner

    reg = known_regime()
    ref_vals = reg["settings"][0]["values"]
    sa = float(np.std(ref_vals["mu_std"], ddof=1))
    twin = {m: list(v) for m, v in ref_vals.items()}
    twin["mu_std"] = (np.array(ref_vals["mu_std"]) + 0.2 * sa).tolist()
    reg["settings"].append(_setting("strang@fp64:dt=5e-07", "grid", 4.0, twin))
    reg["settings"].append(_setting("strang@fp64:dt=1e-07:mean", "grid", 4.0, twin))
    reg["settings"].append(_setting("strang@fp64:dt=2e-08:solve_tol=1e-06", "grid", 4.0, twin))
    fp32_5e7, fp32_1e7 = reg["settings"][1], reg["settings"][3]
    old = {k: v for k, v in fp32_5e7.items() if k not in ("fast_math", "crossing", "growth_dt", "solve_tol")}
    assert fp64_partner(reg, old)["label"] == "strang@fp64:dt=5e-07"
    assert fp64_partner(reg, fp32_1e7) is None  # only a partner that averages its crossings
    assert fp64_partner(reg, reg["settings"][4]) is None  # 2e-8 s: only one with another solve tolerance
    assert fp64_partner(reg, reg["settings"][0]) is None  # an fp64 setting has no partner
    got = step_errors(reg, "mu_std", paired=True)
    assert [(e.family, e.dt) for e in got] == [("strang@fp32 − fp64", 5e-7)]
    assert got[0].error == pytest.approx(-0.7, abs=1e-9)
    steps = collect(_doc(reg), measures=["mu_std"], paired=True)
    assert steps.paired and "fp64 setting of the same step" in errors_by_step(steps)
    path = tmp_path / "pairs.json"
    path.write_text(json.dumps(_doc(reg)))
    assert wps.main(["--steps", str(path), "--precision-pairs", "--figures", str(tmp_path)]) == 0
    assert "| μ std | -0.70 ± 0.00 |" in capsys.readouterr().out
    assert (tmp_path / "wps_cpu_syn_fp32_fp64.png").is_file() and not (tmp_path / "wps_cpu_syn_steps.png").exists()
    lonely = known_regime()  # no fp64 setting but the reference at 1e-8 s, no fp32 setting there
    path.write_text(json.dumps(_doc(lonely)))
    assert wps.main(["--steps", str(path), "--precision-pairs", "--figures", str(tmp_path / "no")]) == 2
    assert "no completed fp32 setting with an fp64 partner" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        wps.main(["--precision-pairs"])
    assert "--precision-pairs goes with --steps" in capsys.readouterr().err


def test_a_reference_partner_is_the_reference():
    """An fp32 setting at the reference's step and variant pairs with the reference itself: the same error as
    against the reference."""
    reg = known_regime()
    reg["settings"].append(_setting("strang@fp32:dt=1e-08", "grid", 5.0, reg["settings"][1]["values"]))
    paired = {e.dt: e.error for e in step_errors(reg, "mu_std", paired=True)}
    plain = {e.dt: e.error for e in step_errors(reg, "mu_std")}
    assert list(paired) == [1e-8] and paired[1e-8] == pytest.approx(plain[1e-8]) == pytest.approx(-0.5)


def test_the_variant_is_every_field_of_a_setting_but_its_precision():
    """The fields that pair settings (twin, fp64 partner) are the study's ``Setting`` fields less the precision, with
    its defaults: a field added to one and not the other would pair settings of different variants."""
    import dataclasses

    fields = {f.name: f.default for f in dataclasses.fields(wps.Setting) if f.name != "precision"}
    assert rule.VARIANT == {k: None if v is dataclasses.MISSING else v for k, v in fields.items()}
    old_row = {"integrator": "strang", "precision": "fp32", "dt": 1e-7, "tolerance": None}
    assert rule.variant(old_row) == rule.variant(_setting("strang@fp64:dt=1e-07", "grid", 1.0, {}))
