"""Validation of §3.3 (multi-timescale study, Figs. 12–13) and §4 from ensembles of LF seeds.

The LF automaton runs the ``multiscale`` load procedure (four 10 s applications at 10 / 30 / 5 / 15 bar, 5 s
pauses) once per seed on the CPU (``[lf] seed`` and the initial patches' ``[patches] seed`` both = the seed;
the quick variant shortens the applications to 2 s and the pauses to 1 s, as ``multiscale_study.py --quick``),
saving the states at the start and end of every application. Each state of each seed becomes one HF pad
(``scene_from_snapshot``: areas frozen, the contact re-solved at the state's load) with the validation's initial
state (equilibrium + the seeded perturbation, or rest). An experiment is a batch of the pads of some states over
all seeds (``Experiment.members``); the states are grouped by their predicted time to saturation and their size
(:data:`GROUPS`), so that no batch runs as long as its slowest state needs, or is sized for its largest, for the
others. Every pad is analysed
like the §3.1 pads (saturation per pad, the measures of ``pad_measures``) over a window half the configured one
(10 ms, 100 Hz; quick 4 ms). In the quick variant (``state_patches`` 60, or ``--patches``) every state is cut
to a sector of the pad holding about that many patches, with the load its patches and its share of the matrix
carry in the full state's contact solution (:func:`state_sector`), so the sector's contact reproduces the full
state's gap.

Rows (§3.3): the largest μ oscillation at the start of application 3 (standard deviation of μ over the saturated
segment, against every other state of the same seed); individual high S there (the mean of the top 1 % of
S − S_null); higher prevalence at the end of application 3 (mean Φ of the synchronised bins); local clustering
linked to Φ there (Spearman ρ of the neighbours' phase coherence against Φ over the frequency bins); S matching
the μ-spectrum peaks (``spectral_agreement``); the first velocity peak of every state within 20–80 kHz (§4); and
the load history (§3.3/§4): application 3's start against the same low-load application run right after the
10-bar one (the schedule 10 / 5 / 30 / 15 bar, ``ms_order``), paired by seed.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.validation.base import (
    EXPERIMENTS,
    Config,
    Experiment,
    _get,
    map_pads,
    member_result,
    pad_member,
    register_experiment,
)

STATES = ("app1_start", "app1_end", "app2_start", "app2_end", "app3_start", "app3_end", "app4_start", "app4_end")
GROUPS = {  # by the predicted time to saturation and the size of LF seed 1's states (docs/validation.md)
    "ms_fast": ("app2_start",),  # 4062 patches, 1.7 ms: alone, so that the larger batches need not be sized for it
    "ms_short": ("app1_start", "app2_end"),  # 2.9 and 12.6 ms
    "ms_mid": ("app1_end", "app4_start", "app4_end"),  # 23–40 ms
    "ms_app3": ("app3_start", "app3_end"),  # 54 and 67 ms
}
MAIN = tuple(GROUPS)
LIN_DURATION, LIN_START = 2.0e-3, 0.5e-3  # s: the linear phase from rest, the single run's window
ORDER_BAR = (10.0, 5.0, 30.0, 15.0)  # the low-load application right after the 10-bar one
QUICK_DURATIONS = (2.0, 1.0)  # s: application and pause lengths of the quick variant (multiscale_study --quick)


# ------------------------------------------------------------------------------------------------ LF runs


def lf_scene(seed: int, schedule_bar: tuple[float, ...] | None, durations: tuple[float, float] | None) -> Any:
    """The ``multiscale`` LF scene with ``[lf] seed`` and ``[patches] seed`` = ``seed``, the applications at
    ``schedule_bar`` [bar] in order (None: the preset's), with ``durations`` (application, pause) [s] instead of
    the preset's (the quick variant's :data:`QUICK_DURATIONS`)."""
    from aca_warp.lf.scene import Segment, load_lf_scene

    base = load_lf_scene("multiscale")
    lf = dataclasses.replace(base.lf, seed=seed)
    patches = None
    if base.patches is not None:
        gen = dict(base.origin["patches"])
        gen["seed"] = seed
        from aca_warp.scene import PatchGenerator

        patches = PatchGenerator(**gen).generate(base.pad)
    segs, k = [], 0
    for s in base.schedule:
        dur = s.duration if durations is None else durations[0 if s.kind == "application" else 1]
        force = s.normal_force
        if s.kind == "application":
            if schedule_bar is not None:
                force = schedule_bar[k] * lf.newton_per_bar
            k += 1
        segs.append(Segment(s.kind, dur, force, s.sliding_speed, min(s.ramp, 0.1 * dur)))
    origin = dict(base.origin or {})
    origin["lf"] = {**origin.get("lf", {}), "seed": seed}
    origin["patches"] = {**origin.get("patches", {}), "seed": seed}
    return base.replace(lf=lf, patches=patches, schedule=tuple(segs), origin=origin)


def lf_path(cfg: Config, seed: int, schedule_bar: tuple[float, ...] | None) -> Path:
    """Where the LF run of ``seed`` (and schedule) is kept: ``<lf_dir>/lf_<full|quick-A-P>_<schedule>_seed<N>.h5``
    (A, P: the quick variant's application and pause lengths)."""
    if cfg.lf_dir is None:
        raise ValueError("the multi-timescale experiments need Config.lf_dir (the folder of their LF runs)")
    sched = "preset" if schedule_bar is None else "-".join(f"{b:g}" for b in schedule_bar)
    length = "quick-{:g}-{:g}".format(*QUICK_DURATIONS) if cfg.quick else "full"
    return Path(cfg.lf_dir) / f"lf_{length}_{sched}_seed{seed}.h5"


def lf_runs(exp: Experiment, cfg: Config) -> dict[str, str]:
    """The LF run files a §3.3 experiment's pads are cut from, each with the digest of its content
    (:func:`lf_digests`; {} for other experiments). Results are joined or reused only where their LF runs are the
    same (:func:`lf_conflicts`): another code version, another device or an LF run made before its sums were put in
    a fixed order may give other states for the same seed."""
    return lf_digests(cfg, exp.schedule_bar) if exp.builder is state_scene else {}


def lf_digests(cfg: Config, schedule_bar: tuple[float, ...] | None) -> dict[str, str]:
    """File name → content digest (:func:`lf_file_digest`) of the LF runs of ``cfg``'s seeds under ``schedule_bar``
    (None: the preset's schedule) in ``cfg.lf_dir``; a file not on disk is left out."""
    out = {}
    for k in range(cfg.seeds):
        path = lf_path(cfg, cfg.first_seed + k, schedule_bar)
        if path.is_file():
            out[path.name] = lf_file_digest(path)
    return out


def lf_file_digest(path: Path) -> str:
    """The content digest of the LF run file ``path`` (:func:`_digest`, cached while the file is unchanged)."""
    st = path.stat()
    return _digest(str(path.resolve()), (st.st_ino, st.st_mtime_ns, st.st_ctime_ns, st.st_size))


@functools.lru_cache(maxsize=256)
def _digest(path: str, stamp: tuple[int, ...]) -> str:
    """The first 16 hex digits of the SHA-256 of the LF run file ``path``'s content: its scene and every dataset
    (name, type, shape, values) in name order; the run's provenance attributes (device, host, versions, wall time)
    are left out, so that two bit-identical runs give one digest. Cached per ``stamp`` (inode, times, size)."""
    import hashlib

    import h5py

    h = hashlib.sha256()
    with h5py.File(path, "r") as f:
        h.update(str(f.attrs.get("scene", "")).encode())
        names: list[str] = []
        f.visit(lambda name: names.append(name) if isinstance(f[name], h5py.Dataset) else None)
        for name in sorted(names):
            data = np.ascontiguousarray(f[name][()])
            h.update(f"{name}|{data.dtype.str}|{data.shape}|".encode())
            h.update(data.tobytes())
    return h.hexdigest()[:16]


def lf_conflicts(runs: dict[str, dict[str, str]]) -> list[str]:
    """The LF run files that two of ``runs`` (source → :func:`lf_runs`) give with different digests, each as
    "file (source, source)"; [] when they agree."""
    seen: dict[str, tuple[str, str]] = {}
    out = []
    for source, files in runs.items():
        for name, digest in files.items():
            first = seen.setdefault(name, (digest, source))
            if first[0] != digest:
                out.append(f"{name} ({first[1]}, {source})")
    return out


def _run_lf_job(job: tuple[int, tuple[float, ...] | None, tuple[float, float] | None, str, str]) -> float:
    """One LF run on ``device`` (the job's last entry) into a temporary file renamed when complete; returns its wall
    time [s]. In a worker process CUDA is hidden before Warp starts (a CPU run needs none, and a context per worker
    would hold GPU memory)."""
    import multiprocessing
    import os
    import sys
    import time

    seed, schedule, durations, path, device = job
    if device == "cpu" and multiprocessing.current_process().name != "MainProcess" and "warp" not in sys.modules:
        os.environ["CUDA_VISIBLE_DEVICES"] = ""
    from aca_warp.lf.commands import run_lf
    from aca_warp.studies.report import init_warp

    init_warp()
    tmp = Path(path).with_suffix(".tmp.h5")
    t0 = time.perf_counter()
    run_lf(lf_scene(seed, schedule, durations), tmp, device=device, overwrite=True, progress=False)
    tmp.replace(path)
    return time.perf_counter() - t0


def lf_jobs(names: list[str], cfg: Config, first_only: bool = False) -> list[tuple[int, Any, Any, str, str]]:
    """The LF runs the experiments ``names`` need that are not on disk yet (seed, schedule, durations, path,
    device: the HF device, since a CUDA machine need not build CPU kernels)."""
    jobs: dict[str, tuple[int, Any, Any, str, str]] = {}
    for name in names:
        exp = EXPERIMENTS[name]
        if exp.builder is not state_scene:
            continue
        for k in range(1 if first_only else cfg.seeds):
            seed = cfg.first_seed + k
            path = lf_path(cfg, seed, exp.schedule_bar)
            if not path.is_file():
                durations = QUICK_DURATIONS if cfg.quick else None
                jobs[str(path)] = (seed, exp.schedule_bar, durations, str(path), cfg.device)
    return list(jobs.values())


def ensure_lf(names: list[str], cfg: Config, log: Any, first_only: bool = False) -> None:
    """Run the missing LF runs of ``names``: on a CUDA device one after the other in this process (2–3 s each on an
    H100); on the CPU the first in this process (it compiles the LF kernels), the others in up to ``cfg.workers``
    processes."""
    jobs = lf_jobs(names, cfg, first_only)
    if not jobs:
        return
    Path(cfg.lf_dir).mkdir(parents=True, exist_ok=True)
    log(f"LF: {len(jobs)} run(s) of the multiscale schedule{' (quick)' if cfg.quick else ''} on {cfg.device}")
    if cfg.device != "cpu":
        walls = [_run_lf_job(j) for j in jobs]
    else:
        walls = [_run_lf_job(jobs[0])]
        walls += map_pads(_run_lf_job, jobs[1:], min(cfg.workers, len(jobs) - 1))
    log(f"LF: done ({', '.join(f'{w:.1f}' for w in walls)} s each)")


def cap_frequency(cfg: Config) -> float:
    """The isolated-patch frequency of the LF automaton's largest patch, √(K_T √A_max / (m″ A_max)) / 2π [Hz]: LF
    states whose patches grew to the cap oscillate there."""
    from aca_warp.lf.scene import load_lf_scene

    s = load_lf_scene("multiscale")
    a, m = s.lf.A_max, s.material
    return float(math.sqrt(m.K_T * math.sqrt(a) / (m.mass_per_area * a)) / (2.0 * math.pi))


COVERAGE_TOLERANCE = 0.5e-3  # m: a patch of one state lies on a patch of another when their centres are this close


def coverage_match(a: Any, b: Any) -> float:
    """Area-weighted share of state a's patches whose centre lies within :data:`COVERAGE_TOLERANCE` of a patch of
    state b (the same place in both coverages)."""
    from scipy.spatial import cKDTree

    pa, pb = a.patches, b.patches
    d, _ = cKDTree(np.column_stack([pb.x, pb.y])).query(np.column_stack([pa.x, pa.y]))
    return float(np.sum(pa.area[d <= COVERAGE_TOLERANCE]) / np.sum(pa.area))


def lf_facts(cfg: Config) -> dict[str, Any]:
    """The LF states of every seed as a result ({"pads": [...]}, one entry per seed, status "LF state"): per state
    the patches, the total patch area [m²] and the normal force [N]; the coverage of app3_start against app2_end
    (the claim of §3.3), app3_end and app2_start (``match_*``, :func:`coverage_match`); and the cap frequency."""
    from aca_warp.lf.io import scene_from_snapshot

    pads = []
    for k in range(cfg.seeds):
        seed = cfg.first_seed + k
        path = lf_path(cfg, seed, None)
        if not path.is_file():
            continue
        states = {s: scene_from_snapshot(path, s) for s in STATES}
        m: dict[str, Any] = {"states": {s: {"patches": sc.patches.count, "area": float(sc.patches.area.sum()),
                                            "force": float(sc.normal_force)} for s, sc in states.items()}}  # fmt: skip
        a3 = states["app3_start"]
        for other in ("app2_end", "app3_end", "app2_start"):
            m[f"match_{other}"] = coverage_match(a3, states[other])
            m[f"match_back_{other}"] = coverage_match(states[other], a3)
        pads.append({"seed": seed, "status": "LF state", "measures": m})
    return {"pads": pads, "cap_frequency_hz": cap_frequency(cfg), "lf_runs": lf_digests(cfg, None), "status": "done"}


# ------------------------------------------------------------------------------------------------ HF scenes


def state_sector(scene: Any, patches: int) -> Any:
    """The sector of an LF state's HF scene that holds about ``patches`` patches (same radii, centred), with the
    load its patches and its share q of the matrix carry in the full state's contact solution, so that the
    sector's contact solve gives the full state's gap and forces; the matrix cells keep their radii and heights
    with q of their area. The state itself when it has no more patches than that."""
    from aca_warp.hf.contact import solve_scene_contact
    from aca_warp.scene import Matrix, Patches

    n = scene.patches.count
    if n <= patches:
        return scene
    q = patches / n
    pad = dataclasses.replace(scene.pad, span_deg=scene.pad.span_deg * q)
    p = scene.patches
    keep = pad.contains_disc(p.x, p.y, p.radius)
    c = solve_scene_contact(scene)
    force = float(c.patch_force[keep].sum() + q * c.matrix_force.sum())
    m = scene.matrix
    return scene.replace(
        pad=pad,
        patches=Patches(p.x[keep], p.y[keep], p.area[keep], p.height[keep], source=f"{p.source} (sector {q:.4g})"),
        matrix=Matrix(m.area * q, m.radius, m.height),
        normal_force=force,
        origin=None,
    )


def state_scene(exp: Experiment, k: int, cfg: Config) -> Any:
    """Pad ``k`` of a multi-timescale experiment: state ``members[k // seeds]`` of the LF run of seed
    ``first_seed + k % seeds`` (schedule ``exp.schedule_bar``), as an HF scene with the experiment's initial state
    (cut to a sector with ``cfg.state_patches`` or ``cfg.patches``)."""
    from aca_warp.lf.io import scene_from_snapshot
    from aca_warp.scene import Initial

    member, seed = pad_member(exp, k, cfg)
    scene = scene_from_snapshot(lf_path(cfg, seed, exp.schedule_bar), member)
    target = cfg.state_patches if cfg.state_patches is not None else cfg.patches
    if target is not None:
        scene = state_sector(scene, target)
    initial = Initial(
        state=exp.initial, perturbation=cfg.perturbation if exp.initial == "equilibrium" else 0.0, seed=seed
    )
    return scene.replace(name=f"{exp.name}:{member}:seed{seed}", initial=initial, origin=None)


def _ms(name: str, description: str, members: tuple[str, ...], stepping: str, **kw: Any) -> Experiment:
    return Experiment(name, "§3.3", description, "multiscale", builder=state_scene, members=members,
                      window_scale=0.5, stepping=stepping, **kw)  # fmt: skip


# each group runs at its regime's stepping (settings.STEPPING, keyed by the group), its variants too
MS_EXPERIMENTS = (
    *(_ms(g, f"LF states {', '.join(m)} (one pad per state and LF seed)", m, g) for g, m in GROUPS.items()),
    *(_ms(f"{g}_rest", f"as {g}, HF started from rest (initial-state variant)", m, g, initial="rest", quick=False,
          opt_in=True) for g, m in GROUPS.items()),
    _ms("ms_order", "LF schedule 10 / 5 / 30 / 15 bar: the low-load application (app2) right after the 10-bar one "
        "(load-history variant)", ("app2_start",), "ms_order", schedule_bar=ORDER_BAR),
    *(_ms(f"{g}_lin", f"as {g}, from rest for 2 ms, analysed over 0.5–2 ms unsaturated (the single run's window; "
          "run-length variant)", m, g, initial="rest", kind="window", duration=LIN_DURATION,
          window_start=LIN_START) for g, m in GROUPS.items()),
)  # fmt: skip


def register() -> None:
    """Register the §3.3 experiments of the rows (the state groups and ``ms_order``; once)."""
    if MAIN[0] in EXPERIMENTS:
        return
    for exp in MS_EXPERIMENTS:
        if exp.name in (*MAIN, "ms_order"):
            register_experiment(exp)


def register_variants() -> None:
    """Register the §3.3 variant experiments (from rest; the linear-phase window)."""
    for exp in MS_EXPERIMENTS:
        if exp.name not in (*MAIN, "ms_order"):
            register_experiment(exp)


# ------------------------------------------------------------------------------------------------ page


STATE_COLUMNS = (
    ("patches", "patches", ".0f", 1.0),
    ("normal_force_N", "F_N [kN]", ".2f", 1e-3),
    ("mu_std", "std μ", ".3g", 1.0),
    ("mu_peak_hz", "largest μ peak [kHz]", ".1f", 1e-3),
    ("f1", "first velocity peak [kHz]", ".1f", 1e-3),
    ("sync_relative.top_excess", "top-1 % S − S_null", ".3f", 1.0),
    ("sync_relative.phi_sync", "mean Φ, S − S_null > 0.05", ".1f", 1.0),
    ("sync_relative.cluster_phi_rho", "ρ(C_neighbours, Φ)", ".2f", 1.0),
    ("sync_relative.agreement", "ρ(S·Φ, μ(f))", ".2f", 1.0),
    ("t_s_sum_abs_velocity", "t_s Σ|u̇| [ms]", ".1f", 1e3),
)


def state_table(results: dict[str, dict], names: tuple[str, ...] = MAIN) -> tuple[list[str], list[list[str]]]:
    """One line per LF state of the experiments ``names``: the pads used and the means over seeds of the
    measures the §3.3 rows read."""
    from aca_warp.studies.validation.base import usable

    header = ["state", "pads used", *(c[1] for c in STATE_COLUMNS)]
    rows = []
    for state in STATES:
        res = member_result(results, names, state)
        if not res["pads"]:
            continue
        ok = usable(res)
        cells = []
        for key, _, spec, scale in STATE_COLUMNS:
            vals = [p.get(key) if key in p else _get(p, key) for p in ok]
            vals = np.array([v for v in vals if v is not None and np.isfinite(v)], dtype=np.float64)
            cells.append(format(float(np.mean(vals)) * scale, spec) if vals.size else "–")
        rows.append([state, f"{len(ok)} / {len(res['pads'])}", *cells])
    return header, rows
