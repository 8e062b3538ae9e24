"""Two validation results files side by side: does a rerun regenerate every number of the committed one?

Compared are what the rows read, experiment by experiment: each pad's facts and measures (``pads``), the analysed
segment (``segment``) and the status, and the §3.3 LF facts (``lf_states``); left out are the provenance and the
timings (``run``, ``plan``'s estimate, ``total_s``, ``analysis_s``, ``config``, ``experiment``). Every number is
compared as stored (six significant digits, :data:`~aca_warp.studies.validation.results.SIGNIFICANT`), so
"identical" means equal to the digits the page is made from. Then the rows: each row's verdict and value text, read
from both files (:func:`~aca_warp.studies.validation.results.evaluate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

COMPARED = ("pads", "segment", "status")
"""The keys of an experiment's result that hold what the rows read."""


@dataclass
class Difference:
    """The comparison of one experiment: numbers compared and differing, the largest relative difference and the
    first differing entry (its path), and entries present on one side only."""

    name: str
    numbers: int = 0
    differing: int = 0
    largest: float = 0.0
    first: str = ""
    only_one_side: list[str] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        return self.differing == 0 and not self.only_one_side


def _leaves(obj: Any, path: str, out: dict[str, Any]) -> None:
    if isinstance(obj, dict):
        for k, v in obj.items():
            _leaves(v, f"{path}.{k}" if path else str(k), out)
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            _leaves(v, f"{path}[{i}]", out)
    else:
        out[path] = obj


def _relative(a: Any, b: Any) -> float:
    """0 when equal (NaN equals NaN), else |a − b| / max(|a|, |b|) for numbers, 1 for anything else."""
    if a == b:
        return 0.0
    numbers = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (a, b))
    if numbers and math.isnan(a) and math.isnan(b):
        return 0.0
    if numbers and math.isfinite(a) and math.isfinite(b):
        return abs(a - b) / max(abs(a), abs(b))
    return 1.0


def compare_experiment(name: str, a: dict[str, Any], b: dict[str, Any]) -> Difference:
    """The :class:`Difference` of the result ``a`` against ``b`` of experiment ``name``."""
    left: dict[str, Any] = {}
    right: dict[str, Any] = {}
    keys = COMPARED if "pads" in a or "pads" in b else tuple(a)  # lf_states: every entry
    for k in keys:
        _leaves(a.get(k), k, left)
        _leaves(b.get(k), k, right)
    d = Difference(name, only_one_side=sorted(set(left) ^ set(right)))
    for path in sorted(set(left) & set(right)):
        d.numbers += 1
        r = _relative(left[path], right[path])
        if r > 0:
            d.differing += 1
            d.first = d.first or f"{path}: {left[path]!r} against {right[path]!r}"
            d.largest = max(d.largest, r)
    return d


def compare_files(path_a: Path, path_b: Path) -> tuple[list[Difference], list[tuple[str, str, str]]]:
    """Per experiment of either file, its :class:`Difference` (an experiment in one file only: every entry on one
    side); and the rows whose verdict or value text differ: (statement, in ``path_a``, in ``path_b``)."""
    from aca_warp.studies.validation.results import evaluate, read_results

    ra, _, cfg_a = read_results(path_a)
    rb, _, cfg_b = read_results(path_b)
    diffs = [compare_experiment(n, ra.get(n) or {}, rb.get(n) or {}) for n in dict.fromkeys([*ra, *rb])]
    rows_a, rows_b = evaluate(ra, cfg_a)[0], evaluate(rb, cfg_b)[0]
    moved = [
        (x["statement"], f"{x['verdict']}: {x['value']}", f"{y['verdict']}: {y['value']}")
        for x, y in zip(rows_a, rows_b, strict=True)
        if (x["verdict"], x["value"]) != (y["verdict"], y["value"])
    ]
    return diffs, moved


def report(path_a: Path, path_b: Path) -> tuple[list[str], bool]:
    """Markdown lines of the comparison, and whether every compared number and row is the same."""
    diffs, moved = compare_files(path_a, path_b)
    lines = [
        f"`{path_a}` against `{path_b}`: every number the rows read, as stored (6 significant digits)",
        "",
        "| experiment | numbers | differing | largest relative difference | first difference | on one side only |",
        "|---|---|---|---|---|---|",
    ]
    for d in diffs:
        one = ", ".join(d.only_one_side[:3]) + (f" (+{len(d.only_one_side) - 3})" if len(d.only_one_side) > 3 else "")
        lines.append(f"| {d.name} | {d.numbers} | {d.differing} | {d.largest:.3g} | {d.first or '–'} | {one or '–'} |")
    same = all(d.identical for d in diffs) and not moved
    total, differing = sum(d.numbers for d in diffs), sum(d.differing for d in diffs)
    lines += ["", f"{differing} of {total} numbers differ; rows whose verdict or value text differ: {len(moved)}."]
    lines += [f"* {s}: {a} → {b}" for s, a, b in moved]
    return lines, same
