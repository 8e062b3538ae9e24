"""Time to solution: the wall time each solver needs to follow μ(t) of a pad to a μ error ≤ ``--target`` (1e-7).

Problems: hf1 from rest over 1 ms (sliding) and stickslip (hf1 at 0.5 m/s at the mean radius: patches stick within
0.1 ms) over 0.2 ms (``--scenes``, ``--duration``; hf2 on request), samples every 1 µs. The μ
error is max |μ(t) − μ_ref(t)| against SciPy DOP853 at rtol 1e-11 on :class:`~aca_warp.hf.reference.ReferenceODE`,
computed in the same run. Solvers, each timed after a warm-up that compiles its kernels:

* ``adaptive`` (ours, fp64), on the on-chip engine (one block or cluster per pad) and on the general engine (a
  trial of every pad per 14 launches): the loosest tolerance of 1e-3 … 1e-7 that reaches the target;
* ``strang`` (ours) at its defaults (:func:`~aca_warp.hf.options.default_step`, fp32:
  :func:`~aca_warp.hf.options.default_precision`, the crossing treatment
  :func:`~aca_warp.hf.options.default_crossing`), and with the point treatment in fp64 at 1e-8 s — on the on-chip
  engine, ``auto``'s choice on either device — and the largest of 1e-8, 5e-9, 2.5e-9 s that reaches the target;
* SciPy DOP853 (host CPU): the loosest rtol of 1e-5 … 1e-10 that reaches it;
* diffrax Dopri8 with a PI(D) controller (``PIDController(pcoeff=0.4, icoeff=0.3)``, JAX in float64) on the same
  equations (the arrays of ``ReferenceODE``: masses, damping, normal forces, disc speeds, the coupling matrix as a
  segment sum over its CSR rows; the state scaled by ReferenceODE's per-patch scales so that ``atol = rtol``
  means what SciPy's per-component atol does), μ saved at the sample times through ``SaveAt(fn=...)``; when JAX
  with diffrax is importable (otherwise the row says so);
* batches of ``--pads`` (64) pads: the scene with per-pad initial velocity perturbations N(0, (1e-3 m/s)²) (seed =
  pad + 1); diffrax vmapped over the pads, and on CUDA ours (on-chip strang, adaptive). The μ error of a batch is
  the largest over ``--check-pads`` pads spread over the batch, each against its own DOP853 reference.

Times (the fastest of up to 3 runs where they take < 5 s together: the host may be shared): ours — the stepping
loop of ``run_hf`` (kernels compiled by the warm-up, graph capture excluded; the time with capture and engine
set-up is in the JSON); SciPy — ``solve_ivp``; diffrax — the jitted solve after a warm-up call, to
``block_until_ready``. A part that fails is marked in its row; the rest of the table goes on. Results:
``OUT/tts_<device>.json`` and a markdown table; ``--report JSON...`` writes the tables into docs/time_to_solution.md.

    python scripts/time_to_solution.py --out /tmp/tts                        # CPU (no batches), ~3 min
    python scripts/time_to_solution.py --device cuda:0 --out $OUT/tts        # GPU
    python scripts/time_to_solution.py --report tts_cpu.json tts_h100.json   # docs/time_to_solution.md
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.hf.options import DEFAULT_TOLERANCE, default_precision, default_step
from aca_warp.hf.reference import ReferenceODE
from aca_warp.scene import Initial, Record, Scene, preset
from aca_warp.studies.report import (
    add_device,
    add_page_options,
    command_line,
    fmt,
    generated_markers,
    md_table,
    measure_or_report,
    replace_generated,
    write_json,
)
from aca_warp.studies.runs import batch_at_start, run_general

SAMPLE_DT = 1.0e-6  # s
REF_RTOL = 1.0e-11
TOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
STEPS = (1e-8, 5e-9, 2.5e-9)
RTOLS = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
DIFFRAX_RTOLS = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
REPEATS, REPEAT_BELOW = 3, 5.0  # runs of a setting at most, while their total stays below this [s]
PAD_PERTURBATION = 1.0e-3  # m/s, per-pad initial velocity perturbation of the batches
STICK_SPEED = 0.5  # m/s at the mean radius (the stickslip scene)
MAX_STEPS = 1 << 21  # diffrax steps per solve (1 ms at 5e-10 s)
SCENES = ("hf1", "hf2", "stickslip")
DURATIONS = {"hf1": 1e-3, "hf2": 1e-3, "stickslip": 2e-4}  # s, default simulated time per scene
# s per simulated ms: DOP853 reference, our ladders, SciPy ladder
COST_PER_MS = {"hf1": (1.5, 50.0, 3.0), "hf2": (1.5, 50.0, 3.0), "stickslip": (35.0, 250.0, 40.0)}
BEGIN, END = generated_markers("scripts/time_to_solution.py --report")
OUT_ARG = re.compile(r"--out \S+")  # the result folder, shown as OUT in the tables


def make_scene(name: str) -> Scene:
    """``hf1``, ``hf2`` or ``stickslip`` (hf1 at 0.5 m/s at the mean radius), from rest, samples every 1 µs."""
    s = preset("hf1" if name == "stickslip" else name).replace(record=Record(sample_dt=SAMPLE_DT))
    if name == "stickslip":
        s = s.replace(name="stickslip", angular_velocity=STICK_SPEED / s.pad.mean_radius)
    return s


def batch_scenes(scene: Scene, pads: int) -> list[Scene]:
    """``pads`` copies of ``scene`` with per-pad initial velocity perturbations (seed = pad + 1)."""
    init = scene.initial
    return [scene.replace(initial=Initial(init.state, PAD_PERTURBATION, p + 1)) for p in range(pads)]


def check_pads(pads: int, count: int) -> list[int]:
    """``count`` pads spread over a batch of ``pads`` (first and last included)."""
    return sorted({round(k * (pads - 1) / max(count - 1, 1)) for k in range(min(count, pads))})


class Problem:
    """One scene on one device: its pads, their DOP853 references and the μ error of a solution."""

    def __init__(
        self,
        scene: Scene,
        pads: int,
        checked: int,
        duration: float,
        log: Callable[[str], None],
        device: str = "cpu",
    ) -> None:
        """``device``: where the pads' start states are built (the Warp device of the run; the references run in
        NumPy/SciPy on the host)."""
        self.scene, self.duration, self.log, self.device = scene, duration, log, device
        self.n = round(duration / SAMPLE_DT)
        self.times = np.arange(self.n + 1) * SAMPLE_DT
        self.scenes = batch_scenes(scene, pads) if pads > 1 else [scene]
        self.checked = check_pads(len(self.scenes), checked)
        self.odes: dict[int, ReferenceODE] = {}
        self.y0: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.ref: dict[int, np.ndarray] = {}
        self.ref_wall = 0.0
        for p in self.checked:
            model, state = batch_at_start([self.scenes[p]], device, "fp64")
            ode = ReferenceODE(model)
            u0, v0 = (x.astype(np.float64) for x in state.numpy())
            sol = ode.solve(self.times, method="DOP853", rtol=REF_RTOL, u0=u0, v0=v0)
            self.odes[p], self.y0[p], self.ref[p] = ode, (u0, v0), ode.globals(sol.u, sol.v)["mu"]
            self.ref_wall += sol.wall_time
        log(f"{scene.name}, {len(self.scenes)} pad(s): DOP853 rtol {REF_RTOL:g} references of pads {self.checked} "
            f"in {self.ref_wall:.3g} s")  # fmt: skip

    def error(self, mu: np.ndarray) -> float:
        """Largest μ error over the checked pads of μ of shape (samples, pads) (or (samples,) for one pad)."""
        mu = np.asarray(mu, dtype=np.float64).reshape(len(self.times), -1)
        return float(max(np.max(np.abs(mu[:, p] - self.ref[p])) for p in self.checked))


# ----------------------------------------------------------------------------------------------- solvers


def run_ours(
    prob: Problem, device: str, integrator: str, engine: str, precision: str = "fp64", **kw: Any
) -> dict[str, Any]:
    """A warm-up run (20 µs) and the timed run of every pad of ``prob`` with ours in ``precision``; μ error and
    times."""
    rec = Record(sample_dt=SAMPLE_DT)
    model, state = batch_at_start(prob.scenes, device, precision)
    run_general(model, state, duration=20 * SAMPLE_DT, integrator=integrator, record=rec, engine=engine, **kw)
    model, state = batch_at_start(prob.scenes, device, precision)
    t0 = time.perf_counter()
    res = run_general(model, state, duration=prob.duration, integrator=integrator, record=rec, engine=engine, **kw)
    total = time.perf_counter() - t0
    if not res.complete:
        raise RuntimeError(f"run stopped: {res.fault}")
    return {
        "error": prob.error(res.collect().globals[:, :, 0]),
        "time_s": res.wall_time,
        "time_with_setup_s": total,
        "steps": res.steps,
        "rejected": res.rejected,
    }


def run_scipy(prob: Problem, rtol: float) -> dict[str, Any]:
    """SciPy DOP853 at ``rtol`` on pad 0 (one pad only)."""
    ode, (u0, v0) = prob.odes[0], prob.y0[0]
    sol = ode.solve(prob.times, method="DOP853", rtol=rtol, u0=u0, v0=v0)
    return {"error": prob.error(ode.globals(sol.u, sol.v)["mu"]), "time_s": sol.wall_time, "fevals": sol.nfev}


@dataclass
class Compiled:
    """A jitted function and whether it has been called once (compiled)."""

    fn: Callable[..., Any]
    warm: bool = False


def rhs_arrays(ode: ReferenceODE) -> dict[str, Any]:
    """The arrays and constants of ``ode``'s equations as diffrax takes them (NumPy, float64): the coupling matrix K
    as COO ``rows``, ``cols``, ``vals`` (row-sorted, diagonal included), masses ``m`` [kg], damping ``c`` [N s/m],
    normal forces ``fn`` [N], disc speeds ``vd`` [m/s], the state scales ``su`` [m] and ``sv`` [m/s] (each (n,)),
    Eq. 4's ``M``, ``slope``, ``decay``, the matrix's Coulomb force ``coulomb`` [N] and the ``load`` [N]."""
    K = ode.K.tocsr()
    K.sort_indices()
    return {
        "n": ode.n,
        "rows": np.repeat(np.arange(ode.n), np.diff(K.indptr)),
        "cols": K.indices.astype(np.int64),
        "vals": K.data.astype(np.float64),
        **{k: np.asarray(getattr(ode, k), np.float64) for k in ("m", "c", "fn", "vd")},
        "su": np.asarray(ode.u_scale, np.float64),
        "sv": np.asarray(ode.v_scale, np.float64),
        "M": ode.M,
        "slope": ode.slope,
        "decay": ode.decay,
        "coulomb": ode.mu_pad * ode.f_matrix * float(np.sign(ode.omega)),
        "load": ode.load,
    }


def equations(a: dict[str, Any], xp: Any, segment_sum: Callable[..., Any]) -> tuple[Callable, Callable]:
    """``rhs(t, z, args)`` and ``mu(t, z, args)`` of the scaled state z = (u / su, u̇ / sv) (shape (2n,)) from
    :func:`rhs_arrays` ``a``, written once for NumPy and JAX: ``xp`` the array module, ``segment_sum(data, rows,
    n)`` the sum of ``data`` over equal ``rows``. In z, diffrax's ``atol = rtol`` is SciPy's per-component atol
    rtol × (F_N/k_T, (F_N/k_T)√(k_T/m)) of :meth:`ReferenceODE.solve`."""
    n, rows, cols, vals = a["n"], a["rows"], a["cols"], a["vals"]
    m, c, fn, vd, su, sv = (xp.asarray(a[k]) for k in ("m", "c", "fn", "vd", "su", "sv"))
    M, slope, decay, coulomb, load = (a[k] for k in ("M", "slope", "decay", "coulomb", "load"))

    def friction(s: Any) -> Any:  # Eq. 4, as ReferenceODE.friction
        return M / np.pi * xp.arctan(slope * s) * (1.0 / (decay * xp.abs(s) + 1.0) + 1.0)

    def rhs(t: Any, z: Any, args: Any) -> Any:
        u, v = z[:n] * su, z[n:] * sv
        ku = segment_sum(vals * u[cols], rows, n)
        return xp.concatenate([v / su, (-ku - c * v + fn * friction(vd - v)) / (m * sv)])

    def mu(t: Any, z: Any, args: Any) -> Any:
        return (xp.sum(fn * friction(vd - z[n:] * sv)) + coulomb) / load

    return rhs, mu


def diffrax_solver(ode: ReferenceODE, times: np.ndarray, batched: bool) -> Compiled:
    """A jitted diffrax Dopri8 + PIDController solve of ``ode``'s equations (:func:`equations`) from 0 to
    ``times[-1]``: ``solve(u0, v0, rtol)`` → (μ at ``times`` (samples,), or (pads, samples) when ``batched`` (u0,
    v0 of shape (pads, n)), accepted steps, rejected steps). Raises ImportError without JAX or diffrax."""
    os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")  # leave the GPU's memory to Warp too
    import diffrax
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)
    a = rhs_arrays(ode)
    a.update({k: jnp.asarray(a[k], jnp.int32) for k in ("rows", "cols")}, vals=jnp.asarray(a["vals"]))

    def segment_sum(data: Any, rows: Any, n: int) -> Any:
        return jax.ops.segment_sum(data, rows, num_segments=n, indices_are_sorted=True)

    rhs, mu = equations(a, jnp, segment_sum)
    su, sv = jnp.asarray(a["su"]), jnp.asarray(a["sv"])

    def solve(u0: Any, v0: Any, rtol: Any) -> Any:
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(rhs),
            diffrax.Dopri8(),
            t0=0.0,
            t1=float(times[-1]),
            dt0=1e-9,
            y0=jnp.concatenate([u0 / su, v0 / sv]),
            saveat=diffrax.SaveAt(ts=jnp.asarray(times), fn=mu),
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol, pcoeff=0.4, icoeff=0.3),
            max_steps=MAX_STEPS,
        )
        return sol.ys, sol.stats["num_accepted_steps"], sol.stats["num_rejected_steps"]

    return Compiled(jax.jit(jax.vmap(solve, in_axes=(0, 0, None)) if batched else solve))


def run_diffrax(prob: Problem, rtol: float, solver: Compiled) -> dict[str, Any]:
    """diffrax on every pad of ``prob`` (initial states from the model of the batch), after a warm-up call."""
    import jax

    pads = len(prob.scenes)
    if pads == 1:
        u0, v0 = prob.y0[0]
    else:
        _, state = batch_at_start(prob.scenes, prob.device, "fp64")
        u0, v0 = (x.astype(np.float64).reshape(pads, -1) for x in state.numpy())
    if not solver.warm:  # compile once (rtol is traced: no recompilation per rtol)
        jax.block_until_ready(solver.fn(u0, v0, rtol))
        solver.warm = True
    t0 = time.perf_counter()
    ys, acc, rej = jax.block_until_ready(solver.fn(u0, v0, rtol))
    wall = time.perf_counter() - t0
    mu = np.asarray(ys).reshape(pads, -1).T
    return {"error": prob.error(mu), "time_s": wall, "steps": int(np.max(acc)), "rejected": int(np.sum(rej))}


# ----------------------------------------------------------------------------------------------- the benchmark


def ladder(settings: tuple[float, ...], fn: Callable[[float], dict], target: float, log: Callable[[str], None],
           what: str) -> list[dict[str, Any]]:  # fmt: skip
    """``fn(setting)`` for each setting in order until one reaches ``target``; a failure ends the ladder, marked.
    A run shorter than ``REPEAT_BELOW`` is repeated (``REPEATS`` runs at most, all within that time) and timed by
    the fastest."""
    tries: list[dict[str, Any]] = []
    for s in settings:
        try:
            r = fn(s)
        except Exception as e:  # noqa: BLE001 — one failing part is marked; the rest of the table goes on
            tries.append({"setting": s, "failed": f"{type(e).__name__}: {e}".splitlines()[0][:300]})
            log(f"{what} {s:g}: FAILED {tries[-1]['failed']}")
            if not isinstance(e, ImportError):
                traceback.print_exc()
            break
        times = [r["time_s"]]
        while len(times) < REPEATS and sum(times) < REPEAT_BELOW:  # short runs: best of a few (a shared host)
            times.append(fn(s)["time_s"])
        r.update(setting=s, reached=bool(r["error"] <= target), time_s=min(times), times_s=times)
        tries.append(r)
        log(f"{what} {s:g}: μ error {r['error']:.2e} in {r['time_s']:.3g} s ({work(r)})")
        if r["reached"]:
            break
    return tries


def entry(scene: str, solver: str, pads: int, where: str, unit: str, tries: list[dict], note: str = "") -> dict:
    """One line of the table: the try that reached the target (or the last one), and the others."""
    return {"scene": scene, "solver": solver, "pads": pads, "where": where, "unit": unit, "tries": tries, "note": note}


def diffrax_entries(probs: list[Problem], target: float, log: Callable[[str], None]) -> list[dict]:
    """diffrax Dopri8 on each problem (one pad, a batch), or a row saying why not."""
    out: list[dict] = []
    for batch in probs:
        name, pads = batch.scene.name, len(batch.scenes)
        try:
            solver = diffrax_solver(batch.odes[0], batch.times, pads > 1)
        except ImportError as e:
            out.append(entry(name, "diffrax Dopri8 + PID", pads, "JAX", "rtol", [], f"skipped: {e} (JAX with "
                             "diffrax is not importable here)"))  # fmt: skip
            log(f"diffrax skipped: {e}")
            return out
        import jax

        where = f"JAX {jax.__version__} on {jax.default_backend()}"
        tries = ladder(DIFFRAX_RTOLS, lambda r, b=batch, s=solver: run_diffrax(b, r, s), target, log,
                       f"diffrax {pads} pad(s) rtol")  # fmt: skip
        note = "vmap over the pads" if pads > 1 else ""
        out.append(entry(name, "diffrax Dopri8 + PID", pads, where, "rtol", tries, note))
    return out


def measure_scene(name: str, args: argparse.Namespace, log: Callable[[str], None]) -> list[dict]:
    """Every solver on scene ``name``: one pad, and the batch of --pads pads where it runs."""
    cuda = args.device.startswith("cuda")
    scene = make_scene(name)
    duration = args.duration or DURATIONS[name]
    prob = Problem(scene, 1, 1, duration, log, args.device)
    batch = Problem(scene, args.pads, args.check_pads, duration, log, args.device) if args.pads > 1 else None
    fixed = "onchip"  # what ``auto`` picks for strang on either device
    rows = [entry(name, "reference: SciPy DOP853", 1, "host CPU", "rtol",
                  [{"setting": REF_RTOL, "error": 0.0, "time_s": prob.ref_wall, "reached": True}])]  # fmt: skip
    for p in [prob] + ([batch] if batch is not None else []):
        pads, dev = len(p.scenes), args.device
        if pads > 1 and not (cuda or args.batch_on_cpu):
            continue

        def ours(
            integ: str, eng: str, key: str, p: Problem = p, precision: str = "fp64", **kw: Any
        ) -> Callable[[float], dict]:
            return lambda s: run_ours(p, args.device, integ, eng, precision, **{key: s}, **kw)

        for eng in ("onchip", "general"):
            what = f"adaptive {eng} {pads} pad(s) tol"
            tries = ladder(TOLS, ours("adaptive", eng, "tolerance"), args.target, log, what)
            rows.append(entry(name, "ours: adaptive (DP5)", pads, f"{dev}, {eng} engine", "tol", tries))
        what = f"auto {pads} pad(s) tol"  # auto at its default tolerances (general engine only)
        tries = ladder((DEFAULT_TOLERANCE,), ours("auto", "general", "tolerance"), args.target, log, what)
        rows.append(entry(name, "ours: auto (its defaults)", pads, f"{dev}, general engine", "tol", tries))
        what = f"strang at its defaults {pads} pad(s) dt"  # step and precision: default_step, default_precision
        at = ours("strang", fixed, "dt", precision=default_precision("strang"), crossing=None)  # its defaults
        tries = ladder((default_step("strang", p.scenes),), at, args.target, log, what)
        where = f"{dev}, {fixed} engine, {default_precision('strang')}"
        rows.append(entry(name, "ours: strang (its defaults)", pads, where, "dt", tries))
        first = ladder(STEPS[:1], ours("strang", fixed, "dt"), args.target, log, f"strang {pads} pad(s) dt")
        rows.append(entry(name, "ours: strang 1e-8 s", pads, f"{dev}, {fixed} engine", "dt", first))
        if first and not first[-1].get("failed") and not first[-1]["reached"]:
            tries = ladder(STEPS[1:], ours("strang", fixed, "dt"), args.target, log, f"strang {pads} pad(s) dt")
            rows.append(entry(name, "ours: strang", pads, f"{dev}, {fixed} engine", "dt", tries))
    tries = ladder(RTOLS, lambda r: run_scipy(prob, r), args.target, log, "SciPy DOP853 rtol")
    rows.append(entry(name, "SciPy DOP853", 1, "host CPU", "rtol", tries))
    if not args.no_diffrax:
        rows += diffrax_entries([prob] + ([batch] if batch is not None else []), args.target, log)
    return rows


def estimate(args: argparse.Namespace) -> float:
    """A rough wall-time estimate of a run [s] from the costs per simulated ms measured on a 2-core CPU host
    (:data:`COST_PER_MS`; ours ÷10 on CUDA), kernel compilation with a cold cache included."""
    cuda = args.device.startswith("cuda")
    total = 60.0
    for name in args.scenes:
        ms = (args.duration or DURATIONS[name]) / 1e-3
        ref, ours, scipy = COST_PER_MS[name]
        total += ms * (ref * (1 + (args.check_pads if args.pads > 1 else 0)) + ours / (10.0 if cuda else 1.0) + scipy)
        total += 0.0 if args.no_diffrax else 20.0 + (40.0 if args.pads > 1 else 0.0)
    return total


def measure(args: argparse.Namespace, argv: list[str]) -> Path:
    """Run the benchmark on --device (--pads by default 64 on CUDA, none on the CPU); writes
    ``OUT/tts_<device>.json`` and prints the markdown table."""
    import scipy
    import warp as wp

    from aca_warp.common.files import machine

    if args.pads is None:
        args.pads = 64 if args.device.startswith("cuda") else 0
    t0 = time.perf_counter()

    def log(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", flush=True)

    log(f"estimated wall time ≈ {estimate(args) / 60:.1f} min (Warp and JAX compilation included)")
    rows: list[dict] = []
    for name in args.scenes:
        rows += measure_scene(name, args, log)
    doc = {
        "machine": machine(wp.get_device(args.device)),
        "versions": {"warp": wp.__version__, "numpy": np.__version__, "scipy": scipy.__version__},
        "target": args.target,
        "durations_s": {name: args.duration or DURATIONS[name] for name in args.scenes},
        "pads": args.pads,
        "check_pads": args.check_pads,
        "pad_perturbation_m_s": PAD_PERTURBATION,
        "rows": rows,
        "total_wall_s": time.perf_counter() - t0,
        "command": command_line("time_to_solution.py", argv),
    }
    try:
        import jax

        doc["versions"]["jax"] = jax.__version__
    except ImportError:
        pass
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = write_json(out / f"tts_{re.sub(r'[^A-Za-z0-9]+', '', args.device)}.json", doc)
    print("\n".join(table(doc)))
    log(f"wrote {path}")
    return path


# ----------------------------------------------------------------------------------------------- report


def chosen(tries: list[dict]) -> dict | None:
    """The try that reached the target, else the last one that ran (None when none ran)."""
    ran = [t for t in tries if "error" in t]
    return next((t for t in ran if t.get("reached")), ran[-1] if ran else None)


def work(t: dict) -> str:
    """The work of a try: steps (+ rejected) of ours and diffrax, right-hand-side evaluations of SciPy."""
    if "fevals" in t:
        return f"{t['fevals']} f-evals"
    steps = t.get("steps", "")
    return f"{steps} (+{t['rejected']} rej.)" if t.get("rejected") else f"{steps}"


def fastest(doc: dict) -> list[str]:
    """One line per (scene, pads): the solvers that reached the target, fastest first, with their times."""
    groups: dict[tuple[str, int], list[tuple[float, str]]] = {}
    for e in doc["rows"]:
        t = chosen(e["tries"])
        if t is not None and t.get("reached") and not e["solver"].startswith("reference"):
            groups.setdefault((e["scene"], e["pads"]), []).append((t["time_s"], e["solver"]))
    return [
        f"* {scene}, {pads} pad(s): " + ", ".join(f"{name} {time_s:.3g} s" for time_s, name in sorted(g))
        for (scene, pads), g in groups.items()
    ]


def table(doc: dict) -> list[str]:
    """The markdown table of one result: a row per solver entry."""
    rows = []
    for e in doc["rows"]:
        t = chosen(e["tries"])
        unit = e["unit"]
        misses = [x for x in e["tries"] if "error" in x and x is not t]
        failed = [x["failed"] for x in e["tries"] if "failed" in x]
        note = "; ".join(
            [e["note"]] * bool(e["note"])
            + [f"{unit} {x['setting']:g}: {x['error']:.1e} in {x['time_s']:.3g} s" for x in misses]
            + [f"failed: {f}" for f in failed]
        )
        if t is None:
            rows.append([e["scene"], e["solver"], e["pads"], e["where"], "–", "–", "–", "–", note])
            continue
        ok = "" if t.get("reached") else " (not reached)"
        rows.append([e["scene"], e["solver"], e["pads"], e["where"], f"{unit} {t['setting']:g}",
                     f"{t['error']:.1e}{ok}", fmt(t["time_s"], ".3g"), work(t), note])  # fmt: skip
    head = ["scene", "solver", "pads", "where", "setting", "μ error", "time [s]", "steps / f-evals"]
    head.append("not reached / notes")
    m = doc["machine"]
    return [
        f"### {m['device_name']} (host: {m['host']})",
        "",
        f"μ error ≤ {doc['target']:g} over "
        + ", ".join(f"{d * 1e3:g} ms ({name})" for name, d in doc["durations_s"].items())
        + f" against SciPy DOP853 rtol {REF_RTOL:g}; "
        + (
            f"batches of {doc['pads']} pads with per-pad initial velocity perturbations N(0, "
            f"({doc['pad_perturbation_m_s']:g} m/s)²), μ error checked on {doc['check_pads']} of them"
            if doc["pads"] > 1
            else "no batches (--pads)"
        )
        + f"; total {doc['total_wall_s']:.0f} s. Versions: "
        + ", ".join(f"{k} {v}" for k, v in doc["versions"].items())
        + f". Command: `{OUT_ARG.sub('--out OUT', doc['command'])}`.",
        "",
        *md_table(head, rows),
        "",
        f"Reaching μ error ≤ {doc['target']:g}, fastest first:",
        "",
        *fastest(doc),
        "",
    ]


def report(paths: list[str], page: Path) -> None:
    """The tables of the result JSONs into the generated part of ``page``."""
    import json

    lines = [""]
    for p in paths:
        lines += table(json.loads(Path(p).read_text()))
    replace_generated(page, lines, (BEGIN, END), "Time to solution")
    print(f"wrote {page}")


# ----------------------------------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    """The command line of the benchmark."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_device(ap)
    ap.add_argument("--out", default="tts_results", help="folder of the result JSON")
    ap.add_argument("--scenes", nargs="+", default=["hf1", "stickslip"], choices=SCENES)
    ap.add_argument("--target", type=positive, default=1e-7, help="μ error to reach")
    ap.add_argument(
        "--duration", type=positive, help="simulated time of every scene [s] (default 1 ms, stickslip 0.2 ms)"
    )
    ap.add_argument("--pads", type=int_at_least(0), help="pads of the batches (default 64 on CUDA, none on the CPU)")
    ap.add_argument("--check-pads", type=int_at_least(1), default=4, help="pads of a batch whose μ error is checked")
    ap.add_argument("--batch-on-cpu", action="store_true", help="run our engines on the batches on the CPU too")
    ap.add_argument("--no-diffrax", action="store_true", help="leave diffrax out")
    ap.add_argument("--report", nargs="+", metavar="JSON", help="write the tables of result JSONs into the page")
    add_page_options(ap, "docs/time_to_solution.md", "docs/figures")
    return ap


def main(argv: list[str] | None = None) -> int:
    """Measure (or, with --report, only report); returns 0."""
    return measure_or_report(build_parser(), argv, lambda args: report(args.report, Path(args.page)), measure)


if __name__ == "__main__":
    sys.exit(main())
