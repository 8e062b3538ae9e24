#!/usr/bin/env python3
"""Time the on-chip engine on the validation's batches of LF-state pads (§3.3) in several launch layouts.

A case is ``GROUP[:STATE][@K]``: the pads of the validation experiment GROUP (``ms_fast``, ``ms_short``,
``ms_mid``, ``ms_app3``) for seeds ``--first-seed`` … (``--seeds`` of them), only those of LF state STATE when given,
on clusters of K blocks per pad (0 or none: the engine's default, ``default_cluster``). The pads are built as the
validation builds them (``prepare``: the LF runs of ``--lf-dir``, made on ``--device`` where missing) and stepped with
the group's stepping (``strang``, its precision and step) from the validation's initial state: a warm-up of two
sample intervals (compilation), then ``--window`` [s] timed. Printed per case: pads, the largest pad's patches, the
most links of one pad, blocks per pad, threads per block, the shared memory a block needs with its neighbour lists on
chip against what the device offers (``shared_bytes`` / ``smem_limit``), whether they are on chip, the most links one
thread gathers per step, and µs per step. Examples::

    python scripts/bench_lf_batches.py --device cuda:0 --lf-dir /tmp/lf --json $OUT/lf_batches.json
    python scripts/bench_lf_batches.py --device cpu --seeds 2 --state-patches 150 --window 2e-6 --cases ms_short
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_path

DEFAULT_CASES = [
    "ms_fast",
    "ms_short",
    "ms_short@8",
    "ms_short@16",
    "ms_short:app2_end",
    "ms_short:app2_end@16",
    "ms_short:app1_start",
    "ms_app3@16",
]


def parse_case(text: str) -> tuple[str, str | None, int]:
    """(group, state or None, blocks per pad; 0: the default) of a case ``GROUP[:STATE][@K]``."""
    head, _, k = text.partition("@")
    group, _, state = head.partition(":")
    return group, state or None, int(k or 0)


def run_case(case: str, preps: dict[str, Any], cfg: Any, window: float) -> dict[str, Any]:
    """Build, lay out and time one case; returns its table row."""
    from aca_warp.hf.engine import EngineTuning
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.onchip import cluster_size
    from aca_warp.hf.onchip_layout import block_config, pad_sizes, shared_bytes, smem_limit, thread_links
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import Record
    from aca_warp.studies.runs import batch_at_start

    group, state, k = parse_case(case)
    prep = preps[group]
    scenes = [s for s, m in zip(prep.scenes, prep.members, strict=True) if state is None or m == state]
    if not scenes:
        raise ValueError(f"{case}: no pad of state {state} in {group} (states: {', '.join(sorted(set(prep.members)))})")
    step = cfg.stepping(prep.exp.stepping)
    model, start = batch_at_start(scenes, cfg.device, step.precision)
    kk = cluster_size(model, k or None)
    block, threads, csr = block_config(model, kk)
    links = np.diff(model.host("nbr_start")[model.pad_patch_start_host])
    row = {
        "case": case,
        "pads": model.pad_count,
        "patches_max": pad_sizes(model)[0],
        "links_max": int(links.max()),
        "cluster": kk,
        "block_dim": block,
        "smem_need": shared_bytes(model, True, kk, threads),
        "smem_limit": smem_limit(model),
        "csr_on_chip": bool(csr),
        "thread_links": int(thread_links(model, kk, threads).max()),
        "precision": step.precision,
        "dt": step.dt,
    }
    # the validation's stepping of the group, with its point treatment of zero-slip crossings (run_engine's)
    options = RunOptions(engine="onchip", integrator=step.integrator, dt=step.dt, force=step.force, crossing="point")
    record = Record(sample_dt=cfg.sample_dt)
    tuning = EngineTuning(cluster=k or None)
    t0 = time.perf_counter()
    run_hf(model, initial_state(model), options.with_duration(2 * cfg.sample_dt), record=record, tuning=tuning)
    row["warmup_s"] = time.perf_counter() - t0
    res = run_hf(model, start, options.with_duration(window), record=record, tuning=tuning)
    row.update(steps=res.steps, wall_s=res.wall_time, us_per_step=1e6 * res.wall_time / max(res.steps, 1))
    row["complete"] = bool(res.complete)
    return row


COLUMNS = (
    ("case", "case", "s"),
    ("pads", "pads", "d"),
    ("patches_max", "N max", "d"),
    ("links_max", "links max", "d"),
    ("cluster", "K", "d"),
    ("block_dim", "block", "d"),
    ("smem_need", "smem need [B]", "d"),
    ("smem_limit", "smem limit [B]", "d"),
    ("csr_on_chip", "CSR on chip", "s"),
    ("thread_links", "links/thread", "d"),
    ("us_per_step", "µs/step", ".2f"),
)


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as a Markdown table (failed cases with their error)."""
    lines = ["| " + " | ".join(c[1] for c in COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['case']} | failed: {r['error']} |")
            continue
        lines.append("| " + " | ".join(format(r[k] if f != "s" else str(r[k]), f) for k, _, f in COLUMNS) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--cases", nargs="+", default=DEFAULT_CASES, help="GROUP[:STATE][@K] (default: %(default)s)")
    ap.add_argument("--seeds", type=int, default=8, help="LF seeds (pads per state)")
    ap.add_argument("--first-seed", type=int_at_least(0), default=1)
    ap.add_argument(
        "--state-patches", type=int_at_least(2), default=None, help="cut every state to a sector of this many patches"
    )
    ap.add_argument("--lf-dir", type=Path, default=Path("out/lf_batches"), help="folder of the LF runs")
    ap.add_argument("--window", type=float, default=5e-4, help="timed simulated time per case [s]")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = ap.parse_args(argv)
    if not args.window > 0 or args.seeds < 1:
        ap.error("--window must be > 0 and --seeds ≥ 1")
    if args.json:
        try:
            check_output_path(args.json, overwrite=True)
        except AcaError as e:
            ap.error(str(e))
    try:
        cases = [parse_case(c) for c in args.cases]
    except ValueError:
        ap.error("a case is GROUP[:STATE][@K], K an integer")

    from aca_warp.common.devices import init_warp

    init_warp()
    import aca_warp.studies.validation  # noqa: F401  (registers the experiments)
    from aca_warp.studies.validation import multiscale
    from aca_warp.studies.validation.base import EXPERIMENTS, Config
    from aca_warp.studies.validation.experiments import prepare

    multiscale.register()
    groups = sorted({c[0] for c in cases})
    unknown = [g for g in groups if g not in multiscale.GROUPS]
    if unknown:
        ap.error(f"unknown group(s) {', '.join(unknown)}; choose from {', '.join(multiscale.GROUPS)}")
    cfg = Config(
        device=args.device, seeds=args.seeds, first_seed=args.first_seed, state_patches=args.state_patches,
        lf_dir=str(args.lf_dir),
    )  # fmt: skip
    rows = []
    try:
        multiscale.ensure_lf(groups, cfg, lambda s: print(s, flush=True))
        preps = {g: prepare(EXPERIMENTS[g], cfg) for g in groups}
    except AcaError as e:
        print(f"bench_lf_batches.py: {e}", file=sys.stderr)
        sys.exit(2)
    for case in args.cases:
        try:
            row = run_case(case, preps, cfg, args.window)
        except (AcaError, ValueError) as e:
            row = {"case": case, "error": str(e)}
        rows.append(row)
        print(json.dumps(row), flush=True)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))
    print(table(rows))


if __name__ == "__main__":
    main()
