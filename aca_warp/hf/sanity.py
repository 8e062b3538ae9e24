"""Physical sanity of an HF run: checks that catch results no physics allows, cheaply and for every engine.

* :func:`contact_problem` — after the contact solve (docs/model.md §2.6) the normal forces of every pad must be
  finite, non-negative and sum to the clamp force within :data:`CONTACT_RTOL`. Stiffnesses or heights beyond what
  float64 resolves break this (``K_N = 1e308``: forces of 1e284 N for a 487 N load; ``K_N ≥ 1e20`` or heights of
  1e6 m: the load lost to cancellation in g = (Σ k_j h_j − F_N)/Σ k_j).
* :func:`mu_bounds` / :func:`mu_fault` — at every chunk end, from the samples the recorder returns anyway: the
  global μ = (Σ F_N,i f_i + μ_pad F_m)/F_N can never exceed max|f| · (patch share) + μ_pad · (matrix share), with
  |f| < M for Eq. 4 (atan < π/2 and the decay factor ≤ 2). A sample beyond it (plus :data:`MU_SLACK`) means the
  state is garbage even though it is finite.
* the step's resolution of the friction slope is checked with the stable step (:func:`aca_warp.hf.solver.check_step`).

Each check raises (contact: :class:`~aca_warp.common.errors.PhysicsError` before the run, exit 3; μ: a
:class:`~aca_warp.common.errors.SimulationFault` that stops the run, exit 3) unless the run options say
``accept_unphysical`` (``aca-warp hf --accept-unphysical``): then it prints one warning and the run goes on.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from aca_warp.common.errors import PhysicsError, SimulationFault, option
from aca_warp.hf.model import PadModel

CONTACT_RTOL = 1.0e-6  # relative mismatch of Σ normal forces and the clamp force (float64 solves reach ~1e-13)
MU_SLACK = 1.0e-5  # relative slack of the μ bound (fp32 friction coefficients and sums)


_WARNED: set[str] = set()


def warn(message: str) -> None:
    """One ``aca-warp: warning:`` line on stderr (each message once per process: the checks before a file is
    created run again in the run loop)."""
    if message in _WARNED:
        return
    _WARNED.add(message)
    print(f"aca-warp: warning: {message}", file=sys.stderr, flush=True)


def contact_problem(model: PadModel) -> str | None:
    """The first pad whose contact solution is not physical, in words; None when all are."""
    for p, (scene, c) in enumerate(zip(model.scenes, model.contacts, strict=True)):
        load = float(scene.normal_force)
        forces = np.concatenate([c.patch_force, c.matrix_force])
        where = f"pad {p} ({scene.name}): " if model.pad_count > 1 else ""
        hint = (
            f"K_N = {scene.material.K_N:g} N/m², matrix stiffness {scene.material.matrix_stiffness:g} N/m³, "
            f"heights up to {float(np.max(scene.patches.height)):g} m are beyond what float64 resolves"
        )
        if not np.all(np.isfinite(forces)):
            return f"{where}the contact solve gave non-finite normal forces; {hint}"
        if np.any(forces < 0):
            return f"{where}the contact solve gave negative normal forces; {hint}"
        total = float(math.fsum(forces))
        if abs(total - load) > CONTACT_RTOL * load:
            return (
                f"{where}the normal forces sum to {total:.6g} N for a clamp force of {load:.6g} N (relative error "
                f"{abs(total - load) / max(load, 1e-300):.2g} > {CONTACT_RTOL:g}); {hint}"
            )
    return None


def check_contact(model: PadModel, *, accept: bool) -> None:
    """Raise :class:`PhysicsError` (or warn, with ``accept``) when :func:`contact_problem` finds one."""
    problem = contact_problem(model)
    if problem is None:
        return
    accept_it = option("accept_unphysical=True", "--accept-unphysical", "")  # (a sweep runs no unphysical pad)
    if accept:
        warn(f"{problem} (accepted: {accept_it})")
        return
    raise PhysicsError(f"{problem}; {accept_it} runs it anyway" if accept_it else problem)


def mu_bounds(model: PadModel) -> np.ndarray:
    """Largest |μ| each pad can reach, shape (pads,): (M Σ F_N,i + μ_pad F_m)/F_N at the start, or max(M, μ_pad)
    for a growing pad (its shares change), times 1 + :data:`MU_SLACK`; +inf without load."""
    out = np.full(model.pad_count, np.inf)
    for p, (s, c) in enumerate(zip(model.scenes, model.contacts, strict=True)):
        load = float(s.normal_force)
        if load <= 0:
            continue
        if s.growth is not None:
            b = max(s.friction.M, s.friction.mu_pad)
        else:
            b = (s.friction.M * float(np.sum(c.patch_force)) + s.friction.mu_pad * float(np.sum(c.matrix_force))) / load
        out[p] = b * (1.0 + MU_SLACK) + 1e-12
    return out


def mu_fault(time: np.ndarray, mu: np.ndarray, bounds: np.ndarray) -> SimulationFault | None:
    """The first sample whose |μ| exceeds its pad's bound, as a fault; None when there is none.

    Args:
        time: Sample times [s], shape (rows,).
        mu: Global μ per sample and pad, shape (rows, pads).
        bounds: :func:`mu_bounds`, shape (pads,).
    """
    bad = np.abs(mu) > bounds[None, :]
    bad |= ~np.isfinite(mu) & np.isfinite(bounds)[None, :]
    if not bad.any():
        return None
    row = int(np.flatnonzero(bad.any(axis=1))[0])
    pad = int(np.flatnonzero(bad[row])[0])
    t = float(time[row])
    return SimulationFault(
        f"unphysical friction coefficient at t = {t:.6g} s, pad {pad}: mu = {mu[row, pad]:.6g}, beyond "
        f"{bounds[pad]:.6g} (M times the patch share of the load plus mu_pad times the matrix share); likely cause: "
        "a state the step does not resolve or extreme scene parameters",
        time=t,
        pad=pad,
        patch=-1,
        cause="unphysical friction coefficient",
    )
