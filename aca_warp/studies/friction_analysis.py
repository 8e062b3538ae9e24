"""Single-patch analysis of the friction sub-steps (:mod:`aca_warp.studies.friction_schemes`).

* :func:`hold` — a sticking patch under a frozen spring force F: repeated sub-steps Φ_h[F] at a given hγ from a
  small slip; the slip sequence shows whether the patch is held (slip → the static slip s* with F_N f(s*) = −F +
  c v) or chatters (slip changing sign every step).
* :func:`limit_cycle` — one isolated patch (its mass, stiffness, damping and normal force from a built pad, its
  links dropped) started stuck to the disc (u = 0, u̇ = ω r): the stick-slip limit cycle that the falling law
  sustains, run by a split scheme at a fixed step and by SciPy's Radau at rtol 1e-11 (:func:`cycle_reference`);
  :func:`cycle_measures` gives its period, displacement amplitude, mean friction coefficient and sticking share.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from aca_warp.studies.friction_schemes import STATIC_SLIP, Pads, Scheme, SplitStepper, friction, substep


def isolated(pads: Pads, i: int, speed: float | None = None) -> Pads:
    """Patch i of ``pads`` alone (its links dropped: K = k_T), at the disc speed ``speed`` [m/s] (None: its own
    ω r_i), stuck to the disc: u = 0, u̇ = the disc speed."""
    one = np.array([i])
    vd = pads.vd[one].copy() if speed is None else np.array([speed])
    return Pads(
        pads.m[one], pads.c[one], pads.fn[one], vd, pads.kt[one], sp.csr_matrix(pads.kt[one][:, None]),
        np.array([0, 1]), pads.M, pads.slope, pads.decay, pads.fn[one].copy(), np.zeros(1), np.zeros(1),
        vd.copy(), [f"patch {i}"],
    )  # fmt: skip


def hold(p1: Pads, method: str, hgamma: float, steps: int = 6, force_share: float = 0.5, slip0: float = 1e-3) -> dict:
    """Sub-steps Φ_h[F] of a single patch at h = hgamma/γ with F = −force_share F_N M frozen, from slip ``slip0``.

    Returns the slips v_d − v after each step [m/s], the static slip s* (F_N f(s*) = −F + c v, solved by
    bisection) and the friction force F_N f(slip)/F_N after each step against the static one."""
    gamma = float(p1.gamma_max()[0])
    h = hgamma / gamma
    force = np.array([-force_share * p1.fn[0] * p1.M])
    v = p1.vd - slip0
    evals = np.zeros(1)
    slips = []
    for _ in range(steps):
        v = substep(p1, method, v, h, force, evals)
        slips.append(float(p1.vd[0] - v[0]))
    lo, hi = -STATIC_SLIP, STATIC_SLIP  # F + F_N f(s) − c (v_d − s) = 0 is increasing in s on the static branch
    for _ in range(200):
        s = 0.5 * (lo + hi)
        g = force[0] + p1.fn[0] * friction(p1, np.array([s]))[0] - p1.c[0] * (p1.vd[0] - s)
        lo, hi = (lo, s) if g > 0 else (s, hi)
    return {
        "method": method,
        "hgamma": hgamma,
        "h": h,
        "slips": slips,
        "static_slip": s,
        "mu": [float(friction(p1, np.array([x]))[0]) for x in slips],
        "static_mu": float(friction(p1, np.array([s]))[0]),
        "evals_per_step": float(evals[0] / steps),
    }


def cycle_reference(p1: Pads, duration: float, sample_dt: float, rtol: float = 1e-11) -> dict[str, np.ndarray]:
    """The isolated patch's motion from its start state (u0, v0) by SciPy Radau (analytic Jacobian), sampled every
    ``sample_dt`` [s]."""
    m, c, k, fn, vd = (float(x[0]) for x in (p1.m, p1.c, p1.kt, p1.fn, p1.vd))

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], (-k * y[0] - c * y[1] + fn * friction(p1, np.array([vd - y[1]]))[0]) / m])

    def jac(_t: float, y: np.ndarray) -> np.ndarray:
        s = vd - y[1]
        at = math.atan(p1.slope * s)
        rq = 1.0 / (p1.decay * abs(s) + 1.0)
        da = p1.slope / (1.0 + (p1.slope * s) ** 2)
        df = p1.M / math.pi * (da * (rq + 1.0) - at * p1.decay * math.copysign(1.0, s) * rq * rq)
        return np.array([[0.0, 1.0], [-k / m, (-c - fn * df) / m]])

    t = np.arange(round(duration / sample_dt) + 1) * sample_dt
    scale = fn * p1.M / k
    sol = solve_ivp(
        rhs, (0.0, t[-1]), [float(p1.u0[0]), float(p1.v0[0])], method="Radau", jac=jac, t_eval=t, rtol=rtol,
        atol=[rtol * scale, rtol * vd],
    )  # fmt: skip
    return {"time": sol.t, "u": sol.y[0], "v": sol.y[1]}


def limit_cycle(p1: Pads, scheme: Scheme, h: float, duration: float) -> dict[str, Any]:
    """The isolated patch's cycle by ``scheme`` at the fixed step h [s]: u and the synchronous u̇ after every step,
    the chatter share (:class:`SplitStepper`) and friction evaluations per step."""
    n = round(duration / h)
    st = SplitStepper(p1, scheme)
    hh = np.full(1, h)
    u, v = np.empty(n + 1), np.empty(n + 1)
    u[0], v[0] = st.u[0], st.w[0]
    close = 0.0
    for j in range(1, n + 1):
        st.step(hh)
        before = st.evals[0]
        u[j], v[j] = st.u[0], st.velocity()[0]
        close += st.evals[0] - before
    return {
        "time": np.arange(n + 1) * h,
        "u": u,
        "v": v,
        "chatter": st.flips / max(st.held, 1),
        "evals_per_step": float((st.evals[0] - close) / n),
    }


def cycle_measures(p1: Pads, run: dict[str, np.ndarray], start: float) -> dict[str, float]:
    """Period [s] (mean spacing of the upward crossings of u through its mean, linearly interpolated), amplitude
    of u [m] (max − min)/2, mean friction coefficient f(v_d − u̇) and sticking share (|v_d − u̇| < STATIC_SLIP) of
    the part of a cycle run after ``start`` [s]."""
    keep = run["time"] >= start
    t, u, v = run["time"][keep], run["u"][keep], run["v"][keep]
    x = u - u.mean()
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    cross = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    slip = p1.vd[0] - v
    return {
        "period": float((cross[-1] - cross[0]) / (len(cross) - 1)) if len(cross) > 1 else math.nan,
        "amplitude": float(0.5 * (u.max() - u.min())),
        "mu_mean": float(friction(p1, slip).mean()),
        "stick_share": float((np.abs(slip) < STATIC_SLIP).mean()),
    }
