"""Figure and docs section of the statistical work-precision study (:mod:`aca_warp.studies.work_precision_stats`)
from its result files: per regime, error/σ between seeds against stepping wall time for every measure; the tables;
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
    compare_setting,
    floor_ratios,
    load_results,
    meets,
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
    setting (one marker per integrator and precision, one colour per measure, a line through the steps or
    tolerances of one integrator and precision), the rule, the floor (×, at the reference's wall time), and the
    chosen setting (dotted). Returns the PNG's path."""
    from aca_warp.studies.report import figure

    regimes = [(d, name) for d in docs for name in d["regimes"]]
    ncol = min(3, len(regimes))
    nrow = math.ceil(len(regimes) / ncol)
    fig = figure(figsize=(max(6.5, 5.2 * ncol), 3.9 * nrow + 1.2), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False).ravel()
    colours = {m: f"C{i % 10}" for i, m in enumerate(MEASURES)}
    styles = {m: "-" if i < 10 else "--" for i, m in enumerate(MEASURES)}
    seen: dict[str, Any] = {}
    for ax, (doc, name) in zip(axes, regimes, strict=False):
        reg = doc["regimes"][name]
        ref = reference_of(reg)
        grid = [s for s in reg["settings"] if s["role"] == "grid" and usable(s)]
        families = list(dict.fromkeys(_family(s) for s in grid))
        floor = floor_ratios(reg, reg["measures"])
        for m in reg["measures"]:
            for fam in families:
                pts = sorted(
                    (s["wall_s"], max(compare_setting(reg, s, m).ratio, RATIO_FLOOR))
                    for s in grid if _family(s) == fam
                )  # fmt: skip
                pts = [p for p in pts if math.isfinite(p[1])]
                if pts:
                    x, y = zip(*pts, strict=True)
                    ax.plot(x, y, styles[m], color=colours[m], lw=0.7, alpha=0.6)
                    h = ax.plot(x, y, _marker(fam, families), color=colours[m], ms=4, ls="none")
                    seen.setdefault(m, h[0])
            if m in floor and math.isfinite(floor[m]) and ref.get("wall_s"):
                ax.plot([ref["wall_s"]], [max(floor[m], RATIO_FLOOR)], "x", color=colours[m], ms=6)
        ax.axhline(rule, color="k", lw=1.0, ls="--")
        choice = settings_for(doc, name, rule=rule)
        ax.axvline(choice.wall_s, color="0.4", lw=1.0, ls=":")
        if ref.get("wall_s"):
            ax.axvline(ref["wall_s"], color="0.7", lw=1.0)
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
    fig.suptitle(
        f"error of the ensemble mean / σ between seeds against wall time ({machine_text(docs[0])})", fontsize=9
    )
    return save_figure(fig, folder, f"wps_{stem}", formats=("png",))[0]


# ------------------------------------------------------------------------------------------------ tables


def _ratio_cell(r: float, rule: float) -> str:
    if not math.isfinite(r):
        return "–"
    return f"**{r:.2g}**" if r > rule else f"{r:.2g}"


def setting_table(reg: dict[str, Any], rule: float, measures: Sequence[str]) -> list[str]:
    """Rows: every setting (reference first, then floor, grid); columns: stepping wall time, its share of the
    reference's, error/σ per measure (bold above the rule), whether it meets the rule on the decided measures."""
    ref = reference_of(reg)
    floor = floor_ratios(reg, measures)
    decided = [m for m in measures if not (m in floor and not floor[m] <= rule)]
    head = ["setting", "role", "wall [s]", "× ref", *(MEASURES[m].label for m in measures), "meets the rule"]
    rows = []
    for s in reg["settings"]:
        wall = s.get("wall_s")
        speed = ref["wall_s"] / wall if wall and ref.get("wall_s") else math.nan
        if s["role"] == "reference":
            cells = ["0"] * len(measures)
        elif usable(s):
            cells = [_ratio_cell(compare_setting(reg, s, m).ratio, rule) for m in measures]
        else:
            cells = ["–"] * len(measures)
        ok = "–" if s["role"] == "floor" else ("yes" if meets(reg, s, decided, rule) else "no")
        if not usable(s) and s["role"] != "reference":
            ok = f"no ({s.get('fault') or 'incomplete'})"
        rows.append([f"`{s['label']}`", s["role"], fmt(wall), fmt(speed, ".2g"), *cells, ok])
    return md_table(head, rows)


def reference_table(reg: dict[str, Any], rule: float, measures: Sequence[str]) -> list[str]:
    """Per measure: unit, the reference ensemble's mean, σ between seeds, the 95 % half-width of its mean, seeds,
    the floor's error/σ and whether the rule can decide the measure."""
    ref = reference_of(reg)
    floor = floor_ratios(reg, measures)
    rows = []
    for m in measures:
        c = compare_setting(reg, ref, m)
        f = floor.get(m, math.nan)
        decided = "no (floor above the rule)" if m in floor and not f <= rule else "yes"
        unit = MEASURES[m].unit
        mean = fmt(c.reference_mean, ".4g") + (" (band mean)" if unit == "log10" else "")
        member = f" ({c.member})" if c.member else ""
        rows.append([MEASURES[m].label + member, unit, mean, fmt(c.sigma, ".3g"), fmt(c.half_width, ".3g"),
                     str(c.n), fmt(f, ".2g"), decided])  # fmt: skip
    head = ["measure", "unit", "reference mean", "σ seeds", "95 % half-width", "seeds", "floor error/σ", "decided"]
    return md_table(head, rows)


def summary_table(docs: Sequence[dict[str, Any]], rule: float, measures: Sequence[str] | None) -> list[str]:
    """One row per regime: pads, run, reference, the chosen setting, its wall time and speed-up, undecided
    measures."""
    rows = []
    for doc in docs:
        for name, reg in doc["regimes"].items():
            use = [m for m in (measures or reg["measures"]) if m in reg["measures"]]
            ch = settings_for(doc, name, use, rule)
            sizes = sorted({p["patches"] for p in reg["pads"]})
            pads = f"{len(reg['pads'])} × {sizes[0]}" + (f"–{sizes[-1]}" if len(sizes) > 1 else "")
            run = f"{reg['duration_s'] * 1e3:.1f} ms"
            ref = reference_of(reg)
            rows.append([name, pads, run, f"`{ref['label']}` ({fmt(ref.get('wall_s'))} s)", f"`{ch.setting}`",
                         fmt(ch.wall_s), fmt(ch.speedup, ".2g"),
                         ", ".join(MEASURES[m].label for m in ch.undecided) or "none"])  # fmt: skip
    head = ["regime", "pads × patches", "run", "reference (wall)", "rule picks", "wall [s]", "speed-up",
            "undecided"]  # fmt: skip
    return md_table(head, rows)


def measure_table(docs: Sequence[dict[str, Any]]) -> list[str]:
    """The measures the result files hold: name, label, unit, what it is."""
    used = dict.fromkeys(m for d in docs for reg in d["regimes"].values() for m in reg["measures"])
    rows = [[f"`{m}`", MEASURES[m].label, MEASURES[m].unit, MEASURES[m].what] for m in used if m in MEASURES]
    return md_table(["name", "label", "unit", "what"], rows)


def _timing_note(reg: dict[str, Any]) -> str:
    """How far the wall time of the floor (the reference's work again) lies from the reference's."""
    ref = reference_of(reg)
    floors = [s for s in reg["settings"] if s["role"] == "floor" and s.get("wall_s")]
    if not floors or not ref.get("wall_s"):
        return ""
    return f" Timing: the floor, the reference's work again, took {floors[0]['wall_s'] / ref['wall_s']:.2f} × its time."


def render(docs: Sequence[dict[str, Any]], names: Sequence[str], figures: Sequence[Path], page: Path, rule: float,
           measures: Sequence[str] | None) -> list[str]:  # fmt: skip
    """The generated section of the page (``names``: the result files, as the page links them)."""
    lines: list[str] = []
    for doc, name in zip(docs, names, strict=True):
        lines += [
            f"Results `{name}` on **{machine_text(doc)}**{' (the quick CPU variant)' if doc.get('quick') else ''}: "
            f"`{doc['command']}` ({fmt(doc.get('total_wall_s'), '.0f')} s in all). Rule: error of the ensemble "
            f"mean ≤ {rule:g} × σ between seeds.",
            "",
        ]
    lines += ["### The settings the rule picks", "", *summary_table(docs, rule, measures), ""]
    lines += ["### Measures", "", *measure_table(docs), ""]
    for fig in figures:
        lines += [
            f"![error/σ against wall time]({fig.relative_to(page.parent).as_posix()})",
            "",
            f"*Per regime, error of the ensemble mean / σ between seeds against stepping wall time: one colour per "
            f"measure, one marker per integrator and precision (a line through its steps or tolerances); dashed: "
            f"the rule ({rule:g}); ×: the floor (chaos alone, at the reference's wall time); grey line: the "
            f"reference's wall time; dotted: the setting the rule picks. Errors below {RATIO_FLOOR:g} σ are drawn "
            f"at {RATIO_FLOOR:g}.*",
            "",
        ]
    for doc in docs:
        for name, reg in doc["regimes"].items():
            use = [m for m in (measures or reg["measures"]) if m in reg["measures"]]
            cfg = reg["config"]
            lines += [
                f"### {name}: {reg['description']}",
                "",
                f"{len(reg['pads'])} pads (seeds {reg['pads'][0]['seed']}…{reg['pads'][-1]['seed']}), "
                f"{reg['duration_s'] * 1e3:.1f} ms ({'growing' if reg['kind'] == 'growth' else 'analysed from'} "
                f"{'' if reg['kind'] == 'growth' else format(reg['window_start_s'] * 1e3, '.1f') + ' ms'}), "
                f"perturbation {cfg['perturbation']:g} m/s; pads the saturation detector calls saturated: "
                f"{reference_of(reg).get('saturated', '–')} of {len(reg['pads'])} in the reference."
                f"{_timing_note(reg)} error/σ per setting (bold: above {rule:g}):",
                "",
                *setting_table(reg, rule, use),
                "",
                "The reference ensemble:",
                "",
                *reference_table(reg, rule, use),
                "",
            ]
    return lines


def report(paths: Sequence[Path], page: Path, figures: Path, rule: float, measures: Sequence[str] | None) -> None:
    """Figure per result file and the page's generated section from ``paths``; a regime named in two files is an
    error."""
    docs = [load_results(p) for p in paths]
    seen: dict[str, Path] = {}
    for p, d in zip(paths, docs, strict=True):
        for name in d["regimes"]:
            if name in seen:
                raise ValueError(f"regime {name} is in both {seen[name]} and {p}")
            seen[name] = p
    figs = [regime_figure([d], figures, p.stem.removeprefix("wps_"), rule) for p, d in zip(paths, docs, strict=True)]
    try:
        names = [p.resolve().relative_to(page.resolve().parent.parent).as_posix() for p in paths]
    except ValueError:
        names = [p.name for p in paths]
    body = render(docs, names, figs, page, rule, measures)
    replace_generated(page, body, generated_markers(MARKER), TITLE)
    print(f"wrote {page} and {', '.join(str(f) for f in figs)}")
