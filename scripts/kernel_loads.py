#!/usr/bin/env python3
"""Where a run's kernel compiles go: into its set-up (``RunResult.compile_time``) or into its stepping time
(``RunResult.wall_time``, which the studies' work-precision and the benchmarks compare).

Per case (integrator, engine, strang's crossing treatment; one pad of the hf1 physics, a 40-patch sector, fp64, 4 µs, on
``--device``: the CPU by default) a process of its own runs it, every Warp module unloaded first, and reports the run's
set-up and stepping times and the kernel modules loaded before and during its stepping (a module loaded at its first
launch, inside the stepping). ``--cold``: each case with an empty kernel cache of its own, so that a load is a compile
(seconds on the CPU); without it the cache of this machine (a load then takes milliseconds, but is still listed). Every
checkout given (default: this one) runs every case; a checkout of an earlier commit (e.g. ``git worktree add /tmp/old
<commit>``) shows what a change moved. JSON and a Markdown table into ``--out``. Examples::

    python3 scripts/kernel_loads.py --out /tmp/loads
    python3 scripts/kernel_loads.py /tmp/old . --cold --out docs/benchmarks/kernel_loads
    python3 scripts/kernel_loads.py /tmp/old . --cold --device cuda:0 --out $OUT/kernel_loads_cuda
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from compare_checkouts import package_view, refuse_bad_checkouts

# (integrator, engine, crossing): every path that launches kernels of its own
CASES = [
    ("strang", "general", "point"),
    ("strang", "general", "mean"),
    ("strang", "onchip", "point"),
    ("strang", "onchip", "mean"),
    ("symplectic-euler", "general", "point"),
    ("implicit-friction", "general", "point"),
    ("adaptive", "general", "point"),
    ("controlled", "general", "point"),
    ("auto", "general", "point"),
    ("adaptive", "onchip", "point"),
]

# runs the cases of argv[2] (JSON) on device argv[3] with the package first on sys.path (argv[1]: a package view, or
# "" for the installed one); prints one JSON line: per case the set-up's and the stepping's loads and times
CHILD = r"""
import json, sys
if sys.argv[1]:
    sys.path.insert(0, sys.argv[1])
import aca_warp
assert not sys.argv[1] or aca_warp.__file__.startswith(sys.argv[1]), aca_warp.__file__
from aca_warp.common.devices import init_warp
init_warp()
import warp._src.context as wc
import aca_warp.hf.loop as loop
from aca_warp.hf.options import RunOptions
from aca_warp.scene import Record
from aca_warp.studies.friction_stats import sector_scenes
from aca_warp.studies.runs import batch_at_start

stepping = [False]
loads = {"setup": [], "stepping": []}
original_load, original_loop = wc.Module.load, loop._Run.loop

def load(self, device, *args, **kwargs):  # lists a module loaded on a device for the first time
    context = wc.runtime.get_device(device).context
    if not any(key[0] == context for key in self.execs):
        loads["stepping" if stepping[0] else "setup"].append(self.name)
    return original_load(self, device, *args, **kwargs)

def timed_loop(self, *args, **kwargs):
    stepping[0] = True
    return original_loop(self, *args, **kwargs)

wc.Module.load, loop._Run.loop = load, timed_loop
out = []
for integrator, engine, crossing in json.loads(sys.argv[2]):
    for module in list(wc.user_modules.values()):
        module.unload()
    stepping[0] = False
    loads = {"setup": [], "stepping": []}
    model, state = batch_at_start(sector_scenes(1, 40), sys.argv[3], "fp64")
    dt = None if integrator in ("adaptive", "controlled", "auto") else 2.5e-7
    options = RunOptions(integrator=integrator, engine=engine, crossing=crossing, duration=4e-6, dt=dt, force=True)
    res = loop.run_hf(model, state, options, record=Record(sample_dt=1e-6))
    out.append({"case": [integrator, engine, crossing], "complete": bool(res.complete),
                "compile_s": res.compile_time, "wall_s": res.wall_time, **loads})
print(json.dumps(out))
"""


def run_cases(
    cases: list[tuple[str, str, str]], view: Path | None = None, cache: Path | None = None, device: str = "cpu"
) -> list[dict]:
    """The cases in one process on ``device`` (the package of ``view``, default the installed one; Warp's kernel
    cache ``cache``, default this machine's): per case its ``setup`` and ``stepping`` module loads, ``compile_s``
    and ``wall_s``."""
    env = dict(os.environ)
    if cache is not None:
        env["WARP_CACHE_PATH"] = str(cache)
    cmd = [sys.executable, "-c", CHILD, "" if view is None else str(view), json.dumps(cases), device]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800)
    if done.returncode != 0:
        raise RuntimeError(f"the cases failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def label(checkout: Path) -> str:
    """The checkout's commit (short hash, "+ changes" where its package differs from it) where it is the top of a git
    work tree, else its path."""
    git = ["git", "-C", str(checkout)]
    top = subprocess.run([*git, "rev-parse", "--show-toplevel"], capture_output=True, text=True)
    if top.returncode != 0 or Path(top.stdout.strip()).resolve() != checkout.resolve():
        return str(checkout)
    head = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    dirty = subprocess.run([*git, "diff", "--quiet", "HEAD", "--", "aca_warp", "kernels"]).returncode != 0
    return head.stdout.strip() + (" + changes" if dirty else "")


def table(rows: list[dict]) -> str:
    """The Markdown table of the rows: per checkout and case the times and the modules loaded while stepping."""
    lines = [
        "| checkout | integrator, engine, crossing | set-up [s] | stepping [s] | loaded while stepping |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        loaded = ", ".join(f"`{m}`" for m in r["stepping"]) or "none"
        case = ", ".join(r["case"])
        lines.append(f"| {r['checkout']} | {case} | {r['compile_s']:.2f} | {r['wall_s']:.2f} | {loaded} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    doc = __doc__ or ""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0], epilog=doc.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("checkouts", nargs="*", type=Path, help="checkouts of aca_warp (default: this one)")
    ap.add_argument("--device", default="cpu", help="the device the runs take: cpu (default) or cuda:N")
    names = [":".join(c) for c in CASES]
    said = "the cases, as integrator:engine:crossing (default: all: " + " ".join(names) + ")"
    ap.add_argument("--cases", nargs="+", choices=names, default=names, metavar="CASE", help=said)
    ap.add_argument("--cold", action="store_true", help="every case with an empty kernel cache of its own")
    ap.add_argument("--out", type=Path, required=True, help="folder for kernel_loads.json and kernel_loads.md")
    args = ap.parse_args(argv)
    checkouts = args.checkouts or [Path(__file__).resolve().parent.parent]
    refuse_bad_checkouts(ap, checkouts)
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import machine

    try:
        device = get_device(args.device)
    except SceneError as e:
        ap.error(f"--device: {e}")

    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, checkout in enumerate(checkouts):
            view = package_view(checkout.resolve(), Path(tmp) / f"v{i}")
            cases = [c for c in CASES if ":".join(c) in args.cases]
            for group in [[c] for c in cases] if args.cold else [cases]:
                cache = Path(tmp) / f"cache{i}_{len(rows)}" if args.cold else None
                for r in run_cases(group, view, cache, args.device):
                    rows.append({"checkout": label(checkout), **r})
                    said = f"{', '.join(r['case'])}: set-up {r['compile_s']:.2f} s, stepping {r['wall_s']:.2f} s"
                    print(f"{rows[-1]['checkout']}: {said}, loaded while stepping: {r['stepping']}")
    args.out.mkdir(parents=True, exist_ok=True)
    doc_out = {"command": "scripts/kernel_loads.py " + " ".join(argv if argv is not None else sys.argv[1:]),
               "machine": machine(device), "cold": args.cold, "rows": rows}  # fmt: skip
    (args.out / "kernel_loads.json").write_text(json.dumps(doc_out, indent=1) + "\n")
    (args.out / "kernel_loads.md").write_text(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
