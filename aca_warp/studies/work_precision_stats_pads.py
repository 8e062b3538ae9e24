"""The pads far from their ensemble's median: which seeds make a heavy-tailed measure's verdict.

A measure such as a growing pad's STFT maximum lies near the pads' median for most pads and several times higher for
the few that turn tonal; which pads do can change from one setting's runs to another's, and then a verdict follows
those pads rather than the step (docs/work_precision_statistics.md, va). :func:`pads_far_from_median` lists them per
setting, with each one's value against the median and its difference from the reference's value of the same pad in
units of the σ between seeds the rule takes, so that statements about them come from the committed result files
(``work_precision_stats.py --by-pad FILE --measures …``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from aca_warp.studies.work_precision_stats_rule import (
    MEASURES,
    _matrix,
    _members,
    measures_asked,
    member_comparisons,
    reference_of,
    usable,
)

DEFAULT_FACTOR = 3.0
"""A pad counts as far from the median when its value is at least this many times the pads' median."""


def _cell(seeds: np.ndarray, v: np.ndarray, r: np.ndarray, median: float, sigma: float, far: np.ndarray) -> str:
    """The far pads of one setting and member: ``seed: value / median ×, difference / σ`` each, or "none".
    ``seeds``, ``v`` (the setting's values), ``r`` (the reference's) and ``far`` (bool): shape (pads of the member,);
    ``median`` in the measure's unit, ``sigma`` the member's σ between seeds in it."""
    parts = []
    for k in np.flatnonzero(far):
        d = (v[k] - r[k]) / sigma if sigma > 0 else math.nan
        parts.append(f"{int(seeds[k])}: {v[k] / median:.1f}×, {d:+.1f} σ")
    return "; ".join(parts) or "none"


def _listable(reg: dict[str, Any], measure: str) -> bool:
    """A scalar measure whose finite reference values are all positive (a median and ratios to it mean something)."""
    r = _matrix(reference_of(reg)["values"][measure])
    finite = r[np.isfinite(r)] if r.ndim == 1 else r
    return r.ndim == 1 and finite.size > 0 and bool(np.all(finite > 0))


def _rows(reg: dict[str, Any], measure: str, factor: float, settings: list[dict[str, Any]]) -> list[str]:
    """The table rows of one measure: per member and setting, the pads' median and the far pads (:func:`_cell`),
    each difference in units of the member's σ as the rule's comparison takes it (:func:`member_comparisons`)."""
    ref = reference_of(reg)
    seeds = np.array([int(p["seed"]) for p in reg["pads"]])
    sigmas = [[c.sigma for c in member_comparisons(reg, s, measure)] for s in settings]  # per setting, per member
    out = []
    for k, (member, idx) in enumerate(_members(reg).items()):
        r = _matrix([ref["values"][measure][i] for i in idx])
        for s, sigma in zip(settings, (per_member[k] for per_member in sigmas), strict=True):
            v = _matrix([s["values"][measure][i] for i in idx])
            median = float(np.nanmedian(v))
            label = f"`{s['label']}`" + (" (reference)" if s is ref else "")
            cell = _cell(seeds[idx], v, r, median, sigma, v >= factor * median)
            out.append(f"| {MEASURES[measure].label} | {member or '–'} | {label} | {median:.4g} | {cell} |")
    return out


def pads_far_from_median(doc: dict[str, Any], measures: Sequence[str] | None = None,
                         factor: float = DEFAULT_FACTOR) -> str:  # fmt: skip
    """Markdown: per scalar measure of the file's one regime whose values are positive, member and completed setting
    (the reference first), the pads' median and every pad whose value is at least ``factor`` × that median, each
    with its seed, its value in units of the median and its difference from the reference's value of the same pad in
    units of σ (the reference's standard deviation between the member's seeds, as the rule's comparison takes it).
    ``measures``: default every measure of the regime; a vector measure or one with a value ≤ 0 is left out with a
    line saying so. ValueError for a file of several regimes, a measure it lacks or a factor ≤ 1."""
    if not factor > 1:
        raise ValueError(f"the factor must exceed 1, got {factor:g}")
    if len(doc.get("regimes", {})) != 1:
        raise ValueError("pads by setting need a result file of one regime")
    name, reg = next(iter(doc["regimes"].items()))
    names = measures_asked(name, reg, measures)
    ref = reference_of(reg)
    settings = [ref] + [s for s in reg["settings"] if s["role"] != "reference" and usable(s)]
    lines = ["| measure | member | setting | pads' median | pads ≥ "
             f"{factor:g} × the median (seed: value / median, difference from the reference / σ) |",
             "|---|---|---|---|---|"]  # fmt: skip
    skipped = [MEASURES[m].label for m in names if not _listable(reg, m)]
    for m in names:
        if MEASURES[m].label not in skipped:
            lines += _rows(reg, m, factor, settings)
    head = f"{name}: the pads far from the median, by setting ({len(reg['pads'])} pads)\n\n"
    tail = "".join(f"\n{label}: left out (a vector measure, or a value not positive)\n" for label in skipped)
    return head + "\n".join(lines) + "\n" + tail
