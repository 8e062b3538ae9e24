"""Figure and docs section of the statistical work-precision study (:mod:`aca_warp.studies.work_precision_stats`)
from its result files: per regime, error/σ between seeds against stepping wall time for every measure, the tables,
the settings the rule picks (:func:`~aca_warp.studies.work_precision_stats_rule.settings_for`), for an amplitude
that a few pads dominate the same comparison in log beside it (:func:`log_candidates`), and the cheaper settings that
one seed alone leaves undecided (:func:`one_seed_notes`). Every number on the page is computed here from the per-pad
values in the result files.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from aca_warp.studies.report import fmt, generated_markers, md_table, replace_generated, save_figure
from aca_warp.studies.work_precision_stats_merge import ABSENT
from aca_warp.studies.work_precision_stats_rule import (
    CRITERIA,
    MEASURES,
    Choice,
    _members,
    compare_setting,
    keep_chance,
    kept,
    load_results,
    member_comparisons,
    reference_of,
    resolution_floor,
    seeds_needed,
    settings_for,
    twin_of,
    usable,
    verdict,
)

MARKERS = {"strang@fp32": "o", "strang@fp64": "s", "adaptive@fp64": "^", "adaptive@fp32": "v"}
OTHER_MARKERS = ("D", "P", "X", "*", "h", "<", ">")
RATIO_FLOOR = 1.0e-3  # error/σ below this is drawn at it (log axis)
TITLE = "Statistical work-precision: integrator settings for the validation's statistics"
MARKER = "scripts/work_precision_stats.py --report"  # the generated section's marker on the page
NEAREST = 6  # cheaper settings the results in words name per regime (those nearest the pick in wall time)
EARLIER = "†"  # marks an fp32 row that ran on kernels older than the fp32 friction sub-step that keeps the damping
LOG_CANDIDATES = ("stft_amplitude",)  # scalar amplitudes a few large pads dominate in the mean: judged in log too


def earlier_fp32(s: dict[str, Any]) -> bool:
    """Whether ``s`` is an fp32 row that ran (in all or some parts) before each row recorded the digest of its
    kernels: on kernels whose fp32 friction sub-step rounded the patch damping away (docs/numerics.md), which set
    fp32's μ mean up to 0.15 σ low in hf1–hf4 at steps of 1e-7 s and below. A row that never ran (cut by a time
    limit, refused) is none."""
    ran = "values" in s or s.get("steps") is not None or re.search(r"complete in [1-9]\d* of", str(s.get("fault")))
    return s.get("precision") == "fp32" and bool(ran) and None in kernel_versions(s)


def kernel_versions(s: dict[str, Any]) -> set[str | None]:
    """The kernel digests a row ran on: one, or one per part of a merged row whose parts differ; None for a row
    (or part) written before rows recorded them."""
    k = s.get("kernels")
    return set(k) if isinstance(k, list) else {k}


def _label(s: dict[str, Any]) -> str:
    """A row's setting as the tables name it: its label, marked where :func:`earlier_fp32`."""
    return f"`{s['label']}`" + (f" {EARLIER}" if earlier_fp32(s) else "")


def machine_text(doc: dict[str, Any]) -> str:
    """The device a result file was measured on, in words (its ``machine`` record)."""
    m = doc["machine"]
    return m["device_name"] if str(m.get("device", "")).startswith("cuda") else m["host"]


def setting_family(setting: dict[str, Any]) -> str:
    """A setting's family in words: integrator@precision with its variant (fast math, growth events, crossings, the
    friction solve's tolerance)."""
    fast = " fast math" if setting.get("fast_math") else ""
    growth = f" events every {setting['growth_dt']:g} s" if setting.get("growth_dt") is not None else ""
    crossing = " crossings averaged" if setting.get("crossing", "point") != "point" else ""
    solve = f" solve tol {setting['solve_tol']:g}" if setting.get("solve_tol") is not None else ""
    return f"{setting['integrator']}@{setting['precision']}{fast}{growth}{crossing}{solve}"


def _marker(family: str, families: list[str]) -> str:
    others = [f for f in families if f not in MARKERS]
    return MARKERS.get(family) or OTHER_MARKERS[others.index(family) % len(OTHER_MARKERS)]


def regime_figure(docs: Sequence[dict[str, Any]], folder: Path, stem: str, rule: float, criterion: str) -> Path:
    """One panel per regime: error/σ of every measure against the stepping wall time of every completed grid
    setting (one marker per integrator and precision, filled where the setting keeps the measure, half filled where
    it keeps it within resolution; one colour per
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
        families = list(dict.fromkeys(setting_family(s) for s in grid))
        for m in reg["measures"]:
            for fam in families:
                pts = sorted(
                    (s["wall_s"], max(c.ratio, RATIO_FLOOR), verdict(reg, s, m, rule, criterion))
                    for s in grid if setting_family(s) == fam
                    for c in [compare_setting(reg, s, m)] if math.isfinite(c.ratio)
                )  # fmt: skip
                if not pts:
                    continue
                x, y, keeps = zip(*pts, strict=True)
                ax.plot(x, y, "-", color=colours[m], lw=0.7, alpha=0.6)
                for xi, yi, v in pts:
                    fill = {"keeps": "full", "within resolution": "left"}.get(v, "none")
                    ax.plot([xi], [yi], _marker(fam, families), color=colours[m], ms=4.5, fillstyle=fill)
                seen.setdefault(m, Line2D([], [], color=colours[m], lw=2))
        ax.axhline(rule, color="k", lw=1.0, ls="--")
        ax.axvline(settings_for(doc, name, rule=rule, criterion=criterion).wall_s, color="0.3", lw=1.0, ls=":")
        ax.axvline(reference_of(reg)["wall_s"], color="0.7", lw=1.5)
        ax.set(xscale="log", yscale="log", xlabel="stepping wall time [s]", ylabel="error of the mean / σ seeds")
        ax.set_title(f"{name}: {_pads(reg).replace(' × ', ' pads × ')} patches", fontsize=9)
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


def _cell(reg: dict[str, Any], setting: dict[str, Any], measure: str, rule: float, criterion: str) -> str:
    """error/σ (bound/σ) with ✓ where the setting keeps the measure, ≈ where it keeps it within resolution, bold
    where it moves it."""
    if setting["role"] == "reference":
        return "0"
    if not usable(setting):
        return "–"
    c = compare_setting(reg, setting, measure)
    if not math.isfinite(c.ratio):
        return "–"
    text = f"{_small(c.ratio)} ({_small(c.bound_ratio)})"
    v = verdict(reg, setting, measure, rule, criterion)
    return {"keeps": f"{text} ✓", "within resolution": f"{text} ≈", "moves": f"**{text}**"}.get(v, text)


def run_in_parts(s: dict[str, Any]) -> str | None:
    """The parts that ran a merged setting, as "K of N parts", where only some parts asked for it and each of those
    ran it in full (its fault as :func:`~aca_warp.studies.work_precision_stats_merge.merge` writes it); None for any
    other setting."""
    m = re.fullmatch(rf"not run: complete in (\d+ of \d+ parts) \({re.escape(ABSENT)}\)", str(s.get("fault")))
    return m.group(1) if m else None


def setting_table(reg: dict[str, Any], rule: float, measures: Sequence[str], criterion: str) -> list[str]:
    """Rows: every setting (the reference first, then the grid as run); columns: stepping wall time, the reference's
    over it, per measure error/σ with the bound (:func:`_cell`), whether it keeps every measure."""
    ref = reference_of(reg)
    head = ["setting", "wall [s]", "× ref", *(MEASURES[m].label for m in measures), "keeps all"]
    rows = []
    passing = set(settings_for({"regimes": {"r": reg}}, "r", measures, rule, criterion).passing)
    twin = twin_of(reg)
    for s in reg["settings"]:
        wall = s.get("wall_s")
        speed = ref["wall_s"] / wall if wall else math.nan
        ok = "yes" if s["label"] in passing and usable(s) else "no"
        if not usable(s):
            some = run_in_parts(s)
            ok = f"no (run in {some} only)" if some else f"no ({s.get('fault') or 'incomplete'})"
        role = " (reference)" if s["role"] == "reference" else " (twin)" if twin is not None and s is twin else ""
        rows.append([f"{_label(s)}{role}", fmt(wall), fmt(speed, ".2g"),
                     *(_cell(reg, s, m, rule, criterion) for m in measures), ok])  # fmt: skip
    return md_table(head, rows)


def _grid_sd(reg: dict[str, Any], measure: str) -> list[float]:
    """sd(d)/σ of ``measure`` for every completed grid setting."""
    grid = [s for s in reg["settings"] if s["role"] == "grid" and usable(s)]
    return [r for s in grid for r in [compare_setting(reg, s, measure).sd_ratio] if math.isfinite(r)]


def _span(values: Sequence[Any], spec: str = ".2g") -> str:
    """min–max of ``values`` (one value alone; – for none)."""
    known = [v for v in values if v is not None]
    if not known:
        return "–"
    lo, hi = fmt(min(known), spec), fmt(max(known), spec)
    return lo if lo == hi else f"{lo}–{hi}"


def reference_table(reg: dict[str, Any], choice: Choice) -> list[str]:
    """Per measure: unit, the reference ensemble's mean, σ between seeds, the 95 % half-width of its mean, seeds
    (of the member with the largest σ), sd(d)/σ of the reference's twin and over the grid, the seeds the strict rule
    would need with them, and the cheapest setting that keeps the measure."""
    ref = reference_of(reg)
    twin = twin_of(reg)
    walls = {s["label"]: s["wall_s"] for s in reg["settings"] if s.get("wall_s") is not None}
    rows = []
    for m in choice.measures:
        c = compare_setting(reg, ref, m)
        unit = MEASURES[m].unit
        mean = fmt(c.reference_mean, ".4g") + (" (band mean)" if unit == "log10" else "")
        member = f" ({c.member})" if c.member else ""
        cheap = choice.cheapest[m]
        tw = compare_setting(reg, twin, m).sd_ratio if twin is not None else math.nan
        grid = _grid_sd(reg, m)
        need_twin = seeds_needed(tw, choice.rule) if math.isfinite(tw) else None
        rows.append([MEASURES[m].label + member, unit, mean, fmt(c.sigma, ".3g"), fmt(c.half_width, ".3g"),
                     str(c.n), fmt(tw, ".2g"), _span(grid), fmt(need_twin),
                     _span([seeds_needed(r, choice.rule) for r in grid], "d"),
                     f"`{cheap}` ({fmt(walls[cheap])} s)"])  # fmt: skip
    head = ["measure", "unit", "reference mean", "σ seeds", "95 % half-width", "seeds", "sd(d)/σ twin", "sd(d)/σ grid",
            "seeds strict: twin", "seeds strict: grid", "cheapest setting keeping it"]  # fmt: skip
    return md_table(head, rows)


def _measures(reg: dict[str, Any], measures: Sequence[str] | None) -> list[str]:
    return [m for m in (measures or reg["measures"]) if m in reg["measures"]]


def _pads(reg: dict[str, Any]) -> str:
    sizes = sorted({p["patches"] for p in reg["pads"]})
    return f"{len(reg['pads'])} × {sizes[0]}" + (f"–{sizes[-1]}" if len(sizes) > 1 else "")


def row_of(reg: dict[str, Any], label: str) -> dict[str, Any]:
    """The row of the setting ``label`` in a regime's result (KeyError naming it when there is none)."""
    for s in reg["settings"]:
        if s["label"] == label:
            return s
    raise KeyError(f"no setting {label} in regime {reg.get('name')}")


def summary_table(docs: Sequence[dict[str, Any]], rule: float, measures: Sequence[str] | None,
                  criterion: str) -> list[str]:  # fmt: skip
    """One row per regime: pads, run, reference, the chosen setting, its wall time and speed-up, the measures that
    bind the choice (each the only one a cheaper setting does not keep) and those it keeps only within resolution."""
    rows = []
    for doc in docs:
        for name, reg in doc["regimes"].items():
            ch = settings_for(doc, name, _measures(reg, measures), rule, criterion)
            ref = reference_of(reg)
            within = [MEASURES[m].label for m, v in ch.verdicts.items() if v == "within resolution"]
            rows.append([name, _pads(reg), _duration(reg),
                         f"{_label(ref)} ({fmt(ref['wall_s'])} s)", _label(row_of(reg, ch.setting)), fmt(ch.wall_s),
                         fmt(ch.speedup, ".2g"),
                         ", ".join(MEASURES[m].label for m in ch.binding), ", ".join(within) or "–"])  # fmt: skip
    head = ["regime", "pads × patches", "run", "reference (wall)", "rule picks", "wall [s]", "speed-up",
            "binding measures", "kept within resolution only"]  # fmt: skip
    return md_table(head, rows)


def candidates_table(docs: Sequence[dict[str, Any]], rule: float, measures: Sequence[str] | None) -> list[str]:
    """One row per regime, one column per criterion of the rule: the setting it picks and its speed-up."""
    rows = []
    for doc in docs:
        for name, reg in doc["regimes"].items():
            picks = [settings_for(doc, name, _measures(reg, measures), rule, c) for c in CRITERIA]
            rows.append([name, _pads(reg), *(f"`{ch.setting}` ({fmt(ch.speedup, '.2g')}×)" for ch in picks)])
    return md_table(["regime", "pads × patches", *(f"`{c}`" for c in CRITERIA)], rows)


def measure_table(docs: Sequence[dict[str, Any]]) -> list[str]:
    """The measures the result files hold: name, label, unit, what it is."""
    used = dict.fromkeys(m for d in docs for reg in d["regimes"].values() for m in reg["measures"])
    rows = [[f"`{m}`", MEASURES[m].label, MEASURES[m].unit, MEASURES[m].what] for m in used if m in MEASURES]
    return md_table(["name", "label", "unit", "what"], rows)


def _seeds(reg: dict[str, Any]) -> int:
    """Seeds per member (the pads of a regime without members)."""
    return len(reg["pads"]) // max(1, len({p.get("member") for p in reg["pads"]}))


def resolution_text(n: int, rule: float) -> str:
    """The resolution floor and what the resolution criterion does at ``n`` seeds, in words."""
    chance = [f"{100 * keep_chance(n, k * rule, rule):.0f} %" for k in range(4)]
    return (
        f"With {n} seeds the resolution floor t₀.₉₇₅ √2 σ/√n is {resolution_floor(n):.2f} σ: the 95 % interval of "
        f"an exact setting whose runs have parted from the reference's reaches that far, so the strict criterion "
        f"cannot keep such a measure at {rule:g} σ. The resolution criterion keeps it when the estimate of the bias "
        f"lies within ± {rule:g} σ: for such a measure with probability {chance[0]} when the setting is exact, "
        f"{chance[1]} when its bias is {rule:g} σ, {chance[2]} at {2 * rule:g} σ and {chance[3]} at {3 * rule:g} σ "
        f"(normal approximation)."
    )


def regime_results(doc: dict[str, Any], name: str, rule: float, measures: Sequence[str] | None,
                   criterion: str) -> str:  # fmt: skip
    """What the rule says for one regime, in words: the pick with its wall time and speed-up, every setting that
    passes, what each cheaper setting does not keep, the measures kept only within resolution with the seeds the
    strict rule would need, the settings a merged regime ran in some parts only, the runs a time limit cut, and the
    other criteria's picks."""
    reg = doc["regimes"][name]
    use = _measures(reg, measures)
    ch = settings_for(doc, name, use, rule, criterion)
    ref = reference_of(reg)
    walls = {s["label"]: s["wall_s"] for s in reg["settings"] if s.get("wall_s") is not None}
    ran = [s for s in reg["settings"] if usable(s)]
    some = [(s["label"], part) for s in reg["settings"] if (part := run_in_parts(s))]
    cut = [s["label"] for s in reg["settings"] if str(s.get("fault")).startswith("not run") and not run_in_parts(s)]
    out = [f"**{name}** ({_pads(reg)} patches, {len(ran)} of {len(reg['settings'])} settings run"]
    if some:
        out[0] += "; run in some parts only, so on fewer seeds and left out of the rule: " + ", ".join(
            f"`{label}` (complete in {part})" for label, part in some
        )
    out[0] += f"; not run, cut by the call's time limit: {', '.join(f'`{c}`' for c in cut)})." if cut else ")."
    if ch.setting == ref["label"]:
        out.append(f"The rule keeps the reference `{ref['label']}` ({fmt(ref['wall_s'])} s).")
    else:
        passing = ", ".join(f"`{p}` ({fmt(walls[p])} s)" for p in ch.passing)
        out.append(f"The rule picks `{ch.setting}`: {fmt(ch.wall_s)} s of stepping against the reference's "
                   f"{fmt(ref['wall_s'])} s, {fmt(ch.speedup, '.2g')}× faster. Every setting that keeps every "
                   f"measure, cheapest first: {passing}.")  # fmt: skip
    settings = {s["label"]: s for s in ran}
    fails = []
    for label, names in list(ch.fails.items())[-NEAREST:]:
        errs = [f"{MEASURES[m].label} {_small(compare_setting(reg, settings[label], m).ratio)} σ" for m in names]
        fails.append(f"`{label}` ({', '.join(errs)})")
    if fails:
        out.append(f"The {min(NEAREST, len(fails))} cheaper settings nearest in wall time, cheapest first, and the "
                   "measures each does not keep (with its error): "
                   + "; ".join(fails) + ".")  # fmt: skip
    within = [m for m, v in ch.verdicts.items() if v == "within resolution"]
    if within:
        parts = []
        for m in within:
            c = compare_setting(reg, row_of(reg, ch.setting), m)
            need = seeds_needed(c.sd_ratio, rule)
            parts.append(f"{MEASURES[m].label} (error {_small(c.ratio)} σ, bound {_small(c.bound_ratio)} σ, sd(d) "
                         f"{c.sd_ratio:.2g} σ: the strict criterion would need {fmt(need)} seeds)")  # fmt: skip
        out.append("It keeps within resolution only, undecided by the strict criterion: " + "; ".join(parts) + ".")
    others = [(c, settings_for(doc, name, use, rule, c)) for c in CRITERIA if c != criterion]
    out.append("The other criteria pick " + ", ".join(f"`{o.setting}` ({c})" for c, o in others) + ".")
    out.extend(log_candidates(reg, rule, criterion, use))
    out.extend(one_seed_notes(reg, ch, rule, criterion))
    out.extend(versions_text(ran))
    early = [s for s in reg["settings"] if earlier_fp32(s)]
    if early:
        out.append(f"{EARLIER} ran before the fp32 friction sub-step kept the patch damping (no kernel digest in "
                   "their rows; in hf1–hf4 fp32's μ mean then sat up to 0.15 σ low at steps ≤ 1e-7 s): "
                   + ", ".join(f"`{s['label']}`" for s in early) + ".")  # fmt: skip
    return " ".join(out)


def logged(reg: dict[str, Any], measure: str) -> dict[str, Any]:
    """``reg`` with ``measure``'s per-pad values replaced by their natural logarithms (NaN where not positive or
    missing): the measure's mean over pads becomes a geometric mean."""

    def log(vals: Sequence[Any]) -> list[float]:
        return [math.log(v) if isinstance(v, (int, float)) and v > 0 else math.nan for v in vals]

    rows = [{**s, "values": {**s["values"], measure: log(s["values"][measure])}} if s.get("values") else s
            for s in reg["settings"]]  # fmt: skip
    return {**reg, "settings": rows}


def log_candidates(
    reg: dict[str, Any], rule: float, criterion: str, measures: Sequence[str] | None = None
) -> list[str]:
    """For an amplitude of :data:`LOG_CANDIDATES` (scalar measures, among ``measures``; None: the regime's) that a
    setting does not keep: the same comparison on the pads' log values (a pad whose value is not positive drops
    out), a candidate convention beside the validation's arithmetic mean over pads, which the few pads whose
    amplitude is several times the others' dominate. One sentence per measure; [] when every setting keeps it."""
    out = []
    for m in (m for m in LOG_CANDIDATES if m in (reg["measures"] if measures is None else measures)):
        view = logged(reg, m)
        parts = []
        for s, v in zip(reg["settings"], view["settings"], strict=True):  # the same rows, in log in ``view``
            if s["role"] == "reference" or not usable(s) or kept(verdict(reg, s, m, rule, criterion)):
                continue
            c = compare_setting(view, v, m)
            parts.append(f"`{s['label']}` {verdict(view, v, m, rule, criterion)} (error {_small(c.ratio)} σ, "
                         f"sd(d) {c.sd_ratio:.2g} σ)")  # fmt: skip
        if parts:
            out.append(f"{MEASURES[m].label} averaged in log over the pads (a geometric mean: a candidate beside the "
                       "arithmetic mean the validation takes, which the few pads several times the others' "
                       "dominate), for the settings that do not keep it: " + "; ".join(parts) + ".")  # fmt: skip
    return out


def without_seeds(reg: dict[str, Any], seeds: set[int]) -> dict[str, Any]:
    """``reg`` without the pads of ``seeds`` (every member of an LF seed), in every setting's per-pad values."""
    keep = [k for k, p in enumerate(reg["pads"]) if p["seed"] not in seeds]
    rows = [{**s, "values": {m: [v[k] for k in keep] for m, v in s["values"].items()}} if s.get("values") else s
            for s in reg["settings"]]  # fmt: skip
    return {**reg, "pads": [reg["pads"][k] for k in keep], "settings": rows}


def seed_differences(reg: dict[str, Any], setting: dict[str, Any], measure: str) -> dict[int, float]:
    """Per seed, the largest |setting − reference| over its pads of a scalar ``measure``, each pad in units of its
    member's σ as the rule takes it (:func:`member_comparisons`: an LF state is judged on its own σ); {} for a vector
    measure or a member without spread."""
    ref = reference_of(reg)["values"][measure]
    if any(isinstance(v, list) for v in ref):
        return {}
    vals = setting["values"][measure]
    out: dict[int, float] = {}
    comparisons = member_comparisons(reg, setting, measure)
    for c, idx in zip(comparisons, _members(reg).values(), strict=True):  # the same members, in the same order
        if not c.sigma > 0:
            return {}
        for i in idx:
            a, b = vals[i], ref[i]
            if isinstance(a, (int, float)) and isinstance(b, (int, float)) and math.isfinite(a - b):
                out[reg["pads"][i]["seed"]] = max(out.get(reg["pads"][i]["seed"], 0.0), abs(a - b) / c.sigma)
    return out


def outlier_bound(n: int) -> float:
    """The largest |d|/σ that ``n`` pads of two runs that have parted give by chance (d of standard deviation √2 σ)
    at the two-sided 5 % level over all of them (Bonferroni): √2 z(1 − 0.025/n); 5.0 for 128 pads."""
    import scipy.stats

    return math.sqrt(2.0) * float(scipy.stats.norm.ppf(1.0 - 0.025 / max(n, 1)))


def one_seed_notes(reg: dict[str, Any], choice: Choice, rule: float, criterion: str) -> list[str]:
    """For each completed setting cheaper than the pick that moves no measure, only leaves some undecided, and keeps
    every measure once the one seed whose pads differ most from the reference's in those measures is left out, that
    seed an outlier (its difference past :func:`outlier_bound`): a sentence naming it (a verdict decided by one seed,
    such as a pad that turns tonal in one run and not in the other). [] when there is none. Settings dearer than the
    pick are not looked at (va's 1e-7 s, dearer than its pick 2.5e-7 s, is decided by its tonal pads too)."""
    bound = outlier_bound(len(reg["pads"]))  # every pad compared: seeds × members
    parts = []
    for label, names in choice.fails.items():
        s = row_of(reg, label)
        if any(verdict(reg, s, m, rule, criterion) != "undecided" for m in names):
            continue
        diffs = {m: seed_differences(reg, s, m) for m in names}
        if not all(diffs.values()):
            continue
        seeds = {max(d, key=d.get) for d in diffs.values()}
        if len(seeds) != 1:
            continue
        seed = seeds.pop()
        if any(d[seed] <= bound for d in diffs.values()):
            continue
        view = without_seeds(reg, {seed})
        row = row_of(view, label)
        if all(kept(verdict(view, row, m, rule, criterion)) for m in choice.measures):
            what = ", ".join(f"{diffs[m][seed]:.2g} σ in {MEASURES[m].label}" for m in names)
            parts.append(f"`{label}` without seed {seed} (its pads' largest difference from the reference's: {what})")
    if not parts:
        return []
    return [f"Kept without one seed: each of these cheaper settings keeps every measure once the seed it names is left "
            f"out (the rule applied as above to the other seeds), a seed whose pads differ from the reference's by "
            f"more than the {bound:.3g} σ the pads of two parted runs reach by chance (at 5 % over all pads); the "
            "rule's verdict stands, this names what decides it: " + "; ".join(parts) + "."]  # fmt: skip


def versions_text(rows: Sequence[dict[str, Any]]) -> list[str]:
    """A sentence where ``rows`` ran on kernels of more than one version (:func:`kernel_versions`; rows from before
    digests were recorded count as one earlier version, a merged row whose parts differ under each of its versions):
    rows of different versions ran in different calls, so their wall times compare only within a version. [] where
    they all ran on one."""
    groups: dict[str, int] = {}
    for s in rows:
        for k in kernel_versions(s):
            groups[k or ""] = groups.get(k or "", 0) + 1
    if len(groups) < 2:
        return []
    parts = [f"{n} on kernels `{k}`" if k else f"{n} from before the rows recorded their kernels"
             for k, n in sorted(groups.items())]  # fmt: skip
    return [f"Its runs come from kernels of {len(groups)} versions ({'; '.join(parts)}), run in different calls: "
            "wall times and speed-ups compare fairly only within one version."]  # fmt: skip


def _length(reg: dict[str, Any]) -> str:
    """A regime's run length and what of it is analysed; for one merged from parts, each part's own."""
    if reg["kind"] == "growth":
        return f"{reg['duration_s'] * 1e3:.1f} ms (growing)"
    parts = reg.get("parts")
    if not parts:
        return f"{reg['duration_s'] * 1e3:.1f} ms (analysed from {reg['window_start_s'] * 1e3:.1f} ms)"
    each = ", ".join(f"{p['duration_s'] * 1e3:.1f} ms (from {p['window_start_s'] * 1e3:.1f} ms)" for p in parts)
    seeds = "; ".join(f"{p['seeds'][0]}…{p['seeds'][-1]}" for p in parts)
    devices = ", ".join(sorted({str(p["device"]) for p in parts}))
    return (
        f"measured in {len(parts)} parts (seeds {seeds}; on {devices}), each over its own plan (run length, "
        f"analysed from): {each} (a setting's wall time: the sum of its parts')"
    )


def _duration(reg: dict[str, Any]) -> str:
    """A regime's run length (its parts' range for one merged from parts)."""
    lengths = sorted(p["duration_s"] for p in reg.get("parts") or [reg])
    span = f"{lengths[0] * 1e3:.1f}" + (f"–{lengths[-1] * 1e3:.1f}" if lengths[-1] > lengths[0] else "")
    return f"{span} ms"


def render(docs: Sequence[dict[str, Any]], names: Sequence[str], figures: Sequence[Path], page: Path, rule: float,
           measures: Sequence[str] | None, criterion: str) -> list[str]:  # fmt: skip
    """The generated section of the page (``names``: the result files, as the page links them)."""
    lines: list[str] = []
    for tag in dict.fromkeys(d["tag"] for d in docs):
        group = [(d, n) for d, n in zip(docs, names, strict=True) if d["tag"] == tag]
        commands = dict.fromkeys(c for d, _ in group for c in d["commands"])
        seeds = sorted({_seeds(reg) for d, _ in group for reg in d["regimes"].values()})
        lines += [
            f"Results on **{machine_text(group[0][0])}**{' (the quick CPU variant)' if group[0][0]['quick'] else ''}: "
            + ", ".join(f"`{n}`" for _, n in group) + " from " + "; ".join(f"`{c}`" for c in commands) + ". Rule: "
            f"± {rule:g} × σ between seeds, criterion `{criterion}` ({CRITERIA[criterion]}). "
            + " ".join(resolution_text(n, rule) for n in seeds),
            "",
            *(f"* {regime_results(d, r, rule, measures, criterion)}" for d, _ in group for r in d["regimes"]),
            "",
        ]  # fmt: skip
    lines += ["### The settings the rule picks", "", *summary_table(docs, rule, measures, criterion), ""]
    lines += ["### The criteria side by side", "", "The setting each criterion picks (speed-up over the reference):",
              "", *candidates_table(docs, rule, measures), ""]  # fmt: skip
    lines += ["### Measures", "", *measure_table(docs), ""]
    for fig in figures:
        lines += [
            f"![error/σ against wall time]({fig.relative_to(page.parent).as_posix()})",
            "",
            f"*Per regime, error of the ensemble mean / σ between seeds against stepping wall time: one colour per "
            f"measure, one marker per integrator and precision (a line through its steps or tolerances), filled "
            f"where the setting keeps the measure, half filled where it keeps it within resolution; dashed: the rule "
            f"({rule:g}); grey line: the reference's wall time; dotted: the setting the rule picks. Errors below "
            f"{RATIO_FLOOR:g} σ are drawn at {RATIO_FLOOR:g}.*",
            "",
        ]
    for doc in docs:
        for name, reg in doc["regimes"].items():
            use = _measures(reg, measures)
            cfg = reg["config"]
            lines += [
                f"### {name}: {reg['description']}",
                "",
                f"{len(reg['pads'])} pads (seeds {reg['pads'][0]['seed']}…{reg['pads'][-1]['seed']}), "
                f"{_length(reg)}, perturbation {cfg['perturbation']:g} m/s; pads the "
                f"saturation detector calls saturated: {reference_of(reg).get('saturated', '–')} of "
                f"{len(reg['pads'])} in the reference; {fmt(doc.get('regime_wall_s'), '.0f')} s of wall time in "
                f"all (runs, analysis, compilation). Per setting and measure: error/σ (the upper end of the 95 % "
                f"interval of |bias|/σ); ✓ keeps (bound ≤ {rule:g}), ≈ keeps within resolution, **bold** moves (the "
                f"whole interval beyond {rule:g}), plain: undecided.",
                "",
                *setting_table(reg, rule, use, criterion),
                "",
                "The reference ensemble; per measure sd(d)/σ of the reference's twin (the grid setting that differs "
                "from it in precision only) and over the grid, the seeds the strict criterion would need with that "
                f"sd(d) for an unbiased setting (t₀.₉₇₅ sd(d)/√n ≤ {rule:g} σ), and the cheapest setting that keeps "
                "the measure:",
                "",
                *reference_table(reg, settings_for(doc, name, use, rule, criterion)),
                "",
            ]
    return lines


def report(paths: Sequence[Path], page: Path, figures: Path, rule: float, measures: Sequence[str] | None,
           criterion: str) -> None:  # fmt: skip
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
    figs = [regime_figure([d for d in docs if d["tag"] == t], figures, t, rule, criterion) for t in tags]
    try:
        names = [p.resolve().relative_to(page.resolve().parent.parent).as_posix() for p in paths]
    except ValueError:
        names = [p.name for p in paths]
    body = render(docs, names, figs, page, rule, measures, criterion)
    replace_generated(page, body, generated_markers(MARKER), TITLE)
    print(f"wrote {page} and {', '.join(str(f) for f in figs)}")
