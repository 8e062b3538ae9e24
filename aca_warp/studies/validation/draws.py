"""How much the draw of seeds decides a verdict: every row read on the whole of a larger ensemble and on each of its
disjoint draws of the validation's size (``scripts/validation_draws.py``; docs/validation.md, "On 32 seeds").

A row whose verdict is the same on every draw is not carried by the draw; a row whose draws disagree sits on the
edge of its criterion at that ensemble size, and its verdict on the whole ensemble (with its narrower intervals) is
the one to read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from aca_warp.studies.validation.base import ROWS, Config, evaluate_rows
from aca_warp.studies.validation.causes import SHORT, seed_range
from aca_warp.studies.validation.verdicts import FAILED, NOT_MEASURED


def draws(cfg: Config, size: int) -> list[tuple[int, int]]:
    """The disjoint draws of ``size`` consecutive seeds that the ensemble of ``cfg`` holds: [(first, last + 1)];
    ValueError when it holds fewer than two."""
    if size < 2:
        raise ValueError(f"a draw needs at least 2 seeds (got {size})")
    count = cfg.seeds // size
    if count < 2:
        raise ValueError(f"{cfg.seeds} seeds hold fewer than two draws of {size}")
    return [(cfg.first_seed + k * size, cfg.first_seed + (k + 1) * size) for k in range(count)]


def draw_verdicts(
    results: dict[str, dict], cfg: Config, size: int, against: list[dict[str, str]] | None = None
) -> list[dict[str, Any]]:
    """Every row measured on the whole ensemble: its verdict and value there (``whole``, ``value``), its verdict on
    each draw of ``size`` seeds (``draws``, in the order of :func:`draws`), how many draws read the whole's verdict
    (``agree``; a failed row agrees with nothing, so that it stands out), and ``against``: the verdict of each other
    results file given (``against``, statement -> verdict per file; not measured where a file lacks the row).

    A draw is evaluated as an ensemble of its own, with the settings of one (``seeds``, ``first_seed``); the rows
    read only the pads' entries today, so the same pads give the same verdict under the whole's settings."""
    ranges = draws(cfg, size)
    whole = evaluate_rows(results, cfg)
    parts = [evaluate_rows(seed_range(lo, hi)(results), dataclasses.replace(cfg, seeds=size, first_seed=lo))
             for lo, hi in ranges]  # fmt: skip
    out = []
    for i, (row, main) in enumerate(zip(ROWS, whole, strict=True)):
        if main["verdict"] == NOT_MEASURED:
            continue
        got = [p[i]["verdict"] for p in parts]
        out.append(
            {
                "section": row.section,
                "statement": row.statement,
                "whole": main["verdict"],
                "value": main["value"],
                "draws": got,
                "agree": sum(v == main["verdict"] != FAILED for v in got),
                "against": [other.get(row.statement, NOT_MEASURED) for other in against or []],
            }
        )
    return out


def verdicts_by_statement(results: dict[str, dict], cfg: Config) -> dict[str, str]:
    """Statement -> verdict of every row of ``results``."""
    return {r["statement"]: r["verdict"] for r in evaluate_rows(results, cfg)}


def render(
    table: list[dict[str, Any]], cfg: Config, size: int, against_labels: Sequence[str] = (), split_only: bool = False
) -> list[str]:
    """The markdown table of :func:`draw_verdicts` (✓ reproduced, ~ partly, ✗ not reproduced, ≈ significant but
    negligible, ? undetermined, n/c not comparable, · not measured, ! failed), rows whose draws disagree (or that
    failed) in bold, a column per other results file (``against_labels``, in the order of the rows' ``against``),
    a line counting the split rows and one per other file counting the rows it reads as the whole ensemble does;
    ``split_only``: the split rows alone."""
    ranges = draws(cfg, size)
    head = ["§", "statement", f"{cfg.seeds} seeds", *(f"seeds {lo}–{hi - 1}" for lo, hi in ranges), "draws agreeing"]
    head += list(against_labels)
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    split = 0
    for r in table:
        marks = [SHORT.get(v, v) for v in (r["whole"], *r["draws"])]
        cells = [r["section"], r["statement"], *marks, f"{r['agree']} of {len(ranges)}"]
        if r["agree"] < len(ranges):
            split += 1
            cells[1] = f"**{cells[1]}**"
        elif split_only:
            continue
        cells += [SHORT.get(v, v) for v in r["against"]]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", f"{split} of {len(table)} rows measured have draws of {size} seeds that read otherwise than all "
              f"{cfg.seeds} seeds."]  # fmt: skip
    for k, label in enumerate([] if split_only else against_labels):
        alike = sum(r["against"][k] == r["whole"] != FAILED for r in table)
        lines.append(f"{label} reads {alike} of the {len(table)} rows as all {cfg.seeds} seeds do.")
    return lines
