"""The estimated wall time of a validation run: stepping per batch, kernel compilation, LF runs and analysis.

**Stepping** (:func:`step_seconds`). On CUDA the on-chip engine advances every pad of a batch in one thread block or
a cluster of K blocks (``default_cluster``: K = 8 for ≤ 14 pads, 5 for ≤ 21, 4 for ≤ 28, 2 for ≤ 66, else 1 on an
H100's or H200's 132 SMs), every block sized for the batch's largest pad. A step then takes, per wave of clusters that
fit the GPU at once (14 of 8, 21 of 5, 28 of 4, 66 of 2, 132 of 1),

    a + b · w / K   [µs],   w = ½ N/1758 + ½ L/L_hf1,

N the largest pad's patches and L its neighbour links (L_hf1 = 20 904, hf1's), a and b fitted to one hf1 pad on
K = 1 … 8 blocks (fp32: 1.8 / 2.57 / 3.78 / 6.30 µs on K = 8 / 4 / 2 / 1; fp64 on K = 2 … 8: 2.62 / 3.45 / 5.95;
docs/benchmarks/onchip_h100/bench_cluster.md): fp32 a = 1.16, b = 5.14; fp64 a = 1.51, b = 8.88. The batched
figures of cluster_waves_default.md (64 fp32 pads on pairs 4.63 µs, 132 on one block 7.45, 1024 51.5) follow from
the waves. Where a block's neighbour lists do not fit its shared memory beside the state (``shared_bytes`` against
the H100's 227 KiB), a batch on clusters of 4 or more takes the smallest wider cluster of 8 or 16 where they fit, as
the engine does (``widen_for_csr``; 7 clusters of 16 per wave); where none does, the gathers read global memory:
b × :data:`OFF_CHIP` (5, from the fp64 LF-state batches of an earlier validation run on an H200: 8 pads of up to
4329 patches with 31 links each, 25.3 µs per step). Growing pads
with a growth event every :data:`FREQUENT_EVENTS` steps or more often (the scenes' own clock: every 4 steps of
5e-8 s) take at least :data:`GROWTH_FLOOR_S`; with sparser events (the stepping table's 5 µs: one per 50 steps of
1e-7 s) their share is left to the estimate's calibration by the run. On the CPU: 1e7 patch-steps/s (general
engine, 2-core AMD EPYC).

These are estimates, a factor 2 either way for dense LF states: a run measures each batch's step time on its first
segment (a probe, after a warm-up) before going on, and corrects the later estimates of
its kind by what it measured (:meth:`Costs.calibrate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from aca_warp.scene.parts import pairs_within

COEFFICIENTS = {"fp32": (1.16e-6, 5.14e-6), "fp64": (1.51e-6, 8.88e-6)}  # (a, b) [s] of a + b·w/K
HF1_PATCHES, HF1_LINKS = 1758, 20904
SM_COUNT = 132  # an H100's or H200's
WAVE = {16: 7, 8: 14, 5: 21, 4: 28, 2: 66, 1: 132}  # clusters of K in one wave on 132 SMs (cluster_waves_*.md,
# cluster5; 16: one per GPC of 18 SMs, the rule that gives the measured 14, 21 and 28)
OFF_CHIP = 5.0
GROWTH_FLOOR_S = {"fp32": 2.7e-6, "fp64": 3.9e-6}
"""Seconds per step of a batch of growing pads in one wave (on-chip engine, a cluster of 8 blocks per pad): 2.7 µs
measured in fp32 for one varying_area pad (an event every 20 steps; docs/onchip.md); fp64 1.45 × that, the fp64/fp32
ratio of one non-growing hf1 pad on 8 blocks."""
FREQUENT_EVENTS = 20  # steps between growth events up to which GROWTH_FLOOR_S applies (its measurement's)
SMEM_BYTES = 227 * 1024  # the H100's shared memory per block (opt-in)
CPU_PATCH_STEPS = 1.0e7  # patch-steps per second of the general engine on the 2-core AMD EPYC host
COMPILE_S = 4.0  # s per batch on CUDA: one on-chip module per tile shape (1.7–4.5 s, docs/benchmarks/onchip_h100)
LF_RUN_S = {"cpu": 11.0, "cuda": 2.5}  # s per LF run of the multiscale schedule (one CPU core; H100: 2.2 s)
ANALYSIS_S = 1.5  # s per analysed pad of 1758 patches × 6667 per-patch samples on one core
TRACK_S = 0.6  # s per track window of a 1758-patch pad (5 ms) on one core


def links(scene: Any, radius: float = 5.0e-3) -> int:
    """Neighbour links of a pad (pairs of patches closer than the coupling radius, counted from both ends)."""
    p = scene.patches
    return 2 * pairs_within(p.x, p.y, radius)


def cluster(pads: int) -> int:
    """Blocks per pad: ``default_cluster`` on an H100's or H200's 132 SMs (a pad that must split to fit aside)."""
    from aca_warp.hf.onchip_layout import default_cluster  # loads Warp: only where a batch is costed

    return default_cluster(pads, SM_COUNT)


def fits_on_chip(n: int, n_links: int, k: int, precision: str) -> bool:
    """Whether a block's share of an ``n``-patch pad's neighbour lists fits beside the pad's state (``shared_bytes``
    without the bank interleaving: u twice, w and F_s per patch, 2 + itemsize bytes per link)."""
    item = 4 if precision == "fp32" else 8
    return 4 * n * item + n_links / k * (2 + item) * 1.1 + 8 * 1024 <= SMEM_BYTES


def step_seconds(pads: int, n: int, n_links: int, precision: str, frequent: bool, device: str) -> float:
    """Estimated seconds per time step of a batch of ``pads`` pads, the largest of ``n`` patches and ``n_links``
    links (module docstring), at least :data:`GROWTH_FLOOR_S` with ``frequent`` growth events; ``device`` "cpu"
    uses the CPU throughput (total patches ≈ pads × n)."""
    if device == "cpu":
        return pads * n / CPU_PATCH_STEPS
    from aca_warp.hf.onchip_layout import widen_for_csr

    a, b = COEFFICIENTS[precision]
    k = widen_for_csr(cluster(pads), lambda w: fits_on_chip(n, n_links, w, precision))  # as the engine widens
    if not fits_on_chip(n, n_links, k, precision):
        b *= OFF_CHIP
    w = 0.5 * n / HF1_PATCHES + 0.5 * n_links / HF1_LINKS
    t = math.ceil(pads / WAVE[k]) * (a + b * w / k)
    return max(t, GROWTH_FLOOR_S[precision]) if frequent else t


def batch_step_seconds(scenes: list[Any], precision: str, frequent: bool, device: str) -> float:
    """:func:`step_seconds` of a batch of ``scenes``: their count, the largest pad's patches and links (a layout that
    several scenes share counted once)."""
    n = max(s.patches.count for s in scenes)
    n_links = max(links(s) for s in {id(s.patches): s for s in scenes}.values())
    return step_seconds(len(scenes), n, n_links, precision, frequent, device)


@dataclass
class Costs:
    """Estimates and the calibration a run learns (measured over estimated step time, per stepping kind)."""

    factors: dict[str, float] = field(default_factory=dict)

    def step(self, batch: Any, cfg: Any) -> float:
        """Estimated seconds per step of ``batch`` (a :class:`~aca_warp.studies.validation.experiments.Batch`)."""
        step = cfg.stepping(batch.stepping_kind)
        frequent = batch.growth and events_every(batch.scenes, step) <= FREQUENT_EVENTS
        raw = batch_step_seconds(batch.scenes, step.precision, frequent, cfg.device)
        return raw * self.factors.get(batch.stepping_kind, 1.0)

    def steps(self, batch: Any, cfg: Any) -> int:
        """Steps of the batch's run at the fixed step of its stepping."""
        return batch.plan.steps(cfg.stepping(batch.stepping_kind).dt, cfg.sample_dt)

    def estimate(self, batch: Any, cfg: Any) -> float:
        """Estimated seconds of stepping of the batch."""
        return self.steps(batch, cfg) * self.step(batch, cfg)

    def calibrate(self, batch: Any, cfg: Any, measured: float) -> None:
        """Correct later estimates of the batch's stepping kind by ``measured`` [s per step] over the estimate."""
        kind = batch.stepping_kind
        raw = self.step(batch, cfg) / self.factors.get(kind, 1.0)
        if raw > 0 and measured > 0:
            self.factors[kind] = measured / raw


def events_every(scenes: list[Any], step: Any) -> int:
    """Steps between the growth events of growing ``scenes`` at ``step`` (a validation ``Stepping``)."""
    from aca_warp.hf.options import steps_per_event

    interval = next(s.growth.interval for s in scenes if s.growth is not None)
    return steps_per_event(interval if step.growth_dt is None else step.growth_dt, step.dt)


def batch_friction_step(scenes: list[Any]) -> float:
    """The friction step of a batch of pads [s] (:func:`~aca_warp.hf.solver.friction_step`), from
    a host model of them (``stable_step``)."""
    from aca_warp.hf.model import build_model
    from aca_warp.hf.solver import friction_step, stable_step

    return friction_step(stable_step(build_model(scenes, device="cpu", precision="fp64")))


def overheads(batches: list[Any], cfg: Any, lf_runs: int) -> dict[str, float]:
    """Estimated wall seconds beside the stepping: kernel compilation (one module per batch on CUDA), LF runs
    (sequential on CUDA, over ``cfg.workers`` processes on the CPU) and the pads' analysis (over the workers)."""
    pads = 0.0
    for b in batches:
        for p in b.members:
            size = sum(s.patches.count for s in p.scenes) / HF1_PATCHES
            if p.exp.kind == "growth":
                pads += 0.3 * len(p.scenes)
            else:
                pads += size * p.plan.patch_samples / 6667
                pads += size * len(p.plan.tracks) * TRACK_S / ANALYSIS_S * (cfg.track_window / 5.0e-3)
    gpu = cfg.device != "cpu"
    lf = LF_RUN_S["cuda" if gpu else "cpu"] * (4.0 / 11.0 if cfg.quick else 1.0)
    return {
        "compile": COMPILE_S * len(batches) if gpu else 0.0,
        "lf": lf * (lf_runs if gpu else math.ceil(lf_runs / max(cfg.workers, 1))) if lf_runs else 0.0,
        "analysis": ANALYSIS_S * pads / max(cfg.workers, 1),
    }


def events(growth_dt: float | None) -> str:
    """The growth events' spacing of a stepping, for the cost table ("" at the scenes' own clock)."""
    return "" if growth_dt is None else f", events every {growth_dt * 1e6:g} µs"


def measured(results: dict[str, dict], parts: list[dict] | None = None) -> list[dict[str, Any]]:
    """The measured stepping of every batch of a results file, by share and then in the order of ``results``.

    Per batch and share (experiments of one batch name finished in one call share one run; one that ran again, as
    ``--without`` makes it, is a batch of its own): its name, experiments, section, share (the letter of the earlier
    call of ``parts``, the meta's ``with``, that finished it: A, B, … in their order; "–" for this run's own), pads,
    patch counts [min, max], simulated time [s], stepping, steps, stepping wall [s], µs per step, blocks per pad and
    the estimate [s] the run logged beside it."""
    from aca_warp.studies.validation.base import EXPERIMENTS

    share = {n: chr(ord("A") + k) for k, p in enumerate(parts or []) for n in p.get("experiments", [])}
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for name, res in results.items():
        run = res.get("run") if isinstance(res, dict) else None
        if name not in EXPERIMENTS or not run or res.get("status") not in ("done", "stopped"):
            continue
        key = (share.get(name, "–"), EXPERIMENTS[name].batch or name)
        if key in rows:
            rows[key]["experiments"].append(name)
            rows[key]["pads"] += len(res["pads"])
            rows[key]["patches"] += [p["patches"] for p in res["pads"]]
            continue
        st = run["stepping"]
        rows[key] = {
            "batch": key[1],
            "experiments": [name],
            "section": EXPERIMENTS[name].section,
            "share": key[0],
            "pads": len(res["pads"]),
            "patches": [p["patches"] for p in res["pads"]],
            "duration_s": res["plan"]["duration_s"],
            "stepping": f"{st['precision']}, {st['dt']:g} s" + events(st.get("growth_dt")),
            "steps": run["steps"],
            "wall_s": run["wall_s"],
            "us_per_step": run["us_per_step"],
            "blocks_per_pad": run.get("blocks_per_pad"),
            "estimate_s": res["plan"].get("estimate_s"),
        }
    for r in rows.values():
        r["patches"] = [min(r["patches"]), max(r["patches"])]
    return sorted(rows.values(), key=lambda r: r["share"])  # stable: a share's batches keep their order
