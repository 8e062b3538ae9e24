"""The runs from rest at the paper's length over time (``Experiment.tracks``): per preset and window the means over
the pads of the first velocity peak (Σu̇; the per-patch one beside), the correlation of the directions of motion of
coupled neighbours and the size of the co-moving groups, S − S_null (median over Φ ≥ 10, both rules), the spread of
S and μ's standard deviation — beside the same measures of the saturated equilibrium-start ensemble.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aca_warp.studies.report import md_table
from aca_warp.studies.validation.base import EXPERIMENTS, usable, values

COLUMNS = (
    ("f1", "f1 Σu̇ [kHz]", ".1f", 1e-3),
    ("f1_patch", "f1 per-patch (0.1) [kHz]", ".1f", 1e-3),
    ("corr_near", "C coupled neighbours", ".3f", 1.0),
    ("corr_zero", "group size [mm]", ".2f", 1e3),
    ("excess_relative", "S − S_null (Φ ≥ 10), relative", ".4f", 1.0),
    ("excess_snr", "S − S_null (Φ ≥ 10), snr", ".4f", 1.0),
    ("spread", "spread", ".3f", 1.0),
    ("mu_std", "std μ", ".3g", 1.0),
)
EQUILIBRIUM_KEYS = {
    "excess_relative": "sync_relative.median_excess_phi10",
    "excess_snr": "sync_snr.median_excess_phi10",
    "spread": "sync_relative.spread",
    "f1_patch": "f1_patch.0p1",
}


def _mean(vals: list[Any], spec: str, scale: float) -> str:
    x = np.array([v for v in vals if isinstance(v, (int, float)) and np.isfinite(v)], dtype=np.float64)
    return format(float(np.mean(x)) * scale + 0.0, spec) if x.size else "–"


def track_table(results: dict[str, dict], name: str) -> tuple[list[str], list[list[str]]]:
    """One line per track window of the experiment ``name`` (means over its analysed pads), then the equilibrium
    ensemble's final values."""
    res = results.get(name) or {}
    pads = [p for p in res.get("pads", []) if p.get("tracks")]
    windows = sorted({(w["start_s"], w["end_s"]) for p in pads for w in p["tracks"]})
    header = ["window [ms]", "pads", *(c[1] for c in COLUMNS)]
    rows = []
    for a, b in windows:
        ws = [w for p in pads for w in p["tracks"] if (w["start_s"], w["end_s"]) == (a, b) and "failed" not in w]
        rows.append([f"{a * 1e3:.1f}–{b * 1e3:.1f}", str(len(ws)),
                     *(_mean([w.get(k) for w in ws], spec, sc) for k, _, spec, sc in COLUMNS)])  # fmt: skip
    base = name.removesuffix("_rest")
    eq = results.get(base)
    if eq is not None and usable(eq):
        cells = []
        for k, _, spec, sc in COLUMNS:
            key = "mu_std" if k == "mu_std" else EQUILIBRIUM_KEYS.get(k, k)
            v = values(eq, key)
            cells.append(format(float(np.mean(v)) * sc + 0.0, spec) if v.size else "–")
        rows.append([f"{base}: equilibrium start, saturated", str(len(usable(eq))), *cells])
    return header, rows


def track_lines(results: dict[str, dict]) -> list[str]:
    """Every tracked experiment's table (markdown lines)."""
    lines: list[str] = []
    for name, exp in EXPERIMENTS.items():
        if not exp.tracks or not (results.get(name) or {}).get("pads"):
            continue
        lines += [f"**{name}** ({exp.description}):", "", *md_table(*track_table(results, name)), ""]
    return lines or ["No run from rest at the paper's length in these results."]
