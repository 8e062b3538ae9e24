#!/usr/bin/env python3
"""Where a kernel's warps wait: the stall reasons of Nsight Compute's warp-state sampling, from a SASS source export.

Reads the export of one profiled launch's source page, made with the ``SourceCounters`` section::

    ncu --clock-control none -k regex:onchip_strang --launch-skip 1 --launch-count 1 \\
        --section WarpStateStats --section SourceCounters -o prof python3 ...
    ncu -i prof.ncu-rep --page source --csv --print-source sass > sass.csv      # gzip it if you like

and prints each stall reason's share of all samples (``stall_wait``: a fixed-latency dependency, the arithmetic
chain; ``short_sb``: shared memory or special-function results; ``long_sb``: global or distributed shared memory;
``barrier``: barriers and mbarrier waits; ``selected``: issuing) and the instructions with the most samples. Writes
the same as Markdown with ``--markdown``. docs/onchip.md, "The friction solve at the default step", cites it.

Example::

    python3 scripts/ncu_stalls.py docs/benchmarks/onchip_h200_solver/ncu_cluster8_sass.csv.gz --top 10

``--against OTHER`` compares with the export of another launch of the same code (the same instructions at the same
offsets from the kernel's first one; refused otherwise): the instructions whose samples grew the most, e.g. where a
pad's step waits longer than another's::

    python3 scripts/ncu_stalls.py docs/benchmarks/onchip_h200_solver/ncu_va_cluster8_sass.csv.gz \
        --against docs/benchmarks/onchip_h200_solver/ncu_cluster8_sass.csv.gz --top 12
"""

from __future__ import annotations

import argparse
import csv
import gzip
import sys
from collections import Counter
from pathlib import Path

SAMPLES = "Warp Stall Sampling (All Samples)"


def read_sass(path: Path) -> tuple[str, list[dict[str, str]]]:
    """(kernel name, one dict per SASS instruction) of an ``ncu --page source --csv --print-source sass`` export."""
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 2 or not rows[0] or rows[0][0] != "Kernel Name":
        raise ValueError(f"{path}: not an ncu source-page export (its first row names no kernel)")
    header = rows[1]
    if SAMPLES not in header:
        raise ValueError(f"{path}: no '{SAMPLES}' column (profile with --section SourceCounters)")
    body = [r for r in rows[2:] if r]
    for k, r in enumerate(body, start=3):
        if len(r) != len(header):
            raise ValueError(f"{path}: row {k} has {len(r)} fields, the header {len(header)}")
    return rows[0][1], [dict(zip(header, r, strict=True)) for r in body]


def _count(value: str) -> int:
    """A sample count of the export: digits, possibly with thousands separators; empty or "-" for none."""
    text = value.strip().replace(",", "")
    if text in ("", "-"):
        return 0
    if not text.isdigit():
        raise ValueError(f"not a sample count: {value!r}")
    return int(text)


def _reasons(row: dict[str, str]) -> Counter[str]:
    """One instruction's samples per stall reason (the columns ``stall_*``, all samples, not only the not-issued)."""
    return Counter({k.removeprefix("stall_"): _count(v) for k, v in row.items()
                    if k.startswith("stall_") and "Not Issued" not in k})  # fmt: skip


def stall_shares(rows: list[dict[str, str]]) -> tuple[int, list[tuple[str, int, float]]]:
    """(all samples, [(reason, samples, share of all)] largest first) over the sampled stall reasons."""
    total = sum(_count(r[SAMPLES]) for r in rows)
    reasons = sum((_reasons(r) for r in rows), Counter())
    return total, [(k, n, n / total if total else 0.0) for k, n in reasons.most_common() if n]


def top_instructions(rows: list[dict[str, str]], n: int) -> list[tuple[str, str, int, str]]:
    """The ``n`` instructions with the most samples: (address, SASS, samples, their two largest reasons)."""
    out = []
    for r in sorted(rows, key=lambda r: -_count(r[SAMPLES]))[:n]:
        words = ", ".join(f"{k} {v}" for k, v in _reasons(r).most_common(2) if v)
        out.append((r.get("Address", ""), " ".join(r.get("Source", "").split()), _count(r[SAMPLES]), words))
    return out


def _mnemonic(sass: str) -> str:
    """The opcode of a SASS line, without its predicate and operands (branch targets are absolute addresses)."""
    words = sass.split()
    return (words[1] if words and words[0].startswith("@") else words[0]) if words else ""


def by_offset(rows: list[dict[str, str]]) -> dict[int, dict[str, str]]:
    """The instructions keyed by their offset [bytes] from the kernel's first one."""
    addresses = [int(r["Address"], 16) for r in rows]
    first = min(addresses, default=0)
    return {a - first: r for a, r in zip(addresses, rows, strict=True)}


def grown_instructions(
    rows: list[dict[str, str]], other: list[dict[str, str]], n: int
) -> tuple[int, list[tuple[str, str, int, int, str]]]:
    """(all samples of ``rows`` less those of ``other``, the ``n`` instructions whose samples grew the most from
    ``other``'s: (offset, SASS, samples, samples in ``other``, the two largest reasons)). The two exports must be of
    the same code: the same opcode at every offset (ValueError otherwise)."""
    here, there = by_offset(rows), by_offset(other)
    same = here.keys() == there.keys() and all(
        _mnemonic(here[k].get("Source", "")) == _mnemonic(there[k].get("Source", "")) for k in here
    )
    if not same:
        raise ValueError("the two exports are not of the same code (instructions differ at equal offsets)")
    grown = sorted(here, key=lambda k: _count(there[k][SAMPLES]) - _count(here[k][SAMPLES]))[:n]
    out = []
    for k in grown:
        words = ", ".join(f"{r} {v}" for r, v in _reasons(here[k]).most_common(2) if v)
        src = " ".join(here[k].get("Source", "").split())
        out.append((f"{k:#x}", src, _count(here[k][SAMPLES]), _count(there[k][SAMPLES]), words))
    total = sum(_count(r[SAMPLES]) for r in rows) - sum(_count(r[SAMPLES]) for r in other)
    return total, out


def span_samples(rows: list[dict[str, str]], first: int, last: int) -> int:
    """The samples of the instructions at offsets ``first`` … ``last`` [bytes] from the kernel's first one."""
    return sum(_count(r[SAMPLES]) for k, r in by_offset(rows).items() if first <= k <= last)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sass", type=Path, help="the source-page export (.csv or .csv.gz)")
    ap.add_argument("--top", type=int, default=10, help="instructions to list (default 10)")
    ap.add_argument("--markdown", type=Path, default=None, help="write the tables here")
    against = "another launch's export of the same code: the instructions whose samples grew most"
    span = "with --against: both exports' samples at offsets FIRST..LAST (hex), e.g. a loop; repeatable"
    ap.add_argument("--against", type=Path, default=None, help=against)
    ap.add_argument("--span", nargs=2, action="append", default=[], metavar=("FIRST", "LAST"), help=span)
    args = ap.parse_args(argv)
    if args.top < 0:
        ap.error("--top must be >= 0")
    try:
        kernel, rows = read_sass(args.sass)
        total, shares = stall_shares(rows)
        top = top_instructions(rows, args.top)
        other = read_sass(args.against)[1] if args.against else None
        grown = grown_instructions(rows, other, args.top) if other is not None else None
        spans = [(int(a, 16), int(b, 16)) for a, b in args.span]
    except (OSError, ValueError) as exc:
        ap.error(str(exc))
    if spans and other is None:
        ap.error("--span needs --against")
    lines = [f"Warp-state samples of {kernel} ({total} samples; {args.sass.name}, scripts/ncu_stalls.py)", "",
             "| stall reason | samples | share |", "|---|---|---|"]  # fmt: skip
    lines += [f"| {k} | {n} | {s:.1%} |" for k, n, s in shares]
    lines += ["", "| address | instruction | samples | largest reasons |", "|---|---|---|---|"]
    lines += [f"| {a} | `{src}` | {n} | {why} |" for a, src, n, why in top]
    if grown is not None:
        more, rows_grown = grown
        lines += ["", f"Against {args.against.name}: {more:+d} samples in all; the instructions that grew most", "",
                  "| offset | instruction | samples | there | more | largest reasons |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        lines += [f"| {o} | `{src}` | {n} | {m} | {n - m:+d} | {why} |" for o, src, n, m, why in rows_grown]
        for a, b in spans:
            n, m = span_samples(rows, a, b), span_samples(other, a, b)
            lines.append(f"\nOffsets {a:#x}..{b:#x}: {n} samples, {m} there ({n - m:+d}).")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
