#!/usr/bin/env python3
"""Validate the on-chip HF kernel on a GPU without ever hanging, then time it briefly.

The on-chip kernel (``aca_warp.hf.onchip``) once never finished on an H100 (docs/onchip.md, "History: the CUDA
hang"). This script runs every CUDA part in a child process with a timeout (the child also dumps its Python stack
and exits on its own shortly before), so a hung kernel costs at most that timeout:

1. **check** (child, ``--check-timeout`` s): the 2-pad hf1 case of ``tests/test_onchip.py`` (two different pads,
   200 steps of 1e-8 s, patch histories, 3 samples per launch) with the general engine and with the on-chip engine,
   fp32 then fp64; passes when μ agrees within rtol 2e-4 (fp32) / 1e-10 (fp64) and the final
   (u, u̇) within that fraction of their maxima (u̇: ×10). Each precision's result is written as soon as it exists.
   ``--growth``: the pads grow 1000× faster than Eq. 10 (an event every 20 steps), and the final areas, link
   stiffnesses and normal forces must agree within rtol too (the in-kernel growth of the on-chip engine).
2. **bench** (child, only if the fp32 check passed; the rest of ``--budget``): on-chip fp32 on one hf1 pad and on
   1024 pads over a ``--window`` [s] window after a warm-up (compile) run: µs/step, steps/s, patch-steps/s; then the
   general path on the same cases while time is left. Rows are appended as they finish.

Outputs in ``--out``: ``onchip_check.json`` (verdicts, errors, timings, the machine), ``onchip_check.md``
(tables), ``log_check.txt`` / ``log_bench.txt`` (child output, with the stack dump on a timeout). Exit code 0 when
the fp32 check passed (and fp64 passed or did not run), 1 otherwise, 2 for a bad argument (a ``--device`` the machine
lacks: nothing run or written). Example (GPU machine, Warp in /tmp/site)::

    PYTHONPATH=/tmp/site python3 scripts/onchip_gpu_check.py --device cuda:0 --out $OUT/onchip_check --budget 80
    PYTHONPATH=/tmp/site python3 scripts/onchip_gpu_check.py --device cuda:0 --out $OUT/growth --growth --no-bench

On a CPU (``--device cpu``) the same runs take seconds per case (smoke test of the script).
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from aca_warp.common.argtypes import int_at_least, int_between, positive
from aca_warp.common.devices import get_device
from aca_warp.common.errors import AcaError
from aca_warp.common.files import check_output_folder
from aca_warp.hf.onchip_layout import MAX_BLOCK, MAX_CLUSTER

RTOL = {"fp32": 2e-4, "fp64": 1e-10}
# adaptive at tolerance ADAPTIVE_TOL: a step decided differently in the last bits of an error near 1 moves the
# results by up to about the tolerance, so the engines are compared to within ten times it
ADAPTIVE_TOL = {"fp32": 1e-5, "fp64": 1e-7}
RTOL_ADAPTIVE = {"fp32": 2e-4, "fp64": 1e-6}


def _write_json(path: Path, obj) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(obj, indent=1))
    os.replace(tmp, path)


def _log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


# ----------------------------------------------------------------------------------------------- child: check
def child_check(args) -> None:
    from aca_warp.scene import Growth, Initial, Record, preset

    out = Path(args.out)
    record = Record(sample_dt=2e-7, patches=("velocity", "displacement"), window=(4e-7, 2e-6), decimation=2)
    s = preset("hf1").replace(record=record)
    scenes = [s, s.replace(normal_force=700.0, angular_velocity=5.0 / 0.13, initial=Initial(perturbation=0.02, seed=3))]
    if args.growth:
        scenes = [x.replace(growth=Growth(increment=1e-6, interval=2e-7)) for x in scenes]
    grown = ("area", "nbr_stiffness", "normal_force") if args.growth else ()
    results = {}
    for precision in args.precisions:
        _check_precision(args, precision, scenes, grown, results, out)
    if not args.growth and args.integrator == "strang":  # beyond the spring limit: the same stop on both engines
        _check_fault(args, results, out)


def _check_precision(args, precision: str, scenes: list, grown: tuple, results: dict, out: Path) -> None:
    """Run the 2-pad case with the general and the on-chip engine in ``precision`` and compare them; the row in
    ``results[precision]``, written to check.json before each run and at the end."""
    import warp as wp

    from aca_warp.common.files import machine
    from aca_warp.hf.loop import EngineTuning, run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state

    row = {"precision": precision, "phase": "start", "block_dim": args.block, "csr_shared": args.csr}
    row.update(growth=bool(args.growth), cluster=args.cluster, integrator=args.integrator)
    adaptive = args.integrator == "adaptive"
    step = {"integrator": "adaptive", "tolerance": ADAPTIVE_TOL[precision]} if adaptive else {"dt": 1e-8}
    results[precision] = row
    runs = {}
    for engine in ("general", "onchip"):
        model = build_model(scenes, device=args.device, precision=precision)
        row.update(machine(model.device), warp_version=wp.__version__)
        state = initial_state(model)
        row["phase"] = f"{engine}: running (compile, launch, flush)"
        _write_json(out / "check.json", results)
        _log(f"{precision} {engine}: start")
        t = time.perf_counter()
        tuning = EngineTuning(samples_per_launch=3, block_dim=args.block, csr_shared=args.csr, cluster=args.cluster)
        res = run_hf(model, state, RunOptions(duration=2e-6, engine=engine, **step), tuning=tuning)
        row[f"{engine}_steps"] = res.steps
        row[f"{engine}_total_s"] = time.perf_counter() - t
        row[f"{engine}_compile_s"] = res.compile_time
        row[f"{engine}_wall_s"] = res.wall_time
        _log(f"{precision} {engine}: done in {row[f'{engine}_total_s']:.2f} s (complete={res.complete})")
        if not (res.complete and (adaptive or res.steps == 200)):
            row["phase"] = f"{engine}: incomplete run ({res.fault})"
            row["passed"] = False
            break
        runs[engine] = (res.collect(), *state.numpy(), {k: model.host(k) for k in grown})
    else:
        _compare_engines(row, runs, precision, grown, (RTOL_ADAPTIVE if adaptive else RTOL)[precision])
    _write_json(out / "check.json", results)


def _compare_engines(row: dict, runs: dict, precision: str, grown: tuple, rtol: float) -> None:
    """The largest relative differences of mu, u [m], u' [m/s] (and the grown arrays) between the on-chip and the
    general run, and the verdict against ``rtol``, into ``row``."""
    import numpy as np

    (cg, ug, vg, ag), (co, uo, vo, ao) = runs["general"], runs["onchip"]
    mu_g, mu_o = cg.globals[:, :, 0], co.globals[:, :, 0]
    row["mu_max_rel_err"] = float(np.max(np.abs(mu_o - mu_g) / np.abs(mu_g)))
    row["u_err_rel_max"] = float(np.abs(uo - ug).max() / np.abs(ug).max())
    row["v_err_rel_max"] = float(np.abs(vo - vg).max() / np.abs(vg).max())
    row["same_sample_times"] = bool(np.array_equal(co.time, cg.time) and co.globals.shape == cg.globals.shape)
    row["rtol"] = rtol
    for k in grown:
        row[f"{k}_err_rel_max"] = float(np.max(np.abs(ao[k] - ag[k]) / np.maximum(np.abs(ag[k]), 1e-300)))
    row["passed"] = bool(
        row["same_sample_times"]
        and row["mu_max_rel_err"] <= rtol
        and row["u_err_rel_max"] <= rtol
        and row["v_err_rel_max"] <= 10 * rtol
        and all(row[f"{k}_err_rel_max"] <= rtol for k in grown)
    )
    row["phase"] = "done"
    _log(
        f"{precision}: passed={row['passed']} dmu/mu={row['mu_max_rel_err']:.2e} "
        f"du={row['u_err_rel_max']:.2e} dv={row['v_err_rel_max']:.2e}"
    )


def _check_fault(args, results: dict, out: Path) -> None:
    """Two hf1 pads forced beyond the spring limit with each engine: both must stop at the same time, pad and
    patch, after the same number of samples; the row in ``results["fault"]``."""
    from aca_warp.hf.loop import EngineTuning, run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import Record, preset

    row = {"phase": "fault: running", "passed": None}
    results["fault"] = row
    faults = []
    s1 = preset("hf1").replace(record=Record(sample_dt=2e-5))
    for engine in ("general", "onchip"):
        model = build_model([s1, s1], device=args.device, precision="fp64")
        options = RunOptions(duration=4e-3, dt=1e-5, force=True, engine=engine)
        tuning = EngineTuning(block_dim=args.block, csr_shared=args.csr, cluster=args.cluster)
        res = run_hf(model, initial_state(model), options, tuning=tuning)
        f = res.fault
        faults.append(None if f is None else [f.time, f.pad, f.patch, len(res.collect().time)])
    row.update(phase="done", general=faults[0], onchip=faults[1])
    row["passed"] = faults[0] is not None and faults[0] == faults[1]
    _log(f"fault: general {faults[0]}, onchip {faults[1]}: passed={row['passed']}")
    _write_json(out / "check.json", results)


# ----------------------------------------------------------------------------------------------- child: bench
def child_bench(args) -> None:
    import numpy as np
    import warp as wp

    from aca_warp.common.files import machine
    from aca_warp.hf.loop import EngineTuning, run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import Record, preset

    out = Path(args.out)
    deadline = args.deadline
    scene = preset("hf1").replace(record=Record(sample_dt=args.window / 20))
    rows: list[dict] = []
    models = {}
    for engine in ("onchip", "general"):
        for pads in args.pads:
            left = deadline - time.time()
            if engine == "general" and left < 15:
                _log(f"general pads={pads}: skipped ({left:.0f} s left)")
                continue
            if pads not in models:
                t = time.perf_counter()
                models[pads] = build_model([scene] * pads, device=args.device, precision="fp32")
                _log(f"built {pads} pads in {time.perf_counter() - t:.1f} s")
            model = models[pads]
            tuning = EngineTuning(block_dim=args.block, csr_shared=args.csr, cluster=args.cluster)
            options = RunOptions(dt=args.dt, engine=engine)
            _log(f"{engine} pads={pads}: warm-up")
            t = time.perf_counter()
            run_hf(model, initial_state(model), options.with_duration(2 * scene.record.sample_dt), tuning=tuning)
            warm = time.perf_counter() - t
            state = initial_state(model)
            _log(f"{engine} pads={pads}: timed window")
            res = run_hf(model, state, options.with_duration(args.window), tuning=tuning)
            c = res.collect()
            n = model.patch_count
            row = {
                **machine(model.device),
                "warp_version": wp.__version__,
                "engine": engine,
                "precision": "fp32",
                "pads": pads,
                "patches": n,
                "block_dim": args.block,
                "csr_shared": args.csr,
                "dt": res.dt,
                "steps": res.steps,
                "window_s": args.window,
                "warmup_s": warm,
                "wall_s": res.wall_time,
                "us_per_step": 1e6 * res.wall_time / res.steps,
                "steps_per_s": res.steps / res.wall_time,
                "patch_steps_per_s": n * res.steps / res.wall_time,
                "mu_last_pad0": float(c.globals[-1, 0, 0]),
                "mu_last_spread_over_pads": float(np.ptp(c.globals[-1, :, 0])),
            }
            rows.append(row)
            _write_json(out / "bench.json", rows)
            _log(
                f"{row['device_name']}: {engine} fp32 pads={pads} {row['us_per_step']:.3f} us/step "
                f"{row['patch_steps_per_s']:.3g} patch-steps/s (warm-up incl. compile {warm:.1f} s)"
            )


# ----------------------------------------------------------------------------------------------- parent
def _run_child(stage: str, args, timeout: float, extra: list[str]) -> dict:
    """Run ``stage`` in a child process group with ``timeout`` [s]; never waits longer (kills the group)."""
    out = Path(args.out)
    cmd = [
        sys.executable, os.path.abspath(__file__), "--stage", stage, "--device", args.device, "--out", str(out),
        "--dt", repr(args.dt), "--window", repr(args.window), "--self-timeout", repr(max(1.0, timeout - 3.0)),
        *extra,
    ]  # fmt: skip
    if args.block is not None:
        cmd += ["--block", str(args.block)]
    if args.cluster != 1:
        cmd += ["--cluster", str(args.cluster)]
    if args.csr is not None:
        cmd += ["--csr" if args.csr else "--no-csr"]
    if args.growth:
        cmd += ["--growth"]
    if args.integrator != "strang":
        cmd += ["--integrator", args.integrator]
    log = out / f"log_{stage}.txt"
    t = time.perf_counter()
    with open(log, "w") as f:
        p = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            rc = p.wait(timeout=timeout)
            timed_out = False
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=30)
            rc, timed_out = None, True
    elapsed = time.perf_counter() - t
    info = {"stage": stage, "rc": rc, "timed_out": timed_out, "timeout_s": timeout, "elapsed_s": elapsed}
    _log(f"{stage}: rc={rc} timed_out={timed_out} after {info['elapsed_s']:.1f} s (log {log})")
    return info


def _markdown(summary: dict) -> str:
    lines = ["# On-chip kernel GPU check (scripts/onchip_gpu_check.py)", ""]
    dev = next((r.get("device_name") for r in summary["check"].values() if r.get("device_name")), summary["device"])
    row = next(iter(summary["check"].values()), {})
    case = f"{row.get('integrator', 'strang')}, {row.get('cluster', 1)} block(s) per pad"
    if row.get("growth"):
        case = "growing pads, " + case
    lines += [f"Device: {dev}; {case}; verdict: **{summary['verdict']}**", ""]
    lines += [
        "| precision | phase | passed | max rel dμ | rel du | rel du̇ | rtol | steps general / on-chip "
        "| on-chip run incl. compile [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for p, r in summary["check"].items():
        lines.append(
            f"| {p} | {r.get('phase')} | {r.get('passed')} | {r.get('mu_max_rel_err', float('nan')):.2g} | "
            f"{r.get('u_err_rel_max', float('nan')):.2g} | {r.get('v_err_rel_max', float('nan')):.2g} | "
            f"{r.get('rtol', RTOL.get(p, float('nan'))):g} | {r.get('general_steps')} / {r.get('onchip_steps')} | "
            f"{r.get('onchip_total_s', float('nan')):.3g} |"
        )
    if summary["bench"]:
        b0 = summary["bench"][0]
        lines += [
            "",
            f"Benchmark: hf1, fp32, dt {b0['dt']:g} s, window {b0['window_s']:g} s, Warp {b0['warp_version']}, "
            f"{b0['device_name']}",
            "",
            "| engine | pads | block | µs/step | steps/s | patch-steps/s | warm-up incl. compile [s] |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in summary["bench"]:
            lines.append(
                f"| {r['engine']} | {r['pads']} | {r['block_dim'] or 'auto'} | {r['us_per_step']:.3g} | "
                f"{r['steps_per_s']:.3g} | {r['patch_steps_per_s']:.3g} | {r['warmup_s']:.3g} |"
            )
    kids = "; ".join(f"{c['stage']} rc={c['rc']} timed_out={c['timed_out']}" for c in summary["children"])
    lines += ["", f"Children: {kids}"]
    return "\n".join(lines) + "\n"


def parent(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_end = time.time() + args.budget
    children = [_run_child("check", args, min(args.check_timeout, args.budget), ["--precisions", *args.precisions])]
    check = json.loads((out / "check.json").read_text()) if (out / "check.json").exists() else {}
    for p in args.precisions:
        check.setdefault(p, {"phase": "not started", "passed": None})
        phase = check[p].get("phase", "")
        if phase != "done" and children[0]["timed_out"]:
            check[p]["phase"] = f"TIMEOUT in '{phase}' (hang or slow compile: see log_check.txt)"
            if phase.startswith("onchip"):  # stuck in the on-chip run: a hang unless the log shows a long compile
                check[p]["passed"] = False
    fp32_ok = check.get("fp32", {}).get("passed") is True
    bench: list[dict] = []
    left = t_end - time.time()
    if fp32_ok and not args.no_bench and args.integrator == "strang" and left > 10:
        deadline = time.time() + left - 2
        extra = ["--pads", *map(str, args.pads), "--deadline", repr(deadline)]
        children.append(_run_child("bench", args, left - 1, extra))
        if (out / "bench.json").exists():
            bench = json.loads((out / "bench.json").read_text())
    ok = fp32_ok and all(r.get("passed") in (True, None) for r in check.values())
    verdict = "PASS" if ok else ("HANG/TIMEOUT" if children[0]["timed_out"] else "FAIL")
    summary = {"verdict": verdict, "device": args.device, "check": check, "bench": bench, "children": children}
    _write_json(out / "onchip_check.json", summary)
    (out / "onchip_check.md").write_text(_markdown(summary))
    _log(f"verdict {verdict}; results in {out}/onchip_check.json and .md")
    return 0 if ok else 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--out", default="onchip_check", help="output directory")
    ap.add_argument("--budget", type=positive, default=80.0, help="wall-time budget of the whole script [s]")
    ap.add_argument("--check-timeout", type=positive, default=40.0, help="timeout of the check child [s]")
    ap.add_argument("--precisions", nargs="+", default=["fp32", "fp64"], choices=["fp32", "fp64"])
    ap.add_argument("--pads", nargs="+", type=int_at_least(1), default=[1, 1024], help="batch sizes of the benchmark")
    ap.add_argument("--window", type=positive, default=2e-5, help="timed simulated window of the benchmark [s]")
    ap.add_argument("--dt", type=positive, default=1e-8)
    ap.add_argument(
        "--block", type=int_between(1, MAX_BLOCK), default=None, help="threads per pad (default: the on-chip engine's)"
    )
    ap.add_argument(
        "--cluster",
        type=int_between(1, MAX_CLUSTER),
        default=1,
        help="blocks per pad (a thread-block cluster; default 1)",
    )
    ap.add_argument("--csr", action=argparse.BooleanOptionalAction, default=None, help="CSR in shared memory")
    ap.add_argument("--no-bench", action="store_true")
    ap.add_argument("--growth", action="store_true", help="check the in-kernel patch growth (growing pads)")
    ap.add_argument(
        "--integrator",
        choices=["strang", "adaptive"],
        default="strang",
        help="adaptive: check the on-chip adaptive kernel (tolerance 1e-5 fp32, 1e-7 fp64; no fault case or benchmark)",
    )
    ap.add_argument("--stage", choices=["check", "bench"], default=None, help=argparse.SUPPRESS)
    ap.add_argument("--deadline", type=float, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--self-timeout", type=float, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.stage is None:
        try:  # every refusal before the first child: nothing run, nothing written
            get_device(args.device)
            check_output_folder(args.out)
        except AcaError as e:
            ap.error(str(e))
        return parent(args)
    # child: dump the Python stack and exit shortly before the parent would kill us
    faulthandler.dump_traceback_later(args.self_timeout, exit=True)
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    _log(f"{args.stage}: Warp {wp.__version__}, device {args.device}")
    (child_check if args.stage == "check" else child_bench)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
