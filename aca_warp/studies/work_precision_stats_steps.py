"""Errors against the step: how each fixed-step family of a statistical work-precision result (an integrator and
precision, with its crossing treatment, fast math or growth events) converges on the reference, measure by measure.

The main figure of :mod:`aca_warp.studies.work_precision_stats_report` plots |error| against wall time, which ranks
settings by cost; whether an error is a step error that vanishes as the step shrinks, or a bias that stays, shows
against the step and with its sign. Per measure and setting: the error of the ensemble mean in units of σ between
the reference's seeds (signed, mean(x − x_ref)/σ, for a scalar measure; for a spectrum the rms over components of
the errors over the rms of their σ, ≥ 0) and the 95 % half-width of that error, t₀.₉₇₅ sd(x − x_ref)/(√n σ) (rms
over components), as the rule counts them
(:func:`~aca_warp.studies.work_precision_stats_rule.compare_setting`: for a regime with members the member with the
largest bound).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.report import save_figure
from aca_warp.studies.work_precision_stats_report import machine_text, setting_family
from aca_warp.studies.work_precision_stats_rule import (
    MEASURES,
    _matrix,
    _members,
    compare_setting,
    reference_of,
    usable,
)


@dataclass(frozen=True)
class StepError:
    """One fixed-step setting's error for one measure, in units of σ between the reference's seeds.

    Attributes:
        family: The setting's integrator and precision, with its variant (:func:`setting_family`).
        dt: Its step [s].
        error: mean(x − x_ref)/σ, signed for a scalar measure; for a vector one the rms over components of the
            errors over the rms of their σ (≥ 0).
        half: 95 % half-width of ``error``.
        signed: Whether ``error`` carries a sign (a scalar measure).
    """

    family: str
    dt: float
    error: float
    half: float
    signed: bool


def step_errors(regime: dict[str, Any], measure: str) -> list[StepError]:
    """Every completed fixed-step grid setting of ``regime`` (a regime of a result file) for ``measure``, by family
    and step."""
    ref = reference_of(regime)
    out = []
    for s in regime["settings"]:
        if s["role"] != "grid" or not usable(s) or s.get("dt") is None or s.get("tolerance") is not None:
            continue
        c = compare_setting(regime, s, measure)
        if not (math.isfinite(c.ratio) and c.sigma > 0):
            continue
        idx = _members(regime)[c.member]
        d = _matrix([s["values"][measure][i] for i in idx]) - _matrix([ref["values"][measure][i] for i in idx])
        signed = d.ndim == 1
        sign = -1.0 if signed and np.nanmean(d) < 0 else 1.0
        out.append(StepError(setting_family(s), float(s["dt"]), sign * c.ratio, (c.bound - c.error) / c.sigma, signed))
    return sorted(out, key=lambda e: (e.family, e.dt))


def _regime(doc: dict[str, Any], name: str | None) -> tuple[str, dict[str, Any]]:
    """The regime ``name`` of a result file (its only one where None); ValueError if it has no such regime."""
    regimes = doc["regimes"]
    if name is None:
        if len(regimes) != 1:
            raise ValueError(f"the file holds the regimes {', '.join(regimes)}: name one")
        name = next(iter(regimes))
    if name not in regimes:
        raise ValueError(f"the file has no regime {name} (it has {', '.join(regimes)})")
    return name, regimes[name]


def errors_by_step(doc: dict[str, Any], name: str | None = None, measures: Sequence[str] | None = None) -> str:
    """Markdown: per family, one row per measure and one column per step, each setting's error ± its 95 %
    half-width in units of σ (:func:`step_errors`; ``measures``: default every measure of the regime)."""
    name, reg = _regime(doc, name)
    names = list(measures or reg["measures"])
    unknown = [m for m in names if m not in reg["measures"]]
    if unknown:
        raise ValueError(f"{name} has no measure {', '.join(unknown)} (it has {', '.join(reg['measures'])})")
    errors = {m: step_errors(reg, m) for m in names}
    families = list(dict.fromkeys(e.family for es in errors.values() for e in es))
    if not families:
        raise ValueError(f"{name} has no completed fixed-step setting besides its reference")
    ref = reference_of(reg)["label"]
    lines = [f"{name}: error / σ ± 95 % half-width of each fixed-step setting against the reference `{ref}`, by "
             "step (signed for a scalar measure, rms for a spectrum)", ""]  # fmt: skip
    for fam in families:
        steps = sorted({e.dt for es in errors.values() for e in es if e.family == fam})
        lines += [f"**{fam}**", "", "| measure | " + " | ".join(f"{dt:g} s" for dt in steps) + " |",
                  "|---|" + "---|" * len(steps)]  # fmt: skip
        for m in names:
            got = {e.dt: e for e in errors[m] if e.family == fam}
            cells = [f"{got[dt].error:+.2f} ± {got[dt].half:.2f}" if dt in got else "–" for dt in steps]
            lines.append(f"| {MEASURES[m].label} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def step_figure(doc: dict[str, Any], folder: Path, name: str | None = None, rule: float = 0.25,
                measures: Sequence[str] | None = None) -> Path:  # fmt: skip
    """``folder``/wps_<tag>_<regime>_steps.png: one panel per measure, each fixed-step family's error/σ with its
    95 % interval against the step, the band ± ``rule`` shaded. Returns the PNG's path."""
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    from aca_warp.studies.report import figure

    name, reg = _regime(doc, name)
    names = list(measures or reg["measures"])
    errors = {m: step_errors(reg, m) for m in names}
    families = list(dict.fromkeys(e.family for es in errors.values() for e in es))
    if not families:
        raise ValueError(f"{name} has no completed fixed-step setting besides its reference")
    colours = {f: colormaps["tab10"](i % 10) for i, f in enumerate(families)}
    ncol = min(4, len(names))
    nrow = math.ceil(len(names) / ncol)
    fig = figure(figsize=(3.1 * ncol, 2.5 * nrow + 0.9), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False).ravel()
    for ax, m in zip(axes, names, strict=False):
        signed = any(e.signed for e in errors[m])
        ax.axhspan(-rule if signed else 0.0, rule, color="0.9", lw=0)
        ax.axhline(0.0, color="0.5", lw=0.6)
        for k, fam in enumerate(families):
            es = [e for e in errors[m] if e.family == fam]
            if not es:
                continue
            x = np.array([e.dt for e in es]) * (1.0 + 0.04 * (k - (len(families) - 1) / 2))  # apart, not hidden
            ax.errorbar(x, [e.error for e in es], yerr=[e.half for e in es], color=colours[fam], marker="o", ms=3.5,
                        lw=1.0, capsize=2, label=fam)  # fmt: skip
        ax.set_xscale("log")
        ax.set_title(f"{MEASURES[m].label}{'' if signed else ' (rms)'}", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    handles = [Line2D([], [], color=colours[f], marker="o", ms=3.5, lw=1.0) for f in families]
    fig.legend(handles, families, loc="outside lower center", ncol=min(4, len(families)), fontsize=7)
    fig.supxlabel("step [s]", fontsize=8)
    fig.supylabel("error of the ensemble mean / σ between seeds", fontsize=8)
    fig.suptitle(f"{name}: error against the step, 95 % intervals; shaded: ± {rule:g} σ\n{machine_text(doc)}",
                 fontsize=9)  # fmt: skip
    return save_figure(fig, folder, f"wps_{doc['tag']}_{name}_steps", dpi=90, formats=("png",))[0]
