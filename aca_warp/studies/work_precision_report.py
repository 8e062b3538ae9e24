"""Figures and the generated docs section of the work-precision study (:mod:`aca_warp.studies.work_precision`).

:func:`report` reads any number of result JSONs (a later file replaces an earlier one for the same device and
scene), draws one figure per (device, scene) — error against wall time, one panel per measure, the floor of the
statistics as a dashed line — and rewrites the part of the docs page between the generated markers: a summary of
the cheapest setting of every method that reaches a μ error (pointwise windows) or the floor (statistics windows),
then one section per scene with its references, start state and tables.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.hf.options import DEFAULT_TOLERANCE, PRESET_CROSSING, PRESET_STEP, default_step
from aca_warp.studies.report import figure, fmt, generated_markers, md_table, replace_generated, save_figure

BEGIN, END = generated_markers("scripts/work_precision.py --report")
TARGETS = (1e-5, 1e-7)  # μ errors of the summary
FLOOR_FACTOR = 2.0  # a statistics row is "at the floor" when every statistic error is ≤ this × the floor's
FLOOR_STATS = ("std", "spectrum", "sync", "stick")
STAT_TOL = {"std": 1e-2, "spectrum": 1e-2, "sync": 1e-2, "stick": 1e-1}  # accuracy asked of the statistics
WINDOW_MEASURES = {
    "mu": "μ(t) over the pointwise window (max abs. error)",
    "state": "final state (rel. max error of u, u̇)",
    "peak_f": "largest spectral peak of μ: frequency (rel. error)",
    "sync": "S(f) (mean abs. error)",
}
LONG_MEASURES = {
    "spectrum": "statistics window: μ spectrum (mean |ln A/A_ref| over bands)",
    "std": "statistics window: std of μ (rel. error)",
    "sync": "statistics window: S(f) (mean abs. error)",
    "stick": "statistics window: sticking fraction (rel. error)",
}
COLOURS = {"adaptive": "C0", "strang": "C1", "scipy-DOP853": "C2", "scipy-Radau": "C3"}


def device_tag(doc: dict) -> str:
    """File-name tag of a result's device (``cpu``, ``cuda0``; ``_quick`` for the quick variant)."""
    return re.sub(r"[^A-Za-z0-9]+", "", doc["machine"]["device"]) + ("_quick" if doc.get("quick") else "")


def load_results(paths: list[str]) -> list[tuple[dict, dict]]:
    """(document, scene block) pairs of several result JSONs; for a repeated (device, scene) the last file wins."""
    out: dict[tuple[str, str], tuple[dict, dict]] = {}
    for p in paths:
        doc = json.loads(Path(p).read_text())
        for sc in doc["scenes"]:
            out[(device_tag(doc), sc["scene"])] = (doc, sc)
    return list(out.values())


def setting(row: dict) -> str:
    """A row's step, tolerance or rtol as a table cell."""
    if "tolerance" in row:
        return f"tol {row['tolerance']:.0e}"
    if "rtol" in row:
        return f"rtol {row['rtol']:.0e}"
    return f"{row['dt']:.3g} s"


def label(row: dict) -> str:
    """Method and precision of a row (the precision only when it is not fp64)."""
    return row["method"] + ("" if row["precision"] == "fp64" else f" {row['precision']}")


def _fmt_s(x: float) -> str:
    return f"{x * 1e3:g} ms" if x >= 1e-3 else f"{x * 1e6:g} µs"


# ----------------------------------------------------------------------------------------------- figures


def _points(sc: dict, block: str, meas: str) -> dict[str, list[tuple[float, float, bool]]]:
    """(wall, error, extrapolated) per method label for one measure of one block."""
    groups: dict[str, list[tuple[float, float, bool]]] = {}
    for r in sc["rows"]:
        b = r.get(block)
        if not b:
            continue
        err, wall = b.get(meas), b.get("wall_s")
        if err is None or wall is None or not (np.isfinite(err) and np.isfinite(wall)):
            continue
        groups.setdefault(label(r), []).append((wall, max(err, 1e-16), bool(b.get("extrapolated"))))
    return groups


def _panel(ax: Any, groups: dict[str, list], title: str, floor: float | None = None) -> None:
    for name, pts in sorted(groups.items()):
        pts.sort()
        w, e, x = (np.array(z) for z in zip(*pts, strict=True))
        c = COLOURS.get(name.split()[0], "k")
        ax.plot(w, e, "-" if "fp32" not in name else "--", color=c, marker="o" if "scipy" in name else "s", ms=4,
                mfc="none" if x.any() else c, label=name)  # fmt: skip
    if floor is not None and np.isfinite(floor) and floor > 0:
        ax.axhline(floor, color="0.4", ls=":", lw=1, label="floor (twin reference)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel("error")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)


def plot(doc: dict, sc: dict, figdir: Path) -> str:
    """One figure per (device, scene): a panel per measure and a legend; returns the file stem."""
    stem = f"wp_{sc['scene']}_{device_tag(doc)}"
    panels = [
        ("window", m, t) for m, t in WINDOW_MEASURES.items() if m in ("mu", "state") or sc["regime"] != "saturated"
    ]
    panels = [p for p in panels if m_present(sc, p[0], p[1])]
    if sc.get("long_reference"):
        panels += [("long", m, t) for m, t in LONG_MEASURES.items()]
    cols = math.ceil((len(panels) + 1) / 2)
    fig = figure(figsize=(5 * cols, 8.5))
    axes = fig.subplots(2, cols).flat
    floor = (sc.get("long_reference") or {}).get("floor", {})
    for ax, (block, meas, title) in zip(axes, panels, strict=False):
        _panel(ax, _points(sc, block, meas), title, floor.get(meas) if block == "long" else None)
    handles: dict[str, Any] = {}
    for ax in fig.axes[: len(panels)]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    for ax in fig.axes[len(panels) :]:
        ax.axis("off")
    fig.axes[len(panels)].legend(list(handles.values()), list(handles), loc="center", fontsize=8)
    ref = sc["reference"]
    fig.suptitle(
        f"Work-precision, {sc['scene']} ({sc['patches']} patches; {sc['what']}) on {doc['machine']['device_name']}\n"
        f"pointwise window {_fmt_s(sc['window_s'])} against SciPy DOP853 rtol {ref['rtol']:g}"
        + (f"; statistics window {_fmt_s(sc['long_window_s'])} against fp64 strang "
           f"{sc['long_reference']['dt']:g} s" if sc.get("long_reference") else "")
        + ". Hollow: SciPy time extrapolated from a tenth of the window.",
        fontsize=9,
    )  # fmt: skip
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    save_figure(fig, figdir, stem)
    return stem


def m_present(sc: dict, block: str, meas: str) -> bool:
    """Whether any row has measure ``meas`` in ``block``."""
    return any(meas in (r.get(block) or {}) for r in sc["rows"])


# ----------------------------------------------------------------------------------------------- tables


def _steps(b: dict, kind: str) -> str:
    if kind == "scipy":
        return f"{b.get('nfev', '')} f-evals"
    s = f"{b.get('steps', '')}"
    return s + (f" (+{b['rejected']} rej.)" if b.get("rejected") else "")


def _wall(b: dict, unit: str = "") -> str:
    """Wall time of a block as a cell (``unit`` after the number), marked when extrapolated."""
    return fmt(b.get("wall_s"), ".3g") + unit + (" (extrap.)" if b.get("extrapolated") else "")


def window_table(sc: dict) -> list[str]:
    """The pointwise-window table of a scene."""
    spectra = any("sync" in (r.get("window") or {}) for r in sc["rows"])
    header = ["method", "setting", "μ err", "state err"] + (["peak f err", "peak A err", "S err"] if spectra else [])
    header += ["wall [s]", "steps"]
    rows = []
    for r in sc["rows"]:
        b = r.get("window")
        if b is None:
            continue
        errs = [fmt(b.get(k), ".1e") for k in ("mu", "state")]
        if spectra:
            errs += [fmt(b.get(k), ".1e") for k in ("peak_f", "peak_a", "sync")]
        fault = f" ({b['fault'].split(':')[0]})" if b.get("fault") else ""
        rows.append([label(r), setting(r), *errs, _wall(b) + fault, _steps(b, r["kind"])])
    return md_table(header, rows)


def long_table(sc: dict) -> list[str]:
    """The statistics-window table of a saturated scene, the floor first."""
    keys = ("mean", "std", "spectrum", "peak_f", "sync", "stick")
    header = ["method", "setting", "mean μ err", "std μ err", "spectrum err", "peak f err", "S err", "stick err"]
    header += ["wall [s]", "steps"]
    lr = sc["long_reference"]
    rows = [["floor (twin reference)", f"{lr['dt']:.3g} s", *(fmt(lr["floor"].get(k), ".1e") for k in keys), "", ""]]
    for r in sc["rows"]:
        b = r.get("long")
        if b is None:
            continue
        rows.append([label(r), setting(r), *(fmt(b.get(k), ".1e") for k in keys), _wall(b), _steps(b, r["kind"])])
    return md_table(header, rows)


def cheapest(sc: dict, method: str, ok: Any, block: str = "window") -> dict | None:
    """The row of ``method`` with the least wall time whose ``block`` passes ``ok`` (None if none)."""
    best = None
    for r in sc["rows"]:
        b = r.get(block)
        if r["method"] != method or r["precision"] != "fp64" or not b or not b.get("complete", True):
            continue
        if ok(b) and (best is None or b["wall_s"] < best[block]["wall_s"]):
            best = r
    return best


def _cell(r: dict | None, block: str = "window") -> str:
    if r is None:
        return "–"
    return f"{_wall(r[block], ' s')} ({setting(r)})"


def at_floor(b: dict, floor: dict) -> bool:
    """Whether every statistic error of ``b`` is within max(FLOOR_FACTOR × the floor's, STAT_TOL): at the floor,
    or accurate enough where the floor lies below STAT_TOL (a window too short for the twin to part). Statistics
    without a floor value are skipped."""
    for k in FLOOR_STATS:
        f = floor.get(k)
        if f is None or not np.isfinite(f):
            continue
        v = b.get(k)
        if v is None or not np.isfinite(v) or v > max(FLOOR_FACTOR * f, STAT_TOL[k]):
            return False
    return True


METHODS = ("adaptive", "strang", "scipy-DOP853", "scipy-Radau")


def scene_cell(doc: dict, sc: dict) -> str:
    """A scene with its patches, window and the quick mark, as a table cell."""
    return f"{sc['scene']} ({sc['patches']} patches, {_fmt_s(sc['window_s'])}{', quick' if doc.get('quick') else ''})"


REGIME_ORDER = {"sliding": 0, "stick-slip": 1, "saturated": 2}


def defaults_table(pairs: list[tuple[dict, dict]]) -> list[str]:
    """Per scene (by regime): μ error over the pointwise window and wall time of strang at its default step and of
    adaptive at its default tolerance and the two below it."""
    d = pairs[0][0]["defaults"] if pairs else {}
    dt, tol = d.get("dt", math.nan), d.get("tolerance", math.nan)
    settings = [("strang", "dt_requested", dt)] + [("adaptive", "tolerance", tol / f) for f in (1, 10, 100)]
    rows = []
    for doc, sc in sorted(pairs, key=lambda p: (REGIME_ORDER.get(p[1]["regime"], 9), p[1]["scene"])):
        cells = []
        for method, key, value in settings:
            r = next(
                (r for r in sc["rows"] if r["method"] == method and _close(r.get(key), value) and r.get("window")),
                None,
            )
            cells.append("–" if r is None else f"{fmt(r['window'].get('mu'), '.1e')} ({_wall(r['window'], ' s')})")
        rows.append([sc["regime"], scene_cell(doc, sc), doc["machine"]["device"], *cells])
    head = ["regime", "scene", "device"] + [f"{m} {'dt' if m == 'strang' else 'tol'} {v:g}" for m, _, v in settings]
    then = " (the default when these runs were made; now {})"
    now = "" if _close(tol, DEFAULT_TOLERANCE) else then.format(f"{DEFAULT_TOLERANCE:g}")
    # strang's default depends on the scene: the note names both when the runs' step is either one's no longer
    treatment = "the crossings averaged" if PRESET_CROSSING == "mean" else "the point treatment"
    steps = (
        f"{PRESET_STEP:g} s with {treatment} for the presets' physics, {default_step('strang'):g} s for other scenes"
    )
    now_dt = "" if any(_close(dt, s) for s in (PRESET_STEP, default_step("strang"))) else then.format(steps)
    return [
        f"**μ error over the pointwise window (wall time) at strang's step {dt:g} s{now_dt} and at adaptive's "
        f"tolerance {tol:g}{now} and below.**",
        "",
        *md_table(head, rows),
        "",
    ]


def _close(a: float | None, b: float) -> bool:
    return a is not None and math.isclose(a, b, rel_tol=1e-9)


def summary(pairs: list[tuple[dict, dict]]) -> list[str]:
    """The summary tables: cheapest setting per method at each μ-error target, and at the statistics floor."""
    rows = []
    for doc, sc in pairs:
        ref = sc["reference"]
        ours = [r["window"].get("mu", math.inf) for r in sc["rows"] if r["method"] == "adaptive" and r.get("window")]
        agree = min(ours, default=math.nan)
        for t in TARGETS:
            cells = [_cell(cheapest(sc, m, lambda b, t=t: b.get("mu", math.inf) <= t)) for m in METHODS]
            rows.append([scene_cell(doc, sc), doc["machine"]["device"], sc["regime"], f"{t:.0e}", *cells,
                         f"{ref['check_mu']:.1e} / {agree:.1e}"])  # fmt: skip
    lines = [
        "**Cheapest setting that reaches a μ error over the pointwise window** (wall time of the stepping; "
        "“–”: no measured setting reaches it; last column: the DOP853 reference against DOP853 at 10× its rtol, "
        "and against our finest adaptive run — errors below these are not resolved).",
        "",
        *md_table(["scene", "device", "regime", "μ err ≤", *METHODS, "reference checks"], rows),
        "",
    ]
    long_rows = []
    for doc, sc in pairs:
        lr = sc.get("long_reference")
        if not lr:
            continue
        cells = [_cell(cheapest(sc, m, lambda b, f=lr["floor"]: at_floor(b, f), "long"), "long") for m in METHODS]
        floor = ", ".join(f"{k} {fmt(lr['floor'].get(k), '.1e')}" for k in FLOOR_STATS)
        long_rows.append([scene_cell(doc, sc), doc["machine"]["device"], _fmt_s(sc["long_window_s"]), *cells, floor])
    if long_rows:
        lines += [
            f"**Cheapest setting whose statistics are at the floor or within the tolerance** (every one of "
            f"{', '.join(f'{k} ≤ {t:g}' for k, t in STAT_TOL.items())}, or within {FLOOR_FACTOR:g}× the difference "
            "between the reference and its twin from a state perturbed by 1e-9 m/s).",
            "",
            *md_table(["scene", "device", "window", *METHODS, "floor"], long_rows),
            "",
        ]
    return lines


def _scene_section(doc: dict, sc: dict, figdir: Path, stem: str) -> list[str]:
    """A scene on a device: figure, caption, start state, references and checks, tables."""
    ref, st = sc["reference"], sc["reference"]["stick"]
    v = doc["versions"]
    rel = (Path("figures") / figdir.name / f"{stem}.png").as_posix()
    t_first = st.get("first_stick_s")
    first = f"{t_first * 1e6:.0f} µs" if t_first is not None and math.isfinite(t_first) else "never"
    start = sc["start"]
    lines = [
        f"### {sc['scene']} on {doc['machine']['device_name']}{' (--quick)' if doc.get('quick') else ''}",
        "",
        f"![work-precision {sc['scene']}]({rel})",
        "",
        f"*{sc['what']}; {sc['patches']} patches, ω = {sc['angular_velocity']:.4g} rad/s; "
        f"{doc['machine']['device_name']}; Warp {v['warp']}, SciPy {v['scipy']}; samples every "
        f"{_fmt_s(doc['sample_dt_s'])}. PDF: `{rel[:-4]}.pdf`.*",
        "",
        f"Start state: {start['how']}"
        + (f" ({start['wall_s']:.0f} s); {start['verdict']}" if "verdict" in start else "")
        + (f"; mean area ×{start['mean_area_growth']:.3g}, patch share of the load {start['patch_share']:.3f}"
           if "patch_share" in start else "") + ".",
        "",
        f"Pointwise window {_fmt_s(sc['window_s'])}: reference SciPy DOP853 rtol {ref['rtol']:g} "
        f"({ref['wall_s']:.3g} s, {ref['nfev']} f-evals); DOP853 at rtol {ref['check_rtol']:g} differs by μ "
        f"{ref['check_mu']:.1e}, state {ref['check_state']:.1e}. Mean μ {ref['mu_mean']:.4f}"
        + (f", spectral peak {ref['peak_hz'] / 1e3:.2f} kHz (amplitude {ref['peak_amplitude']:.3g})" if "peak_hz" in ref
           else "")
        + f". Sticking (|ωr − u̇| < {st['threshold_m_s']:g} m/s): at most {100 * st['max_fraction']:.2f} % of the "
        f"patches at once, {100 * st['patches_ever_stuck']:.1f} % at some time, first: {first}.",
        "",
        *window_table(sc),
        "",
    ]  # fmt: skip
    lr = sc.get("long_reference")
    if lr:
        lines += [
            f"Statistics window {_fmt_s(sc['long_window_s'])}: reference fp64 strang at {lr['dt']:g} s "
            f"({lr['wall_s'][0]:.3g} s; over the pointwise window it differs from DOP853 by μ "
            f"{lr['vs_reference_mu']:.1e}); mean μ {lr['mean']:.4f}, std {lr['std']:.2e}, sticking fraction "
            f"{lr['stick']:.2e}, largest peak {lr['peak_hz'] / 1e3:.1f} kHz. Floor: the same from u̇ + "
            f"N(0, ({lr['twin_dv_m_s']:g} m/s)²).",
            "",
            *long_table(sc),
            "",
        ]
    return lines


def report(paths: list[str], page: Path, figdir: Path) -> None:
    """Figures for every (device, scene) of the result JSONs and the generated part of ``page``."""
    pairs = load_results(paths)
    lines = ["", *defaults_table(pairs), *summary(pairs)]
    for doc, sc in pairs:
        lines += _scene_section(doc, sc, figdir, plot(doc, sc, figdir))
    replace_generated(page, lines, (BEGIN, END), "Work-precision")
    print(f"wrote {page} and figures in {figdir}")
