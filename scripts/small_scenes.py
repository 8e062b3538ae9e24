"""Small HF and LF scene files as TOML text, for the fault scripts (``fault_injection.py``, ``corrupt_files.py``) and
the tests: runs of a few seconds on a CPU that still record per-patch histories, checkpoints and snapshots.

    from small_scenes import small_scene_toml, small_lf_scene_toml   # scripts/ on sys.path, as when a script runs
"""

from __future__ import annotations

import json
from typing import Any


def toml_text(doc: dict[str, Any]) -> str:
    """``doc`` ({table: {key: value}}, or {table: [{key: value}, ...]} for an array of tables) as TOML text; values
    are numbers, booleans, strings or lists of them."""
    out = []
    for table, body in doc.items():
        for kv, head in ((b, f"[[{table}]]") for b in body) if isinstance(body, list) else ((body, f"[{table}]"),):
            out.append(head + "\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in kv.items()))
    return "".join(out)


def small_scene_toml(
    name: str = "small",
    *,
    count: int = 60,
    duration: float = 2.0e-6,
    sample_dt: float = 1.0e-7,
    patches: tuple[str, ...] = (),
    perturbation: float | None = None,
    disc: bool = True,
    tables: dict[str, dict] | None = None,
) -> str:
    """A small HF scene file: ``count`` HF1-size patches (seed 4, 3 µm), 20 N, samples every ``sample_dt`` [s] for
    ``duration`` [s]; ``patches``: the per-patch histories recorded; ``perturbation``: a seeded initial velocity
    perturbation [m/s] (seed 2); ``disc``: the disc at 10 m/s stated; ``tables`` ({table: {key: value}}): keys
    replaced or added."""
    doc: dict[str, dict] = {"scene": {"name": name}, "load": {"normal_force": 20.0}}
    if disc:
        doc["disc"] = {"sliding_speed": 10.0}
    doc["patches"] = {"count": count, "area_min": 2.0e-8, "area_max": 8.0e-8, "height": 3.0e-6, "seed": 4}
    if perturbation is not None:
        doc["initial"] = {"perturbation": perturbation, "seed": 2}
    doc["record"] = {"sample_dt": sample_dt, **({"patches": list(patches)} if patches else {})}
    doc["run"] = {"duration": duration}
    for t, kv in (tables or {}).items():
        doc.setdefault(t, {}).update(kv)
    return toml_text(doc)


def three_applications(first: float) -> list[dict[str, Any]]:
    """An LF schedule: 300 N for ``first`` [s] (0.05 s ramp), a 0.1 s pause, 100 N for 0.4 s."""
    return [
        {"kind": "application", "duration": first, "normal_force": 300.0, "ramp": 0.05},
        {"kind": "pause", "duration": 0.1},
        {"kind": "application", "duration": 0.4, "normal_force": 100.0},
    ]


def small_lf_scene_toml(
    name: str,
    schedule: list[dict[str, Any]],
    *,
    lf: dict[str, Any] | None = None,
    snapshots: dict[str, Any] | None = None,
) -> str:
    """A small LF scene file: a 10 mm × 8° pad (r = 0.100 … 0.110 m) with 60 seeded HF1-size patches (seed 3,
    3 µm) and room for 512 cells (~150 cells: births, deaths and merges within a few dozen steps), run through
    ``schedule`` (the ``[[schedule]]`` segments, e.g. :func:`three_applications`); ``lf``: constants of ``[lf]``
    besides the capacity; ``snapshots``: the ``[snapshots]`` table (none without)."""
    doc: dict[str, Any] = {
        "scene": {"name": name},
        "pad": {"r_inner": 0.100, "r_outer": 0.110, "span_deg": 8.0},
        "patches": {"count": 60, "area_min": 2e-8, "area_max": 8e-8, "height": 3e-6, "seed": 3},
        "lf": {"capacity": 512, **(lf or {})},
    }
    if snapshots is not None:
        doc["snapshots"] = snapshots
    doc["schedule"] = schedule
    return toml_text(doc)
