#!/usr/bin/env python3
"""Where the on-chip HF kernel spends its time: ablation profile on one hf1 pad (or a batch of them).

Times the on-chip engine (``aca_warp.hf.onchip``) on one pad (``--pads N``: a batch of N identical pads) for a
window of steps with parts of the step left out (``ablate``: the implicit friction solve → an explicit kick, the
neighbour gather or its second half, the block barrier, a sample's per-patch work; the results of
an ablated run are wrong and only its time counts), for several block sizes, with the CSR in shared or global
memory, fp32 and fp64, and the general per-step path for comparison. The difference between two rows is the cost
of the part left out. Writes a JSON list and a Markdown table.

``--growth`` profiles the growing pad of the varying-area study instead (preset ``varying_area``: hf1 patches,
an event every 0.202 µs ≈ 20 steps): the same pad without growth, with growth as in the study, with the
event's stiffness update (``coupling``) and/or contact re-solve (``contact``) left out, with events 100× rarer
(the cost of the growth code being in the kernel at all), and the general path. ``--state STATE.npz`` (a
``scripts/varying_area.py`` state file) starts every case from that point of the study instead of t = 0 (the
grown areas, stiffnesses, forces and the patch motion). ``--growth-dt S`` spaces the events S apart as
``aca-warp hf --growth-dt`` does (5e-6 s is ``strang``'s default there), × 100 in the rarer-event cases.

``--saturate S`` first runs the fp32 batch S seconds with the on-chip engine's defaults and profiles every case,
the fp64 ones too, from the state it reached (e.g. 0.02 s: hf1's saturated stick-slip, where the friction solves and
the crossing treatment are busiest); ``--crossing point|mean`` sets the treatment of zero-slip crossings of every
case (default: the batch's default, ``mean`` for the presets' physics).

Example (GPU machine)::

    python3 scripts/profile_onchip.py --device cuda:0 --json $OUT/profile_onchip.json --markdown $OUT/profile.md
    python3 scripts/profile_onchip.py --device cuda:0 --growth --json $OUT/profile_growth.json --markdown $OUT/g.md
    python3 scripts/profile_onchip.py --device cuda:0 --pads 1024 --window 2e-5 --only "full, default block" \
        "no friction solve, default block" "no gather, default block" --markdown $OUT/batch.md
    python3 scripts/profile_onchip.py --device cuda:0 --pads 64 --dt 2.5e-7 --sample-dt 1e-6 --saturate 0.02 \
        --window 5e-3 --only "full, cluster 2 [fp32]" "no sample outputs, cluster 2 [fp32]" --markdown $OUT/saturated.md
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from aca_warp.common.argtypes import positive
from aca_warp.common.devices import get_device
from aca_warp.common.errors import SceneError

CASES = [
    # (label, precision, block_dim, csr_shared, ablations)
    ("full", "fp32", 512, None, ()),
    ("full, CSR global", "fp32", 512, False, ()),
    ("full, block 256", "fp32", 256, None, ()),
    ("full, block 1024", "fp32", 1024, None, ()),
    ("no friction solve", "fp32", 512, None, ("friction",)),
    ("no gather", "fp32", 512, None, ("gather",)),
    ("no barrier", "fp32", 512, None, ("sync",)),
    ("no friction, no gather", "fp32", 512, None, ("friction", "gather")),
    ("loop only (no friction, gather, barrier)", "fp32", 512, None, ("friction", "gather", "sync")),
    ("full", "fp64", 512, None, ()),
    ("full, fast math", "fp32", 512, None, ("fast_math",)),
    ("full, fast math, block 1024", "fp32", 1024, None, ("fast_math",)),
    # the on-chip engine's block (640 threads fp32): with --pads 1024 the batched target's case
    ("full, default block", "fp32", None, None, ()),
    ("no friction solve, default block", "fp32", None, None, ("friction",)),
    ("no gather, default block", "fp32", None, None, ("gather",)),
    ("no friction, no gather, default block", "fp32", None, None, ("friction", "gather")),
    ("no sample outputs, default block", "fp32", None, None, ("sample",)),
    # a pad over a thread-block cluster of K blocks ("clusterK"; block size: the engine's default_block, the part
    # rounded up to 32: in fp32 up to 1024, in fp64 at most 512)
    ("full, cluster 2", "fp32", None, None, ("cluster2",)),
    # the default layout of 29-66 pads on 132 SMs (default_cluster): with --pads 64 --dt 1e-7 --sample-dt 1e-6 the
    # recording floor of the saturated hf1 benchmark
    ("no sample outputs, cluster 2", "fp32", None, None, ("cluster2", "sample")),
    ("no friction solve, cluster 2", "fp32", None, None, ("cluster2", "friction")),
    ("no gather, cluster 2", "fp32", None, None, ("cluster2", "gather")),
    ("half gather, cluster 2", "fp32", None, None, ("cluster2", "gather_half")),
    ("no barrier, cluster 2", "fp32", None, None, ("cluster2", "sync")),
    ("no friction, no gather, cluster 2", "fp32", None, None, ("cluster2", "friction", "gather")),
    ("loop only, cluster 2", "fp32", None, None, ("cluster2", "friction", "gather", "sync")),
    ("full, fast math, cluster 2", "fp32", None, None, ("cluster2", "fast_math")),
    # the same per-SM load in smaller blocks (two patches per thread): with --pads 64, 2 or 4 blocks per SM
    ("full, cluster 4, block 224", "fp32", 224, None, ("cluster4",)),
    ("full, cluster 4, block 256", "fp32", 256, None, ("cluster4",)),
    ("full, cluster 8, block 128", "fp32", 128, None, ("cluster8",)),
    ("full, cluster 8, block 112", "fp32", 112, None, ("cluster8",)),
    # the same layout with other threads per block: more threads, fewer registers per thread (fp32: 256 threads use
    # 199, 320 and 384 168, 448 and 512 128, 640 96, 896 72; scripts/onchip_registers.py), one to four patches per
    # thread
    *[
        (f"full, cluster 2, block {block}", precision, block, None, ("cluster2",))
        for block, precision in [(1024, "fp32"), (896, "fp32"), (1024, "fp64"), (896, "fp64")]
        + [(b, "fp32") for b in (768, 640, 576, 448, 384, 320, 256)]
        + [(384, "fp64"), (256, "fp64")]
    ],
    ("full, cluster 2", "fp64", None, None, ("cluster2",)),
    ("no sample outputs, cluster 2", "fp64", None, None, ("cluster2", "sample")),
    ("full, cluster 4", "fp32", None, None, ("cluster4",)),
    ("full, cluster 8", "fp32", None, None, ("cluster8",)),
    ("no gather, cluster 4", "fp32", None, None, ("cluster4", "gather")),
    ("no friction solve, cluster 4", "fp32", None, None, ("cluster4", "friction")),
    ("no barrier, cluster 4", "fp32", None, None, ("cluster4", "sync")),
    ("no gather, cluster 8", "fp32", None, None, ("cluster8", "gather")),
    ("no friction solve, cluster 8", "fp32", None, None, ("cluster8", "friction")),
    ("no barrier, cluster 8", "fp32", None, None, ("cluster8", "sync")),
    ("no friction, no gather, cluster 8", "fp32", None, None, ("cluster8", "friction", "gather")),
    ("loop only, cluster 8", "fp32", None, None, ("cluster8", "friction", "gather", "sync")),
    ("full, fast math, cluster 8", "fp32", None, None, ("cluster8", "fast_math")),
    # the gather's first half of every row only: what a gather split over two threads per patch could save at best
    ("half gather, cluster 8", "fp32", None, None, ("cluster8", "gather_half")),
    ("full, cluster 8, block 448", "fp32", 448, None, ("cluster8",)),  # two threads per patch
    ("half gather, cluster 8, block 448", "fp32", 448, None, ("cluster8", "gather_half")),
    ("half gather, default block", "fp32", None, None, ("gather_half",)),
    # 16 blocks: a "non-portable" cluster (H100/H200)
    ("full, cluster 16", "fp32", None, None, ("cluster16",)),
    ("no gather, cluster 16", "fp32", None, None, ("cluster16", "gather")),
    ("no friction solve, cluster 16", "fp32", None, None, ("cluster16", "friction")),
    ("no friction, no gather, cluster 16", "fp32", None, None, ("cluster16", "friction", "gather")),
    ("loop only, cluster 16", "fp32", None, None, ("cluster16", "friction", "gather", "sync")),
    ("full, cluster 4", "fp64", None, None, ("cluster4",)),
    ("full, cluster 8", "fp64", None, None, ("cluster8",)),
    ("full, cluster 16", "fp64", None, None, ("cluster16",)),
]
# --growth: (label, precision, block_dim (None: the on-chip engine's choice), ablations (with "clusterK" tags as
# above) or None for the general path, event interval × this; 0: no growth)
GROWTH_CASES = [
    ("general path, growth", "fp32", None, None, 1),
    ("no growth", "fp32", 512, (), 0),
    ("growth", "fp32", 512, (), 1),
    ("growth, no contact re-solve", "fp32", 512, ("contact",), 1),
    ("growth, no stiffness update", "fp32", 512, ("coupling",), 1),
    ("growth, no stiffness update, no contact re-solve", "fp32", 512, ("coupling", "contact"), 1),
    ("growth, events 100x rarer", "fp32", 512, (), 100),
    ("growth, no friction solve", "fp32", 512, ("friction",), 1),
    ("growth", "fp64", 512, (), 1),
    ("growth, block 384", "fp32", 384, (), 1),
    ("growth, block 384, events 100x rarer", "fp32", 384, (), 100),
    ("no growth, cluster 8", "fp32", None, ("cluster8",), 0),
    ("growth, cluster 2", "fp32", None, ("cluster2",), 1),
    ("growth, cluster 4", "fp32", None, ("cluster4",), 1),
    ("growth, cluster 8", "fp32", None, ("cluster8",), 1),
    ("growth, cluster 8, no contact re-solve", "fp32", None, ("cluster8", "contact"), 1),
    ("growth, cluster 8, no stiffness update", "fp32", None, ("cluster8", "coupling"), 1),
    ("growth, cluster 8, events 100x rarer", "fp32", None, ("cluster8",), 100),
    ("growth, cluster 8, no friction solve", "fp32", None, ("cluster8", "friction"), 1),
    ("no growth, cluster 8, no friction solve", "fp32", None, ("cluster8", "friction"), 0),
    ("no growth, cluster 8, no gather", "fp32", None, ("cluster8", "gather"), 0),
    ("growth, cluster 16", "fp32", None, ("cluster16",), 1),
    ("growth, cluster 8", "fp64", None, ("cluster8",), 1),
    ("growth, cluster 2, block 384", "fp32", 384, ("cluster2",), 1),
    ("growth, cluster 4, block 384", "fp32", 384, ("cluster4",), 1),
    ("growth, cluster 4, block 256", "fp32", 256, ("cluster4",), 1),
]


def _parse(argv: list[str] | None) -> argparse.Namespace:
    """The command line, with its combinations checked."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="Warp device (default cuda:0)")
    ap.add_argument("--window", type=positive, default=1e-4, help="simulated time per timed run [s] (default 1e-4)")
    ap.add_argument("--sample-dt", type=positive, default=1e-5, help="sample interval [s] (default 1e-5)")
    ap.add_argument("--dt", type=positive, default=1e-8, help="time step [s] (default 1e-8)")
    ap.add_argument("--growth", action="store_true", help="profile the growing varying-area pad (GROWTH_CASES)")
    ap.add_argument("--state", type=Path, help="with --growth: start from this varying_area.py state file")
    ap.add_argument(
        "--growth-dt",
        type=positive,
        default=None,
        help="with --growth: simulated time between growth events [s] (default: the scene's interval, 2.02e-7; "
        "strang's default spacing in the hf command is 5e-6), × the case's factor for the rarer-event cases",
    )
    ap.add_argument("--crossing", choices=("point", "mean"), default=None,
                    help="treatment of zero-slip crossings (default: the batch's default)")  # fmt: skip
    ap.add_argument("--saturate", type=positive, default=None,
                    help="run the batch this long first [s] and profile from the state it reached")  # fmt: skip
    ap.add_argument("--only", nargs="*", default=None, help="labels of the cases to run (default: all)")
    ap.add_argument(
        "--pads", type=int, default=1, help="identical pads in the batch (default 1; e.g. 1024: the batched target)"
    )
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument("--markdown", type=Path, default=None, help="write a table here")
    args = ap.parse_args(argv)
    if args.state and not args.growth:
        ap.error("--state needs --growth")
    if args.growth_dt is not None and not args.growth:
        ap.error("--growth-dt needs --growth")
    if args.pads < 1:
        ap.error("--pads must be ≥ 1")
    if args.state and args.pads != 1:
        ap.error("--state holds one pad: use it with --pads 1")
    if args.saturate is not None and args.growth:
        ap.error("--saturate profiles a batch that does not grow: leave out --growth (or start from --state)")
    try:
        get_device(args.device)
    except SceneError as e:
        ap.error(str(e))
    return args


def _cases(growth: bool) -> list[tuple]:
    """(label, precision, block_dim, csr_shared, ablations, event interval factor) of every case to profile."""
    if growth:
        return [(label, prec, block, None, abl, k) for label, prec, block, abl, k in GROWTH_CASES]
    return [(label, prec, block, csr, abl, 1) for label, prec, block, csr, abl in
            [("general path", "fp32", None, None, None), *CASES]]  # fmt: skip


def _put(arr, values) -> None:
    """Copy the NumPy array ``values`` into the Warp array ``arr`` (converted to its dtype)."""
    import warp as wp

    arr.assign(values.astype(wp.dtype_to_numpy(arr.dtype)))


def _start(model, saved: dict | None):
    """A fresh state of ``model``, its u [m] and v [m/s] taken from the saved state file where given."""
    from aca_warp.hf.state import initial_state

    st = initial_state(model)
    if saved is not None:
        _put(st.u, saved["u"])
        _put(st.v, saved["v"])
    return st


def _case_model(args: argparse.Namespace, scene, model, prec: str, k: int, saved: dict | None):
    """The model of one case: ``model``, or with --growth and an event interval factor ``k`` other than 1 one built
    with the events ``k`` times rarer (0: no growth); the grown arrays of the state file (``--state``) put in."""
    from aca_warp.hf.model import build_model
    from aca_warp.hf.solver import GROWTH_MUTABLE

    if args.growth and k != 1:
        g = None if k == 0 else dataclasses.replace(scene.growth, interval=scene.growth.interval * k)
        model = build_model([scene.replace(growth=g)] * args.pads, device=args.device, precision=prec)
    if args.state is not None:
        for k2 in (k3 for k3 in GROWTH_MUTABLE if k3 in model.arrays):  # a model without growth lacks some
            _put(model.arrays[k2], saved[f"model_{k2}"])
    return model


def _case_runner(args: argparse.Namespace, model, block, csr, abl, k: int):
    """``fn(state, duration)``: one run of the case, the general path (``abl`` None) or the on-chip engine with
    the case's block size, CSR placement, ablations, fast-math and cluster tags; growth events ``--growth-dt`` × ``k``
    apart where --growth-dt is given and the case grows."""
    from aca_warp.hf.loop import EngineTuning, run_hf
    from aca_warp.hf.options import RunOptions

    growth_dt = None if args.growth_dt is None or k == 0 else args.growth_dt * k
    if abl is None:

        def fn(st, duration, model=model):
            options = RunOptions(
                duration=duration, dt=args.dt, engine="general", growth_dt=growth_dt, crossing=args.crossing
            )
            return run_hf(model, st, options)
    else:

        def fn(st, duration, model=model, block=block, csr=csr, abl=abl):
            tags = {a for a in abl if a == "fast_math" or a.startswith("cluster")}
            cluster = max([int(a[7:]) for a in tags if a.startswith("cluster")], default=1)
            tuning = EngineTuning(block_dim=block, csr_shared=csr, ablate=frozenset(abl) - tags, cluster=cluster)
            options = RunOptions(
                engine="onchip",
                duration=duration,
                dt=args.dt,
                fast_math="fast_math" in abl,
                growth_dt=growth_dt,
                crossing=args.crossing,
            )
            return run_hf(model, st, options, tuning=tuning)

    return fn


def _saturated(args: argparse.Namespace, model) -> dict:
    """The synchronous state (u [m], v [m/s]) the batch reaches after ``--saturate`` seconds with the on-chip
    engine's defaults from its start (``--dt``, ``--crossing``)."""
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state

    st = initial_state(model)
    res = run_hf(model, st, RunOptions(engine="onchip", duration=args.saturate, dt=args.dt, crossing=args.crossing))
    if not res.complete:
        raise SceneError(f"the saturating run stopped at {res.steps} steps")
    return {"u": st.u.numpy(), "v": st.v.numpy()}


def _time_case(row: dict, fn, model, args: argparse.Namespace, saved: dict | None) -> None:
    """Warm up (one sample interval), then time a window; the times [s] and rates into ``row``, or its error."""
    from aca_warp.common.errors import SceneError

    try:
        t = time.perf_counter()
        fn(_start(model, saved), args.sample_dt)
        row["warmup_s"] = time.perf_counter() - t
        res = fn(_start(model, saved), args.window)
        row.update(steps=res.steps, wall_s=res.wall_time, us_per_step=1e6 * res.wall_time / res.steps)
        row["blocks_per_pad"] = res.blocks_per_pad
        row["patch_steps_per_s"] = model.patch_count * res.steps / res.wall_time
    except (SceneError, RuntimeError) as exc:  # e.g. too many resources for a 1024-thread block
        row["error"] = str(exc).splitlines()[0][:200]


def _markdown_lines(args: argparse.Namespace, name: str, patches: int, rows: list[dict], info: dict) -> list[str]:
    """The Markdown table of the rows, under a line naming the pad, steps, machine and Warp version."""
    import warp as wp

    lines = [
        f"On-chip ablation profile: {name} ({patches} patches), {args.pads} pad(s), "
        f"dt {args.dt:g} s, "
        f"{f'growth events every {args.growth_dt:g} s (× the case factor), ' if args.growth_dt else ''}"
        f"{rows[0].get('steps', '?')} steps"
        f"{f' from {args.state.name}' if args.state else ''}"
        f"{f' from the state after {args.saturate:g} s' if args.saturate else ''}"
        f"{f', crossings {args.crossing}' if args.crossing else ''}, "
        f"sample interval {args.sample_dt:g} s; {info.get('device_name', args.device)}, Warp "
        f"{wp.__version__} (scripts/profile_onchip.py)",
        "",
        "| case | precision | block | µs/step | patch-steps/s |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        t = f"{r['us_per_step']:.2f} | {r['patch_steps_per_s']:.3g}" if "us_per_step" in r else f"{r['error']} | –"
        lines.append(f"| {r['case']} | {r['precision']} | {r['block_dim'] or '–'} | {t} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)

    import warp as wp

    from aca_warp.common.files import machine
    from aca_warp.hf.model import build_model
    from aca_warp.scene import Record, preset

    name = "varying_area" if args.growth else "hf1"
    scene = preset(name).replace(record=Record(sample_dt=args.sample_dt))
    models = {p: build_model([scene] * args.pads, device=args.device, precision=p) for p in ("fp32", "fp64")}
    cases = _cases(args.growth)

    saved = dict(np.load(args.state)) if args.state else None  # read once, put into every case's model and state
    if args.saturate is not None:
        try:
            saved = _saturated(args, models["fp32"])
        except SceneError as e:
            print(f"profile_onchip: the run to --saturate {args.saturate:g} s failed: {e}", file=sys.stderr)
            return 1
    rows = []
    for label, prec, block, csr, abl, k in cases:
        key = f"{label} [{prec}]"
        if args.only is not None and label not in args.only and key not in args.only:
            continue
        model = _case_model(args, scene, models[prec], prec, k, saved)
        fn = _case_runner(args, model, block, csr, abl, k)
        row = {"case": label, "precision": prec, "block_dim": block, "csr_shared": csr, "ablate": list(abl or ())}
        if args.growth:
            row["growth_interval_factor"] = k
        _time_case(row, fn, model, args, saved)
        rows.append(row)
        print(f"{key:52s} " + (f"{row['us_per_step']:8.2f} us/step" if "us_per_step" in row else row["error"]),
              flush=True)  # fmt: skip
    info = {**machine(models["fp32"].device), "warp_version": wp.__version__, "dt": args.dt, "window_s": args.window,
            "saturate_s": args.saturate, "crossing": args.crossing or "the batch's default",
            "sample_dt": args.sample_dt, "growth_dt": args.growth_dt}  # fmt: skip
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"machine": info, "rows": rows}, indent=1))
    if args.markdown:
        lines = _markdown_lines(args, name, models["fp32"].patch_count, rows, info)
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
