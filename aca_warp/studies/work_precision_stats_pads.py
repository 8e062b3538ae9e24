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
    reference_of,
    usable,
)

DEFAULT_FACTOR = 3.0
"""A pad counts as far from the median when its value is at least this many times the pads' median."""


def _cell(seeds: np.ndarray, v: np.ndarray, r: np.ndarray, median: float, sigma: float, far: np.ndarray) -> str:
    """The far pads of one setting: ``seed: value / median ×, difference / σ`` each, or "none"."""
    parts = []
    for k in np.flatnonzero(far):
        d = (v[k] - r[k]) / sigma if sigma > 0 else math.nan
        parts.append(f"{int(seeds[k])}: {v[k] / median:.1f}×, {d:+.1f} σ")
    return "; ".join(parts) or "none"


def pads_far_from_median(doc: dict[str, Any], measures: Sequence[str] | None = None,
                         factor: float = DEFAULT_FACTOR) -> str:  # fmt: skip
    """Markdown: per scalar measure of the file's one regime whose values are positive, member and completed setting
    (the reference first), the pads' median and every pad whose value is at least ``factor`` × that median, each
    with its seed, its value in units of the median and its difference from the reference's value of the same pad in
    units of σ (the reference's standard deviation between the member's seeds, as the rule takes it). ``measures``:
    default every measure of the regime; a vector measure or one with a value ≤ 0 is left out with a line saying
    so. ValueError for a file of several regimes, a measure it lacks or a factor ≤ 1."""
    if not factor > 1:
        raise ValueError(f"the factor must exceed 1, got {factor:g}")
    if len(doc.get("regimes", {})) != 1:
        raise ValueError("pads by setting need a result file of one regime")
    name, reg = next(iter(doc["regimes"].items()))
    names = measures_asked(name, reg, measures)
    ref = reference_of(reg)
    rows = [ref] + [s for s in reg["settings"] if s["role"] != "reference" and usable(s)]
    seeds = np.array([int(p["seed"]) for p in reg["pads"]])
    lines = ["| measure | member | setting | pads' median | pads ≥ "
             f"{factor:g} × the median (seed: value / median, difference from the reference / σ) |",
             "|---|---|---|---|---|"]  # fmt: skip
    skipped = []
    for m in names:
        for member, idx in _members(reg).items():
            r = _matrix([ref["values"][m][i] for i in idx])
            if r.ndim != 1 or not np.all(np.isfinite(r) & (r > 0)):
                skipped.append(MEASURES[m].label)
                break
            sigma = float(np.std(r, ddof=1)) if len(r) > 1 else math.nan
            for s in rows:
                v = _matrix([s["values"][m][i] for i in idx])
                median = float(np.nanmedian(v))
                far = v >= factor * median
                label = f"`{s['label']}`" + (" (reference)" if s is ref else "")
                cell = _cell(seeds[idx], v, r, median, sigma, far)
                lines.append(f"| {MEASURES[m].label} | {member or '–'} | {label} | {median:.4g} | {cell} |")
    head = f"{name}: the pads far from the median, by setting ({len(seeds)} pads)\n\n"
    tail = "".join(f"\n{label}: left out (a vector measure, or values not all positive)\n" for label in skipped)
    return head + "\n".join(lines) + "\n" + tail
