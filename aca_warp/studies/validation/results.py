"""The compact results behind the page, ``results.json``: every experiment's per-pad summaries (the saturation
figures and the scalar measures the rows read) and the run's facts, with the settings and the provenance (command,
machine, versions, time). The page's generated section is rendered from this file alone (:func:`render_report`),
so anyone can rebuild it on a CPU in seconds (``python3 scripts/validation.py --report RESULTS --page PAGE``) and
check every number against it; the per-frequency arrays stay in the run folder (``arrays.npz``).
"""

from __future__ import annotations

import dataclasses
import gzip
import json
from pathlib import Path
from typing import Any

from aca_warp.studies.report import clean, write_json
from aca_warp.studies.validation.base import Config

FORMAT = "aca_warp validation results 1"
SIGNIFICANT = 6  # significant digits kept of every float (the page prints at most 4)
DROPPED = ("params",)  # per-pad keys left out of the compact file (the Φ rule's parameters: in the settings)


def _round(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _round(v) for k, v in obj.items() if k not in DROPPED}
    if isinstance(obj, list):
        return [_round(v) for v in obj]
    if isinstance(obj, float):
        return float(f"{obj:.{SIGNIFICANT}g}")
    return obj


def compact(results: dict[str, dict]) -> dict[str, dict]:
    """The results as the rows and the page read them, floats to :data:`SIGNIFICANT` digits."""
    return {name: _round(clean(res)) for name, res in results.items()}


def write_results(path: Path, results: dict[str, dict], meta: dict[str, Any]) -> Path:
    """Write ``results.json``: the format, the provenance and settings (``meta``), and the compact results."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_json(path, {"format": FORMAT, "meta": clean(meta), "results": compact(results)}, indent=None)


def read_results(path: Path) -> tuple[dict[str, dict], dict[str, Any], Config]:
    """(results, meta, settings) of a ``results.json`` (or its gzip, ``.json.gz``); ValueError when it is not one."""
    try:
        doc = json.loads(gzip.decompress(path.read_bytes()) if path.suffix == ".gz" else path.read_text())
    except (OSError, ValueError, EOFError) as e:  # EOFError: a truncated gzip
        raise ValueError(f"{path}: not a readable results file ({type(e).__name__}: {e})") from None
    got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
    if got != FORMAT:
        raise ValueError(f"{path}: not a validation results file (format {got!r}, want {FORMAT!r})")
    meta, results = doc.get("meta"), doc.get("results")
    if not (isinstance(meta, dict) and isinstance(meta.get("config"), dict) and isinstance(results, dict)):
        raise ValueError(f"{path}: not a complete validation results file (its meta, settings or results missing)")
    fields = {f.name for f in dataclasses.fields(Config)}
    cfg = {k: tuple(v) if isinstance(v, list) else v for k, v in meta["config"].items() if k in fields}
    return results, meta, Config(**cfg)


def evaluate(results: dict[str, dict], cfg: Config) -> tuple[list[dict], list[dict | None], list[dict]]:
    """The rows, each beside from rest at the paper's length, and the causes of the open ones."""
    from aca_warp.studies.validation import causes
    from aca_warp.studies.validation.base import evaluate_rows

    rows = evaluate_rows(results, cfg)
    return rows, causes.beside_rest(results, cfg), causes.evaluate_causes(results, cfg, rows)


def render_report(path: Path) -> tuple[list[str], list[dict], dict[str, Any]]:
    """The page's generated section from ``results.json`` at ``path`` (lines), the rows, and the meta."""
    from aca_warp.studies.validation.base import evaluate_rows
    from aca_warp.studies.validation.hf_sync import relative_s
    from aca_warp.studies.validation.page import relative_counts, render, strict_counts
    from aca_warp.studies.validation.verdicts import strict_direction

    results, meta, cfg = read_results(path)
    rows, rest, causes = evaluate(results, cfg)
    readings = []
    for reading, counts in ((strict_direction, strict_counts), (relative_s, relative_counts)):
        with reading():
            readings.append(counts(rows, evaluate_rows(results, cfg)))
    return render(results, rows, {**meta, "results": path.name}, causes, rest, readings), rows, meta
