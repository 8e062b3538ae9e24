"""Normal force distribution between patches and the pad matrix (docs/model.md §2.6).

A rigid backplate is pressed toward the disc with the clamp force F_N. Every contact element is a
compression-only spring in parallel: patch i with stiffness k_N,i = K_N √A_i and free height h_i, matrix
cell e with stiffness k_m a_e (Winkler) and elevation z_e. With g the height of the disc surface above the
matrix reference plane,

    F_N,i = k_N,i max(h_i − g, 0),    F_e = k_m a_e max(z_e − g, 0),    Σ_i F_N,i + Σ_e F_e = F_N.

The total force is a monotone, piecewise-linear function of g, so the solve here is exact: sort the
breakpoints, find the active segment, solve the linear equation on it. Re-solve whenever areas (and so
stiffnesses) change; the device version for growing patches on a flat matrix is ``contact_flat`` in ``kernels/hf.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aca_warp.common.errors import SceneError
from aca_warp.scene import Scene


@dataclass(frozen=True)
class ContactSolution:
    """Result of a contact solve.

    Attributes:
        gap: Height g of the disc surface above the matrix reference plane [m] (+inf without load).
        patch_force: Normal force on each patch [N], shape (n,).
        matrix_force: Normal force on each matrix cell [N], shape (c,).
    """

    gap: float
    patch_force: np.ndarray
    matrix_force: np.ndarray

    @property
    def total(self) -> float:
        """Sum of all normal forces [N]."""
        return float(self.patch_force.sum() + self.matrix_force.sum())

    @property
    def patch_share(self) -> float:
        """Fraction of the load carried by the patches [1] (0 without load)."""
        t = self.total
        return float(self.patch_force.sum() / t) if t > 0 else 0.0


def solve_contact(
    stiffness: np.ndarray, height: np.ndarray, load: float, *, n_patches: int | None = None
) -> ContactSolution:
    """Exact solve of Σ_j k_j max(H_j − g, 0) = load for g, then the element forces.

    Args:
        stiffness: Spring stiffness of every element, patches first [N/m], shape (n + c,).
        height: Free height of every element [m], shape (n + c,).
        load: Clamp force F_N [N] (≥ 0).
        n_patches: How many leading elements are patches (default: all).
    """
    k = np.asarray(stiffness, dtype=np.float64)
    h = np.asarray(height, dtype=np.float64)
    n = len(k) if n_patches is None else n_patches
    if load < 0 or not np.isfinite(load):
        raise SceneError(f"normal force must be finite and >= 0, got {load}")
    if load == 0.0:
        return ContactSolution(np.inf, np.zeros(n), np.zeros(len(k) - n))
    if not np.any(k > 0):
        raise SceneError("no contact element has positive stiffness: the load cannot be carried")
    order = np.argsort(-h, kind="stable")  # highest first: they come into contact first as g falls
    hs, ks = h[order], k[order]
    ck = np.cumsum(ks)
    ckh = np.cumsum(ks * hs)
    # F(hs[m]) = Σ_{j<m} k_j (hs_j − hs_m): non-decreasing in m, F(hs[0]) = 0 < load
    f_at = ckh - ck * hs
    m = int(np.searchsorted(f_at, load, side="left"))  # first breakpoint where F ≥ load, m ≥ 1
    # on that segment elements 0..m-1 are active (all of them if the load exceeds every breakpoint);
    # ck[m-1] > 0 because F(hs[m]) ≥ load > 0 needs some stiffness among them
    g = (ckh[m - 1] - load) / ck[m - 1]
    f = k * np.maximum(h - g, 0.0)
    return ContactSolution(float(g), f[:n], f[n:])


def solve_scene_contact(scene: Scene, *, area: np.ndarray | None = None) -> ContactSolution:
    """Contact of a scene (optionally with patch areas ``area`` [m²] replacing the scene's)."""
    k, h = scene_elements(scene, area=area)
    return solve_contact(k, h, scene.normal_force, n_patches=scene.patches.count)


def scene_elements(scene: Scene, *, area: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness [N/m] and free height [m] of every contact element, patches first, shape (n + c,) each.

    Patches: k_N,i = K_N √A_i (Eq. 1) and h_i; matrix cells: k_m a_e and z_e. ``area`` [m²] replaces the
    scene's patch areas (growth).
    """
    p, mat = scene.patches, scene.matrix
    a = p.area if area is None else np.asarray(area, dtype=np.float64)
    k = np.concatenate([scene.material.K_N * np.sqrt(a), scene.material.matrix_stiffness * mat.area])
    h = np.concatenate([p.height, mat.height])
    return k, h


def load_at_gap(stiffness: np.ndarray, height: np.ndarray, gap: float) -> float:
    """Σ_j k_j max(H_j − g, 0) [N]: the clamp force that puts the disc surface at height ``gap`` [m]."""
    k = np.asarray(stiffness, dtype=np.float64)
    return float(np.sum(k * np.maximum(np.asarray(height, dtype=np.float64) - gap, 0.0)))


@dataclass(frozen=True)
class LoadWindow:
    """The loads between which every patch touches the disc and the matrix does not (paper §3.1) [N].

    Attributes:
        all_in_contact: Load at which the disc reaches the lowest patch (g = min h_i): above it every patch
            is in contact; Σ k_N,i (h_i − h_min) on a matrix below the patches.
        matrix_contact: Load at which the disc reaches the highest matrix cell (g = max z_e): above it the
            matrix carries load; Σ k_N,i h_i on a fresh (flat, elevation 0) matrix.
    """

    all_in_contact: float
    matrix_contact: float

    def holds(self, load: float) -> bool:
        """Whether ``load`` [N] keeps every patch in contact and the matrix free (both ends included)."""
        return self.all_in_contact <= load <= self.matrix_contact

    def margin(self, load: float) -> float:
        """How far ``load`` [N] lies above the all-in-contact load, relative to it [1] (inf if that is 0)."""
        return load / self.all_in_contact - 1.0 if self.all_in_contact > 0 else np.inf


def load_window(scene: Scene, *, area: np.ndarray | None = None) -> LoadWindow:
    """The :class:`LoadWindow` of a scene (optionally at patch areas ``area`` [m²], e.g. after growth)."""
    k, h = scene_elements(scene, area=area)
    n = scene.patches.count
    return LoadWindow(load_at_gap(k, h, float(h[:n].min())), load_at_gap(k, h, float(h[n:].max())))
