"""How the validation reads the paper's statements: the combination of HF2's and HF3's changes as both present in
HF4, the rows that hold by construction counted apart, the first peak's other readings beside the exponent rows,
the §3.3 amplitude rows read on this LF automaton, and the column from rest counted beside the primary
(docs/validation.md, "Revisions of 2026-12-01")."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

import aca_warp.studies.validation  # noqa: F401  (registers the experiments and rows)
from aca_warp.studies.validation import base as VB
from aca_warp.studies.validation import hf_peaks as VP
from aca_warp.studies.validation import hf_sync as VS
from aca_warp.studies.validation import multiscale_rows as VMR
from aca_warp.studies.validation.page import relative_counts, rest_counts, strict_counts, verdict_counts
from aca_warp.studies.validation.results import read_results

PRESETS = ("hf1", "hf2", "hf3", "hf4")
SEEDS32 = Path(__file__).resolve().parent.parent / "docs" / "validation" / "seeds32" / "results.json.gz"
R, P, N, U, G = "reproduced", "partly", "not reproduced", "undetermined", "significant but negligible"


@pytest.fixture(scope="module")
def seeds32() -> tuple[dict, VB.Config]:
    results, _, cfg = read_results(SEEDS32)
    return results, cfg


def _row(statement: str) -> VB.Row:
    return next(r for r in VB.ROWS if r.statement == statement)


@pytest.mark.parametrize(
    ("a", "b", "want"),
    [
        (R, R, R),
        (R, U, P),
        (U, R, P),
        (P, N, P),
        (N, U, U),
        (N, N, N),
        (G, N, P),
        (G, G, G),
        (G, R, P),
        ("not measured", R, "not measured"),
        (R, "failed", "failed"),
    ],
)
def test_both_changes_present(a: str, b: str, want: str) -> None:
    assert VS.both_verdict(a, b) == want


def test_combination_reads_both_changes_of_hf4_against_hf1(seeds32) -> None:
    """The combination row's verdict is both_verdict of the spread row and the 'S greater' row of HF4 vs HF1, on the
    committed 32 seeds (spread reproduced, S greater undetermined: partly); the additive reading is in its notes."""
    results, cfg = seeds32
    combo = _row("HF4 can be interpreted as the combination of the changes of HF2 and HF3").measure(results, cfg)
    spread = _row("HF4 vs HF1: S more spread out (the influence of the patch size)").measure(results, cfg)
    greater = _row("HF4 vs HF1: S greater, especially at higher frequencies (the influence of M)").measure(results, cfg)
    assert combo.verdict == VS.both_verdict(spread.verdict, greater.verdict) == P
    assert combo.notes.startswith("the additive reading: interaction") and "(reproduced within ± 0.05)" in combo.notes


def test_rows_by_construction_are_marked_and_counted_apart(seeds32) -> None:
    """Fifteen rows hold by construction or check the code; the count names them apart, and a marked row that is not
    reproduced is not counted among them."""
    marked = [r for r in VB.ROWS if r.construction]
    assert len(marked) == 15
    assert {r.section.split(",")[0] for r in marked} == {"§2.2", "§3.1", "§3.2", "§3.3", "§5", "Appendix"}
    results, cfg = seeds32
    rows = VB.evaluate_rows(results, cfg)
    text = verdict_counts(rows)
    assert "Of the 35 reproduced, 15 hold by construction or check the code" in text and "20 are findings" in text
    k = next(i for i, r in enumerate(rows) if r["construction"])
    assert "Of the 34 reproduced, 14 hold" in verdict_counts([*rows[:k], {**rows[k], "verdict": N}, *rows[k + 1 :]])


def test_exponent_rows_show_every_reading_of_the_first_peak(seeds32) -> None:
    """Both spectral exponent rows give each other reading of f1 its exponent and verdict: the convention decides them
    (the per-patch spectrum at 0.02 reproduces where the primary does not)."""
    results, cfg = seeds32
    for statement in ("f_p ∝ A_p^(−1/4): exponent of the first velocity peak against the mean patch area",
                      "f_p ∝ A_p^(−1/4) from the two patch sizes of Table 1 (HF1, HF2)"):  # fmt: skip
        v = _row(statement).measure(results, cfg)
        assert v.verdict == N
        for label, _ in VP.F1_CANDIDATES:
            assert label in v.notes
        assert "Σ|u̇| largest peak -0.15" in v.notes  # the rectified sum's doubled peaks give a shallower exponent
        assert "per-patch mean spectrum at 0.02 -0.232 [-0.234, -0.231] (n = 32) (reproduced)" in v.notes


def test_amplitude_rows_read_on_this_automaton(seeds32) -> None:
    """The five §3.3/§4 amplitude rows give verdicts (four not reproduced, low pressures reproduced) with the LF caveat
    first in their notes; none reads 'not comparable'."""
    results, cfg = seeds32
    amplitude = [r for r in VB.ROWS if r.criterion == VMR.AMPLITUDE_CRITERION]
    got = {r.statement: r.measure(results, cfg) for r in amplitude}
    assert all(v.notes.startswith(VMR.ON_THIS_LF) for v in got.values())
    assert sorted(v.verdict for v in got.values()) == [N, N, N, N, R]
    assert got["significant friction oscillations are associated with low normal pressures"].verdict == R


def test_amplitude_rows_show_fig_13_s_states_beside_all_eight(seeds32) -> None:
    """Read over the five states Fig. 13 shows, 'greatest amplitudes during application 3' is partly (app3_end above
    the others), where all eight states make it not reproduced (app1_end the largest in every seed)."""
    results, cfg = seeds32
    during = _row("μ oscillates with the greatest amplitudes during application 3 (low pressure)").measure(results, cfg)
    assert during.verdict == N and "app1_end ×32" in during.notes
    assert (
        "over Fig. 13's five states only: -0.267 [-0.362, -0.172] (n = 32); 0.362 [0.259, 0.466] (n = 32) (partly)"
        in (during.notes)
    )


def test_size_row_shows_the_paper_s_order_of_the_effects(seeds32) -> None:
    results, cfg = seeds32
    row = _row("HF1 vs HF2: the size increase does not significantly affect the synchronisation quality")
    notes = row.measure(results, cfg).notes
    assert "the M effect of the paper's next sentence (hf3 − hf1) 0.00506" in notes
    assert "size effect − M effect 0.0161" in notes and "(the paper orders them M > size)" in notes


def test_s_rows_give_the_relative_reading_of_their_margin(seeds32) -> None:
    """Beside the absolute margin 0.05 of S − S_null, each S row's notes read the ratio of the two excesses at equal
    Φ against ln 1.25: on 32 seeds HF2's excess is 1.8× HF1's (the size row, reproduced within ± 0.05, is not within
    ± ln 1.25), HF4's exceeds HF2's by 25 % (reproduced where the absolute margin reads negligible), HF3's HF1's by
    20 % (negligible on both), and the rules disagree on the interaction and above f1 (undetermined)."""
    results, cfg = seeds32

    def notes(statement: str) -> tuple[str, str]:
        value = _row(statement).measure(results, cfg)
        return value.verdict, value.notes

    verdict, text = notes("HF1 vs HF2: the size increase does not significantly affect the synchronisation quality")
    assert verdict == R
    assert ("relative reading ln(S − S_null at equal Φ, hf2 / hf1): 0.598 [0.578, 0.617] (n = 32), snr rule "
            "0.49 [0.462, 0.519] (n = 32): not reproduced within ± ln 1.25") in text  # fmt: skip
    verdict, text = notes("lower friction coefficients yield higher S for large patches too (HF4 vs HF2)")
    assert verdict == G and "mean 0.225 against the margin 0.223 (agrees): reproduced" in text
    verdict, text = notes("lower M raises S significantly for small patches (HF3 vs HF1)")
    assert verdict == G and "mean 0.179 against the margin 0.223 (small): significant but negligible" in text
    verdict, text = notes("the rise with lower M is not as substantial for the larger patches")
    assert verdict == N and "ln(hf3 / hf1) − ln(hf4 / hf2) of S − S_null at equal Φ: -0.0455" in text
    assert text.endswith("mean -0.0455 against the margin 0.223 (opposite): undetermined")
    verdict, text = notes("HF4 vs HF1: S greater, especially at higher frequencies (the influence of M)")
    assert verdict == U and "above f1, ln(S − S_null at equal Φ, hf4 / hf1): -0.287 [-0.451, -0.123]" in text
    assert "(with the ratio above f1 less the whole band's -1.13 [-1.3, -0.961] (n = 32))" in text


def test_the_relative_reading_of_the_s_rows_moves_three_rows_on_32_seeds(seeds32) -> None:
    """The page's line on the relative reading: evaluated inside ``relative_s`` the S rows take their relative
    verdicts (three move on 32 seeds), and outside it the absolute margin again."""
    results, cfg = seeds32
    rows = VB.evaluate_rows(results, cfg)
    with VS.relative_s():
        relative = VB.evaluate_rows(results, cfg)
    assert VB.evaluate_rows(results, cfg) == rows  # the context is left as it was
    assert relative_counts(rows, relative).endswith(
        "3 of the 73 verdicts move: HF1 vs HF2: the size increase does not significantly affect the "
        "synchronisation quality (reproduced → not reproduced); lower friction coefficients yield higher S for large "
        "patches too (HF4 vs HF2) (significant but negligible → reproduced); the rise with lower M is not as "
        "substantial for the larger patches (not reproduced → undetermined)."
    )
    changed = [(r, s) for r, s in zip(rows, relative, strict=True) if r != s]
    assert len(changed) == 3 and all({**s, "verdict": r["verdict"]} == r for r, s in changed)  # the verdict alone
    assert relative_counts(rows, rows).endswith("no verdict moves.")


def test_equal_phi_ratio_is_the_log_ratio_of_the_two_excesses() -> None:
    """Over the classes both populate: a's excess twice b's gives ln 2; a seed whose excess is not positive on one
    side gives NaN, not a number."""

    def pad(seed: int, excess: list[float]) -> dict:
        table = {"lower": [2, 4, 8], "upper": [4, 8, 16], "bins": [20, 20, 0], "mean_S": [0.5] * 3,
                 "mean_S_null": [0.1] * 3, "mean_excess": excess}  # fmt: skip
        return {"seed": seed, "status": "saturated", "measures": {"sync_relative": {"table": table}}}

    results = {"a": {"pads": [pad(1, [0.2, 0.4, 9.0]), pad(2, [0.1, -0.3, 0.0])]},
               "b": {"pads": [pad(1, [0.1, 0.2, 1.0]), pad(2, [0.1, 0.1, 0.0])]}}  # fmt: skip
    ratio = VB.equal_phi_ratio(results, "a", "b")
    assert ratio[1] == pytest.approx(math.log(2.0)) and math.isnan(ratio[2])
    assert VB.equal_phi(results, "a", "b")[0] == pytest.approx([0.15, -0.2])
    assert VB.equal_phi_ratio(results, "a", "c") == {}
    assert VB.equal_phi_ratio(results, "a", "b", only={1}) == pytest.approx({1: math.log(2.0)})  # seed 2 left out


def test_the_strict_reading_of_direction_parts_moves_one_row_on_32_seeds(seeds32) -> None:
    """The page's line on the stricter reading of a direction part: on 32 seeds it moves one row, the growth of the
    friction oscillations (its interval 0.293 [0.186, 0.401] reaches below the margin ln 1.25); a list that moves
    nothing says so."""
    from aca_warp.studies.validation.verdicts import strict_direction

    results, cfg = seeds32
    rows = VB.evaluate_rows(results, cfg)
    with strict_direction():
        strict = VB.evaluate_rows(results, cfg)
    text = strict_counts(rows, strict)
    assert text.endswith(
        "1 of the 73 verdicts moves: friction oscillations grow as the patch-disc contacts come to dominate "
        "(reproduced → significant but negligible)."
    )
    assert strict_counts(rows, rows).endswith("no verdict moves.")


def test_the_column_from_rest_is_counted_beside_the_primary_on_the_same_rows():
    rows = [{"statement": s, "verdict": v} for s, v in (("a", N), ("b", R), ("c", P), ("d", N))]
    rest = [{"verdict": R}, {"verdict": R}, None, {"verdict": "not measured"}]
    text = rest_counts(rows, rest)
    assert text.startswith("From rest at the paper's length (the column beside the verdict), 2 of the rows")
    assert "2 reproduced (the primary on the same rows: 1 reproduced, 1 not reproduced)." in text
    assert text.endswith("differs from the primary's in 1: a (not reproduced → reproduced).")
    assert rest_counts(rows, [None, None, None, {"verdict": "not measured"}]) == ""
    assert "differs" not in rest_counts(rows[1:2], rest[1:2])


def test_the_committed_page_counts_hf2_from_rest(seeds32):
    """Every hf2_rest pad is saturated under the rule for pads released from rest, so the rows that need HF2 are
    measured from rest; the page's count of that column names the first peaks it reproduces."""
    results, _ = seeds32
    assert {p["status"] for p in results["hf2_rest"]["pads"]} == {"saturated"}
    page = (SEEDS32.parent / "validation.md").read_text()
    line = next(x for x in page.splitlines() if x.startswith("From rest at the paper's length"))
    assert "HF2: first velocity-spectrum peak (not reproduced → reproduced)" in line


def test_the_rows_of_the_first_peak_against_m_the_pressures_and_the_filtered_extremes(seeds32) -> None:
    """The three statements added to the table: f1 read against M as an equivalence of the pairs of one seed, the
    surface pressures from the pads' loads, and S = 1 / S = 0 with the filter; each fails when its quantity moves."""
    results, cfg = seeds32
    m_row = _row("the first velocity peak does not depend on M (HF3 as HF1, HF4 as HF2)")
    v = m_row.measure(results, cfg)
    assert v.verdict == P and v.value.startswith("hf3/hf1: f1 ×0.995") and "per-patch mean spectrum at 0.1" in v.notes
    rest = {n: results[f"{n}_rest"] for n in ("hf1", "hf2", "hf3", "hf4")}
    assert m_row.measure(rest, cfg).verdict == R
    pads = [{**p, "measures": {**p["measures"], "f1": 1.2 * p["measures"]["f1"]}} for p in rest["hf3"]["pads"]]
    shifted = {**rest, "hf3": {**rest["hf3"], "pads": pads}}
    assert m_row.measure(shifted, cfg).verdict == P  # hf3/hf1 beyond ± 5 %, hf4/hf2 still within
    p_row = _row("the loads give a surface pressure of about 44 kPa (HF1, HF3) and 1108 kPa (HF2, HF4)")
    assert p_row.measure(results, cfg).verdict == R and "hf2 1115 [1115, 1115] kPa" in p_row.measure(results, cfg).value
    heavy = {
        **results,
        "hf1": {**results["hf1"], "pads": [{**p, "normal_force_N": 600.0} for p in results["hf1"]["pads"]]},
    }
    assert p_row.measure(heavy, cfg).verdict == P
    pads = {n: [{**p, "normal_force_N": p["normal_force_N"] * 150 / 1758} for p in results[n]["pads"]] for n in PRESETS}
    fewer = {n: {**results[n], "pads": pads[n]} for n in PRESETS}  # a narrower sector of 150 patches, its load alike
    assert p_row.measure(fewer, dataclasses.replace(cfg, patches=150)).value.startswith("F_N / A_pad: hf1 43.91")
    f_row = next(r for r in VB.ROWS if r.section == "§2.2, Eq. 6")
    f = f_row.measure({}, cfg)
    assert (
        f.verdict == R
        and f.value.startswith("one bin: S 1.000–1.000")
        and "n_AB,min = 1.176 with the filter" in f.notes
    )


def test_the_growth_rows_of_the_cwt_and_of_the_load_path(seeds32) -> None:
    """§3.2's CWT (Fig. 11) and the load's path, read from the committed growth runs: the ridge of the
    energy-normalised CWT within 20–80 kHz falls and follows a trend the STFT's largest bin there does not, but the
    CWT's other readings give other verdicts, so the row is undetermined, each reading in the notes with its verdict;
    the matrix share never rises in any pad and falls by its start; the emergence of lines reads the CWT beside the
    spectrum (not from equilibrium, in both from rest)."""
    results, cfg = seeds32
    cwt = _row("in the CWT of μ the decreasing frequencies of the characteristic peaks are clearer to observe")
    v = cwt.measure(results, cfg)
    assert v.verdict == U and v.value.startswith("−Δ ln f of the ridge of μ's CWT in 20–80 kHz: 0.298")
    assert "there: 0.534 [0.476, 0.593]" in v.value and "the ridge in 20–80 kHz: reproduced" in v.notes
    assert "edge grid point in 6 % of the windows" in v.notes
    for reading in ("ridge (against", "first line (against", "ridge, amplitude-true", "first line, amplitude-true"):
        assert reading in v.notes
    assert "ridge, amplitude-true (against μ's STFT dominant line): −Δ ln f 0.367" in v.notes
    assert cwt.measure({"va_full": results["va_full_rest"]}, cfg).verdict == U
    share = _row(
        "as the patches grow, their stiffnesses increase and they carry an increasing portion of the normal load"
    )
    v = share.measure(results, cfg)
    assert v.verdict == R and "pads whose share never rises: 32 of 32" in v.notes and share.construction
    assert "its fall from the start to the end: 0.533" in v.value
    emerge = _row("individual dominant frequencies emerge in μ's spectrum, in the STFT and in the CWT")
    assert emerge.measure(results, cfg).verdict == N
    rest = emerge.measure({"va_full": results["va_full_rest"]}, cfg)
    assert rest.verdict == R and "of μ's CWT: 0.816" in rest.value
