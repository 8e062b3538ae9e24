"""Two validation results files side by side: does a rerun regenerate every number of the committed one?

Compared is every entry of every experiment's result — each pad's facts and measures, the plan, the run's steps,
step and segments, the analysed segment, the status, and the §3.3 LF facts with the LF runs' digests — except the
provenance, the timings and the stepping's reason (:data:`NOT_COMPARED`); an entry absent from one file and None
in the other counts as the same (a field added since, at its default). Every entry is compared as stored (floats
to six significant digits, :data:`~aca_warp.studies.validation.results.SIGNIFICANT`), so "the same" means equal to
the digits the page is made from. Then what the page says: every row's verdict and value text, the rows from rest
beside them, and the variants of the causes (:func:`~aca_warp.studies.validation.results.evaluate`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

NOT_COMPARED = (
    "experiment",  # the definition (checked when results are reused, not here)
    "config",  # the settings as the run key (the page's settings line)
    "total_s",
    "analysis_s",
    "run.wall_s",
    "run.compile_s",
    "run.us_per_step",
    "run.stages",
    "run.device",
    "run.engine",
    "run.stepping.reason",  # why the table chose the stepping: documentation
    "plan.estimate_s",
)
"""Entries of an experiment's result that are provenance, timings or documentation (dotted paths; everything below
them)."""


@dataclass
class Difference:
    """The comparison of one experiment: entries compared and differing, the largest relative difference of two
    numbers and the first differing entry (its path), and entries present on one side only."""

    name: str
    entries: int = 0
    differing: int = 0
    largest: float = 0.0
    first: str = ""
    only_one_side: list[str] = field(default_factory=list)

    @property
    def same(self) -> bool:
        return self.differing == 0 and not self.only_one_side


def _leaves(obj: Any, path: str, out: dict[str, Any]) -> None:
    if path in NOT_COMPARED:
        return
    if isinstance(obj, dict):
        for k, v in obj.items():
            _leaves(v, f"{path}.{k}" if path else str(k), out)
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            _leaves(v, f"{path}[{i}]", out)
    else:
        out[path] = obj


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _relative(a: Any, b: Any) -> float:
    """0 when equal (NaN equals NaN), else |a − b| / max(|a|, |b|) for two finite numbers, 1 for anything else."""
    if type(a) is type(b) and a == b:
        return 0.0
    if _number(a) and _number(b):
        if math.isnan(a) and math.isnan(b):
            return 0.0
        if math.isfinite(a) and math.isfinite(b) and a != b:
            return abs(a - b) / max(abs(a), abs(b))
        if a == b:  # 1 against 1.0
            return 0.0
    return 1.0


def compare_experiment(name: str, a: dict[str, Any] | None, b: dict[str, Any] | None) -> Difference:
    """The :class:`Difference` of the result ``a`` against ``b`` of experiment ``name`` (None: not in that file)."""
    if a is None or b is None:
        return Difference(name, only_one_side=["(the whole experiment)"])
    left: dict[str, Any] = {}
    right: dict[str, Any] = {}
    _leaves(a, "", left)
    _leaves(b, "", right)
    both = {**left, **right}  # an entry absent on one side and None on the other: a field added later, at its default
    d = Difference(name, only_one_side=sorted(p for p in set(left) ^ set(right) if both[p] is not None))
    for path in sorted(set(left) & set(right)):
        d.entries += 1
        r = _relative(left[path], right[path])
        if r > 0:
            d.differing += 1
            d.first = d.first or f"{path}: {left[path]!r} against {right[path]!r}"
            d.largest = max(d.largest, r if _number(left[path]) and _number(right[path]) else 0.0)
    return d


def _said(results: dict[str, dict], cfg: Any) -> dict[str, list[tuple[str, str]]]:
    """What the page says, by group: (row statement, everything said of it) for the rows, the rows from rest and
    the variants of the causes."""
    from aca_warp.studies.validation.results import evaluate

    rows, rest, causes = evaluate(results, cfg)

    def text(d: dict[str, Any] | None) -> str:
        return json.dumps(d, sort_keys=True, default=str)

    return {
        "rows": [(r["statement"], f"{r['verdict']}: {r['value']} ({r['notes']})") for r in rows],
        "from rest": [(r["statement"], text(x)) for r, x in zip(rows, rest, strict=True)],
        "variants": [(f"{c['statement']} — {c['cause']}: {c['variant']}", text(c)) for c in causes],
    }


def _verdict(said: str) -> str:
    """The verdict in one entry of what the page says (a row's text, or a row from rest or variant as JSON); an entry
    on one side only ("–") counts as a verdict of its own, so a variant that appears or goes counts as moved."""
    if said.startswith("{"):
        return str(json.loads(said).get("verdict"))
    return said.split(":", 1)[0]


def compare_files(
    path_a: Path, path_b: Path, partial: bool = False
) -> tuple[list[Difference], dict[str, list[tuple[str, str, str]]]]:
    """Per experiment of either file, its :class:`Difference`; and per group of what the page says, the entries
    that differ: (statement, in ``path_a``, in ``path_b``). ``partial``: ``path_a`` holds some experiments only
    (e.g. one group run at another stepping): the experiments it lacks are taken from ``path_b``, and only its own
    are compared entry by entry; the two files must share their settings but the stepping. ValueError for a file
    that is not a results file, or for partial files of other settings."""
    from aca_warp.studies.validation.base import without_stepping
    from aca_warp.studies.validation.results import read_results

    ra, meta_a, cfg_a = read_results(path_a)
    rb, meta_b, cfg_b = read_results(path_b)
    if partial and without_stepping(meta_a["config"]) != without_stepping(meta_b["config"]):
        raise ValueError(f"{path_a} and {path_b} were made with other settings (besides the stepping): the first "
                         "file's experiments cannot stand in for the second's")  # fmt: skip
    names = list(ra) if partial else list(dict.fromkeys([*ra, *rb]))
    ra = {**rb, **ra} if partial else ra
    diffs = [compare_experiment(n, ra.get(n), rb.get(n)) for n in names]
    said_a, said_b = _said(ra, cfg_a), _said(rb, cfg_b)
    moved = {}
    for group in said_a:  # by statement: a verdict that moves can add or drop variants
        a, b = dict(said_a[group]), dict(said_b[group])
        moved[group] = [(s, a.get(s, "–"), b.get(s, "–")) for s in dict.fromkeys([*a, *b]) if a.get(s) != b.get(s)]
    return diffs, moved


def report(path_a: Path, path_b: Path, partial: bool = False) -> tuple[list[str], bool]:
    """Markdown lines of the comparison, and whether everything compared is the same (``partial``:
    :func:`compare_files`)."""
    diffs, moved = compare_files(path_a, path_b, partial)
    which = (f"the experiments of `{path_a}`, the others taken from `{path_b}`, against `{path_b}`" if partial
             else f"`{path_a}` against `{path_b}`")  # fmt: skip
    lines = [
        f"{which}: every entry of every experiment's result but provenance, timings and the "
        "stepping's reason, as stored (6 significant digits), then what the page says",
        "",
        "| experiment | entries | differing | largest relative difference | first difference | on one side only |",
        "|---|---|---|---|---|---|",
    ]
    for d in diffs:
        one = ", ".join(d.only_one_side[:3]) + (f" (+{len(d.only_one_side) - 3})" if len(d.only_one_side) > 3 else "")
        lines.append(f"| {d.name} | {d.entries} | {d.differing} | {d.largest:.3g} | {d.first or '–'} | {one or '–'} |")
    same = all(d.same for d in diffs) and not any(moved.values())
    total, differing = sum(d.entries for d in diffs), sum(d.differing for d in diffs)
    one_side = sum(len(d.only_one_side) for d in diffs)
    verdicts = {g: sum(_verdict(a) != _verdict(b) for _, a, b in m) for g, m in moved.items()}
    lines += [
        "",
        f"{differing} of {total} entries differ, {one_side} on one side only; what the page says differs in "
        + ", ".join(f"{len(m)} {group}" for group, m in moved.items())
        + "; the verdict moved in "
        + ", ".join(f"{n} {group}" for group, n in verdicts.items())
        + ".",
    ]
    for group, m in moved.items():
        lines += [f"* {group}: {s}: {a} → {b}" for s, a, b in m]
    return lines, same
