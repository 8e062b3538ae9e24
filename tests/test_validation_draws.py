"""Verdicts on disjoint draws of seeds (aca_warp.studies.validation.draws, scripts/validation_draws.py) and the table
of docs/validation.md that the script prints from the committed 32-seed file."""

from __future__ import annotations

import dataclasses
import gzip
import json
import re
from pathlib import Path

import pytest
from scriptload import load_script

import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
from aca_warp.studies.validation import base as VB
from aca_warp.studies.validation import causes as VC
from aca_warp.studies.validation import draws as VD
from aca_warp.studies.validation.results import read_results

REPO = Path(__file__).resolve().parents[1]
SEEDS32 = REPO / "docs" / "validation" / "seeds32" / "results.json.gz"
HF2_PEAK = "HF2: first velocity-spectrum peak"


def _hf2(f1_of_seed: dict[int, float]) -> dict[str, dict]:
    """hf2 pads whose first velocity peak is ``f1_of_seed[seed]`` [Hz] (the row reads ≈ 32.8 kHz ± 5 %)."""
    pads = [{"seed": s, "status": "saturated", "measures": {"f1": f, "f1_patch": {}}} for s, f in f1_of_seed.items()]
    return {"hf2": {"pads": pads}}


def test_draws_are_the_disjoint_runs_of_seeds_the_ensemble_holds():
    cfg = VB.Config(seeds=12, first_seed=3)
    assert VD.draws(cfg, 4) == [(3, 7), (7, 11), (11, 15)]
    assert VD.draws(cfg, 5) == [(3, 8), (8, 13)]  # the two seeds left over are in no draw
    with pytest.raises(ValueError, match="fewer than two draws"):
        VD.draws(cfg, 7)
    with pytest.raises(ValueError, match="at least 2 seeds"):
        VD.draws(cfg, 1)


def test_each_draw_reads_its_own_seeds():
    """Seeds 1–4 at the paper's peak, 5–8 far from it: the first draw reproduces the row; the second and all eight
    seeds together (their mean off the tolerance) do not. One of the two draws agrees, and the table marks the row."""
    res = _hf2({s: (32.8e3 + 50.0 * s if s <= 4 else 45e3 + 50.0 * s) for s in range(1, 9)})
    cfg = VB.Config(seeds=8)
    table = VD.draw_verdicts(res, cfg, 4, against=[{HF2_PEAK: "partly"}, {}])
    row = next(r for r in table if r["statement"] == HF2_PEAK)
    assert row["draws"] == ["reproduced", "not reproduced"]
    assert row["whole"] == "not reproduced" and row["agree"] == 1
    assert row["against"] == ["partly", "not measured"]  # a file without the row: not measured
    assert not any("HF1" in r["statement"] for r in table)  # rows of experiments not run are left out
    lines = VD.render([row], cfg, 4, ["other (8 seeds)", "empty (8 seeds)"])
    head = "| § | statement | 8 seeds | seeds 1–4 | seeds 5–8 | draws agreeing | other (8 seeds) | empty (8 seeds) |"
    assert lines[0] == head
    assert lines[2].endswith(f"| **{HF2_PEAK}** | ✗ | ✓ | ✗ | 1 of 2 | ~ | · |")
    assert lines[-3] == "1 of 1 rows measured have draws of 4 seeds that read otherwise than all 8 seeds."
    assert lines[-2] == "other (8 seeds) reads 0 of the 1 rows as all 8 seeds do."
    alike = dict(row, against=["not reproduced", "partly"])
    assert VD.render([alike], cfg, 4, ["a", "b"])[-2:] == ["a reads 1 of the 1 rows as all 8 seeds do.",
                                                           "b reads 0 of the 1 rows as all 8 seeds do."]  # fmt: skip
    same = VD.draw_verdicts(_hf2({s: 32.8e3 + 50.0 * s for s in range(1, 9)}), cfg, 4)
    assert next(r for r in same if r["statement"] == HF2_PEAK)["draws"] == ["reproduced", "reproduced"]
    agreeing = next(r for r in same if r["statement"] == HF2_PEAK)
    assert "**" not in VD.render([agreeing], cfg, 4)[2]
    only = VD.render([agreeing, row], cfg, 4, split_only=True)  # the agreeing row left out, the split one kept
    assert len(only) == 5 and f"**{HF2_PEAK}**" in only[2]
    assert only[-1] == "1 of 2 rows measured have draws of 4 seeds that read otherwise than all 8 seeds."


def test_draws_of_half_the_seeds_are_the_seed_halves_of_the_causes():
    """On the committed 32-seed file, draws of 16 give every open row the verdicts of the causes' seed halves (a
    variant of its own, read with the ensemble's settings)."""
    results, _, cfg = read_results(SEEDS32)
    rows = VB.evaluate_rows(results, cfg)
    halves = {(c["statement"], c["variant"]): c["verdict"]
              for c in VC.evaluate_causes(results, cfg, rows) if c["cause"] == "seeds"}  # fmt: skip
    table = {r["statement"]: r for r in VD.draw_verdicts(results, cfg, 16)}
    assert halves
    for (statement, variant), verdict in halves.items():
        k = 0 if variant == "seeds 1–16" else 1
        assert table[statement]["draws"][k] == verdict, (statement, variant)


def test_results_read_from_gzip_as_from_json(tmp_path):
    plain = tmp_path / "results.json"
    plain.write_bytes(gzip.decompress(SEEDS32.read_bytes()))
    a, meta, cfg = read_results(SEEDS32)
    b, meta_b, cfg_b = read_results(plain)
    assert a == b and meta == meta_b and cfg == cfg_b and cfg.seeds == 32
    broken = tmp_path / "broken.json.gz"
    broken.write_bytes(b"not gzip")
    truncated = tmp_path / "truncated.json.gz"
    truncated.write_bytes(SEEDS32.read_bytes()[:5000])
    for path in (broken, truncated):
        with pytest.raises(ValueError, match="not a readable results file"):
            read_results(path)


def test_a_failed_row_agrees_with_no_draw(monkeypatch):
    """A row whose measure raises reads "failed" everywhere: it counts as agreeing with no draw, so that the table
    shows it in bold instead of as settled."""
    i = next(k for k, r in enumerate(VB.ROWS) if r.statement == HF2_PEAK)

    def boom(results, cfg):
        raise RuntimeError("broken measure")

    rows = list(VB.ROWS)
    rows[i] = dataclasses.replace(rows[i], measure=boom)
    monkeypatch.setattr(VB, "ROWS", rows)  # evaluate_rows reads the module's list
    monkeypatch.setattr(VD, "ROWS", rows)
    cfg = VB.Config(seeds=8)
    table = VD.draw_verdicts(_hf2({s: 32.8e3 for s in range(1, 9)}), cfg, 4)
    row = next(r for r in table if r["statement"] == HF2_PEAK)
    assert row["whole"] == "failed" and row["draws"] == ["failed", "failed"] and row["agree"] == 0
    assert VD.render([row], cfg, 4)[2].endswith(f"| **{HF2_PEAK}** | ! | ! | ! | 0 of 2 |")
    failed_there_too = VD.render([dict(row, against=["failed"])], cfg, 4, ["x"])  # a failure agrees with nothing
    assert failed_there_too[-1] == "x reads 0 of the 1 rows as all 8 seeds do."


@pytest.mark.parametrize(
    ("results", "seeds"), [(SEEDS32, 32), (SEEDS32.parent.parent / "rerun_twice" / "results.json", 8)]
)
def test_the_folders_pages_are_rendered_from_their_results(results: Path, seeds: int):
    """docs/validation/seeds32/validation.md's and rerun_twice/validation.md's generated sections are what --report
    writes from the results file beside each."""
    from aca_warp.studies.report import generated_markers
    from aca_warp.studies.validation.cli import MARKER
    from aca_warp.studies.validation.results import render_report

    body, rows, meta = render_report(results)
    begin, end = generated_markers(MARKER)
    committed = (results.parent / "validation.md").read_text().split(begin, 1)[1].split(end, 1)[0]
    assert committed == "\n" + "\n".join(body) + "\n"
    assert meta["config"]["seeds"] == seeds and len(rows) == len(VB.ROWS)


def test_the_pages_draws_table_is_the_scripts_output(capsys):
    page = (REPO / "docs" / "validation.md").read_text()
    blocks = re.findall(r"<!-- DRAWS ([^>]*?) -->\n(.*?)<!-- END DRAWS -->", page, flags=re.S)
    assert [m.endswith(" split-only") for m, _ in blocks] == [False, True]  # all rows at eight seeds, split at 16
    script = load_script("validation_draws")
    for marker, table in blocks:
        path, size, *against = marker.removesuffix(" split-only").split()
        args = [str(REPO / path), "--size", size, "--against", *(str(REPO / a) for a in against)]
        assert script.main(args + (["--split-only"] if marker.endswith(" split-only") else [])) == 0
        assert capsys.readouterr().out == table


def test_the_script_refuses_what_it_cannot_read(tmp_path, capsys):
    script = load_script("validation_draws")
    eight = REPO / "docs" / "validation" / "results.json"
    assert script.main([str(eight), "--size", "8"]) == 2
    assert "8 seeds hold fewer than two draws of 8" in capsys.readouterr().err
    other = tmp_path / "x.json"
    other.write_text(json.dumps({"format": "something else"}))
    assert script.main([str(other)]) == 2
    assert "not a validation results file" in capsys.readouterr().err
