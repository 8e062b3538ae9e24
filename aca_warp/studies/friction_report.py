"""Markdown tables of the friction-step study's result JSONs (:mod:`aca_warp.studies.friction_study`), for
docs/friction_step.md: ``python3 scripts/friction_schemes.py --report --out OUT`` prints the tables of one result
folder; with ``--page docs/friction_step.md`` the tables of OUT's sub-folders :data:`FOLDERS` replace the page's
generated section."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.friction_schemes import METHODS
from aca_warp.studies.report import generated_markers, md_table, replace_generated

STAT_HEAD = ["μ mean", "μ std", "Σ|u̇|", "Σu̇ peak (pads)", "Σu̇ peak (ens.)", "μ spec.", "Σu̇ spec.",
             "patch spec.", "static share", "mean ΔS"]  # fmt: skip


def pct(x: Any, digits: int = 2) -> str:
    """A relative error as a signed percentage ("–" for None)."""
    return "–" if x is None else f"{100.0 * x:+.{digits}f} %"


def num(x: Any, spec: str = ".3f") -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def stat_cells(e: dict[str, Any]) -> list[str]:
    """The statistics errors of :func:`~aca_warp.studies.friction_stats.compare` as table cells."""
    if not e.get("finite", False):
        return ["not finite"] * len(STAT_HEAD)
    return [pct(e["mu_mean"]), pct(e["mu_std"], 1), pct(e["abs_velocity_mean"]), pct(e["velocity_peak_hz"]),
            pct(e["ensemble_velocity_peak_hz"]), num(e["mu_bands"]), num(e["velocity_bands"]),
            num(e.get("patch_bands")), pct(e.get("stick_share"), 1), num(e.get("sync"))]  # fmt: skip


def single(d: dict[str, Any]) -> list[str]:
    """Stability functions, hold test, isolated patch, held case."""
    hg = [float(z) for z in d["R"][METHODS[0]]]
    out = ["**Stability functions** R(−hγ) of the sub-steps (a slip deviation is multiplied by R per step):", ""]
    out += md_table(["sub-step", *(f"hγ = {z:g}" for z in hg)],
                    [[m, *(f"{d['R'][m][str(z)]:+.3g}" for z in hg)] for m in d["R"]])  # fmt: skip
    out += ["", "**Hold test** (slip after steps 1, 2, 3 and 6 over the static slip s*; friction evaluations per "
            "step):", ""]  # fmt: skip
    rows = []
    for r in d["hold"]:
        q = [x / r["static_slip"] for x in r["slips"]]
        rows.append(
            [r["method"], f"{r['hgamma']:g}", *(f"{q[k]:.3f}" for k in (0, 1, 2, 5)), f"{r['evals_per_step']:.1f}"]
        )
    out += md_table(["sub-step", "hγ", "s₁/s*", "s₂/s*", "s₃/s*", "s₆/s*", "evals/step"], rows)
    c, ref = d["cycle"], d["cycle"]["reference"]
    out += ["", f"**Isolated patch at {c['speed']:g} m/s** against Radau at rtol 1e-11 (period "
            f"{ref['period'] * 1e6:.3f} µs, amplitude {ref['amplitude'] * 1e9:.1f} nm, mean f {ref['mu_mean']:.4f}, "
            f"static share {ref['stick_share']:.3f}):", ""]  # fmt: skip
    out += md_table(["scheme", "h [s]", "hγ", "period", "amplitude", "Δ mean f", "evals/step"],
                    [[r["scheme"], f"{r['h']:g}", f"{r['hgamma']:.1f}", pct(r["period"]), pct(r["amplitude"]),
                      f"{r['mu_mean']:+.2e}", f"{r['evals_per_step']:.1f}"] for r in c["rows"]])  # fmt: skip
    rows = d["held"]["rows"]
    steps = sorted({r["h"] for r in rows}, reverse=True)
    gamma = rows[0]["hgamma"] / rows[0]["h"]
    out += ["", "**Held case** (40 patches, 20 N, M = 100: every patch holds to the disc; mean μ over 20 µs):", ""]
    out += md_table(["scheme", *(f"h = {h:g} s (hγ = {h * gamma:.1f})" for h in steps)],
                    [[name, *(next((f"{r['mu_mean']:.3f}" for r in rows if r["scheme"] == name and r["h"] == h), "–")
                              for h in steps)] for name in dict.fromkeys(r["scheme"] for r in rows)])  # fmt: skip
    return out


def fixed(d: dict[str, Any]) -> list[str]:
    """Fixed-step runs against the reference, with the twin floor and the spread between the seeds."""
    st, sp = d["settings"], d["seed_spread"]
    speed = "the preset's speed" if st.get("speed") is None else f"{st['speed']:g} m/s at the mean radius"
    out = [f"**Fixed steps**, {st['seeds']} × {st['patches']}-patch hf1 sectors at {speed}, "
           f"{st['duration'] * 1e3:g} ms, statistics of the last {st['window'] * 1e3:g} ms: ensemble errors against "
           f"strang at {st['ref_dt']:g} s (spectra: rms of log10 of the band ratio):", ""]  # fmt: skip
    rows = [["twin (another start, same pads)", f"{st['ref_dt']:g}", "", "", *stat_cells(d["floor"])]]
    for r in sorted(d["rows"], key=lambda r: (-r["dt"], r["scheme"])):
        rows.append([r["scheme"], f"{r['dt']:g}", f"{r['steps']:d}", f"{r['evals_per_step']:.2f}", *stat_cells(r)])
    out += md_table(["scheme", "h [s]", "steps", "evals/step", *STAT_HEAD], rows)
    out += ["", "Spread between the seeds (relative standard deviation; 95 % half-width of the ensemble mean): "
            + ", ".join(f"{k} {sp[k]:.2%} ({sp[k + '_ci95']:.2%})" for k in
                        ("mu_mean", "mu_std", "abs_velocity_mean", "velocity_peak_hz")) + "."]  # fmt: skip
    return out


def stability(d: dict[str, Any]) -> list[str]:
    """Runs at 0.95 × the spring bound."""
    out = ["**At the spring bound** (0.95 × 2/ω_max, ω_max the exact largest network frequency; 30 ms, last 10 ms):",
           ""]  # fmt: skip
    out += md_table(["pads", "scheme", "h [s]", "hγ max", "bounded", "μ mean", "μ std"],
                    [[f"{r['what']} ({r['patches']} patches)", r["scheme"], f"{r['h']:.3g}", f"{r['hgamma_max']:.0f}",
                      "yes" if r["finite"] else "no", "–" if r["mu_mean"] is None else f"{np.mean(r['mu_mean']):.4f}",
                      "–" if r["mu_std"] is None else f"{np.mean(r['mu_std']):.4f}"] for r in d["rows"]])  # fmt: skip
    return out


def controlled(d: dict[str, Any]) -> list[str]:
    """The composite's settings: work and statistics errors."""
    out = ["**Error-controlled composite** on the same sectors (per pad; errors as above; × = strang at 1e-8 s over "
           "this setting):", ""]  # fmt: skip
    head = ["setting", "steps/pad", "rejected", "E trials", "I steps", "mean I step [s]", "gathers/pad", "× steps",
            "× gathers", *STAT_HEAD]  # fmt: skip
    rows = [[r["job"], f"{r['steps_per_pad']:.0f}", f"{r['rejected_per_pad']:.0f}", f"{r['accepted_E']:.0f}",
             f"{r['accepted_I']:.0f}", f"{r['mean_step_I']:.3g}", f"{r['gathers_per_pad']:.0f}",
             f"{r['strang_steps'] / r['steps_per_pad']:.1f}", f"{r['strang_steps'] / r['gathers_per_pad']:.1f}",
             *stat_cells(r)] for r in d["rows"]]  # fmt: skip
    return out + md_table(head, rows)


def sliding(d: dict[str, Any]) -> list[str]:
    """hf1 from rest: μ errors and evaluations."""
    out = [f"**Sliding**: hf1 ({d['patches']} patches) from its start over {d['duration'] * 1e3:g} ms, max |μ − μ_ref| "
           "against DOP853 at rtol 1e-11:", ""]  # fmt: skip
    return out + md_table(
        ["solver", "right-hand-side evaluations", "μ error"],
        [[r["solver"], f"{r['evaluations']}", f"{r['mu_error']:.2g}"] for r in d["rows"]],
    )


OUT_ARG = re.compile(r"--out \S+")  # the result folder, shown as OUT
PARTS = {"single": single, "fixed": fixed, "stability": stability, "controlled": controlled, "sliding": sliding}


def report(folder: Path) -> list[str]:
    """Markdown tables of the result JSONs in ``folder`` (the parts that exist), each with the command and machine
    that made it."""
    out: list[str] = []
    for name, table in PARTS.items():
        path = folder / f"{name}.json"
        if path.exists():
            d = json.loads(path.read_text())
            command = OUT_ARG.sub("--out OUT", d["command"])
            out += [*table(d), "", f"(`{command}`; {d['machine']['host']}, shared with other jobs)", ""]
    return out


# sub-folders of a result tree, in the page's order, with their section titles
FOLDERS = {
    "study": "One patch, the held case, the spring bound, sliding",
    "hf1": "hf1 sectors, saturated",
    "ss": "Stick-slip sectors (0.5 m/s)",
}
MARKERS = generated_markers("scripts/friction_schemes.py --report --page")


def write_page(root: Path, page: Path) -> None:
    """Replace the generated section of ``page`` with the tables of ``root``'s sub-folders."""
    body: list[str] = []
    for name, title in FOLDERS.items():
        if (root / name).is_dir():
            body += ["", f"### {title}", "", *report(root / name)]
    replace_generated(page, body, MARKERS, "Friction sub-step")
