#!/usr/bin/env python3
"""The table "Targets at a glance" of docs/status.md and its figure, read from the committed benchmark data.

Each speed, throughput or accuracy target is one entry of TARGETS: the target in words, its value and direction, the
committed files (under docs/) that hold the measured value, and the function that reads it there. The script
writes the table between the lines "<!-- TARGETS scripts/targets_table.py -->" and "<!-- END TARGETS -->" of
docs/status.md (placing them instead of the table under "## Targets at a glance" where they are missing), the
figure docs/figures/targets/targets.png (each target's measured value over its target value, inverted for a
"≥" target, so that below 1 is met) and the values behind both, docs/figures/targets/targets.json::

    python3 scripts/targets_table.py            # writes the table, the figure and the JSON
    python3 scripts/targets_table.py --check    # writes nothing; exit 1 with the differences where they are stale

A value that no committed file holds is shown as "not in committed data" (an entry without files). After a new
measurement, point the entry at its file and run the script again.
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"
STATUS = DOCS / "status.md"
FIGURES = DOCS / "figures" / "targets"
BEGIN, END = "<!-- TARGETS scripts/targets_table.py -->", "<!-- END TARGETS -->"
HEADING = "## Targets at a glance"
NOT_IN_DATA = "not in committed data"
MET, MISSED = "#4c9a5b", "#c8553d"  # bar colours


@dataclass(frozen=True)
class Measured:
    """What an entry's files hold: one value per run of its measurement (a range), the machine, and a
    short qualifier for the table."""

    values: tuple[float, ...]
    machine: str
    note: str = ""


@dataclass(frozen=True)
class Target:
    """One speed or throughput target and where its measured value is read."""

    name: str  # short, for the figure
    words: str  # the target in words, with its unit
    goal: float  # the target value
    direction: str  # "≤" or "≥": the measured value must be at most / at least the goal
    unit: str  # of the measured value ("×": a ratio)
    files: tuple[str, ...]  # relative to docs/; none: the value is not in committed data
    read: Callable[[list[Path]], Measured] | None
    page: str  # the Markdown link to the page with the history


# ------------------------------------------------------------------------------------------------ reading files


def load(path: Path) -> Any:
    return json.loads(path.read_text())


def one(items: list[dict[str, Any]], **match: Any) -> dict[str, Any]:
    """The single item of ``items`` whose keys have the values ``match``; ValueError unless exactly one has."""
    found = [it for it in items if all(it.get(k) == v for k, v in match.items())]
    if len(found) != 1:
        raise ValueError(f"{len(found)} items match {match}, want 1")
    return found[0]


def processor(text: str) -> str:
    """A processor's name as the files record it, without trademarks and remarks: "Intel Xeon, 2 cores"."""
    text = re.sub(r"\((R|TM)\)| Processor", "", text)
    return re.sub(r"\s*\(.*\)", "", text).strip()


def bench_machine(machine: dict[str, str]) -> str:
    """The GPU of a benchmark's ``machine`` record, or its CPU where it ran on the CPU."""
    return machine["device_name"] if machine["device"].startswith("cuda") else processor(machine["host"])


def cpu_device(name: str) -> str:
    """The processor in a CPU device's name, "CPU (Intel(R) Xeon(R) Processor, 2 cores; ...)": "Intel Xeon, 2 cores"."""
    inside = re.match(r"CPU \((.*?);", name)
    return processor(inside[1]) if inside else processor(name)


def machines(names: list[str]) -> str:
    """The distinct machines of an entry's files, in their order."""
    return "; ".join(dict.fromkeys(names))


def per_machine(values: list[float], names: list[str], fmt: Callable[[float], str]) -> str:
    """The values of an entry's files by machine, where it has more than one: "H100 80GB HBM3 1.72–1.78; H200
    1.99–2.02" (the range over each machine's runs, the name without "NVIDIA "), else nothing."""
    if len(set(names)) < 2:
        return ""
    groups: dict[str, list[float]] = {}
    for v, n in zip(values, names, strict=True):
        groups.setdefault(n, []).append(v)
    parts = []
    for n, vs in groups.items():
        lo, hi = fmt(min(vs)), fmt(max(vs))
        parts.append(f"{n.removeprefix('NVIDIA ')} {lo if lo == hi else f'{lo}–{hi}'}")
    return "; ".join(parts)


def validation_stepping(paths: list[Path]) -> Measured:
    """The stepping time [s] of every batch of each validation results file (one value per file, each a run of the
    whole validation), summed over the calls that made that file."""
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation.cost import measured
    from aca_warp.studies.validation.results import read_results

    values, names, counts = [], [], set()
    for path in paths:
        results, meta, _ = read_results(path)
        calls = [meta, *meta.get("with", [])]
        values.append(sum(r["wall_s"] for r in measured(results, meta.get("with"))))
        names += [c["machine"] for c in calls]
        counts.add(len(calls))
    n = counts.pop() if len(counts) == 1 else 0  # calls per file, where every file has as many
    each = f"{n} call{'s' * (n > 1)}" if n else "calls"
    return Measured(tuple(values), machines(names), each if len(paths) == 1 else f"{each} each")


def bench_wall(paths: list[Path]) -> Measured:
    """The wall time [s] of the one run of each ``aca-warp bench`` file."""
    docs = [load(p) for p in paths]
    return Measured(
        tuple(one(d["results"])["wall_s"] for d in docs), machines([bench_machine(d["machine"]) for d in docs])
    )


def command_wall(paths: list[Path]) -> Measured:
    """The wall time [s] of the one command timed by ``scripts/time_varying_area.py``."""
    doc = load(paths[0])
    return Measured((one(doc["rows"])["wall_s"],), processor(doc["machine"].split(";")[0]))


def record_stepping(paths: list[Path]) -> Measured:
    """The stepping time [s] of each record's one or more calls (``scripts/varying_area.py``'s ``meta``), as a
    benchmark folder keeps them."""
    docs = [load(p)["meta"] for p in paths]
    names = [bench_machine(c["machine"]) for d in docs for c in d["calls"]]
    return Measured(tuple(d["wall_s"] for d in docs), machines(names))


def md_rows(path: Path) -> list[dict[str, str]]:
    """The rows of the one Markdown table of ``path``, as {column: cell}."""
    lines = [ln.strip().strip("|").split("|") for ln in path.read_text().splitlines() if ln.startswith("|")]
    head = [c.strip() for c in lines[0]]
    return [dict(zip(head, (c.strip() for c in ln), strict=True)) for ln in lines[2:]]


def profile_md_machine(path: Path) -> str:
    """The device a Markdown profile of ``scripts/profile_onchip.py`` ran on, from its first line ("…; NVIDIA H100 80GB
    HBM3, Warp 1.19.0 (…)"); ValueError where the line does not name one."""
    found = re.search(r"; ([^;]+?), Warp \d", path.read_text().splitlines()[0])
    if found is None:
        raise ValueError(f"{path}: its first line names no device")
    return found[1]


def profile_us_per_step(paths: list[Path]) -> Measured:
    """µs per step of one hf1 pad in fp32 on a cluster of 8 blocks (the default), one value per profile run
    (``scripts/profile_onchip.py``: JSON, or its Markdown table where no JSON was kept)."""
    case = {"case": "full, cluster 8", "precision": "fp32"}
    values: list[float] = []
    names: list[str] = []
    for p in paths:
        if p.suffix == ".json":
            doc = load(p)
            values.append(one(doc["rows"], **case)["us_per_step"])
            names.append(doc["machine"]["device_name"])
        else:
            values.append(float(one(md_rows(p), **case)["µs/step"]))
            names.append(profile_md_machine(p))
    split = per_machine(values, names, lambda v: f"{v:.2f}")
    return Measured(tuple(values), machines(names), "fp32, cluster of 8 blocks" + (f"; {split}" if split else ""))


def onchip_1024_pads(paths: list[Path]) -> Measured:
    """Patch-steps/s of 1024 hf1 pads, on chip in fp32, one value per file (``aca-warp bench --engine general
    onchip``)."""
    docs = [load(p) for p in paths]
    values = [one(d["results"], engine="onchip", precision="fp32", pads=1024)["patch_steps_per_s"] for d in docs]
    names = [bench_machine(d["machine"]) for d in docs]
    split = per_machine(values, names, lambda v: f"{v:.2e}".replace("e+", "e"))
    return Measured(tuple(values), machines(names), "fp32" + (f"; {split}" if split else ""))


def tts_try(doc: dict[str, Any], scene: str, solver: str, where: str = "") -> dict[str, Any]:
    """The try of a time-to-solution row (one pad) that reached the target, else its last one (its finest)."""
    rows = [r for r in doc["rows"] if (r["scene"], r["solver"], r["pads"]) == (scene, solver, 1)]
    ran = [t for t in one(rows, **({"where": where} if where else {}))["tries"] if "error" in t]
    return next((t for t in ran if t["reached"]), ran[-1])


def tts_ratio(
    scene: str, ours: tuple[str, str], other: tuple[str, str], speedup: bool
) -> Callable[[list[Path]], Measured]:
    """A reader of one time-to-solution run per file: our solver's time over the other's (their speed-up of ours
    where ``speedup``); ``ours`` and ``other`` are (solver, where) as the rows name them."""

    def read(paths: list[Path]) -> Measured:
        values: list[float] = []
        names: list[str] = []
        notes: list[str] = []
        for p in paths:
            doc = load(p)
            a, b = tts_try(doc, scene, *ours), tts_try(doc, scene, *other)
            values.append(b["time_s"] / a["time_s"] if speedup else a["time_s"] / b["time_s"])
            names.append(bench_machine(doc["machine"]))
            notes.append(f"{num(a['time_s'])} s against {num(b['time_s'])} s")
            if not a["reached"]:
                notes[-1] += f"; ours at {num(a['error'], 2)}, short of the error"
            if not b["reached"]:
                bound = "at least" if speedup else "at most"
                stays = f"the other stays at {num(b['error'], 2)} at its finest setting"
                notes[-1] += f"; {stays}: {bound} this ratio at equal error"
        if len(paths) > 2:  # a readable cell: the runs' times for one or two runs only
            notes = []
        elif len(paths) == 2:  # each run's times, named by its machine (and numbered where both ran on one)
            same = names[0] == names[1]
            notes = [
                f"{n.removeprefix('NVIDIA ')}{f' run {k + 1}' if same else ''}: ({t})"
                for k, (n, t) in enumerate(zip(names, notes, strict=True))
            ]
        return Measured(tuple(values), machines(names), "; ".join(notes))

    return read


def tts_default_error(paths: list[Path]) -> Measured:
    """The μ error of ``strang`` at its defaults over each time-to-solution run (hf1, one pad)."""
    docs = [load(p) for p in paths]
    tries = [tts_try(doc, "hf1", "ours: strang (its defaults)") for doc in docs]
    steps = sorted({f"dt {t['setting']:g} s".replace("e-0", "e-") for t in tries})
    return Measured(tuple(t["error"] for t in tries), machines([processor(d["machine"]["host"]) for d in docs]),
                    ", ".join(steps))  # fmt: skip


def sector_speedup(paths: list[Path]) -> Measured:
    """The 150-patch sector, one call per file: ``strang`` at 1e-8 s on the general engine (the default engine
    when the target was set) over the default, on chip in fp32, in the same call; beside it, the default against
    ``strang`` at 1e-8 s on its own engine."""
    docs = [load(p) for p in paths]
    wall = [{r["run"]: r["wall_s"] for r in d["runs"]} for d in docs]
    default = [w["strang@fp32"] for w in wall]
    reference = [w["strang:1e-8/general"] for w in wall]
    on_chip = [w["strang:1e-8"] / w["strang@fp32"] for w in wall]
    note = f"{span(default)} s against {span(reference)} s on the general engine in the same call"
    note += f"; {span(on_chip)}× against `strang` at 1e-8 s on chip"
    ratios = tuple(r / d for r, d in zip(reference, default, strict=True))
    return Measured(ratios, processor(docs[0]["setup"]["machine"]), note)


def cpu_patch_steps(paths: list[Path]) -> Measured:
    """Patch-steps/s of one hf1 pad, ``strang`` in fp64, on one CPU core (``scripts/bench_hf.py``), one value per
    file (a run of the benchmark)."""
    docs = [load(p) for p in paths]
    rows = [one(d["results"], integrator="strang", precision="fp64", pads=1) for d in docs]
    names = machines([f"{bench_machine(d['machine'])}, one thread used" for d in docs])
    return Measured(tuple(r["patch_steps_per_s"] for r in rows), names, "fp64")


def sweep_runs(doc: dict[str, Any], units: int) -> list[dict[str, Any]]:
    """The timed runs of the default path (overlapped, this code) on ``units`` GPUs, in their order."""
    runs = [r for r in doc["runs"] if (r["code"], r["mode"], r["units"]) == ("new", "overlapped", units)]
    return sorted(runs, key=lambda r: r["run"])


def sweep_machine(doc: dict[str, Any], units: int) -> str:
    """The GPUs and the host of a sweep benchmark: "2 × NVIDIA H200, Intel Xeon, 32 cores"."""
    gpus = doc["machine"]["device_name"] if units == 1 else f"{units} × {doc['machine']['device_name']}"
    return f"{gpus}, {processor(doc['machine']['host'])}"


def sweep_wall_fraction(paths: list[Path]) -> Measured:
    """One GPU's wall rate over its in-shard rate [%], per timed run (``scripts/bench_sweep.py``)."""
    doc = load(paths[0])
    return Measured(tuple(100 * r["wall_over_in_shard"] for r in sweep_runs(doc, 1)), sweep_machine(doc, 1))


def sweep_two_over_one(paths: list[Path]) -> Measured:
    """Two GPUs' speed-up over one, run by run (the timed sweep on the warm cluster)."""
    doc = load(paths[0])
    pairs = list(zip(sweep_runs(doc, 1), sweep_runs(doc, 2), strict=True))
    command = [a["command_wall_s"] / b["command_wall_s"] for a, b in pairs if a.get("command_wall_s")]
    note = f"the whole command, cluster start included, {span(command)}×" if command else ""
    return Measured(tuple(a["wall_s"] / b["wall_s"] for a, b in pairs), sweep_machine(doc, 2), note)


def lf_steps(paths: list[Path]) -> Measured:
    """LF steps/s of the ``multiscale`` schedule, one value per ``scripts/bench_lf.py`` file."""
    docs = [load(p) for p in paths]
    names = [d["device_name"] if d["device"].startswith("cuda") else cpu_device(d["device_name"]) for d in docs]
    return Measured(tuple(d["steps_per_s"] for d in docs), machines(names))


# ------------------------------------------------------------------------------------------------ the targets

TTS, SWEEP = "figures/time_to_solution/", "benchmarks/sweep/"
# the time-to-solution runs since strang's default step follows the scene: the README main job's rows read them
MAIN_JOB_RUNS = (TTS + "tts_cpu_epyc_three_steps_1.json", TTS + "tts_cpu_epyc_three_steps_2.json")
DEFAULT_MEAN = "benchmarks/default_mean_h200/"  # the default of 2.5e-7 s with the crossings averaged, 2026-12-02
THREE_STEPS = "benchmarks/three_steps_h200/ab/"  # hf1's default of three steps a 1 µs sample (A/B runs)
PROFILES = "benchmarks/onchip_h100/halo_exchange/final_profile_"
PROFILES_H200 = "benchmarks/onchip_h200/one_pad_profile/profile_"  # the code of 2026-12-01
GPU_TTS = (TTS + "tts_h100.json", TTS + "tts_h200.json")  # the GPU's time-to-solution runs, H100 and H200
ADAPTIVE_GPU = ("ours: adaptive (DP5)", "cuda:0, onchip engine")
ADAPTIVE_CPU = ("ours: adaptive (DP5)", "cpu, onchip engine")
STRANG_GPU = ("ours: strang", "cuda:0, onchip engine")
DOP853 = ("SciPy DOP853", "")
LINK = {
    name: f"[{name}]({name})"
    for name in (
        "validation.md",
        "time_to_solution.md",
        "onchip.md",
        "friction_step.md",
        "benchmarks.md",
        "sweeps.md",
        "lf_model.md",
    )
}

TARGETS: tuple[Target, ...] = (
    Target("full validation", "full validation ≤ 2 min (120 s) of stepping", 120.0, "≤", "s",
           ("validation/rerun_twice/results.json", "validation/rerun_twice/results_b.json.gz"), validation_stepping,
           LINK["validation.md"]),
    Target("64 pads × 30 ms", "64 saturated hf1 pads × 30 ms at the default settings ≤ 0.5 s", 0.5, "≤", "s",
           tuple(f"{THREE_STEPS}default_new_{r}.json" for r in "abcd"), bench_wall,
           LINK["time_to_solution.md"]),
    Target("moonshot 64 pads × 0.36 s", "moonshot: 64 hf1 pads × 0.36 s at the default settings ≤ 6 s", 6.0, "≤",
           "s", (THREE_STEPS + "default_360ms_new_moon.json",), bench_wall, LINK["time_to_solution.md"]),
    Target("varying-area record", "varying-area record (0.36 s) at the defaults ≤ 20 s (set for one H100)", 20.0,
           "≤", "s", (DEFAULT_MEAN + "varying_area/time_varying_area.json",), command_wall,
           LINK["time_to_solution.md"]),
    Target("varying-area record, on chip, 1e-8 s",
           "varying-area record (0.36 s) on the on-chip engine at 1e-8 s ≤ 60 s (the record at the defaults, above, "
           "runs on chip too)", 60.0, "≤", "s",
           tuple(f"benchmarks/varying_area_onchip_h200/record_{c}.json" for c in "ab"), record_stepping,
           LINK["onchip.md"]),
    Target("one pad per step", "one hf1 pad ≤ 1.5 µs per step", 1.5, "≤", "µs per step",
           tuple(PROFILES + s for s in ("r0.md", "r1.json", "r2.json", "r3.json"))
           + tuple(f"{PROFILES_H200}r{r}.json" for r in range(5)), profile_us_per_step,
           LINK["onchip.md"]),
    Target("1024 pads", "1024 hf1 pads ≥ 1e11 patch-steps/s", 1e11, "≥", "patch-steps/s",
           ("benchmarks/bench_h100_engines.json", "benchmarks/bench_h200_engines.json"), onchip_1024_pads,
           LINK["onchip.md"]),
    Target("μ ≤ 1e-7: over strang", "one hf1 pad to μ error ≤ 1e-7: `adaptive` ≥ 10× faster than on-chip `strang`",
           10.0, "≥", "×", GPU_TTS, tts_ratio("hf1", ADAPTIVE_GPU, STRANG_GPU, speedup=True),
           LINK["time_to_solution.md"]),
    Target("μ ≤ 1e-7: over diffrax", "one hf1 pad to μ error ≤ 1e-7: `adaptive` ≥ 5× faster than diffrax Dopri8",
           5.0, "≥", "×", GPU_TTS,
           tts_ratio("hf1", ADAPTIVE_GPU, ("diffrax Dopri8 + PID", ""), speedup=True), LINK["time_to_solution.md"]),
    Target("CPU against DOP853", "CPU, hf1 1 ms to μ error ≤ 1e-7: `adaptive`'s time / SciPy DOP853's ≤ 1", 1.0,
           "≤", "×",
           tuple(TTS + f for f in ("tts_cpu.json", "tts_cpu_xeon.json", "tts_cpu_xeon_fp32.json",
                                   "tts_cpu_xeon_default_step.json", "tts_cpu_epyc_default_step.json",
                                   "tts_cpu_epyc_default_mean_1.json", "tts_cpu_epyc_default_mean_2.json",
                                   "tts_cpu_xeon_step_sample_1.json", "tts_cpu_xeon_step_sample_2.json",
                                   "tts_cpu_epyc_three_steps_1.json", "tts_cpu_epyc_three_steps_2.json")),
           tts_ratio("hf1", ADAPTIVE_CPU, DOP853, speedup=False), LINK["time_to_solution.md"]),
    Target("stick-slip against strang", "stick-slip to μ error ≤ 1e-7: `adaptive`'s time / on-chip `strang`'s ≤ 1",
           1.0, "≤", "×", GPU_TTS, tts_ratio("stickslip", ADAPTIVE_GPU, STRANG_GPU, speedup=False),
           LINK["time_to_solution.md"]),
    Target("main job: μ error", "README main job (CPU, hf1 1 ms, defaults): μ error ≤ 1e-7", 1e-7, "≤", "",
           MAIN_JOB_RUNS, tts_default_error, LINK["time_to_solution.md"]),
    Target("main job: against DOP853", "README main job (CPU, hf1 1 ms, defaults): time / SciPy DOP853's ≤ 1", 1.0,
           "≤", "×", MAIN_JOB_RUNS,
           tts_ratio("hf1", ("ours: strang (its defaults)", ""), DOP853, speedup=False), LINK["time_to_solution.md"]),
    Target("150-patch CPU sector", "150-patch CPU sector at the defaults ≥ 5× faster than `strang` at 1e-8 s", 5.0,
           "≥", "×",
           ("figures/friction_step/sector_step_sample_cpu_1.json",
            "figures/friction_step/sector_step_sample_cpu_2.json"),
           sector_speedup, LINK["friction_step.md"]),
    Target("one CPU core", "one CPU core, hf1, `strang` at 1e-8 s in fp64 on the general engine (the benchmark of "
           "this target) ≥ 2e7 patch-steps/s", 2e7, "≥", "patch-steps/s",
           ("benchmarks/hf_cpu.json", "benchmarks/hf_cpu_2026-12-02.json"), cpu_patch_steps, LINK["benchmarks.md"]),
    Target("sweep, one GPU, 1e-8 s", "2048-pad sweep at 1e-8 s, one GPU: wall rate ≥ 90 % of the in-shard rate",
           90.0, "≥", "%", (SWEEP + "worker_malloc_h200/bench_1e-8.json",), sweep_wall_fraction,
           LINK["sweeps.md"]),
    Target("sweep, one GPU, default step",
           "2048-pad product sweep at its default step (5e-8 s), one GPU: wall rate ≥ 90 % of the in-shard rate",
           90.0, "≥", "%", (SWEEP + "worker_malloc_h200/bench_default.json",), sweep_wall_fraction, LINK["sweeps.md"]),
    Target("sweep, two GPUs, 1e-8 s", "2048-pad sweep at 1e-8 s: two GPUs ≥ 1.9× one (timed on a warm cluster)",
           1.9, "≥", "×", (SWEEP + "worker_malloc_h200/bench_1e-8.json",), sweep_two_over_one,
           LINK["sweeps.md"]),
    Target("sweep, two GPUs, default step",
           "2048-pad product sweep at its default step (5e-8 s): two GPUs ≥ 1.9× one (timed on a warm cluster)",
           1.9, "≥", "×", (SWEEP + "worker_malloc_h200/bench_default.json",), sweep_two_over_one, LINK["sweeps.md"]),
    Target("LF on the CPU", "LF automaton on the CPU ≥ 100 steps/s", 100.0, "≥", "steps/s",
           tuple(f"benchmarks/lf_ordered_fast_h200/bench_lf_cpu_new_{k}.json" for k in (1, 2)), lf_steps,
           LINK["lf_model.md"]),
    Target("LF on a GPU", "LF automaton on a GPU ≥ 2000 steps/s", 2000.0, "≥", "steps/s",
           tuple(f"benchmarks/lf_ordered_fast_h200/bench_lf_new_{k}.json" for k in (1, 2)), lf_steps,
           LINK["lf_model.md"]),
)  # fmt: skip


# ------------------------------------------------------------------------------------------------ verdicts, numbers


def num(x: float, digits: int = 3) -> str:
    """``x`` to ``digits`` significant digits, never fewer than its integer digits; powers of ten outside
    [1e-3, 1e5): "3.50e10"."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    if not 1e-3 <= abs(x) < 1e5:
        mantissa, exponent = f"{x:.{digits - 1}e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return f"{x:.{max(0, digits - 1 - math.floor(math.log10(abs(x))))}f}"


def span(values: list[float], digits: int = 3) -> str:
    """One number, or the range "low–high" where the values differ at ``digits`` digits."""
    low, high = num(min(values), digits), num(max(values), digits)
    return low if low == high else f"{low}–{high}"


def ratios(values: list[float], goal: float, direction: str) -> list[float]:
    """Each value against the goal, so that ≤ 1 is met: value / goal for a "≤" target, goal / value for "≥"."""
    if direction not in ("≤", "≥"):
        raise ValueError(f"direction {direction!r}: want ≤ or ≥")
    if direction == "≥" and min(values) <= 0:
        raise ValueError(f"a value of {min(values):g} for a ≥ target: want a positive one")
    return [v / goal if direction == "≤" else goal / v for v in values]


def factor(r: float) -> str:
    """A ratio to two significant digits, three between 1 and 1.1 (where two would read 1.0)."""
    return num(r, 3 if 1 < r < 1.1 else 2)


def verdict(values: list[float], goal: float, direction: str) -> str:
    """The verdict over the runs: "met" where every run meets the goal, "missed 3.2×" (the factor by which the value
    misses it; a range over the runs) where none does, "met in k of n runs" between."""
    r = ratios(values, goal, direction)
    missed = [x for x in r if x > 1]
    if not missed:
        return "met"
    if len(missed) < len(r):
        return f"met in {len(r) - len(missed)} of {len(r)} runs"
    low, high = factor(min(missed)), factor(max(missed))
    return f"missed {low}×" if low == high else f"missed {low}–{high}×"


# ------------------------------------------------------------------------------------------------ table, JSON, figure


def measure(t: Target) -> dict[str, Any]:
    """The entry's row of the JSON: what its files hold and the verdict."""
    row: dict[str, Any] = {"name": t.name, "target": t.words, "goal": t.goal, "direction": t.direction, "page": t.page}
    if not t.files or t.read is None:
        return {**row, "value": NOT_IN_DATA, "unit": t.unit, "machine": "–", "file": [], "note": "",
                "verdict": "–", "ratio": []}  # fmt: skip
    got = t.read([DOCS / f for f in t.files])
    values = list(got.values)
    return {**row, "value": values, "unit": t.unit, "machine": got.machine, "file": list(t.files),
            "note": got.note, "verdict": verdict(values, t.goal, t.direction),
            "ratio": ratios(values, t.goal, t.direction)}  # fmt: skip


def measured_cell(row: dict[str, Any]) -> str:
    """The table's "measured" cell: the value or the range over the runs, its unit and the qualifiers."""
    if row["value"] == NOT_IN_DATA:
        return NOT_IN_DATA
    values, unit = row["value"], row["unit"]
    text = span(values) + ("" if unit in ("", "×") else " ") + unit
    notes = [n for n in (row["note"], f"{len(values)} runs" if len(values) > 1 else "") if n]
    return text + (f" ({'; '.join(notes)})" if notes else "")


def files_cell(files: list[str]) -> str:
    """Links to the files, relative to docs/; files in one folder after the folder's name once."""
    folders: dict[str, list[str]] = {}
    for f in files:
        folder, _, name = f.rpartition("/")
        folders.setdefault(folder, []).append(f"[{name}]({f})")
    return "; ".join((f"`{d}/`: " if d else "") + ", ".join(links) for d, links in folders.items()) or "–"


def block(rows: list[dict[str, Any]]) -> list[str]:
    """The lines between the markers: the table, then the figure with its sentence."""
    lines = [
        "Generated by `python3 scripts/targets_table.py` from the committed data files named in each row: the latest "
        "committed measurement of each target, on each machine where two were measured (a range over its runs), made "
        "with the code of its day (later changes "
        "and earlier measurements are on the linked pages).",
        "",
        "| target | measured | machine | verdict | data file | page |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [r["target"], measured_cell(r), r["machine"], r["verdict"], files_cell(r["file"]), r["page"]]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return lines + [
        "",
        "Each target's measured value over its target value (target over measured for a ≥ target), so that "
        "below 1 is met: a bar per target, its line the range over the runs.",
        "",
        "![Measured value over target value per target](figures/targets/targets.png)",
    ]


def with_block(text: str, body: list[str]) -> str:
    """``text`` (status.md) with ``body`` between the markers; where they are missing, in place of the table under
    :data:`HEADING`."""
    if BEGIN not in text:
        head, sep, rest = text.partition(HEADING + "\n")
        if not sep:
            raise ValueError(f"no markers and no heading {HEADING!r}")
        lines = rest.split("\n")
        start = next((i for i, ln in enumerate(lines) if ln.startswith("|")), None)
        if start is None:
            raise ValueError(f"no markers and no table under {HEADING!r}")
        stop = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
        rest = "\n".join([*lines[:start], BEGIN, END, *lines[stop:]])
        text = head + sep + rest
    head, rest = text.split(BEGIN, 1)
    if END not in rest:
        raise ValueError(f"{BEGIN} without {END}")
    return head + "\n".join([BEGIN, *body, END]) + rest.split(END, 1)[1]


def figure(rows: list[dict[str, Any]], path: Path) -> None:
    """One horizontal bar per target from 1 to its measured over target value (log axis), the runs' range as a
    line, coloured met / missed, labelled with the factor."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    shown = [r for r in rows if r["ratio"]]
    fig = Figure(figsize=(9.0, 0.34 * len(shown) + 1.1), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for y, r in enumerate(shown):
        low, high = min(r["ratio"]), max(r["ratio"])
        ax.barh(y, low - 1.0, left=1.0, height=0.6, color=MET if r["verdict"] == "met" else MISSED)
        if high > low:
            ax.plot([low, high], [y, y], color="black", lw=1.2)
        right = high > 1.0  # the label beyond the bar's end, on the side away from 1
        label = factor(low) if factor(low) == factor(high) else f"{factor(low)}–{factor(high)}"
        ax.annotate(label + "×", (high if right else low, y), xytext=(4 if right else -4, 0),
                    textcoords="offset points", ha="left" if right else "right", va="center", fontsize=8)  # fmt: skip
    ax.axvline(1.0, color="black", lw=1.0)
    ax.legend(handles=[Patch(color=MET, label="met"), Patch(color=MISSED, label="missed")], loc="lower right",
              fontsize=8)  # fmt: skip
    ax.set_xscale("log")
    ax.set_yticks(range(len(shown)), [r["name"] for r in shown], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("measured / target (target / measured for ≥ targets): below 1 met, above 1 missed")
    lo = min(min(r["ratio"]) for r in shown)
    hi = max(max(r["ratio"]) for r in shown)
    ax.set_xlim(min(lo, 1.0) / 3.0, max(hi, 1.0) * 3.0)
    ax.grid(axis="x", which="major", alpha=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata={"Software": None})


def json_text(rows: list[dict[str, Any]]) -> str:
    return json.dumps(rows, indent=1, ensure_ascii=False) + "\n"


def diff(old: str, new: str, name: str) -> list[str]:
    return list(difflib.unified_diff(old.splitlines(), new.splitlines(), name, f"{name} (generated)", lineterm=""))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true",
                    help="write nothing; exit 1 and print the differences where status.md's block or the figure's "
                         "JSON differ from what the script would write (or the figure is missing)")  # fmt: skip
    ap.add_argument("--status", type=Path, default=STATUS, metavar="PATH",
                    help="the page with the markers (default docs/status.md)")  # fmt: skip
    ap.add_argument("--figures", type=Path, default=FIGURES, metavar="DIR",
                    help="folder of targets.png and targets.json (default docs/figures/targets)")  # fmt: skip
    args = ap.parse_args(argv)
    try:
        rows = [measure(t) for t in TARGETS]
        page = args.status.read_text()
        new_page = with_block(page, block(rows))
    except (OSError, ValueError, KeyError) as e:
        print(f"targets_table: {type(e).__name__}: {e}", file=sys.stderr)
        return 2
    data, png = args.figures / "targets.json", args.figures / "targets.png"
    new_json = json_text(rows)
    if args.check:
        old_json = data.read_text() if data.is_file() else ""
        problems = diff(page, new_page, str(args.status)) + diff(old_json, new_json, str(data))
        problems += [] if png.is_file() else [f"{png}: missing"]
        print("\n".join(problems) if problems else "targets_table: up to date")
        return 1 if problems else 0
    args.status.write_text(new_page)
    data.parent.mkdir(parents=True, exist_ok=True)
    data.write_text(new_json)
    figure(rows, png)
    print(f"targets_table: wrote {args.status}, {data} and {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
