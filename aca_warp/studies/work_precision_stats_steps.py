"""Errors against the step: how each fixed-step family of a statistical work-precision result (an integrator and
precision, with its crossing treatment, fast math or growth events) converges on the reference, measure by measure.

The main figure of :mod:`aca_warp.studies.work_precision_stats_report` plots |error| against wall time, which ranks
settings by cost; whether an error is a step error that vanishes as the step shrinks, or a bias that stays, shows
against the step and with its sign. Per measure and setting, in units of σ between the reference's seeds, as the
rule counts them (:func:`~aca_warp.studies.work_precision_stats_rule.compare_setting`: for a regime with members the
member with the largest bound): the error of the ensemble mean, mean(x − x_ref)/σ, signed for a scalar measure (for
a spectrum the rms over its components of the errors over the rms of their σ, ≥ 0), and how far the upper end of its
95 % interval lies beyond it, (bound − error)/σ: for a scalar measure the half-width t₀.₉₇₅ sd(x − x_ref)/(√n σ).

With ``paired`` (``--steps FILE --precision-pairs``) each fp32 setting is measured against the fp64 setting of the
same step and variant instead (:func:`fp64_partner`; the reference where it is that setting), in units of that
setting's own σ between seeds (within a few per cent of the reference's for μ mean on the committed files, up to a
quarter apart for S − S_null): what the precision alone moves at each step, on the same seeds, free of the step's
own error.
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
    measures_asked,
    reference_of,
    usable,
    variant,
)


@dataclass(frozen=True)
class StepError:
    """One fixed-step setting's error for one measure, in units of σ between the reference's seeds.

    Attributes:
        family: The setting's integrator and precision, with its variant (:func:`setting_family`).
        dt: Its step [s].
        error: mean(x − x_ref)/σ, signed for a scalar measure; for a vector one the rms over components of the
            errors over the rms of their σ (≥ 0).
        half: (bound − error)/σ, the 95 % interval's reach beyond ``error`` (a scalar's half-width).
    """

    family: str
    dt: float
    error: float
    half: float


@dataclass(frozen=True)
class Steps:
    """The errors against the step of one regime of a result file (:func:`collect`).

    Attributes:
        regime: The regime's name.
        reference: What the settings are measured against: the reference, by its label, or (paired) their fp64
            partners.
        measures: The measures, in the order asked for.
        signed: Per measure, whether it is a scalar (its errors signed).
        errors: Per measure, the errors of every completed fixed-step setting (:func:`step_errors`).
        families: The families with at least one error, in order of first appearance.
        tag: The result file's tag (its device and variant).
        machine: The device the file was measured on, in words.
        paired: fp32 against fp64 step by step (:func:`step_errors`), not against the reference.
    """

    regime: str
    reference: str
    measures: list[str]
    signed: dict[str, bool]
    errors: dict[str, list[StepError]]
    families: list[str]
    tag: str
    machine: str
    paired: bool = False


def fp64_partner(regime: dict[str, Any], setting: dict[str, Any]) -> dict[str, Any] | None:
    """The completed fp64 setting (grid or reference) of ``setting``'s step and variant, for an fp32 ``setting``;
    None where there is none."""
    if setting.get("precision") != "fp32":
        return None
    partners = [s for s in regime["settings"] if s.get("precision") == "fp64" and usable(s)]
    return next((s for s in partners if variant(s) == variant(setting)), None)


def step_errors(regime: dict[str, Any], measure: str, paired: bool = False) -> list[StepError]:
    """Every completed fixed-step grid setting of ``regime`` (a regime of a result file; a setting with a tolerance
    has its step chosen by error control and is left out) for ``measure``, by family and step, against the
    reference; ``paired``: every such fp32 setting against its :func:`fp64_partner` (family "… − fp64"), where it has
    one."""
    out = []
    for s in regime["settings"]:
        if s["role"] != "grid" or not usable(s) or s.get("dt") is None or s.get("tolerance") is not None:
            continue
        ref = fp64_partner(regime, s) if paired else reference_of(regime)
        if ref is None:
            continue
        c = compare_setting(regime, s, measure, ref)
        if not (math.isfinite(c.ratio) and c.sigma > 0):
            continue
        idx = _members(regime)[c.member]  # the sign over the pads the comparison took: its member's
        d = _matrix([s["values"][measure][i] for i in idx]) - _matrix([ref["values"][measure][i] for i in idx])
        sign = -1.0 if d.ndim == 1 and np.nanmean(d) < 0 else 1.0
        family = f"{setting_family(s)} − fp64" if paired else setting_family(s)
        out.append(StepError(family, float(s["dt"]), sign * c.ratio, (c.bound - c.error) / c.sigma))
    return sorted(out, key=lambda e: (e.family, e.dt))


def collect(
    doc: dict[str, Any], name: str | None = None, measures: Sequence[str] | None = None, paired: bool = False
) -> Steps:
    """The errors against the step of the regime ``name`` of a result file (its only one where None) for
    ``measures`` (default every measure of the regime); ``paired``: fp32 against fp64 step by step
    (:func:`step_errors`). ValueError for a regime or measure the file lacks, a file of several regimes without a
    name, or a regime with no completed fixed-step setting besides its reference (paired: no fp32 setting with an
    fp64 partner)."""
    regimes = doc["regimes"]
    if name is None:
        if len(regimes) != 1:
            raise ValueError(f"the file holds the regimes {', '.join(regimes)}: name one")
        name = next(iter(regimes))
    if name not in regimes:
        raise ValueError(f"the file has no regime {name} (it has {', '.join(regimes)})")
    reg = regimes[name]
    names = measures_asked(name, reg, measures)
    errors = {m: step_errors(reg, m, paired) for m in names}
    families = list(dict.fromkeys(e.family for m in names for e in errors[m]))
    if not families:
        lacks = "fp32 setting with an fp64 partner" if paired else "fixed-step setting besides its reference"
        raise ValueError(f"{name} has no completed {lacks}")
    ref = reference_of(reg)
    signed = {m: _matrix(ref["values"][m]).ndim == 1 for m in names}
    partner = "the fp64 setting of the same step and variant (σ: that setting's)"
    against = partner if paired else f"the reference `{ref['label']}`"
    return Steps(name, against, names, signed, errors, families, doc["tag"], machine_text(doc), paired)


def errors_by_step(steps: Steps) -> str:
    """Markdown: per family, one row per measure and one column per step, each setting's error ± its 95 % reach in
    units of σ ("–" where the setting has no figure for the measure)."""
    lines = [f"{steps.regime}: error / σ ± 95 % half-width of each fixed-step setting against "
             f"{steps.reference}, by step (signed for a scalar measure, rms for a spectrum)", ""]  # fmt: skip
    for fam in steps.families:
        dts = sorted({e.dt for m in steps.measures for e in steps.errors[m] if e.family == fam})
        lines += [f"**{fam}**", "", "| measure | " + " | ".join(f"{dt:g} s" for dt in dts) + " |",
                  "|---|" + "---|" * len(dts)]  # fmt: skip
        for m in steps.measures:
            got = {e.dt: e for e in steps.errors[m] if e.family == fam}
            cells = [f"{got[dt].error:+.2f} ± {got[dt].half:.2f}" if dt in got else "–" for dt in dts]
            lines.append(f"| {MEASURES[m].label} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def step_figure(steps: Steps, folder: Path, rule: float = 0.25) -> Path:
    """``folder``/wps_<tag>_<regime>_steps.png: one panel per measure, each family's error/σ with its 95 % interval
    against the step (families side by side, a few per cent apart in step), the band ± ``rule`` shaded (0 to
    ``rule`` for a spectrum). Returns the PNG's path."""
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    from aca_warp.studies.report import figure

    colours = {f: colormaps["tab10"](i % 10) for i, f in enumerate(steps.families)}
    ncol = min(4, len(steps.measures))
    nrow = math.ceil(len(steps.measures) / ncol)
    fig = figure(figsize=(3.1 * ncol, 2.5 * nrow + 0.9), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False).ravel()
    for ax, m in zip(axes, steps.measures, strict=False):
        ax.axhspan(-rule if steps.signed[m] else 0.0, rule, color="0.9", lw=0)
        ax.axhline(0.0, color="0.5", lw=0.6)
        for k, fam in enumerate(steps.families):
            es = [e for e in steps.errors[m] if e.family == fam]
            if es:
                x = np.array([e.dt for e in es]) * (1.0 + 0.04 * (k - (len(steps.families) - 1) / 2))
                ax.errorbar(x, [e.error for e in es], yerr=[e.half for e in es], color=colours[fam], marker="o",
                            ms=3.5, lw=1.0, capsize=2)  # fmt: skip
        ax.set_xscale("log")
        ax.set_title(f"{MEASURES[m].label}{'' if steps.signed[m] else ' (rms)'}", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(steps.measures) :]:
        ax.set_visible(False)
    handles = [Line2D([], [], color=colours[f], marker="o", ms=3.5, lw=1.0) for f in steps.families]
    fig.legend(handles, steps.families, loc="outside lower center", ncol=min(4, len(steps.families)), fontsize=7)
    fig.supxlabel("step [s]", fontsize=8)
    fig.supylabel("error of the ensemble mean / σ between seeds", fontsize=8)
    what = "fp32 against fp64 at the same step" if steps.paired else "error against the step"
    fig.suptitle(f"{steps.regime}: {what}, 95 % intervals; shaded: ± {rule:g} σ\n{steps.machine}", fontsize=9)
    name = f"wps_{steps.tag}_{steps.regime}_{'fp32_fp64' if steps.paired else 'steps'}"
    return save_figure(fig, folder, name, dpi=90, formats=("png",))[0]
