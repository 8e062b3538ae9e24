"""The candidate causes of the open verdicts, run as experiments: does a change move a verdict?

Every row whose verdict is *not reproduced*, *partly*, *significant but negligible* or *undetermined* is evaluated
again under each **variant** that applies to it, and the page shows, statement by statement, which change moves
which verdict. A variant either replaces experiments by others that differ in one respect (``substitute``: the same
seeds and layouts, one setting changed) or changes the analysis of the same runs (``transform``):

* **initial state** — from rest at the paper's length (``hf*_rest``: 0.36 s; ``va_full_rest``), and for §3.3 from
  rest (``ms_*_rest``, opt-in); this variant is also shown beside every row of the main table
  (:func:`beside_rest`), since which state the paper's figures show is not stated;
* **run length** — the linear phase: the presets from rest for 4 ms, analysed over 0.2–4 ms unsaturated, as the
  single-run study of results_hf.md (``hf*_lin``); for §3.3 every LF state from rest for 2 ms (``ms_*_lin``);
* **height spread** — every patch height 3 µm (``hf*_equal``; for §3.2 ``va_equal``, compressed as ``va``);
* **single-run conditions** — equal heights, from rest and the 4 ms window together (``hf*_equal_lin``);
* **growth clock** — the varying-area growth compressed × ``Config.growth_speedup`` (``va``);
* **Φ rule** — the ``snr`` rule (κ = 5) as the primary rule instead of ``relative`` (η = 0.1), for rows built on
  S and Φ;
* **STFT window** — the STFT maximum over windows of 2^13 … 2^17 samples instead of 2^12 (rows built on it);
* **seeds** — the first and the second half of the seeds alone (is the verdict carried by a few seeds?).

A variant applies to a row when it replaces every experiment of the row (so that nothing is compared across
settings) or, for an analysis variant, when the row is built on what it changes (``Row.uses``).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from aca_warp.studies.validation.base import ROWS, Config, Row, evaluate_rows
from aca_warp.studies.validation.hf_experiments import PRESETS
from aca_warp.studies.validation.verdicts import (
    FAILED,
    NEGLIGIBLE,
    NOT_COMPARABLE,
    NOT_MEASURED,
    NOT_REPRODUCED,
    PARTLY,
    REPRODUCED,
    UNDETERMINED,
)

OPEN = (NOT_REPRODUCED, PARTLY, NEGLIGIBLE, UNDETERMINED)  # the verdicts whose causes are tested


# ------------------------------------------------------------------------------------------------ variants


@dataclass(frozen=True)
class Variant:
    """One candidate cause, as a change of the experiments or of the analysis.

    Attributes:
        cause: The candidate cause (column of the summary).
        label: What the variant changes, in a few words.
        substitute: Experiment -> the experiment that replaces it (pairs).
        transform: ``results -> results`` (an analysis change of the same runs), or None.
        needs: For an analysis variant, what a row must use (``Row.uses``) for it to apply.
    """

    cause: str
    label: str
    substitute: tuple[tuple[str, str], ...] = ()
    transform: Callable[[dict[str, dict]], dict[str, dict]] | None = None
    needs: str | None = None

    def applies(self, row: Row) -> bool:
        """Whether the variant changes something the row depends on, and only that."""
        if self.substitute:
            return bool(row.experiments) and set(row.experiments) <= {a for a, _ in self.substitute}
        if self.needs is not None:
            return self.needs in row.uses
        return True

    def results(self, results: dict[str, dict]) -> dict[str, dict]:
        """The results the row sees under the variant."""
        out = dict(results)
        for a, b in self.substitute:
            if b in results:
                out[a] = results[b]
            else:
                out.pop(a, None)
        return self.transform(out) if self.transform is not None else out


def _map_pads(results: dict[str, dict], fn: Callable[[dict[str, Any]], dict[str, Any] | None]) -> dict[str, dict]:
    """A copy of ``results`` with every pad passed through ``fn`` (None drops the pad)."""
    out = {}
    for name, res in results.items():
        pads = [q for q in (fn(copy.copy(p)) for p in res.get("pads", [])) if q is not None]
        out[name] = {**res, "pads": pads}
    return out


def snr_rule(results: dict[str, dict]) -> dict[str, dict]:
    """Every pad's S and Φ measures under the snr rule where the rows read the relative rule's (and back)."""

    def swap(p: dict[str, Any]) -> dict[str, Any]:
        m = p.get("measures")
        if m and "sync_relative" in m and "sync_snr" in m:
            p["measures"] = {**m, "sync_relative": m["sync_snr"], "sync_snr": m["sync_relative"]}
        return p

    return _map_pads(results, swap)


def stft_window(samples: int) -> Callable[[dict[str, dict]], dict[str, dict]]:
    """Rows built on the STFT maximum read the window of ``samples`` samples."""

    def use(results: dict[str, dict]) -> dict[str, dict]:
        return _map_pads(results, lambda p: {**p, "stft_window": samples})

    return use


def seed_range(lo: int, hi: int) -> Callable[[dict[str, dict]], dict[str, dict]]:
    """Only the pads of seeds ``lo`` … ``hi`` − 1."""

    def keep(results: dict[str, dict]) -> dict[str, dict]:
        return _map_pads(results, lambda p: p if lo <= int(p.get("seed", 0)) < hi else None)

    return keep


def seed_half(first: bool, seeds: int, first_seed: int) -> Callable[[dict[str, dict]], dict[str, dict]]:
    """Only the pads of the first (or the second) half of the seeds."""
    half = first_seed + seeds // 2
    return seed_range(first_seed, half) if first else seed_range(half, first_seed + seeds)


def _sub(names: tuple[str, ...], suffix: str) -> tuple[tuple[str, str], ...]:
    return tuple((n, f"{n}{suffix}") for n in names)


REST_VARIANTS = (
    ("initial state", "from rest, paper length", tuple((p, f"{p}_rest") for p in PRESETS)),
    ("initial state", "from rest, paper's growth rate", (("va_full", "va_full_rest"),)),
)


def variants(cfg: Config) -> list[Variant]:
    """Every variant, in the order of the summary's columns."""
    from aca_warp.studies.validation.multiscale import MAIN as ms

    half = cfg.seeds // 2
    out = [
        *(Variant(c, label, sub) for c, label, sub in REST_VARIANTS),
        Variant("initial state", "from rest", _sub(ms, "_rest")),
        Variant("run length", "linear phase: 4 ms from rest, 0.2–4 ms", _sub(PRESETS, "_lin")),
        Variant("run length", "linear phase: 2 ms from rest, 0.5–2 ms", _sub(ms, "_lin")),
        Variant("height spread", "equal heights (3 µm)", _sub(PRESETS, "_equal")),
        Variant("height spread", f"equal heights, growth compressed × {cfg.growth_speedup:g}",
                (("va_full", "va_equal"),)),
        Variant("single-run conditions", "equal heights, rest, 0.2–4 ms", _sub(PRESETS, "_equal_lin")),
        Variant("growth clock", f"compressed × {cfg.growth_speedup:g}", (("va_full", "va"),)),
        Variant("Φ rule", "snr rule (κ = 5)", transform=snr_rule, needs="sync"),
        *(Variant("STFT window", f"2^{k} samples", transform=stft_window(2**k), needs="stft") for k in range(13, 18)),
        Variant("seeds", f"seeds {cfg.first_seed}–{cfg.first_seed + half - 1}",
                transform=seed_half(True, cfg.seeds, cfg.first_seed)),
        Variant("seeds", f"seeds {cfg.first_seed + half}–{cfg.first_seed + cfg.seeds - 1}",
                transform=seed_half(False, cfg.seeds, cfg.first_seed)),
    ]  # fmt: skip
    return out


def beside_rest(results: dict[str, dict], cfg: Config, rows: list[Row] | None = None) -> list[dict[str, Any] | None]:
    """Every row evaluated from rest at the paper's length (the §3.1 presets' ``hf*_rest``, §3.2's
    ``va_full_rest``), or None where that variant does not apply or was not run."""
    out: list[dict[str, Any] | None] = []
    for row in ROWS if rows is None else rows:
        entry = None
        for cause, label, sub in REST_VARIANTS:
            v = Variant(cause, label, sub)
            if v.applies(row) and all(b in results for a, b in sub if a in row.experiments):
                entry = evaluate_rows(v.results(results), cfg, [row])[0]
                entry["variant"] = label
                break
        out.append(entry)
    return out


def evaluate_causes(results: dict[str, dict], cfg: Config, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every applicable variant of every open row (verdict in :data:`OPEN`): value, verdict, and whether it moved.

    ``rows``: the main rows as :func:`evaluate_rows` returned them (in the order of :data:`ROWS`).
    """
    out = []
    for row, main in zip(ROWS, rows, strict=True):
        if main["verdict"] not in OPEN:
            continue
        for v in variants(cfg):
            targets = [b for a, b in v.substitute if a in row.experiments]
            if not v.applies(row) or not all(b in results for b in targets):
                continue  # a variant whose experiments were not run
            if v.substitute and all(results.get(a) is results.get(b) for a, b in v.substitute):
                continue  # the variant is what the row already reads (va_full as the rows' source)
            e = evaluate_rows(v.results(results), cfg, [row])[0]
            if v.transform is not None and e["verdict"] == NOT_MEASURED:
                continue  # an analysis the runs cannot give (a window longer than the record, a half of 1 seed)
            out.append(
                {
                    "section": row.section,
                    "statement": row.statement,
                    "main_verdict": main["verdict"],
                    "cause": v.cause,
                    "variant": v.label,
                    "experiments": [dict(v.substitute).get(n, n) for n in row.experiments],
                    "value": e["value"],
                    "verdict": e["verdict"],
                    "notes": e["notes"],
                    "moved": e["verdict"] not in (main["verdict"], NOT_MEASURED, FAILED),
                }
            )
    return out


SHORT = {
    REPRODUCED: "✓",
    PARTLY: "~",
    NOT_REPRODUCED: "✗",
    NEGLIGIBLE: "≈",
    UNDETERMINED: "?",
    NOT_COMPARABLE: "n/c",
    NOT_MEASURED: "·",
    FAILED: "!",
}


def cause_summary(causes: list[dict[str, Any]]) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of the summary: one row per open statement, one column per cause; a cell lists the
    variants' verdicts (✓ reproduced, ~ partly, ✗ not reproduced, ≈ significant but negligible, ? undetermined,
    · not measured), in bold where it moved."""
    order = list(dict.fromkeys(c["cause"] for c in causes))
    by_row: dict[tuple[str, str], dict[str, list[str]]] = {}
    mains: dict[tuple[str, str], str] = {}
    for c in causes:
        key = (c["section"], c["statement"])
        mains[key] = c["main_verdict"]
        mark = SHORT.get(c["verdict"], c["verdict"])
        cell = f"**{mark}**" if c["moved"] else mark
        by_row.setdefault(key, {}).setdefault(c["cause"], []).append(f"{c['variant']}: {cell}")
    header = ["§", "statement", "main", *order]
    rows = [
        [sec, st, SHORT[mains[(sec, st)]], *("; ".join(cells.get(k, ["–"])) for k in order)]
        for (sec, st), cells in by_row.items()
    ]
    return header, rows
