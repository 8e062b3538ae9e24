"""Time-varying HF state: patch displacements u [m], velocities u̇ [m/s] and the cached spring force [N]."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from aca_warp.hf.model import PadModel, coupling_matrix
from aca_warp.scene import Initial


@dataclass
class HFState:
    """State arrays in the model's precision, shape (patch_count,).

    Attributes:
        u: Tangential displacement of each patch along the local disc direction, relative to the pad [m].
        v: Patch velocity u̇ in the pad frame [m/s].
        force: Elastic force F_s(u) = −k_T u − Σ k_ij (u_i − u_j) at the current u [N] (Strang cache).
    """

    u: wp.array
    v: wp.array
    force: wp.array

    def numpy(self) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) on the host."""
        return self.u.numpy(), self.v.numpy()


def initial_state(model: PadModel) -> HFState:
    """Initial state of every pad from its scene's ``[initial]`` table (docs/model.md §2.7).

    ``rest``: u = u̇ = 0. ``equilibrium``: (diag k_T + L) u = F_N f(ω r), u̇ = 0, L the coupling Laplacian.
    Then, per pad, ``perturbation`` adds N(0, σ²) velocities [m/s] and ``displacement_perturbation`` N(0, σ²)
    displacements [m], drawn as :func:`perturbations` does.
    """
    n = model.patch_count
    u = np.zeros(n)
    v = np.zeros(n)
    if any(s.initial.state == "equilibrium" for s in model.scenes):
        u_eq = _equilibrium(model)
        for p, s in enumerate(model.scenes):
            if s.initial.state == "equilibrium":
                a, b = model.pad_patch_start_host[p : p + 2]
                u[a:b] = u_eq[a:b]
    for p, s in enumerate(model.scenes):
        a, b = model.pad_patch_start_host[p : p + 2]
        du, dv = perturbations(s.initial, b - a)
        if dv is not None:
            v[a:b] += dv
        if du is not None:
            u[a:b] += du
    return state_from_host(model, u, v)


def state_from_host(model: PadModel, u: np.ndarray, v: np.ndarray) -> HFState:
    """A state on the model's device from displacements ``u`` [m] and velocities ``v`` [m/s] on the host, shape
    (patch_count,), rounded to the model's precision; the force cache zero (a run fills it)."""
    np_t = np.float32 if model.dtype == wp.float32 else np.float64
    mk = lambda a: wp.array(a.astype(np_t), dtype=model.dtype, device=model.device)  # noqa: E731
    return HFState(u=mk(u), v=mk(v), force=mk(np.zeros(model.patch_count)))


def perturbations(initial: Initial, n: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Seeded perturbations (displacement [m], velocity [m/s]) of ``n`` patches, shape (n,) each; None when off.

    Velocities: ``np.random.default_rng(seed).normal(0, perturbation, n)``. Displacements: the same from the
    first child of the seed's ``SeedSequence``, so each stream is the same whether the other is on or not.
    """
    dv = du = None
    if initial.perturbation > 0:
        dv = np.random.default_rng(initial.seed).normal(0.0, initial.perturbation, n)
    if initial.displacement_perturbation > 0:
        rng = np.random.default_rng(np.random.SeedSequence(initial.seed).spawn(1)[0])
        du = rng.normal(0.0, initial.displacement_perturbation, n)
    return du, dv


def _equilibrium(model: PadModel) -> np.ndarray:
    """Static displacement with u̇ = 0: sparse solve of (diag k_T + L) u = F_N f(ω r)."""
    import scipy.sparse as sp  # here, not at the top: a run from rest needs no SciPy (≈ 0.2 s CPU of every start-up)
    import scipy.sparse.linalg as spla

    start, index, kij = coupling_matrix(model)
    n = model.patch_count
    rows = np.repeat(np.arange(n), np.diff(start))
    lap = sp.csr_matrix((-kij, (rows, index)), shape=(n, n))
    diag = model.host("k_t").astype(np.float64) + np.bincount(rows, kij, minlength=n)
    a = (lap + sp.diags(diag)).tocsc()
    pad = model.host("patch_pad")
    fric = np.zeros(n)
    for p, s in enumerate(model.scenes):
        m = pad == p
        fric[m] = s.friction.coefficient(s.angular_velocity * model.host("radius")[m].astype(np.float64))
    return spla.spsolve(a, model.host("normal_force").astype(np.float64) * fric)
