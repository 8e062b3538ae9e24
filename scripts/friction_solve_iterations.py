#!/usr/bin/env python3
"""How many Newton iterations the friction sub-step's solve takes, patch by patch, at states of a run.

On a GPU one pad's step is a chain through the slowest patch of its cluster, so the tail of the solves' iteration
counts is a suspect for the solve's share of a step (docs/onchip.md, "The friction solve at the default step"). This
script runs a preset with the general engine up to each time of ``--times`` (whole numbers of the scene's sample
interval, and of the growth spacing on a growing scene) and there counts, for every patch, the iterations of the
next step's solve from the synchronous state: the damped-midpoint sub-step of ``kernels/physics.py``
(:func:`~aca_warp.kernels.physics.friction_substep`) over one step ``--dt`` [s], with the cached spring force
frozen. The counting copy of the solve below returns the same velocity as the kernels' to the last bit
(``tests/test_friction_solve_iterations.py``). ``--zero-slip`` counts beside it a variant tried and not kept: the
bracket split at the zero-slip point and, where the first Newton step leaves the bracket, the Newton step from
there. ``--crossing mean`` runs the scene with the zero-slip crossings averaged and counts the second solves of the
steps whose slip changes sign too (row ``segment``), with each warp's chain of its longest point solve and its
longest second solve.

Writes a JSON file and a Markdown table (mean, 99th percentile and largest count per time; the mean over warps of
32 consecutive patches of their largest count, about what a GPU warp waits for; the histogram; and the long
solves with how many of them are of patches whose slip changes sign in the step).

Example (CPU, ~1 min)::

    python3 scripts/friction_solve_iterations.py --scene varying_area --dt 5e-8 --times 2e-4 1e-3 3e-3 1e-2 \\
        --zero-slip --out out/solve_iterations
    python3 scripts/friction_solve_iterations.py --scene hf1 --dt 2.5e-7 --times 15e-3 20e-3 25e-3 30e-3 \\
        --crossing mean --out out/solve_iterations_crossing    # saturated hf1 at the default stepping
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import warp as wp
from aca_warp.kernels.physics import friction_integral, friction_pair, law_pair

from aca_warp.common.argtypes import positive
from aca_warp.hf.options import NEWTON_TOL

wp.set_module_options({"enable_backward": False})


@wp.func
def counted_solve(
    a: Any, r: Any, hfn: Any, vd: Any, guess: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any, zero_slip: int,
    seg: int, s0: Any, g0: Any,
):  # fmt: skip
    """:func:`~aca_warp.kernels.physics.solve_velocity` (``r`` = b − a·guess, formed by its terms) with its
    iterations and bisections counted; ``zero_slip`` = 1 the variant of the module docstring; ``seg`` ≠ 0 the
    crossing treatment's second solve, with Eq. 4 averaged along the slip segment from ``s0`` (G(s0) = ``g0``).
    Returns (iterations, bisections, v [m/s])."""
    fmax = mu_scale * type(a)(3.141592653589793)
    lo = (r - hfn * fmax) / a
    hi = (r + hfn * fmax) / a
    dtol = tol * (wp.abs(r) + hfn * fmax) / a
    vp0 = vd - guess
    zero = a - a
    half = type(a)(0.5)
    gz = a * vp0 - r
    split = zero_slip != 0 and vp0 > lo and vp0 < hi
    if split:
        if gz > zero:
            hi = vp0
        else:
            lo = vp0
    d = wp.clamp(zero, lo, hi)
    last = type(a)(2.0) * (hi - lo)
    before = last
    n = int(0)  # noqa: UP018 (a mutable kernel variable)
    nb = int(0)  # noqa: UP018
    for it in range(60):
        n += 1
        f, df = law_pair(vp0 - d, seg, s0, g0, mu_scale, slope, decay, tol)
        g = a * d - hfn * f - r
        if g == zero:
            break
        if g > zero:
            hi = d
        else:
            lo = d
        dg = a + hfn * df
        dn = d - g / dg
        if it == 0 and split and (dg <= zero or dn < lo or dn > hi) and (g > zero) != (gz > zero):
            dn = vp0 - gz / (a + hfn * type(a)(2.0) * mu_scale * slope)
        if dg <= zero or dn < lo or dn > hi or wp.abs(dn - d) > half * before:
            dn = half * (lo + hi)
            nb += 1
        step = wp.abs(dn - d)
        converged = step <= dtol or hi - lo <= dtol
        before = last
        last = step
        d = dn
        if converged:
            break
    return n, nb, guess + d


@wp.kernel
def count_substeps(
    v: wp.array[Any],
    force: wp.array[Any],
    mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    disc_speed: wp.array[Any],
    h: Any,
    mu_scale: Any,
    slope: Any,
    decay: Any,
    tol: Any,
    zero_slip: int,
    crossing: int,
    iterations: wp.array[wp.int32],
    bisections: wp.array[wp.int32],
    segment_iterations: wp.array[wp.int32],
    segment_bisections: wp.array[wp.int32],
    v_out: wp.array[Any],
):
    """Per patch (n,): :func:`~aca_warp.kernels.physics.friction_substep` over ``h`` [s] from ``v`` [m/s] with
    ``force`` [N] frozen, counting its solve's iterations and bisections; with ``crossing`` ≠ 0 (the ``mean``
    treatment) a midpoint step whose slip changes sign is solved again with the segment law from the first root, and
    ``segment_iterations``, ``segment_bisections`` count that solve's (0 where there is none); ``v_out`` the velocity
    [m/s]."""
    i = wp.tid()
    one = type(h)(1.0)
    m = mass[i]
    c = damping[i]
    fn = normal_force[i]
    vi = v[i]
    f0, df0 = friction_pair(disc_speed[i] - vi, mu_scale, slope, decay)
    x = h * (c + fn * df0) / m
    theta = type(h)(0.5)
    if x > type(h)(6.0):
        theta = wp.min((one - type(h)(1.5) / x) / type(h)(1.5), one)
    th = theta * h
    zero = vi - vi
    s0 = disc_speed[i] - vi
    a = m + th * c
    n, nb, vm = counted_solve(
        a, th * (force[i] - c * vi), th * fn, disc_speed[i], vi, mu_scale, slope, decay, tol, zero_slip, 0, s0, zero
    )
    iterations[i] = n
    bisections[i] = nb
    out = vm + (vm - vi) * (one / theta - one)
    segment_iterations[i] = 0
    segment_bisections[i] = 0
    if crossing != 0 and theta == type(h)(0.5) and s0 * (disc_speed[i] - out) < zero:
        g0 = friction_integral(s0, mu_scale, slope, decay)
        r = th * (force[i] - c * vm) + m * (vi - vm)
        n2, nb2, v2 = counted_solve(a, r, th * fn, disc_speed[i], vm, mu_scale, slope, decay, tol, 0, 1, s0, g0)
        segment_iterations[i] = n2
        segment_bisections[i] = nb2
        out = v2 + (v2 - vi) * (one / theta - one)
    v_out[i] = out


def count(
    patch: dict[str, np.ndarray], pad: dict[str, float], h: float, precision: str, zero_slip: bool,
    crossing: bool = False,
) -> dict:  # fmt: skip
    """Run :func:`count_substeps` on the CPU for the per-patch arrays ``patch`` (v [m/s], force [N], mass [kg],
    damping [N s/m], normal_force [N], disc_speed [m/s]; (n,) each) and the friction law ``pad`` (mu_scale, slope,
    decay), ``crossing``: with the ``mean`` treatment's second solves; returns iterations, bisections,
    segment_iterations, segment_bisections (int32 (n,)) and v (n,) as NumPy arrays."""
    dtype = wp.float32 if precision == "fp32" else wp.float64
    n = len(patch["v"])
    arrays = {k: wp.array(np.asarray(patch[k]), dtype=dtype, device="cpu") for k in
              ("v", "force", "mass", "damping", "normal_force", "disc_speed")}  # fmt: skip
    counts = ("iterations", "bisections", "segment_iterations", "segment_bisections")
    out = {k: wp.zeros(n, dtype=wp.int32, device="cpu") for k in counts}
    v_out = wp.zeros(n, dtype=dtype, device="cpu")
    wp.launch(
        count_substeps,
        dim=n,
        inputs=[
            *arrays.values(),
            dtype(h),
            *(dtype(pad[k]) for k in ("mu_scale", "slope", "decay")),
            dtype(NEWTON_TOL[precision]),
            int(zero_slip),
            int(crossing),
        ],
        outputs=[*out.values(), v_out],
        device="cpu",
    )
    return {**{k: a.numpy() for k, a in out.items()}, "v": v_out.numpy()}


def state_arrays(model, state) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """The per-patch inputs of :func:`count` at ``state`` of a one-pad ``model``, as the engine's next step takes
    them: the synchronous velocity [m/s], the cached spring force F_s(u) [N] (after a growth event still at the
    stiffnesses of before, as the step uses it), mass [kg], damping [N s/m], normal force [N] and disc speed ω r
    [m/s]; and the pad's friction law (mu_scale, slope [s/m], decay [s/m])."""
    arr = model.arrays
    n = model.patch_count
    patch = {
        "v": state.v.numpy(),
        "force": state.force.numpy(),
        "mass": 1.0 / arr["inv_mass"].numpy()[:n],
        "damping": arr["damping"].numpy()[:n],
        "normal_force": arr["normal_force"].numpy()[:n],
        "disc_speed": arr["pad_omega"].numpy()[0] * arr["radius"].numpy()[:n],
    }
    pad = {k: float(arr[f"pad_{k}"].numpy()[0]) for k in ("mu_scale", "slope", "decay")}
    return patch, pad


LONG = 5  # iterations from which a solve counts as long
WARP = 32  # the patches of one GPU warp: a block's threads own consecutive patches (the kernel's warps start anew at
# each block's first patch, so groups counted from patch 0 approximate them)


def summary(iterations: np.ndarray, bisections: np.ndarray, through_zero: np.ndarray) -> dict:
    """Mean, 99th percentile, largest count, mean over warps (:data:`WARP` consecutive patches, the last group
    shorter) of their largest count and histogram of one time's iterations; bisections' mean and largest;
    the long solves (≥ :data:`LONG` iterations) and how many of them are of patches whose slip changes sign in the
    sub-step (``through_zero``, bool (n,))."""
    hist = np.bincount(iterations)
    long = iterations >= LONG
    return {
        "mean": float(iterations.mean()),
        "p99": float(np.percentile(iterations, 99)),
        "warp_max_mean": float(np.maximum.reduceat(iterations, np.arange(0, len(iterations), WARP)).mean()),
        "max": int(iterations.max()),
        "histogram": {int(i): int(c) for i, c in enumerate(hist) if c},
        "bisections_mean": float(bisections.mean()),
        "bisections_max": int(bisections.max()),
        "long": int(long.sum()),
        "long_through_zero": int((long & through_zero).sum()),
    }


SEGMENT_NOTE = (
    "Row 'segment': the second solves of the steps whose slip changed sign, counted over those patches (their number "
    "in brackets); its warp column is the mean over warps of their longest second solve (0 where none), and 'chain' "
    "the mean over warps of their longest point solve plus their longest second one."
)


def segment_rows(t: float, got: dict) -> list[dict]:
    """The row of the crossing steps' second solves at time ``t`` [s] (counts over the patches that took one; none
    when no patch did), with the warps' chain: the mean over warps of their longest point solve plus their longest
    second solve (a warp runs the second solves after all its lanes' first ones)."""
    seg = got["segment_iterations"]
    took = seg > 0
    if not took.any():
        return []
    starts = np.arange(0, len(seg), WARP)
    row = summary(seg[took], got["segment_bisections"][took], np.ones(int(took.sum()), dtype=bool))
    row["warp_max_mean"] = float(np.maximum.reduceat(seg, starts).mean())
    row["solves"] = int(took.sum())
    row["warp_chain_mean"] = float(
        (np.maximum.reduceat(got["iterations"], starts) + np.maximum.reduceat(seg, starts)).mean()
    )
    return [{"time_s": t, "variant": "segment", **row}]


def whole(gap: float, unit: float) -> bool:
    """Whether ``gap`` [s] is a whole number (≥ 1) of ``unit`` [s], to rounding."""
    k = round(gap / unit)
    return k >= 1 and abs(gap - k * unit) <= 1e-9 * gap


def _parse(argv: list[str] | None) -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="varying_area", help="preset (default varying_area)")
    ap.add_argument(
        "--dt",
        type=positive,
        default=5e-8,
        help="time step [s] (default 5e-8, strang's default for a scene of no preset)",
    )
    ap.add_argument("--times", type=positive, nargs="+", default=[2e-4, 1e-3, 3e-3, 1e-2],
                    help="simulated times at which to count [s], increasing (default 2e-4 1e-3 3e-3 1e-2)")  # fmt: skip
    ap.add_argument("--precision", choices=("fp32", "fp64"), default="fp32", help="state precision (default fp32)")
    ap.add_argument("--zero-slip", action="store_true", help="count the zero-slip variant beside the kernels' solve")
    ap.add_argument("--crossing", choices=("point", "mean"), default="point",
                    help="the run's treatment of zero-slip crossings (default point); with mean the crossing steps' "
                    "second solves are counted too (row 'segment')")  # fmt: skip
    ap.add_argument("--out", type=Path, required=True, help="folder for solve_iterations.json and .md")
    args = ap.parse_args(argv)
    if any(b <= a for a, b in zip(args.times, args.times[1:], strict=False)):
        ap.error("--times must increase")
    return ap, args


def main(argv: list[str] | None = None) -> int:
    ap, args = _parse(argv)
    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import machine
    from aca_warp.hf.loop import run_hf
    from aca_warp.hf.model import build_model
    from aca_warp.hf.options import RunOptions, growth_asked
    from aca_warp.hf.solver import fitted_step
    from aca_warp.hf.state import initial_state
    from aca_warp.scene import preset

    wp.config.quiet = True
    try:
        scene = preset(args.scene)
    except SceneError as exc:
        ap.error(str(exc))
    sample = scene.record.sample_dt
    interval = scene.growth.interval if scene.growth is not None else None
    growth_dt = growth_asked("strang", None, interval, args.times[-1])
    taken = fitted_step(args.dt, sample)  # the step the engine takes: a whole number of them per sample interval
    if abs(taken - args.dt) > 1e-9 * args.dt:
        ap.error(f"--dt {args.dt:g} s must divide the scene's sample interval, {sample:g} s (the run would take "
                 f"{taken:.6g} s)")  # fmt: skip
    for gap in np.diff([0.0, *args.times]):
        if not whole(gap, sample) or (growth_dt is not None and not whole(gap, growth_dt)):
            spacing = f" and of the growth spacing, {growth_dt:g} s" if growth_dt is not None else ""
            ap.error(f"--times: {gap:g} s between counts is not a whole number of sample intervals, {sample:g} s"
                     f"{spacing}")  # fmt: skip
    model = build_model([scene], device="cpu", precision=args.precision)
    state = initial_state(model)
    variants = ["kernel", "zero-slip"] if args.zero_slip else ["kernel"]
    rows, now = [], 0.0
    for t in args.times:
        options = RunOptions(
            duration=t - now, dt=args.dt, engine="general", growth_dt=growth_dt, crossing=args.crossing
        )
        res = run_hf(model, state, options)
        if not res.complete:
            ap.error(f"the run stopped at {now + res.sim_time:g} s: {res.fault}")
        now = t
        patch, pad = state_arrays(model, state)
        slip = patch["disc_speed"] - patch["v"]
        for variant in variants:
            got = count(patch, pad, args.dt, args.precision, variant == "zero-slip", args.crossing == "mean")
            through_zero = np.sign(slip) != np.sign(patch["disc_speed"] - got["v"])
            new = [{"time_s": t, "variant": variant, **summary(got["iterations"], got["bisections"], through_zero)}]
            if args.crossing == "mean" and variant == "kernel":
                new += segment_rows(t, got)
            rows += new
            for r in new:
                print(f"t = {t:g} s, {r['variant']:9s}: iterations mean {r['mean']:.2f}, p99 {r['p99']:.0f}, "
                      f"max {r['max']}, warp max mean {r['warp_max_mean']:.2f}", flush=True)  # fmt: skip
    info = {"scene": args.scene, "patches": model.patch_count, "dt_s": args.dt, "precision": args.precision,
            "crossing": args.crossing,
            "growth_dt_s": growth_dt, "machine": machine(model.device), "warp_version": wp.__version__}  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "solve_iterations.json").write_text(json.dumps({**info, "rows": rows}, indent=1))
    lines = [
        f"Newton iterations of the friction sub-step's solve per patch: {args.scene} ({model.patch_count} patches), "
        f"{args.precision}, dt {args.dt:g} s, crossings {args.crossing} (scripts/friction_solve_iterations.py)",
        *([] if args.crossing == "point" else ["", SEGMENT_NOTE]),
        "",
        "| t [s] | solve | mean | p99 | max | warp max, mean | histogram (iterations: patches) "
        f"| solves ≥ {LONG} iterations (of them, slip through zero) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        hist = ", ".join(f"{k}: {v}" for k, v in r["histogram"].items())
        solve = r["variant"] if "solves" not in r else f"segment [{r['solves']}]; chain {r['warp_chain_mean']:.2f}"
        lines.append(f"| {r['time_s']:g} | {solve} | {r['mean']:.2f} | {r['p99']:.0f} | {r['max']} "
                     f"| {r['warp_max_mean']:.2f} | {hist} "
                     f"| {r['long']} ({r['long_through_zero']}) |")  # fmt: skip
    (args.out / "solve_iterations.md").write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
