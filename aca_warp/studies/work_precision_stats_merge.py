"""One result file of the statistical work-precision study from parts measured side by side.

A regime whose reference does not fit one call (ms_app3: 64 pads × 78.8 ms at 1e-8 s in fp64, ≈ 1400 s on one
H200) is measured in parts: the same regime, settings and reference over disjoint seeds (``--seeds K
--first-seed S``), e.g. one process per GPU. :func:`merge` joins the parts' result files into one, as if one run
had held every pad: per setting the per-pad values side by side (pads ordered by member, then seed, as one run
orders them), its stepping wall time the sum of the parts' (the time one device would take running the parts one
after the other), the parts' own times kept beside it. The parts must be one regime (settings besides the seeds,
reference, device model, versions) over disjoint seeds that together are consecutive; a merged file is not a part.

Each part runs the validation's plan for its own pads, so the parts' run lengths may differ (the plan is the
predicted time to saturation of its slowest pad + the window); every pad is still compared with its own reference
over the same window at the end of the same run, which is what the rule's per-seed differences need. The merged
regime keeps each part's run length in ``parts``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import without_stepping
from aca_warp.studies.work_precision_stats_rule import (
    MEASURES,
    _matrix,
    _members,
    load_results,
    measures_asked,
    reference_of,
)

SAME = ("name", "description", "kind", "measures", "reference")
"""Regime fields every part must share (besides its configuration less the seeds)."""
SAME_TOP = ("quick", "rule", "versions")
"""Top-level fields every part must share (besides the device's name)."""
ABSENT = "not run: not in this part"
"""The fault a merged setting records for a part that did not ask for it."""
SUMMED = ("wall_s", "compile_s", "steps", "rejected", "saturated")
"""Setting fields the merged row sums over the parts."""


def _only_regime(doc: dict[str, Any], path: Path) -> tuple[str, dict[str, Any]]:
    if len(doc["regimes"]) != 1:
        raise ValueError(f"{path} holds {len(doc['regimes'])} regimes; a part holds one")
    return next(iter(doc["regimes"].items()))


def _config_less_seeds(reg: dict[str, Any]) -> dict[str, Any]:
    """The regime's validation settings as a continued file compares them (:func:`without_stepping`), less the
    seeds."""
    return {k: v for k, v in without_stepping(reg["config"]).items() if k not in ("seeds", "first_seed")}


def merged_tag(tags: Sequence[str]) -> str:
    """The tag of the merged file: one tag when the parts share it; tags that differ only in a trailing device
    number joined as one, in order ("cuda1", "cuda0" → "cuda01"); else the tags joined by "_", in order."""
    uniq = sorted(set(tags))
    if len(uniq) == 1:
        return uniq[0]
    split = [m for m in (re.fullmatch(r"(.*?)(\d+)((?:_quick)?)", t) for t in uniq) if m]
    if len(split) == len(uniq) and len({(m.group(1), m.group(3)) for m in split}) == 1:
        numbers = sorted(int(m.group(2)) for m in split)
        return split[0].group(1) + "".join(map(str, numbers)) + split[0].group(3)
    return "_".join(uniq)


def _check(parts: list[tuple[Path, dict[str, Any], str, dict[str, Any]]]) -> None:
    """ValueError unless the parts are one regime over disjoint seeds on one kind of device."""
    p0, d0, n0, r0 = parts[0]
    seen: dict[tuple[str | None, int], Path] = {}
    for p, d, n, r in parts:
        if "merged_from" in d:
            raise ValueError(f"{p} is itself merged from parts: merge the parts it names")
        if n != n0:
            raise ValueError(f"{p} holds regime {n}, {p0} holds {n0}")
        if d["machine"]["device_name"] != d0["machine"]["device_name"]:
            raise ValueError(f"{p} was measured on {d['machine']['device_name']}, {p0} on "
                             f"{d0['machine']['device_name']}")  # fmt: skip
        for k in SAME_TOP:
            if d.get(k) != d0.get(k):
                raise ValueError(f"{p} and {p0} differ in {k}: {d.get(k)!r} against {d0.get(k)!r}")
        for k in SAME:
            if r.get(k) != r0.get(k):
                raise ValueError(f"{p} and {p0} differ in the regime's {k}: {r.get(k)!r} against {r0.get(k)!r}")
        if _config_less_seeds(r) != _config_less_seeds(r0):
            raise ValueError(f"{p} and {p0} were run with other settings of the regime (besides the seeds)")
        for pad in r["pads"]:
            key = (pad.get("member"), int(pad["seed"]))
            if key in seen:
                raise ValueError(f"seed {key[1]}{f' of {key[0]}' if key[0] else ''} is in both {seen[key]} and {p}")
            seen[key] = p
    seeds = sorted({k[1] for k in seen})
    if seeds != list(range(seeds[0], seeds[-1] + 1)):
        missing = sorted(set(range(seeds[0], seeds[-1] + 1)) - set(seeds))
        raise ValueError(f"the parts' seeds leave a gap (missing {', '.join(map(str, missing))}): a merged regime "
                         "holds consecutive seeds")  # fmt: skip


def _join_field(out: dict[str, Any], rows: list[dict[str, Any]], key: str) -> None:
    """``out[key]``: the parts' rows' common value of ``key``, or each row's in a list where they differ; left out
    where no row has it (rows written before the field was recorded)."""
    out.pop(key, None)
    if any(key in r for r in rows):
        vals = [r.get(key) for r in rows]
        out[key] = vals[0] if len({repr(v) for v in vals}) == 1 else vals


def _merged_row(label: str, role: str, rows: list[dict[str, Any] | None], order: list[tuple[int, int]],
                measures: Sequence[str]) -> dict[str, Any]:  # fmt: skip
    """One setting of the merged regime from its row in each part (None: the part lacks it); ``order``: (part,
    pad) of each merged pad."""
    have = [r for r in rows if r is not None]
    base = {k: v for k, v in have[0].items() if k not in (*SUMMED, "values", "fault", "complete")}
    if len(have) < len(rows) or not all(r.get("complete") and "values" in r for r in have):
        faults = [ABSENT if r is None else str(r.get("fault")) for r in rows]
        bad = [f for r, f in zip(rows, faults, strict=True) if r is None or not r.get("complete")]
        kinds = "; ".join(dict.fromkeys(bad))
        # "not run" only when no part ran it and failed: the report reads that prefix as cut by a time limit
        prefix = "not run" if all(f.startswith("not run") for f in bad) else "incomplete"
        out = {**base, "label": label, "role": role, "complete": False, "wall_s": None,
               "fault": f"{prefix}: complete in {len(rows) - len(bad)} of {len(rows)} parts ({kinds})"}  # fmt: skip
        _join_field(out, [r for r in have if r.get("steps") is not None], "kernels")  # the parts that ran it
        return out
    row: dict[str, Any] = {**base, "complete": True, "fault": None}
    for k in SUMMED:
        vals = [r.get(k) for r in have]
        row[k] = sum(vals) if all(v is not None for v in vals) else None
    row["part_wall_s"] = [r["wall_s"] for r in have]
    for k in ("dt_used", "engine", "host", "kernels"):
        _join_field(row, have, k)
    row["values"] = {m: [have[i]["values"][m][j] for i, j in order] for m in measures}
    return row


def merge(paths: Sequence[Path]) -> dict[str, Any]:
    """The result document of one regime measured in parts (``paths``: the parts' result files, each one regime
    over its own seeds). Raises ValueError when the files are not parts of one regime."""
    if len(paths) < 2:
        raise ValueError("merging needs at least two result files")
    parts = []
    for p in paths:
        d = load_results(p)
        parts.append((Path(p), d, *_only_regime(d, Path(p))))
    _check(parts)
    parts.sort(key=lambda part: min(int(x["seed"]) for x in part[3]["pads"]))
    _, d0, name, r0 = parts[0]
    members = list(dict.fromkeys(pad.get("member") for _, _, _, r in parts for pad in r["pads"]))
    keyed = sorted((members.index(pad.get("member")), int(pad["seed"]), i, j)
                   for i, (_, _, _, r) in enumerate(parts) for j, pad in enumerate(r["pads"]))  # fmt: skip
    order = [(i, j) for *_, i, j in keyed]
    pads = [parts[i][3]["pads"][j] for i, j in order]
    keys = list(dict.fromkeys((s["label"], s["role"]) for _, _, _, r in parts for s in r["settings"]))
    settings = []
    for label, role in keys:
        rows = [next((s for s in r["settings"] if (s["label"], s["role"]) == (label, role)), None)
                for _, _, _, r in parts]  # fmt: skip
        settings.append(_merged_row(label, role, rows, order, r0["measures"]))
    seeds = sorted({int(p["seed"]) for p in pads})
    reg = {k: v for k, v in r0.items() if k not in ("pads", "settings")}
    reg["config"] = {**r0["config"], "seeds": len(seeds), "first_seed": seeds[0]}
    longest = max((r for _, _, _, r in parts), key=lambda r: r["duration_s"])  # the regime's plan: its longest part's
    for k in ("duration_s", "settle_s", "window_start_s"):
        reg[k] = longest.get(k)
    reg["parts"] = [
        {"file": p.as_posix(), "device": d["machine"]["device"], "seeds": sorted({int(x["seed"]) for x in r["pads"]}),
         "pads": len(r["pads"]), "duration_s": r["duration_s"], "window_start_s": r["window_start_s"],
         "settle_s": r.get("settle_s"), "regime_wall_s": d.get("regime_wall_s")}
        for p, d, _, r in parts
    ]  # fmt: skip
    reg["pads"], reg["settings"] = pads, settings
    devices = list(dict.fromkeys(d["machine"]["device"] for _, d, _, _ in parts))
    hosts = list(dict.fromkeys(d["machine"]["host"] for _, d, _, _ in parts))
    machine = {**d0["machine"], "device": ",".join(devices), "host": hosts[0] if len(hosts) == 1 else hosts}
    walls = [d.get("regime_wall_s") for _, d, _, _ in parts]
    return {
        **{k: v for k, v in d0.items() if k not in ("tag", "machine", "commands", "regimes", "regime_wall_s")},
        "tag": merged_tag([d["tag"] for _, d, _, _ in parts]),
        "machine": machine,
        "commands": list(dict.fromkeys(c for _, d, _, _ in parts for c in d["commands"])),
        "merged_from": [p.as_posix() for p, _, _, _ in parts],
        "regimes": {name: reg},
        "regime_wall_s": sum(walls) if all(w is not None for w in walls) else None,
    }


def _signed_error(ref: np.ndarray, val: np.ndarray, sigma: float) -> float:
    """The mean of val − ref over the seeds that have both, in units of ``sigma``: signed for a scalar measure, the
    rms over components of the per-component means for a vector one (NaN without two such seeds)."""
    ref2, val2 = ref.reshape(ref.shape[0], -1), val.reshape(val.shape[0], -1)
    rows = np.isfinite(ref2).all(axis=1) & np.isfinite(val2).all(axis=1)
    if rows.sum() < 2 or not sigma > 0:
        return math.nan
    mean = (val2[rows] - ref2[rows]).mean(axis=0)
    return float(mean[0] / sigma) if mean.size == 1 else float(np.sqrt(np.mean(np.square(mean))) / sigma)


def errors_by_part(doc: dict[str, Any], measures: Sequence[str] | None = None) -> str:
    """Markdown: per measure, member and setting, its error in units of σ over all of a merged regime's pads and over
    each part's pads alone (σ: the reference's standard deviation between all the seeds, rms over components; signed
    for a scalar measure). The reference's own sampling noise enters every setting's error alike, so errors that
    share one sign within a part and change it between parts are that draw rather than a bias of the settings.
    ``measures``: default every measure of the regime. ValueError for a document that is not a merged regime."""
    if "merged_from" not in doc or len(doc.get("regimes", {})) != 1:
        raise ValueError("errors by part need a merged result file (work_precision_stats.py --merge)")
    name, reg = next(iter(doc["regimes"].items()))
    names = measures_asked(name, reg, measures)
    seeds = np.array([int(p["seed"]) for p in reg["pads"]])
    parts = [(min(p["seeds"]), max(p["seeds"])) for p in reg["parts"]]
    ref = reference_of(reg)
    rows = [s for s in reg["settings"] if s["role"] != "reference" and s.get("complete") and "values" in s]
    head = ["measure", "member", "setting", f"all {len(seeds)} seeds", *(f"seeds {a}–{b}" for a, b in parts)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for m in names:
        for member, idx in _members(reg).items():
            r = _matrix([ref["values"][m][i] for i in idx])
            r2 = r.reshape(r.shape[0], -1)
            sigma = float(np.sqrt(np.mean(np.square(np.nanstd(r2, axis=0, ddof=1)))))
            s_idx = seeds[idx]
            for s in rows:
                v = _matrix([s["values"][m][i] for i in idx])
                cells = [_signed_error(r, v, sigma)]
                cells += [_signed_error(r[(s_idx >= a) & (s_idx <= b)], v[(s_idx >= a) & (s_idx <= b)], sigma)
                          for a, b in parts]  # fmt: skip
                txt = ["–" if not math.isfinite(c) else f"{c:+.2f}" for c in cells]
                lines.append(f"| {MEASURES[m].label} | {member or '–'} | `{s['label']}` | " + " | ".join(txt) + " |")
    return f"{name}: error / σ of each setting against the reference, by part\n\n" + "\n".join(lines) + "\n"
