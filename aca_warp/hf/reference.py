"""Independent SciPy reference of the HF equations of motion (NumPy/SciPy only, no Warp kernels).

The equation of motion of patch i (docs/model.md §2.2, docs/stability.md),

    m_i ü_i + c_i u̇_i + k_T,i u_i + Σ_j k_ij (u_i − u_j) = F_N,i f(ω r_i − u̇_i),

is written as a first-order system y = (u, u̇) of size 2n and handed to ``scipy.integrate.solve_ivp``
with an analytic sparse Jacobian. The constants (masses, stiffnesses, damping, normal forces, radii) are
read from a built :class:`~aca_warp.hf.model.PadModel` of one pad; the integration is SciPy's. Used by
``scripts/work_precision.py`` as the high-order reference of short windows and as the baseline solvers a
user would otherwise pick.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from aca_warp.common.errors import SceneError
from aca_warp.hf.model import PadModel, coupling_matrix

SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau", "BDF")
IMPLICIT_METHODS = ("LSODA", "Radau", "BDF")


@dataclass
class ReferenceSolution:
    """A SciPy solution sampled at ``t``.

    Attributes:
        t: Sample times [s], shape (N,).
        u: Displacements [m], shape (N, n).
        v: Velocities [m/s], shape (N, n).
        wall_time: Wall time of ``solve_ivp`` [s].
        nfev: Right-hand-side evaluations.
        njev: Jacobian evaluations.
        method: SciPy method name.
        rtol: Relative tolerance.
    """

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    wall_time: float
    nfev: int
    njev: int
    method: str
    rtol: float


class ReferenceODE:
    """The HF system of one pad as a SciPy ODE (float64, host).

    Args:
        model: A built model with exactly one pad and no growth (its current arrays are used).
    """

    def __init__(self, model: PadModel) -> None:
        if model.pad_count != 1:
            raise SceneError(f"the SciPy reference takes one pad, got {model.pad_count}")
        if "pad_growth" in model.arrays:
            raise SceneError("the SciPy reference does not model patch growth")
        scene = model.scenes[0]
        f64 = lambda name: model.host(name).astype(np.float64)  # noqa: E731
        n = model.patch_count
        self.n = n
        self.m = 1.0 / f64("inv_mass")
        self.c = f64("damping")
        self.fn = f64("normal_force")
        self.r = f64("radius")
        self.x, self.y = f64("x"), f64("y")
        start, index, kij = coupling_matrix(model)
        rows = np.repeat(np.arange(n), np.diff(start))
        lap = sp.csr_matrix((-kij, (rows, index)), shape=(n, n))
        diag = f64("k_t") + np.bincount(rows, kij, minlength=n)
        self.K = (lap + sp.diags(diag)).tocsr()
        self.vd = scene.angular_velocity * self.r
        fr = scene.friction
        self.M, self.slope, self.decay, self.mu_pad = fr.M, fr.slope, fr.decay, fr.mu_pad
        self.load = scene.normal_force
        self.f_matrix = float(f64("pad_matrix_force")[0])
        self.r_matrix = float(f64("pad_matrix_radius")[0])
        self.omega = scene.angular_velocity
        self._minv_K = sp.diags(1.0 / self.m) @ self.K
        self._eye = sp.identity(n, format="csr")
        kt = f64("k_t")
        self.u_scale = np.maximum(self.fn, 1e-12 * max(self.fn.max(), 1e-30)) / kt
        self.v_scale = self.u_scale * np.sqrt(kt / self.m)

    def friction(self, s: np.ndarray) -> np.ndarray:
        """Signed Eq. 4, f(s) for sliding velocity s [m/s]."""
        return self.M / np.pi * np.arctan(self.slope * s) * (1.0 / (self.decay * np.abs(s) + 1.0) + 1.0)

    def friction_slope(self, s: np.ndarray) -> np.ndarray:
        """df/ds [s/m]."""
        a = np.arctan(self.slope * s)
        g = 1.0 / (self.decay * np.abs(s) + 1.0)
        return (
            self.M
            / np.pi
            * (self.slope / (1.0 + (self.slope * s) ** 2) * (g + 1.0) - a * self.decay * np.sign(s) * g * g)
        )

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt for y = (u, u̇), shape (2n,)."""
        n = self.n
        u, v = y[:n], y[n:]
        acc = (-(self.K @ u) - self.c * v + self.fn * self.friction(self.vd - v)) / self.m
        return np.concatenate([v, acc])

    def jac(self, _t: float, y: np.ndarray) -> sp.csr_matrix:
        """Sparse Jacobian [[0, I], [−M⁻¹K, −diag((c + F_N f′(v_d − u̇))/m)]]."""
        v = y[self.n :]
        dv = -(self.c + self.fn * self.friction_slope(self.vd - v)) / self.m
        return sp.bmat([[None, self._eye], [-self._minv_K, sp.diags(dv)]], format="csc")

    def jac_sparsity(self) -> sp.csr_matrix:
        """Sparsity pattern of :meth:`jac`."""
        pattern = (self._minv_K != 0).astype(np.int8)
        eye = self._eye.astype(np.int8)
        return sp.bmat([[sp.csr_matrix((self.n, self.n), dtype=np.int8), eye], [pattern, eye]], format="csr")

    def globals(self, u: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
        """μ, torque [N m], Σu̇ and Σ|u̇| [m/s] and the friction centroid |Σ F_i r⃗_i| / |Σ F_i| [m] of the patches
        for states of shape (N, n) (docs/model.md §2.8)."""
        f = self.fn * self.friction(self.vd[None, :] - v)
        fsum = f.sum(axis=1)
        centroid = np.hypot(f @ self.x, f @ self.y) / np.where(fsum != 0.0, np.abs(fsum), np.inf)
        coulomb = self.mu_pad * self.f_matrix * np.sign(self.omega)
        ftot = f.sum(axis=1) + coulomb
        return {
            "mu": ftot / self.load,
            "torque": (f * self.r).sum(axis=1) + coulomb * self.r_matrix,
            "sum_velocity": v.sum(axis=1),
            "sum_abs_velocity": np.abs(v).sum(axis=1),
            "friction_centroid": centroid,
        }

    def solve(
        self,
        times: np.ndarray,
        *,
        method: str = "DOP853",
        rtol: float = 1e-10,
        atol_factor: float | None = None,
        u0: np.ndarray | None = None,
        v0: np.ndarray | None = None,
        analytic_jacobian: bool = True,
    ) -> ReferenceSolution:
        """Integrate from t = 0 to ``times[-1]`` and sample at ``times`` [s].

        ``atol`` is per component: ``atol_factor`` × the patch's displacement scale F_N,i/k_T,i or velocity
        scale (F_N,i/k_T,i)√(k_T,i/m_i) (default ``atol_factor = rtol``). Implicit methods get the analytic
        sparse Jacobian (``analytic_jacobian``) or only its sparsity pattern (SciPy's finite differences).
        """
        if method not in SCIPY_METHODS:
            raise SceneError(f"unknown SciPy method {method!r}; choose from {', '.join(SCIPY_METHODS)}")
        n = self.n
        y0 = np.concatenate([np.zeros(n) if u0 is None else u0, np.zeros(n) if v0 is None else v0])
        f = rtol if atol_factor is None else atol_factor
        atol = np.concatenate([f * self.u_scale, f * self.v_scale])
        kw: dict = {}
        if method in IMPLICIT_METHODS:
            if method == "LSODA":  # LSODA (ODEPACK) takes only a dense Jacobian
                kw["jac"] = lambda t, y: self.jac(t, y).toarray()
            elif analytic_jacobian:
                kw["jac"] = self.jac
            else:
                kw["jac_sparsity"] = self.jac_sparsity()
        t0 = time.perf_counter()
        sol = solve_ivp(self.rhs, (0.0, float(times[-1])), y0, method=method, rtol=rtol, atol=atol, t_eval=times, **kw)
        wall = time.perf_counter() - t0
        if not sol.success:
            raise RuntimeError(f"solve_ivp {method} failed: {sol.message}")
        return ReferenceSolution(
            t=sol.t,
            u=sol.y[:n].T,
            v=sol.y[n:].T,
            wall_time=wall,
            nfev=int(sol.nfev),
            njev=int(sol.njev),
            method=method,
            rtol=rtol,
        )
