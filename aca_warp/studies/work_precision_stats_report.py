"""Figure and docs section of the statistical work-precision study (:mod:`aca_warp.studies.work_precision_stats`)
from its result files: per regime, error/σ between seeds against stepping wall time for every measure, the tables,
the settings the rule picks (:func:`~aca_warp.studies.work_precision_stats_rule.settings_for`). Every number on the
page is computed here from the per-pad values in the result files.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from aca_warp.studies.report import fmt, generated_markers, md_table, replace_generated, save_figure
from aca_warp.studies.work_precision_stats_rule import (
    MEASURES,
    Choice,
    compare_setting,
    load_results,
    reference_of,
    settings_for,
    usable,
)

MARKERS = {"strang@fp32": "o", "strang@fp64": "s", "adaptive@fp64": "^", "adaptive@fp32": "v"}
OTHER_MARKERS = ("D", "P", "X", "*", "h", "<", ">")
RATIO_FLOOR = 1.0e-3  # error/σ below this is drawn at it (log axis)
TITLE = "Statistical work-precision: integrator settings for the validation's statistics"
MARKER = "scripts/work_precision_stats.py --report"  # the generated section's marker on the page


def machine_text(doc: dict[str, Any]) -> str:
    """The device a result file was measured on, in words (its ``machine`` record)."""
    m = doc["machine"]
    return m["device_name"] if str(m.get("device", "")).startswith("cuda") else m["host"]


def _family(setting: dict[str, Any]) -> str:
    return f"{setting['integrator']}@{setting['precision']}"


def _marker(family: str, families: list[str]) -> str:
    others = [f for f in families if f not in MARKERS]
    return MARKERS.get(family) or OTHER_MARKERS[others.index(family) % len(OTHER_MARKERS)]


def regime_figure(docs: Sequence[dict[str, Any]], folder: Path, stem: str, rule: float) -> Path:
    """One panel per regime: error/σ of every measure against the stepping wall time of every completed grid
    setting (one marker per integrator and precision, filled where the setting keeps the measure; one colour per
    measure; a line through the steps or tolerances of one integrator and precision), the rule, the reference's
    wall time and the chosen setting's. Returns the PNG's path."""
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    from aca_warp.studies.report import figure

    regimes = [(d, name) for d in docs for name in d["regimes"]]
    ncol = min(3, len(regimes))
    nrow = math.ceil(len(regimes) / ncol)
    fig = figure(figsize=(max(6.5, 5.2 * ncol), 3.9 * nrow + 1.3), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False).ravel()
    palette = colormaps["tab20"]
    colours = {m: palette(i % 20) for i, m in enumerate(MEASURES)}
    seen: dict[str, Any] = {}
    for ax, (doc, name) in zip(axes, regimes, strict=False):
        reg = doc["regimes"][name]
        grid = [s for s in reg["settings"] if s["role"] == "grid" and usable(s)]
        families = list(dict.fromkeys(_family(s) for s in grid))
        for m in reg["measures"]:
            for fam in families:
                pts = sorted(
                    (s["wall_s"], max(c.ratio, RATIO_FLOOR), c.verdict(rule) == "keeps")
                    for s in grid if _family(s) == fam for c in [compare_setting(reg, s, m)] if math.isfinite(c.ratio)
                )  # fmt: skip
                if not pts:
                    continue
                x, y, keeps = zip(*pts, strict=True)
                ax.plot(x, y, "-", color=colours[m], lw=0.7, alpha=0.6)
                for xi, yi, k in pts:
                    ax.plot([xi], [yi], _marker(fam, families), color=colours[m], ms=4.5,
                            mfc=colours[m] if k else "none")  # fmt: skip
                seen.setdefault(m, Line2D([], [], color=colours[m], lw=2))
        ax.axhline(rule, color="k", lw=1.0, ls="--")
        ax.axvline(settings_for(doc, name, rule=rule).wall_s, color="0.3", lw=1.0, ls=":")
        ax.axvline(reference_of(reg)["wall_s"], color="0.7", lw=1.5)
        ax.set(xscale="log", yscale="log", xlabel="stepping wall time [s]", ylabel="error of the mean / σ seeds")
        pads = reg["pads"]
        ax.set_title(f"{name}: {len(pads)} pads × {max(p['patches'] for p in pads)} patches", fontsize=9)
        for fam in families:
            ax.plot([], [], _marker(fam, families), color="0.3", ls="none", label=fam)
        ax.legend(fontsize=6, loc="best", title="setting", title_fontsize=6)
    for ax in axes[len(regimes) :]:
        ax.set_visible(False)
    fig.legend(
        [seen[m] for m in seen], [MEASURES[m].label for m in seen], loc="outside lower center", ncol=min(8, 3 * ncol),
        fontsize=7,
    )  # fmt: skip
    fig.suptitle(f"error of the ensemble mean / σ between seeds against wall time\n{machine_text(docs[0])}", fontsize=9)
    return save_figure(fig, folder, f"wps_{stem}", dpi=90, formats=("png",))[0]


# ------------------------------------------------------------------------------------------------ tables


def _small(x: float) -> str:
    """A ratio with two digits; below :data:`RATIO_FLOOR` as "< 0.001" (exact zero as 0)."""
    return "0" if x == 0 else f"< {RATIO_FLOOR:g}" if x < RATIO_FLOOR else f"{x:.2g}"


def _cell(reg: dict[str, Any], setting: dict[str, Any], measure: str, rule: float) -> str:
    """error/σ (bound/σ) with ✓ where the setting keeps the measure, bold where it moves it."""
    if setting["role"] == "reference":
        return "0"
    if not usable(setting):
        return "–"
    c = compare_setting(reg, setting, measure)
    if not math.isfinite(c.ratio):
        return "–"
    text = f"{_small(c.ratio)} ({_small(c.bound_ratio)})"
    v = c.verdict(rule)
    return f"{text} ✓" if v == "keeps" else (f"**{text}**" if v == "moves" else text)


def setting_table(reg: dict[str, Any], rule: float, measures: Sequence[str]) -> list[str]:
    """Rows: every setting (the reference first, then the grid as run); columns: stepping wall time, the reference's
    over it, per measure error/σ with the bound (:func:`_cell`), whether it keeps every measure."""
    ref = reference_of(reg)
    head = ["setting", "wall [s]", "× ref", *(MEASURES[m].label for m in measures), "keeps all"]
    rows = []
    passing = set(settings_for({"regimes": {"r": reg}}, "r", measures, rule).passing)
    for s in reg["settings"]:
        wall = s.get("wall_s")
        speed = ref["wall_s"] / wall if wall else math.nan
        ok = "yes" if s["label"] in passing and usable(s) else "no"
        if not usable(s):
            ok = f"no ({s.get('fault') or 'incomplete'})"
        label = f"`{s['label']}`" + (" (reference)" if s["role"] == "reference" else "")
        rows.append([label, fmt(wall), fmt(speed, ".2g"), *(_cell(reg, s, m, rule) for m in measures), ok])
    return md_table(head, rows)


def reference_table(reg: dict[str, Any], choice: Choice) -> list[str]:
    """Per measure: unit, the reference ensemble's mean, σ between seeds, the 95 % half-width of its mean, seeds
    (of the member with the largest σ), and the cheapest setting that keeps it."""
    ref = reference_of(reg)
    walls = {s["label"]: s["wall_s"] for s in reg["settings"] if s.get("wall_s") is not None}
    rows = []
    for m in choice.measures:
        c = compare_setting(reg, ref, m)
        unit = MEASURES[m].unit
        mean = fmt(c.reference_mean, ".4g") + (" (band mean)" if unit == "log10" else "")
        member = f" ({c.member})" if c.member else ""
        cheap = choice.cheapest[m]
        rows.append([MEASURES[m].label + member, unit, mean, fmt(c.sigma, ".3g"), fmt(c.half_width, ".3g"),
                     str(c.n), f"`{cheap}` ({fmt(walls[cheap])} s)"])  # fmt: skip
    head = ["measure", "unit", "reference mean", "σ seeds", "95 % half-width", "seeds", "cheapest setting keeping it"]
    return md_table(head, rows)


def _measures(reg: dict[str, Any], measures: Sequence[str] | None) -> list[str]:
    return [m for m in (measures or reg["measures"]) if m in reg["measures"]]


def summary_table(docs: Sequence[dict[str, Any]], rule: float, measures: Sequence[str] | None) -> list[str]:
    """One row per regime: pads, run, reference, the chosen setting, its wall time and speed-up, and the measures
    that bind the choice (those no cheaper setting keeps)."""
    rows = []
    for doc in docs:
        for name, reg in doc["regimes"].items():
            ch = settings_for(doc, name, _measures(reg, measures), rule)
            sizes = sorted({p["patches"] for p in reg["pads"]})
            pads = f"{len(reg['pads'])} × {sizes[0]}" + (f"–{sizes[-1]}" if len(sizes) > 1 else "")
            ref = reference_of(reg)
            binding = [MEASURES[m].label for m in ch.measures if ch.cheapest[m] == ch.setting]
            rows.append([name, pads, f"{reg['duration_s'] * 1e3:.1f} ms", f"`{ref['label']}` ({fmt(ref['wall_s'])} s)",
                         f"`{ch.setting}`", fmt(ch.wall_s), fmt(ch.speedup, ".2g"), ", ".join(binding)])  # fmt: skip
    head = ["regime", "pads × patches", "run", "reference (wall)", "rule picks", "wall [s]", "speed-up",
            "binding measures"]  # fmt: skip
    return md_table(head, rows)


def measure_table(docs: Sequence[dict[str, Any]]) -> list[str]:
    """The measures the result files hold: name, label, unit, what it is."""
    used = dict.fromkeys(m for d in docs for reg in d["regimes"].values() for m in reg["measures"])
    rows = [[f"`{m}`", MEASURES[m].label, MEASURES[m].unit, MEASURES[m].what] for m in used if m in MEASURES]
    return md_table(["name", "label", "unit", "what"], rows)


def render(docs: Sequence[dict[str, Any]], names: Sequence[str], figures: Sequence[Path], page: Path, rule: float,
           measures: Sequence[str] | None) -> list[str]:  # fmt: skip
    """The generated section of the page (``names``: the result files, as the page links them)."""
    lines: list[str] = []
    for tag in dict.fromkeys(d["tag"] for d in docs):
        group = [(d, n) for d, n in zip(docs, names, strict=True) if d["tag"] == tag]
        commands = dict.fromkeys(c for d, _ in group for c in d["commands"])
        lines += [
            f"Results on **{machine_text(group[0][0])}**{' (the quick CPU variant)' if group[0][0]['quick'] else ''}: "
            + ", ".join(f"`{n}`" for _, n in group) + " from " + "; ".join(f"`{c}`" for c in commands) + ". Rule: "
            f"the 95 % interval of a setting's bias within ± {rule:g} × σ between seeds.",
            "",
        ]  # fmt: skip
    lines += ["### The settings the rule picks", "", *summary_table(docs, rule, measures), ""]
    lines += ["### Measures", "", *measure_table(docs), ""]
    for fig in figures:
        lines += [
            f"![error/σ against wall time]({fig.relative_to(page.parent).as_posix()})",
            "",
            f"*Per regime, error of the ensemble mean / σ between seeds against stepping wall time: one colour per "
            f"measure, one marker per integrator and precision (a line through its steps or tolerances), filled "
            f"where the setting keeps the measure; dashed: the rule ({rule:g}); grey line: the reference's wall "
            f"time; dotted: the setting the rule picks. Errors below {RATIO_FLOOR:g} σ are drawn at {RATIO_FLOOR:g}.*",
            "",
        ]
    for doc in docs:
        for name, reg in doc["regimes"].items():
            use = _measures(reg, measures)
            cfg = reg["config"]
            span = "growing" if reg["kind"] == "growth" else f"analysed from {reg['window_start_s'] * 1e3:.1f} ms"
            lines += [
                f"### {name}: {reg['description']}",
                "",
                f"{len(reg['pads'])} pads (seeds {reg['pads'][0]['seed']}…{reg['pads'][-1]['seed']}), "
                f"{reg['duration_s'] * 1e3:.1f} ms ({span}), perturbation {cfg['perturbation']:g} m/s; pads the "
                f"saturation detector calls saturated: {reference_of(reg).get('saturated', '–')} of "
                f"{len(reg['pads'])} in the reference; {fmt(doc.get('regime_wall_s'), '.0f')} s of wall time in "
                f"all (runs, analysis, compilation). Per setting and measure: error/σ (the upper end of the 95 % "
                f"interval of |bias|/σ); ✓ keeps (bound ≤ {rule:g}), **bold** moves (the whole interval beyond "
                f"{rule:g}), plain: undecided.",
                "",
                *setting_table(reg, rule, use),
                "",
                "The reference ensemble, and per measure the cheapest setting that keeps it:",
                "",
                *reference_table(reg, settings_for(doc, name, use, rule)),
                "",
            ]
    return lines


def report(paths: Sequence[Path], page: Path, figures: Path, rule: float, measures: Sequence[str] | None) -> None:
    """The figure of each machine (``wps_<tag>.png``: the files' device and variant) and the page's generated section
    from the result files ``paths``; a regime given twice for one machine is an error."""
    docs = [load_results(p) for p in paths]
    seen: dict[tuple[str, str], Path] = {}
    for p, d in zip(paths, docs, strict=True):
        for name in d["regimes"]:
            if (d["tag"], name) in seen:
                raise ValueError(f"regime {name} is in both {seen[d['tag'], name]} and {p}")
            seen[d["tag"], name] = p
    tags = list(dict.fromkeys(d["tag"] for d in docs))
    figs = [regime_figure([d for d in docs if d["tag"] == t], figures, t, rule) for t in tags]
    try:
        names = [p.resolve().relative_to(page.resolve().parent.parent).as_posix() for p in paths]
    except ValueError:
        names = [p.name for p in paths]
    body = render(docs, names, figs, page, rule, measures)
    replace_generated(page, body, generated_markers(MARKER), TITLE)
    print(f"wrote {page} and {', '.join(str(f) for f in figs)}")
