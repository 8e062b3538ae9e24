"""The first velocity peak of §3.1 (Fig. 8, Table 1) as a figure, from a validation results file: every reading of
the peak the paper leaves open (:data:`~aca_warp.studies.validation.hf_peaks.F1_CANDIDATES` beside the primary) for
HF1–HF4 from the equilibrium start and from rest, each as the ensemble mean with its 95 % interval over the seeds
and the seeds' own values, against the paper's 73 and 32.8 kHz ± the rows' tolerance; and beside it the exponent of
f ∝ A^b each reading gives, from Table 1's two sizes (HF2 against HF1) and, from equilibrium, over the area sweep,
against −1/4 ± its tolerance. The rows read the same values (``first_peak_row``, ``two_area_row``,
``exponent_row``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import values
from aca_warp.studies.validation.hf_experiments import PRESETS
from aca_warp.studies.validation.hf_peaks import (
    EXPONENT_TOLERANCE,
    F1_CANDIDATES,
    PAPER_EXPONENT,
    PAPER_PEAK_HZ,
    PEAK_TOLERANCE,
    sweep_exponents,
    two_area_exponent,
)
from aca_warp.studies.validation.verdicts import ci

READINGS: tuple[tuple[str, str], ...] = (("primary: Σu̇'s largest peak", "f1"), *F1_CANDIDATES)
"""(label, per-pad measure key) of every reading of the first peak, the primary first."""
STARTS = (("", "from equilibrium", "o"), ("_rest", "from rest", "s"))
"""(experiment suffix, label, marker) of the two initial states."""


def first_peaks(results: dict[str, dict]) -> dict[tuple[str, str, str], np.ndarray]:
    """(preset, start suffix, measure key) → the per-seed first peaks [Hz] of the experiments the results hold."""
    out = {}
    for name in PRESETS:
        for suffix, _, _ in STARTS:
            res = results.get(name + suffix)
            if res is None:
                continue
            for _, key in READINGS:
                out[(name, suffix, key)] = values(res, key)
    return out


def exponents(results: dict[str, dict]) -> dict[tuple[str, str], np.ndarray]:
    """(fit, measure key) → per-seed exponents b of f ∝ A^b: "two sizes" (HF2 against HF1) from equilibrium and
    "two sizes, from rest" where the results hold both, and "area sweep" (from equilibrium) where they hold it."""
    out = {}
    for _, key in READINGS:
        for suffix, label, _ in STARTS:
            if {"hf1" + suffix, "hf2" + suffix} <= results.keys():
                pair = (("hf2" + suffix, "hf1" + suffix),)
                out[(f"two sizes, {label}", key)] = two_area_exponent(results, key, pair)
        b = sweep_exponents(results, key)[0]
        if b.size:
            out[("area sweep, from equilibrium", key)] = b
    return out


def _point(ax: Any, x: float, v: np.ndarray, color: Any, marker: str, label: str | None, scale: float) -> None:
    v = np.asarray(v, dtype=np.float64)
    v = v[np.isfinite(v)] * scale
    if v.size == 0:
        return
    m, lo, hi = ci(v)
    ax.plot(np.full(v.size, x), v, ".", color=color, alpha=0.25, ms=3)
    err = None if not np.isfinite(lo) else [[m - lo], [hi - m]]
    ax.errorbar([x], [m], yerr=err, fmt=marker, color=color, mfc="white" if marker == "s" else color, ms=5,
                capsize=2, label=label)  # fmt: skip


def peaks_figure(results: dict[str, dict], path: Path, title: str = "") -> Path:
    """Write the figure (PNG) of the first velocity peaks and their exponents to ``path``; its parent is created."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    peaks = first_peaks(results)
    if not peaks:
        raise ValueError(f"the results hold none of the §3.1 experiments ({', '.join(PRESETS)} and from rest)")
    fits = exponents(results)
    colors = plt.get_cmap("tab10").colors
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(14.0, 6.4), gridspec_kw={"width_ratios": [3, 2]})
    width = 0.8 / (2 * len(READINGS))
    for i, name in enumerate(PRESETS):
        paper = PAPER_PEAK_HZ[name] / 1e3
        ax.fill_between([i - 0.45, i + 0.45], paper * (1 - PEAK_TOLERANCE), paper * (1 + PEAK_TOLERANCE),
                        color="0.85", lw=0)  # fmt: skip
        ax.hlines(paper, i - 0.45, i + 0.45, color="k", lw=1)
        for j, (label, key) in enumerate(READINGS):
            for k, (suffix, _, marker) in enumerate(STARTS):
                v = peaks.get((name, suffix, key))
                if v is None:
                    continue
                x = i - 0.4 + width * (2 * j + k + 0.5)
                legend = label if i == 0 and k == 0 else None
                _point(ax, x, v, colors[j], marker, legend, 1e-3)
    ax.set_xticks(range(len(PRESETS)), [n.upper() for n in PRESETS])
    ax.set_ylabel("first velocity peak [kHz]")
    ax.set_title(f"first peak per reading; the paper's value ± {100 * PEAK_TOLERANCE:g} % (shaded)", fontsize=10)
    handles, _ = ax.get_legend_handles_labels()
    for _, start, marker in STARTS:
        face = "white" if marker == "s" else "0.3"
        handles.append(ax.errorbar([], [], fmt=marker, color="0.3", mfc=face, label=start))
    ax.legend(handles=handles, fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.08))
    groups = sorted({fit for fit, _ in fits}, key=["two sizes, from equilibrium", "two sizes, from rest",
                                                   "area sweep, from equilibrium"].index)  # fmt: skip
    bx.axhspan(PAPER_EXPONENT - EXPONENT_TOLERANCE, PAPER_EXPONENT + EXPONENT_TOLERANCE, color="0.85", lw=0)
    bx.axhline(PAPER_EXPONENT, color="k", lw=1)
    bwidth = 0.8 / len(READINGS)
    for i, fit in enumerate(groups):
        marker = "s" if "rest" in fit else "o"
        for j, (_, key) in enumerate(READINGS):
            if (fit, key) in fits:
                _point(bx, i - 0.4 + bwidth * (j + 0.5), fits[(fit, key)], colors[j], marker, None, 1.0)
    bx.set_xticks(range(len(groups)), [g.replace(", ", "\n") for g in groups], fontsize=8)
    bx.set_ylabel("exponent b of f ∝ A^b")
    bx.set_title(f"exponent per reading (colours as left); −1/4 ± {EXPONENT_TOLERANCE:g} (shaded)", fontsize=10)
    fig.suptitle(title or "§3.1: the first velocity peak (Fig. 8, Table 1), every reading, mean and 95 % interval "
                 "over the seeds (dots: the seeds)", fontsize=11)  # fmt: skip
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
