#!/usr/bin/env python3
"""Where a run's kernel compiles go: into its set-up (``RunResult.compile_time``) or into its stepping time
(``RunResult.wall_time``, which the studies' work-precision and the benchmarks compare).

Per case (integrator, engine, strang's crossing treatment and a variant: plain, growing patches, or Warp's cooperative
CPU blocks on; one pad of the hf1 physics, a 40-patch sector, fp64, 4 µs, on ``--device``: the CPU by default) a run
after every Warp module was unloaded, reporting its set-up and stepping times and the kernel module variants (a
module compiles once per block size) loaded in its set-up, inside a graph capture (which the run counts as set-up)
and while it stepped: a variant loaded at its first launch, inside the stepping. ``--cold``: each case in a process of
its own with an empty kernel cache, so that a load is a compile (seconds); without it a checkout's cases share one
process and this machine's cache (a load then takes milliseconds, but is still listed). Every checkout given
(default: this one) runs the cases; a checkout of an earlier commit (e.g. ``git worktree add /tmp/old <commit>``)
shows what a change moved. JSON and a Markdown table into ``--out``. Examples::

    python3 scripts/kernel_loads.py --out /tmp/loads
    python3 scripts/kernel_loads.py /tmp/old . --cold --out docs/benchmarks/kernel_loads
    python3 scripts/kernel_loads.py /tmp/old . --cold --device cuda:0 --out /tmp/kernel_loads_cuda
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from compare_checkouts import package_view, refuse_bad_checkouts

# (integrator, engine, crossing, variant): every path that launches kernels of its own. Variants: "plain", "growth"
# (the pad's patches grow, an event every 1 µs), "cpu-blocks" (Warp's cooperative CPU blocks on, so that a launch in
# blocks takes its real block size on the CPU as on CUDA: a module compiles once per block size) and both
CASES = [
    ("strang", "general", "point", "plain"),
    ("strang", "general", "mean", "plain"),
    ("strang", "onchip", "point", "plain"),
    ("strang", "onchip", "mean", "plain"),
    ("symplectic-euler", "general", "point", "plain"),
    ("implicit-friction", "general", "point", "plain"),
    ("adaptive", "general", "point", "plain"),
    ("controlled", "general", "point", "plain"),
    ("auto", "general", "point", "plain"),
    ("adaptive", "onchip", "point", "plain"),
    ("strang", "general", "point", "growth"),
    ("strang", "onchip", "point", "growth"),
    ("adaptive", "general", "point", "growth"),
    ("strang", "onchip", "point", "cpu-blocks"),
    ("adaptive", "onchip", "point", "cpu-blocks"),
    ("strang", "general", "mean", "cpu-blocks"),
    ("adaptive", "general", "point", "cpu-blocks"),
    ("controlled", "general", "point", "cpu-blocks"),
    ("auto", "general", "point", "cpu-blocks"),
    ("strang", "general", "point", "growth-cpu-blocks"),
]

# runs the cases of argv[2] (JSON) on device argv[3] with the package first on sys.path (argv[1]: a package view, or
# "" for the installed one); prints one JSON line: per case the modules loaded (name, block size) in the run's set-up,
# inside a graph capture (which the run counts as set-up) and while it stepped, and its times
CHILD = r"""
import json, sys
if sys.argv[1]:
    sys.path.insert(0, sys.argv[1])
import aca_warp, aca_warp.kernels
for m in (aca_warp, aca_warp.kernels):
    assert not sys.argv[1] or m.__file__.startswith(sys.argv[1]), m.__file__
from aca_warp.common.devices import init_warp
init_warp()
import warp as wp
import warp._src.context as wc
import aca_warp.hf.loop as loop
from aca_warp.hf.options import RunOptions
from aca_warp.scene import Record
from aca_warp.scene.parts import Growth
from aca_warp.studies.friction_stats import sector_scenes
from aca_warp.studies.runs import batch_at_start

phase = ["setup"]
loads = {}
original_load, original_loop = wc.Module.load, loop._Run.loop
enter, leave = wp.ScopedCapture.__enter__, wp.ScopedCapture.__exit__

def load(self, device, block_dim=None, *args, **kwargs):  # lists a module variant loaded for the first time
    dim = block_dim if block_dim is not None else self.options["block_dim"]  # as Module.load resolves it
    if (wc.runtime.get_device(device).context, dim) not in self.execs:
        loads[phase[-1]].append([self.name, dim])
    return original_load(self, device, block_dim, *args, **kwargs)

def timed_loop(self, *args, **kwargs):
    phase.append("stepping")
    return original_loop(self, *args, **kwargs)

def capture_enter(self):
    phase.append("capture")
    return enter(self)

def capture_leave(self, *args):
    phase.pop()
    return leave(self, *args)

wc.Module.load, loop._Run.loop = load, timed_loop
wp.ScopedCapture.__enter__, wp.ScopedCapture.__exit__ = capture_enter, capture_leave
out = []
for integrator, engine, crossing, variant in json.loads(sys.argv[2]):
    for module in list(wc.user_modules.values()):
        module.unload()
    phase[:] = ["setup"]
    loads = {"setup": [], "capture": [], "stepping": []}
    wp.config.enable_cpu_blocks = variant.endswith("cpu-blocks")
    scene = sector_scenes(1, 40)[0]
    if variant.startswith("growth"):
        scene = scene.replace(growth=Growth(increment=1e-9, interval=1e-6))
    model, state = batch_at_start([scene], sys.argv[3], "fp64")
    dt = None if integrator in ("adaptive", "controlled", "auto") else 2.5e-7
    options = RunOptions(integrator=integrator, engine=engine, crossing=crossing, duration=4e-6, dt=dt, force=True)
    res = loop.run_hf(model, state, options, record=Record(sample_dt=1e-6))
    out.append({"case": [integrator, engine, crossing, variant], "complete": bool(res.complete),
                "compile_s": res.compile_time, "wall_s": res.wall_time, **loads})
print(json.dumps(out))
"""


def run_cases(
    cases: list[tuple[str, str, str, str]], view: Path | None = None, cache: Path | None = None, device: str = "cpu"
) -> list[dict]:
    """The cases in one process on ``device`` (the package of ``view``, default the installed one; Warp's kernel
    cache ``cache``, default this machine's), every Warp module unloaded before each: per case its module loads
    (``setup``, ``capture``, ``stepping``: [name, block size] each), ``compile_s`` and ``wall_s`` [s]. A case that
    fails raises RuntimeError with the last line of the process's error output."""
    env = dict(os.environ)
    if cache is not None:
        env["WARP_CACHE_PATH"] = str(cache)
    cmd = [sys.executable, "-c", CHILD, "" if view is None else str(view), json.dumps(cases), device]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no error output"])[-1]
        raise RuntimeError(f"the cases failed (exit {done.returncode}): {last}")
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


def modules_text(loads: list[list[Any]]) -> str:
    """Module variants as Markdown: `name` (block size), or "none"."""
    return ", ".join(f"`{name}` ({dim})" for name, dim in loads) or "none"


def table(rows: list[dict]) -> str:
    """The Markdown table of the rows: per checkout and case the times, the module variants (block size in
    parentheses) loaded inside a graph capture, which the run counts as set-up, and those loaded while stepping."""
    lines = [
        "| checkout | integrator, engine, crossing, variant | set-up [s] | stepping [s] | loaded in a capture "
        "| loaded while stepping |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        case, times = ", ".join(r["case"]), f"{r['compile_s']:.2f} | {r['wall_s']:.2f}"
        loaded = f"{modules_text(r['capture'])} | {modules_text(r['stepping'])}"
        lines.append(f"| {r['checkout']} | {case} | {times} | {loaded} |")
    return "\n".join(lines) + "\n"


def parse(argv: list[str] | None) -> argparse.Namespace:
    """The command line, checked (exit 2 and one line on bad input); ``checkouts``, ``labels`` and ``device`` filled
    in."""
    doc = __doc__ or ""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0], epilog=doc.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("checkouts", nargs="*", type=Path, help="checkouts of aca_warp (default: this one)")
    ap.add_argument("--device", default="cpu", help="the device the runs take: cpu (default) or cuda:N")
    names = [":".join(c) for c in CASES]
    said = "the cases, as integrator:engine:crossing:variant (default: all: " + " ".join(names) + ")"
    ap.add_argument("--cases", nargs="+", choices=names, default=names, metavar="CASE", help=said)
    ap.add_argument("--cold", action="store_true", help="every case in a process of its own, its kernel cache empty")
    ap.add_argument("--labels", nargs="+", help="the checkouts' names in the record (default: commit or path)")
    ap.add_argument("--out", type=Path, required=True, help="folder for kernel_loads.json and kernel_loads.md")
    args = ap.parse_args(argv)
    args.checkouts = args.checkouts or [Path(__file__).resolve().parent.parent]
    refuse_bad_checkouts(ap, args.checkouts)
    if args.labels is not None and len(args.labels) != len(args.checkouts):
        ap.error(f"--labels: give one name per checkout ({len(args.checkouts)}), got {len(args.labels)}")
    args.labels = args.labels or [label(c) for c in args.checkouts]
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import SceneError

    try:
        args.device = get_device(args.device)
    except SceneError as e:
        ap.error(f"--device: {e}")
    return args


def measure(args: argparse.Namespace) -> list[dict]:
    """Every asked case of every checkout (each in a process of its own with ``--cold``), a line per case on stdout;
    the rows of the record. RuntimeError (one line) when a case fails."""
    rows: list[dict] = []
    cases = [c for c in CASES if ":".join(c) in args.cases]
    with tempfile.TemporaryDirectory() as tmp:
        for i, (checkout, name) in enumerate(zip(args.checkouts, args.labels, strict=True)):
            view = package_view(checkout.resolve(), Path(tmp) / f"v{i}")
            for group in [[c] for c in cases] if args.cold else [cases]:
                cache = Path(tmp) / f"cache{i}_{len(rows)}" if args.cold else None
                try:
                    done = run_cases(group, view, cache, str(args.device))
                except RuntimeError as e:
                    raise RuntimeError(f"{name}: {e}") from None
                for r in done:
                    rows.append({"checkout": name, **r})
                    said = f"{', '.join(r['case'])}: set-up {r['compile_s']:.2f} s, stepping {r['wall_s']:.2f} s"
                    print(f"{name}: {said}, loaded while stepping: {modules_text(r['stepping'])}")
    return rows


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    try:
        rows = measure(args)
    except RuntimeError as e:
        print(f"kernel_loads: {e}", file=sys.stderr)
        return 1
    from aca_warp.common.files import machine

    args.out.mkdir(parents=True, exist_ok=True)
    doc_out = {"command": "scripts/kernel_loads.py " + " ".join(argv if argv is not None else sys.argv[1:]),
               "machine": machine(args.device), "cold": args.cold, "rows": rows}  # fmt: skip
    (args.out / "kernel_loads.json").write_text(json.dumps(doc_out, indent=1) + "\n")
    (args.out / "kernel_loads.md").write_text(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
