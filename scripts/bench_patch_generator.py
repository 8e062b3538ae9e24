#!/usr/bin/env python3
"""Time the patch generator of one or two checkouts and check that they place the same patches.

A sweep over patch seeds makes one layout per pad before it runs (random sequential addition,
``aca_warp.scene.generator.PatchGenerator``), so the generator's speed bounds how fast its shards are prepared. Per
checkout, in its own Python process, this generates the layouts of ``--seeds`` seeds for each case (a preset's pad
with its patch count and areas: hf1's, which hf3 and varying_area share, and hf2's, which hf4 shares; and a
4000-patch and a 200-patch variant) and reports the wall time and a SHA-256 of every layout's x, y and area bytes;
with two checkouts the hashes must agree (exit 1 otherwise). JSON and a Markdown table into ``--out``. Example
(the baseline checkout from ``git archive``)::

    python3 scripts/bench_patch_generator.py build/base . --seeds 50 --out out/patch_generator
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from compare_checkouts import package_view, refuse_bad_checkouts

from aca_warp.cli import Parser
from aca_warp.common.argtypes import int_at_least

# (preset whose pad is used, patch count, area_min, area_max [m²])
CASES = [
    ("hf1", 1758, 2e-8, 8e-8),  # hf1, hf3 and varying_area
    ("hf2", 1758, 5e-7, 2e-6),  # hf2 and hf4: larger patches, a fifth of the pad covered
    ("varying_area", 4000, 2e-8, 6e-8),
    ("hf3", 200, 1e-7, 4e-7),
]

CHILD = """
import hashlib, json, sys, time
sys.path.insert(0, sys.argv[1])
import aca_warp
assert aca_warp.__file__.startswith(sys.argv[1]), aca_warp.__file__
from aca_warp.scene import preset
from aca_warp.scene.generator import PatchGenerator
a = json.loads(sys.argv[2])
out = []
for name, count, amin, amax in a["cases"]:
    pad, digest, t = preset(name).pad, hashlib.sha256(), 0.0
    for seed in range(1, a["seeds"] + 1):
        t0 = time.perf_counter()
        p = PatchGenerator(count=count, area_min=amin, area_max=amax, seed=seed).generate(pad)
        t += time.perf_counter() - t0
        for v in (p.x, p.y, p.area):
            digest.update(v.tobytes())
    out.append({"case": [name, count, amin, amax], "wall_s": t, "sha256": digest.hexdigest()})
print(json.dumps(out))
"""


def run_checkout(checkout: Path, work: Path, seeds: int) -> list[dict]:
    """The child's rows for one checkout (its own package view and process)."""
    view = package_view(checkout, work)
    arg = json.dumps({"cases": CASES, "seeds": seeds})
    done = subprocess.run([sys.executable, "-c", CHILD, str(view), arg], capture_output=True, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise RuntimeError(f"{checkout}: {last}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("checkouts", nargs="+", type=Path, metavar="CHECKOUT", help="one or two checkouts (folders)")
    ap.add_argument("--seeds", type=int_at_least(1), default=20, help="seeds per case (default 20)")
    ap.add_argument("--out", default="out/patch_generator", help="folder of the JSON and Markdown results")
    args = ap.parse_args(argv)
    if len(args.checkouts) > 2:
        ap.error("give one or two checkouts")
    refuse_bad_checkouts(ap, args.checkouts)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            runs = [run_checkout(c.resolve(), Path(tmp) / f"c{k}", args.seeds) for k, c in enumerate(args.checkouts)]
        except RuntimeError as e:
            print(f"bench_patch_generator: {e}", file=sys.stderr)
            return 3
    same = None if len(runs) == 1 else all(a["sha256"] == b["sha256"] for a, b in zip(*runs, strict=True))
    head = "| case (pad, patches) | " + " | ".join(f"{c} [s]" for c in args.checkouts) + " |"
    lines = [
        f"Patch layouts of seeds 1–{args.seeds} per case (`python3 scripts/bench_patch_generator.py`), wall time "
        "of the generator.",
        "",
        head,
        "|---" * (1 + len(runs)) + "|",
        *(
            f"| {rows[0]['case'][0]}, {rows[0]['case'][1]} | " + " | ".join(f"{r['wall_s']:.2f}" for r in rows) + " |"
            for rows in zip(*runs, strict=True)
        ),
    ]
    if same is not None:
        lines += ["", f"Every layout bit for bit the same in both: {same}."]
    doc = {"seeds": args.seeds, "checkouts": [str(c) for c in args.checkouts], "runs": runs, "identical": same}
    (out / "patch_generator.json").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "patch_generator.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0 if same in (None, True) else 1


if __name__ == "__main__":
    raise SystemExit(main())
