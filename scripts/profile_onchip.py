#!/usr/bin/env python3
"""Where the on-chip HF kernel spends its time: ablation profile on one hf1 pad.

Times ``aca_warp.onchip.run_onchip`` on one pad for a window of steps with parts of the step left out
(``ablate``: the implicit friction solve → an explicit kick, the neighbour gather, the block barrier; the results
of an ablated run are wrong and only its time counts), for several block sizes, with the CSR in shared or global
memory, fp32 and fp64, and the general per-step path for comparison. The difference between two rows is the
cost of the part left out. Writes a JSON list and a Markdown table.

Example (GPU machine)::

    python3 scripts/profile_onchip.py --device cuda:0 --json $OUT/profile_onchip.json --markdown $OUT/profile.md
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

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
]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0", help="Warp device (default cuda:0)")
    ap.add_argument("--window", type=float, default=1e-4, help="simulated time per timed run [s] (default 1e-4)")
    ap.add_argument("--sample-dt", type=float, default=1e-5, help="sample interval [s] (default 1e-5)")
    ap.add_argument("--dt", type=float, default=1e-8, help="time step [s] (default 1e-8)")
    ap.add_argument("--only", nargs="*", default=None, help="labels of the cases to run (default: all)")
    ap.add_argument("--json", type=Path, default=None, help="write the rows here")
    ap.add_argument("--markdown", type=Path, default=None, help="write a table here")
    args = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    wp.init()
    from aca_warp.errors import SceneError
    from aca_warp.hf import run_hf
    from aca_warp.io import machine
    from aca_warp.model import build_model
    from aca_warp.onchip import run_onchip
    from aca_warp.scene import Record, preset
    from aca_warp.state import initial_state

    scene = preset("hf1").replace(record=Record(sample_dt=args.sample_dt))
    models = {p: build_model([scene], device=args.device, precision=p) for p in ("fp32", "fp64")}
    rows = []
    cases = [("general path", "fp32", None, None, None), *CASES]
    for label, prec, block, csr, abl in cases:
        key = f"{label} [{prec}]"
        if args.only is not None and label not in args.only and key not in args.only:
            continue
        model = models[prec]
        if abl is None:

            def fn(st, duration, model=model):
                return run_hf(model, st, duration=duration, dt=args.dt)
        else:

            def fn(st, duration, model=model, block=block, csr=csr, abl=abl):
                return run_onchip(
                    model, st, duration=duration, dt=args.dt, block_dim=block, csr_shared=csr,
                    ablate=frozenset(abl) - {"fast_math"}, fast_math="fast_math" in abl,
                )  # fmt: skip

        row = {"case": label, "precision": prec, "block_dim": block, "csr_shared": csr, "ablate": list(abl or ())}
        try:
            t = time.perf_counter()
            fn(initial_state(model), args.sample_dt)
            row["warmup_s"] = time.perf_counter() - t
            res = fn(initial_state(model), args.window)
            row.update(steps=res.steps, wall_s=res.wall_time, us_per_step=1e6 * res.wall_time / res.steps)
            row["patch_steps_per_s"] = model.patch_count * res.steps / res.wall_time
        except (SceneError, RuntimeError) as exc:  # e.g. too many resources for a 1024-thread block
            row["error"] = str(exc).splitlines()[0][:200]
        rows.append(row)
        print(f"{key:52s} " + (f"{row['us_per_step']:8.2f} us/step" if "us_per_step" in row else row["error"]),
              flush=True)  # fmt: skip
    info = {**machine(models["fp32"].device), "warp_version": wp.__version__, "dt": args.dt, "window_s": args.window}
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"machine": info, "rows": rows}, indent=1))
    if args.markdown:
        lines = [
            f"On-chip ablation profile: hf1 (1758 patches), one pad, dt {args.dt:g} s, {rows[0].get('steps', '?')} "
            f"steps, sample interval {args.sample_dt:g} s; {info.get('device_name', args.device)}, Warp "
            f"{wp.__version__} (scripts/profile_onchip.py)",
            "",
            "| case | precision | block | µs/step | patch-steps/s |",
            "|---|---|---|---|---|",
        ]
        for r in rows:
            t = f"{r['us_per_step']:.2f} | {r['patch_steps_per_s']:.3g}" if "us_per_step" in r else f"{r['error']} | –"
            lines.append(f"| {r['case']} | {r['precision']} | {r['block_dim'] or '–'} | {t} |")
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
