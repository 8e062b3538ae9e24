"""The generated part of docs/validation.md: the table of the paper's statements (each also from rest at the
paper's length, beside it), the runs from rest over time, which change moves which verdict, the §3.2 growth runs
and the §3.3 LF states, the experiments (runs, saturation, pads not used), the initial-state comparison and the §3.1
STFT maxima, under a header naming the command, machine, versions and settings that produced it. Everything is
rendered from the results alone (``results.json``), so the section can be rebuilt without running anything.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from aca_warp.studies.report import fmt, md_table, unsigned_zero
from aca_warp.studies.validation import area as validation_area
from aca_warp.studies.validation import causes as validation_causes
from aca_warp.studies.validation import multiscale as validation_multiscale
from aca_warp.studies.validation.base import EXPERIMENTS, USABLE, Experiment, interval, usable, values
from aca_warp.studies.validation.verdicts import CRITERIA, REPRODUCED, VERDICTS


def _range(v: list[float | None], scale: float = 1.0, spec: str = ".3g") -> str:
    x = np.array([np.nan if a is None else a for a in v], dtype=np.float64) * scale
    x = x[np.isfinite(x)]
    if x.size == 0:
        return "–"
    one = [unsigned_zero(format(a, spec)) for a in (np.mean(x), x.min(), x.max())]
    return one[0] + (f" ({one[1]}–{one[2]})" if x.size > 1 else "")


def experiment_rows(results: dict[str, dict]) -> list[list[str]]:
    """One line per experiment: what, pads used, run, predicted against measured growth, saturation, segment."""
    rows = []
    for name, exp in EXPERIMENTS.items():
        res = results.get(name)
        if not res or "plan" not in res:
            rows.append([name, exp.description, res.get("status", "not run") if res else "not run", *["–"] * 7])
            continue
        pads, run = res.get("pads", []), res.get("run") or {}
        ok = usable(res)
        grow = np.array([p["growth_rate"] for p in ok if p.get("growth_rate") is not None])
        seg = res.get("segment") or {}
        rows.append(
            [
                name,
                exp.description,
                f"{len(ok)} / {len(pads)}" + ("" if res.get("status") == "done" else f" ({res.get('status')})"),
                _contact_text(pads),
                _run_text(exp, res),
                f"{run.get('steps', 0):,} at {fmt(run.get('dt'), '.3g')} s; {fmt(run.get('wall_s'), '.0f')} s, "
                f"{fmt(run.get('us_per_step'), '.3g')} µs/step",
                " / ".join(
                    _range([p[k] for p in pads], spec=".0f") for k in ("sigma_min", "sigma_median", "sigma_max")
                ),
                interval(grow, ".0f"),
                f"{_range([p.get('t_s_sum_abs_velocity') for p in pads], 1e3)} / "
                f"{_range([p.get('t_s_mu') for p in pads], 1e3)}",
                f"{fmt((seg.get('seconds') or 0) * 1e3, '.2f')} ms, {fmt(seg.get('resolution_hz'), '.0f')} Hz"
                if seg.get("samples")
                else "–",
            ]
        )
    return rows


def _contact_text(pads: list[dict[str, Any]]) -> str:
    """Patches per pad (the range where they differ) and how many are in contact."""
    if not pads:
        return "–"
    n = [p.get("patches", 0) for p in pads]
    c = [p.get("in_contact", 0) for p in pads]
    if all(a == b for a, b in zip(c, n, strict=True)):
        where = "all in contact"
    else:
        where = f"at least {min(b / max(a, 1) for a, b in zip(n, c, strict=True)) * 100:.0f} % in contact"
    size = f"{max(n)}" if min(n) == max(n) else f"{min(n)}–{max(n)}"
    return f"{size} ({where})"


def _run_text(exp: Experiment, res: dict[str, Any]) -> str:
    """Start and run length: predicted settling + window, a fixed window, or a growth run."""
    plan = res["plan"]
    dur = f"{plan['duration_s'] * 1e3:.1f} ms"
    if exp.kind == "window":
        return f"{exp.initial}; {dur} fixed, per-patch window from {plan['window_start_s'] * 1e3:.2f} ms"
    if exp.kind == "growth":
        return f"{exp.initial}; {dur} of growth (first saturation predicted at {plan['settle_s'] * 1e3:.1f} ms)"
    members = f", {len(exp.members)} state{'s' if len(exp.members) > 1 else ''}" if exp.members else ""
    settle = plan["window_start_s"]  # the planned settling: the predicted one, at least one window
    predicted = "" if abs(settle - plan["settle_s"]) < 1e-4 else f"; predicted {plan['settle_s'] * 1e3:.1f}"
    return f"{exp.initial}; {dur} ({settle * 1e3:.1f} + window{members}{predicted})"


EXPERIMENT_HEADER = [
    "experiment",
    "what",
    "pads used / seeds",
    "patches per pad",
    "start; run (predicted settling + window)",
    "steps at dt; wall (the batch's)",
    "predicted σ_i min / median / max [1/s] (mean over pads)",
    "measured σ on Σ|u̇| [1/s]",
    "t_s Σ|u̇| / μ [ms], mean (range)",
    "analysed segment, Δf",
]


def pad_notes(results: dict[str, dict]) -> list[str]:
    """Every pad that is not used, with the reason (the detector's verdict)."""
    lines = []
    for name, res in results.items():
        for p in res.get("pads", []):
            st = p.get("status")
            if st is not None and not (st in USABLE and "measures" in p):
                who = f"{name}, {p['member'] + ', ' if p.get('member') else ''}seed {p.get('seed')}"
                lines.append(f"* {who}: **{st}** — Σ|u̇|: {p.get('verdict_sum_abs_velocity')}")
    return lines or ["* none: every pad of every experiment run was analysed (saturated, or over its fixed window)."]


def initial_state_rows(results: dict[str, dict]) -> list[list[str]]:
    """hf1 from equilibrium + perturbation against hf1 from rest: saturation and the main measures."""
    out = []
    for key, label, scale, unit in (
        ("t_s_sum_abs_velocity", "t_s of Σ|u̇|", 1e3, "ms"),
        ("t_s_mu", "t_s of μ", 1e3, "ms"),
        ("growth_rate", "fitted growth rate of Σ|u̇|", 1.0, "1/s"),
    ):
        out.append(
            [label, *(interval(_pad_values(results.get(n), key), ".3g", scale, unit) for n in ("hf1", "hf1_rest"))]
        )
    for key, label, scale, unit in (
        ("f1", "first velocity peak (Σu̇)", 1e-3, "kHz"),
        ("sync_relative.median_excess_phi10", "median S − S_null (Φ ≥ 10)", 1.0, ""),
        ("corr_near", "C of the directions of motion of coupled neighbours (≤ 5 mm)", 1.0, ""),
        ("patch_spacing", "patch spacing (median nearest-neighbour distance)", 1e3, "mm"),
        ("corr_zero", "distance where that C falls to 0", 1e3, "mm"),
        ("corr_f1_near", "C of the phases at f1 of coupled neighbours", 1.0, ""),
    ):
        out.append([label, *(interval(values(results.get(n), key), ".3g", scale, unit) for n in ("hf1", "hf1_rest"))])
    return out


def _pad_values(res: dict[str, Any] | None, key: str) -> np.ndarray:
    v = [p.get(key) for p in usable(res)]
    return np.array([x for x in v if x is not None], dtype=np.float64)


def stft_lines(results: dict[str, dict]) -> list[str]:
    """Largest STFT amplitude of μ/μ̄ per window length, per §3.1 experiment (mean over pads)."""
    lines = []
    for name, res in results.items():
        if name not in EXPERIMENTS or EXPERIMENTS[name].section != "§3.1" or EXPERIMENTS[name].kind != "saturated":
            continue
        per: dict[str, list[tuple[float, float]]] = {}
        for p in usable(res):
            for w in p["measures"].get("stft", []):
                per.setdefault(w["window"], []).append((w["amplitude"], w["frequency"]))
        for window, v in per.items():
            a, f = np.array(v).T
            lines.append(f"* {name}, {window}: {interval(a, '.3g')} at {interval(f, '.1f', 1e-3, 'kHz')}")
    return lines or ["* no saturated segment holds a window of 2^12 samples."]


def cause_lines(causes: list[dict[str, Any]]) -> list[str]:
    """The summary of the variants of the open rows and, folded, every variant's value."""
    if not causes:
        return ["No open verdict, or no variant of one was run."]
    header, rows = validation_causes.cause_summary(causes)
    moved = [c for c in causes if c["moved"]]
    lines = [
        "Each open statement (main verdict ✗ not reproduced or ~ partly) evaluated again with one change (a "
        "variant); a cell gives the variant and its verdict (✓ reproduced, ~ partly, ✗ not reproduced, · not "
        "measured), **bold** where the verdict moved. Variants whose experiments were not run are left out.",
        "",
        *md_table(header, rows),
        "",
        f"Verdicts moved by a variant: {len(moved)} of {len(causes)}"
        + (
            ": "
            + "; ".join(
                f"{c['statement']} — {c['cause']} ({c['variant']}): {c['main_verdict']} → {c['verdict']}" for c in moved
            )
            if moved
            else ""
        )
        + ".",  # fmt: skip
        "",
        "<details><summary>Every variant's value</summary>",
        "",
        *md_table(
            ["statement", "cause", "variant", "experiments", "value", "verdict"],
            [
                [c["statement"], c["cause"], c["variant"], ", ".join(c["experiments"]), c["value"], c["verdict"]]
                for c in causes
            ],
        ),  # fmt: skip
        "",
        "</details>",
    ]
    return lines


def verdict_counts(rows: list[dict[str, Any]]) -> str:
    """How many rows carry each verdict, in one sentence, and how many of the reproduced ones hold by construction
    or check the code (:attr:`~aca_warp.studies.validation.base.Row.construction`)."""
    counts: dict[str, int] = {}
    for r in rows:
        counts[r["verdict"]] = counts.get(r["verdict"], 0) + 1
    text = f"{len(rows)} statements: " + ", ".join(f"{n} {v}" for v, n in counts.items()) + "."
    built = sum(1 for r in rows if r["verdict"] == REPRODUCED and r.get("construction"))
    if built:
        text += (
            f' Of the {counts[REPRODUCED]} reproduced, {built} hold by construction or check the code (marked "by '
            f'construction" in the table), so {counts[REPRODUCED] - built} are findings of the model.'
        )
    return text


def rest_counts(rows: list[dict[str, Any]], rest: list[dict[str, Any] | None]) -> str:
    """The verdicts of the column "from rest, paper length" in one sentence: how many rows it measures, how many
    carry each verdict there and in the primary, and the rows whose verdict there differs from the primary's (""
    when no row has one)."""
    pairs = [(r, b) for r, b in zip(rows, rest, strict=True) if b is not None and b["verdict"] in VERDICTS]
    if not pairs:
        return ""

    def counted(verdicts: list[str]) -> str:
        return ", ".join(f"{verdicts.count(v)} {v}" for v in VERDICTS if v in verdicts)

    moved = [f"{r['statement']} ({r['verdict']} → {b['verdict']})" for r, b in pairs if b["verdict"] != r["verdict"]]
    text = (
        f"From rest at the paper's length (the column beside the verdict), {len(pairs)} of the rows are measured: "
        f"{counted([b['verdict'] for _, b in pairs])} (the primary on the same rows: "
        f"{counted([r['verdict'] for r, _ in pairs])})."
    )
    if moved:
        text += f" The verdict there differs from the primary's in {len(moved)}: " + "; ".join(moved) + "."
    return text


def moved_counts(rows: list[dict[str, Any]], other: list[dict[str, Any]], text: str) -> str:
    """``text`` followed by the rows whose verdict differs in ``other`` (the rows evaluated under another reading),
    in one sentence."""
    moved = [f"{r['statement']} ({r['verdict']} → {s['verdict']})" for r, s in zip(rows, other, strict=True)
             if s["verdict"] != r["verdict"]]  # fmt: skip
    if not moved:
        return text + "no verdict moves."
    verb = "moves" if len(moved) == 1 else "move"
    return text + f"{len(moved)} of the {len(rows)} verdicts {verb}: " + "; ".join(moved) + "."


def strict_counts(rows: list[dict[str, Any]], strict: list[dict[str, Any]]) -> str:
    """The rows whose verdict the stricter reading of a direction part moves (the whole interval beyond the margin,
    :func:`~aca_warp.studies.validation.verdicts.strict_direction`), in one sentence."""
    return moved_counts(rows, strict, "Read strictly, a direction part agrees only when its whole 95 % interval, not "
                        "its mean alone, reaches the margin: ")  # fmt: skip


def relative_counts(rows: list[dict[str, Any]], relative: list[dict[str, Any]]) -> str:
    """The rows whose verdict the relative reading of the S rows moves (the ratio of two presets' excesses at equal
    Φ against ln 1.25, :func:`~aca_warp.studies.validation.hf_sync.relative_s`), in one sentence."""
    return moved_counts(rows, relative, "Read relatively, each difference of S − S_null at equal Φ between two "
                        "presets as the ratio of the two excesses against ln 1.25, not against 0.05: ")  # fmt: skip


def statement_rows(rows: list[dict[str, Any]], rest: list[dict[str, Any] | None]) -> list[list[str]]:
    """The main table's lines: the row, and beside it the same measure from rest at the paper's length."""
    out = []
    for r, b in zip(rows, rest, strict=True):
        beside = "–" if b is None else f"**{b['verdict']}**: {b['value']}"
        built = f"; by construction: {r['construction']}" if r.get("construction") else ""
        out.append([r["section"], r["statement"], r["value"], r["paper"], f"**{r['verdict']}** ({r['kind']}: "
                    f"{r['criterion']}{built})", beside, ", ".join(r["experiments"]), r["notes"]])  # fmt: skip
    return out


def criteria_lines() -> list[str]:
    return [f"* **{k}**: {v}." for k, v in CRITERIA.items()]


def render(
    results: dict[str, dict],
    rows: list[dict[str, Any]],
    meta: dict[str, Any],
    causes: list[dict[str, Any]] | None = None,
    rest: list[dict[str, Any] | None] | None = None,
    readings: Sequence[str] = (),
) -> list[str]:
    """The generated part of docs/validation.md (``readings``: a line per other reading of the rows on what it would
    move, :func:`strict_counts`, :func:`relative_counts`)."""
    from aca_warp.studies.validation import tracks as validation_tracks

    rest = rest if rest is not None else [None] * len(rows)
    rested = rest_counts(rows, rest)
    header = ["§", "statement", "ours: mean [95 % interval] (n seeds)", "paper", "verdict (criterion)",
              "from rest, paper length", "experiments", "notes"]  # fmt: skip
    return [
        *_header_lines(meta),
        "",
        "### The paper's statements",
        "",
        verdict_counts(rows),
        "",
        *([rested, ""] if rested else []),
        *(part for line in readings for part in (line, "")),
        "Criteria:",
        "",
        *criteria_lines(),
        "",
        *md_table(header, statement_rows(rows, rest)),
        "",
        "### From rest to the paper's length: the first peak, the neighbours' correlation and S over time",
        "",
        *validation_tracks.track_lines(results),
        "",
        "### Which change moves which verdict",
        "",
        *cause_lines(causes or []),
        "",
        "### §3.2: the growth runs (means over the analysed pads)",
        "",
        *md_table(*validation_area.growth_table(results)),
        "",
        "### §3.3: the LF states (means over the seeds' pads; equilibrium start)",
        "",
        *md_table(*validation_multiscale.state_table(results)),
        "",
        "### Experiments",
        "",
        *md_table(EXPERIMENT_HEADER, experiment_rows(results)),
        "",
        "Pads not used:",
        "",
        *pad_notes(results),
        "",
        "### Initial state: equilibrium + perturbation (hf1) against rest at the paper's length (hf1_rest)",
        "",
        *md_table(
            ["measure", "hf1 (equilibrium, saturated)", "hf1_rest (rest, paper length)"], initial_state_rows(results)
        ),  # fmt: skip
        "",
        "### §3.1: STFT maximum of μ/μ̄ over the saturated span (Fig. 10's normalisation; the paper gives "
        "≈ 0.004 at 69.1 kHz for §3.2 only)",
        "",
        *stft_lines(results),
    ]


def _kernels(versions: dict[str, str]) -> str:
    """ ", kernels DIGEST" where the run recorded its kernels' digest (``versions()["kernels"]``); "" for a file made
    before runs recorded it."""
    return f", kernels {versions['kernels']}" if "kernels" in versions else ""


def _earlier_runs(meta: dict[str, Any]) -> str:
    """The runs whose finished experiments this one took as done (``--with``), one clause each; "" if none."""
    parts = meta.get("with") or []
    if not parts:
        return ""
    each = "; ".join(
        f"`{p['command']}` on {p['created']}, {p['machine']}, wall time {p['wall_s']:.0f} s: "
        f"{', '.join(p['experiments'])}"
        for p in parts
    )
    return f" It took the finished experiments of {len(parts)} earlier run(s) as done: {each}."


def _header_lines(meta: dict[str, Any]) -> list[str]:
    """The opening of the generated page: the variant (quick or full), the command, machine, versions and wall
    time that produced it, and the settings of its runs."""
    cfg = meta["config"]
    variant = (
        "**QUICK variant (reduced CPU smoke check: small pads, short windows, few seeds, a coarser step) — not the "
        "validation itself.**"
        if cfg["quick"]
        else "Full variant."
    )
    dtp = cfg["sample_dt"] * cfg["decimation"]
    cut = cfg.get("state_patches") or cfg["patches"]
    steps = cfg.get("stepping") or {}  # as the run described it (the code's table may have changed since)
    stepping = "; ".join(f"{k}: {text}" for k, text in steps.items()) or "not recorded"
    if cfg["quick"] and steps:  # one stepping, the growing kinds' events aside
        common = max(set(steps.values()), key=list(steps.values()).count)
        stepping = "; ".join([f"every experiment {common}", *(f"{k}: {t}" for k, t in steps.items() if t != common)])
    over = ", ".join(f"{k} = {cfg[k]}" for k in ("dt", "precision", "growth_dt") if cfg.get(k) is not None)
    if not meta.get("complete", True):
        variant += (
            " **Incomplete: the run stopped before its last batch (the results file is written after every batch); "
            "experiments not run read not run.**"
        )
    return [
        variant,
        "",
        f"Produced by `{meta['command']}` on {meta['created']}, {meta['machine']}; "
        f"Warp {meta['versions'].get('warp-lang')}, aca-warp {meta['versions'].get('aca-warp')}"
        f"{_kernels(meta['versions'])}; "
        f"wall time {meta['wall_s']:.0f} s (the experiments' runs and analyses, from their checkpoints: "
        f"{meta.get('experiments_s', 0.0):.0f} s).{_earlier_runs(meta)} Rebuilt from "
        f"`{meta.get('results', 'results.json')}` by `python3 scripts/validation.py --report RESULTS --page PAGE`.",
        "",
        f"Settings: {cfg['seeds']} seeds from {cfg['first_seed']}; {cfg['patches'] or 'the preset’s'} patches per pad; "
        f"stepping {stepping}{f' (overridden: {over})' if over else ''}; global outputs every {cfg['sample_dt']:g} s, "
        f"per-patch velocities every {dtp:g} s (Nyquist {0.5 / dtp / 1e3:.0f} kHz) over the last "
        f"{cfg['window'] * 1e3:g} ms; initial velocity perturbation {cfg['perturbation']:g} m/s; settling factor "
        f"{cfg['settle_safety']:g}; S(f) over {cfg['sync_band'][0] / 1e3:g}–{cfg['sync_band'][1] / 1e3:g} kHz; runs "
        f"from rest {cfg['paper_length'] * 1e3:g} ms with {cfg['track_windows']} track windows of "
        f"{cfg['track_window'] * 1e3:g} ms. §3.2: `va_full` at the paper's growth rate (compressed × "
        f"{0.36 / cfg['paper_length']:g} where the paper length is shorter), the compressed `va` × "
        f"{cfg['growth_speedup']:g}. §3.3: the LF {'quick ' if cfg['quick'] else ''}schedule per seed, every state "
        f"{f'cut to about {cut} patches' if cut else 'whole'}, a window of half the above.",
    ]
