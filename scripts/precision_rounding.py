#!/usr/bin/env python3
"""fp32 against fp64 over a few strang steps from one state: rounding, or a lost term?

The statistical work-precision compares fp32 with fp64 at one step over seed ensembles (docs/figures/
work_precision_statistics/fp32_fp64/). This script looks at the arithmetic itself. It runs one pad in fp64 with
strang at ``--dt`` [s] for ``--settle`` [s] from equilibrium + 0.01 m/s (the saturated state the statistics analyse),
rounds that state to fp32, and from it runs each of ``--steps`` strang steps twice on the general engine, in fp32
and in fp64. Each patch's velocity difference is given in ulps of fp32 at 10 m/s (9.5e-7 m/s, the disc speed of the
presets and the LF states) and its displacement difference in ulps of fp32 at the pad's rms |u|. Rounding alone leaves
every patch within a few ulps growing slowly with the steps, and a mean signed velocity difference within a few of
its standard errors (given beside it); an operation that loses a term in fp32 (as the patch damping once was,
fp32_fp64/README.md) shows as patches far apart from the rest or as a mean signed difference many standard errors
from 0.

The pad: a preset or a scene file (``--scene hf1``) or an LF state of the multiscale schedule (``--scene
app1_start``, LF seed ``--lf-seed``; the LF run is made on the CPU into ``--out`` first, ≈ 10–20 s).

Writes ``OUT/precision_rounding_<scene>.json`` (with the machine, versions and command) and prints a Markdown table.

Example (CPU, ≈ 20 s with the LF run on a 2-core machine)::

    python3 scripts/precision_rounding.py --scene app1_start --settle 3e-3 --out out/rounding
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.studies.validation.multiscale import STATES as LF_STATES

ULP_10 = float(np.spacing(np.float32(10.0)))  # m/s: one ulp of fp32 at the disc speed 10 m/s


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog="See the module docstring.")
    ap.add_argument("--scene", default="app1_start", help="a preset name, a scene TOML file or an LF state "
                    f"({', '.join(LF_STATES)}) (app1_start)")  # fmt: skip
    ap.add_argument("--lf-seed", type=int_at_least(1), default=1, help="LF and patch seed of an LF state, and the "
                    "seed of the initial perturbation (1)")  # fmt: skip
    ap.add_argument("--settle", type=positive, default=3e-3, help="fp64 run before the comparison [s] (3e-3)")
    ap.add_argument("--dt", type=positive, default=5e-8, help="strang step [s] (5e-8)")
    ap.add_argument("--steps", type=int_at_least(1), nargs="+", default=[1, 20], help="steps compared (1 20)")
    ap.add_argument("--out", required=True, help="folder for the LF run and the JSON file")
    return ap.parse_args(argv)


def pad_scene(args: argparse.Namespace, out: Path) -> Any:
    """The pad at equilibrium + 0.01 m/s (seeded by ``--lf-seed``): a preset, or an LF state of the multiscale
    schedule of LF seed ``--lf-seed`` (its LF run made into ``out`` when missing)."""
    from aca_warp.scene import Initial, load_scene

    if args.scene in LF_STATES:
        from aca_warp.lf.io import scene_from_snapshot
        from aca_warp.studies.validation import multiscale
        from aca_warp.studies.validation.base import Config

        multiscale.register()
        group = next(g for g, members in multiscale.GROUPS.items() if args.scene in members)
        cfg = Config(device="cpu", seeds=1, first_seed=args.lf_seed, lf_dir=str(out))
        multiscale.ensure_lf([group], cfg, print)  # the validation's LF run of that seed, made once into ``out``
        scene = scene_from_snapshot(multiscale.lf_path(cfg, args.lf_seed, None), args.scene)
    else:
        scene = load_scene(args.scene)
    initial = Initial(state="equilibrium", perturbation=0.01, seed=args.lf_seed)
    return scene.replace(initial=initial, origin=None)


def run_steps(scene: Any, precision: str, u: np.ndarray, v: np.ndarray, dt: float, n: int) -> tuple[Any, Any]:
    """(u [m], u̇ [m/s]) after ``n`` strang steps of ``dt`` [s] in ``precision`` from (u, v), as float64 arrays."""
    from aca_warp.scene import Record
    from aca_warp.studies.runs import model_from_state, run_general

    model, state = model_from_state(scene, "cpu", precision, u, v)
    run_general(model, state, duration=n * dt, integrator="strang", dt=dt, record=Record(sample_dt=n * dt))
    return state.u.numpy().astype(np.float64), state.v.numpy().astype(np.float64)


def compare(scene: Any, u: np.ndarray, v: np.ndarray, dt: float, n: int) -> dict[str, Any]:
    """fp32 against fp64 after ``n`` steps from (u, v): velocity differences in ulps of fp32 at 10 m/s, displacement
    differences in ulps of fp32 at the pad's rms |u| (quantiles, largest, the mean signed velocity difference [m/s]
    and its standard error over the patches)."""
    u32, v32 = run_steps(scene, "fp32", u, v, dt, n)
    u64, v64 = run_steps(scene, "fp64", u, v, dt, n)
    dv = np.abs(v32 - v64) / ULP_10
    du = np.abs(u32 - u64) / float(np.spacing(np.float32(np.sqrt(np.mean(u64**2)))))
    q = (50, 99)
    return {
        "steps": n,
        "dv_ulp10": {f"q{k}": float(np.percentile(dv, k)) for k in q} | {"max": float(dv.max())},
        "du_ulp": {f"q{k}": float(np.percentile(du, k)) for k in q} | {"max": float(du.max())},
        "mean_signed_dv_m_s": float(np.mean(v32 - v64)),
        "mean_signed_dv_se_m_s": float(np.std(v32 - v64, ddof=1) / np.sqrt(v32.size)),
        "dv_max_over_q99": float(dv.max() / max(np.percentile(dv, 99), 1e-30)),
    }


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out = Path(args.out)
    from aca_warp.studies.report import init_warp

    wp = init_warp()
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import machine
    from aca_warp.scene import Record
    from aca_warp.studies.report import command_line, write_json
    from aca_warp.studies.runs import batch_at_start, run_general

    t0 = time.perf_counter()
    try:
        out.mkdir(parents=True, exist_ok=True)
        scene = pad_scene(args, out)
    except (AcaError, OSError) as e:
        print(f"precision_rounding: {e}", file=sys.stderr)
        return 2
    model, state = batch_at_start([scene], "cpu", "fp64")
    res = run_general(model, state, duration=args.settle, integrator="strang", dt=args.dt, record=Record())
    if not res.complete or res.fault is not None:
        print(f"precision_rounding: the fp64 run to {args.settle:g} s did not complete ({res.fault})", file=sys.stderr)
        return 2
    u = state.u.numpy().astype(np.float32).astype(np.float64)  # the state rounded to fp32: both runs start on it
    v = state.v.numpy().astype(np.float32).astype(np.float64)
    rows = [compare(scene, u, v, args.dt, n) for n in args.steps]
    doc = {"command": command_line("precision_rounding.py", sys.argv[1:] if argv is None else argv),
           "machine": machine(wp.get_device("cpu")), "warp": wp.__version__, "numpy": np.__version__,
           "scene": args.scene, "lf_seed": args.lf_seed, "patches": int(u.size), "settle_s": args.settle,
           "dt_s": args.dt, "ulp10_m_s": ULP_10, "rms_velocity_m_s": float(np.sqrt(np.mean(v**2))),
           "rms_displacement_m": float(np.sqrt(np.mean(u**2))), "rows": rows,
           "wall_s": time.perf_counter() - t0}  # fmt: skip
    path = out / f"precision_rounding_{args.scene}.json"
    write_json(path, doc)
    print(f"{args.scene} ({u.size} patches; rms u̇ {doc['rms_velocity_m_s']:.3g} m/s, rms u "
          f"{doc['rms_displacement_m']:.3g} m), fp32 − fp64 after n strang steps of {args.dt:g} s from the state at "
          f"{args.settle:g} s rounded to fp32\n")  # fmt: skip
    print("| steps | |Δu̇| / ulp(10 m/s): median, 99 %, largest | |Δu| / ulp(rms u): median, 99 %, largest "
          "| mean signed Δu̇ ± its standard error [m/s] |\n|---|---|---|---|")  # fmt: skip
    for r in rows:
        a, b = r["dv_ulp10"], r["du_ulp"]
        print(f"| {r['steps']} | {a['q50']:.2f}, {a['q99']:.2f}, {a['max']:.2f} | {b['q50']:.2f}, {b['q99']:.2f}, "
              f"{b['max']:.2f} | {r['mean_signed_dv_m_s']:.2g} ± {r['mean_signed_dv_se_m_s']:.2g} |")  # fmt: skip
    print(f"\nwrote {path} ({doc['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
