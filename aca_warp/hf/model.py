"""Static HF model of a batch of pads: per-patch and per-pad Warp arrays, CSR neighbours, normal forces.

Flat layout: the patches of all pads are concatenated; ``patch_pad`` (n,) gives each patch's pad and
``pad_patch_start`` (pads + 1,) the offsets. Per-pad parameters are arrays of length ``pad_count``.
Array dtype is the model's precision T (float32 or float64) unless noted. Built once per patch set by
:func:`build_model`; growth (varying-area study) updates the area-dependent arrays in place on the device.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.devices import init_warp, load_kernels
from aca_warp.common.errors import SceneError
from aca_warp.hf import limits
from aca_warp.hf.contact import ContactSolution, solve_scene_contact
from aca_warp.kernels import hf as hf_kernels
from aca_warp.kernels import neighbours as neighbours_kernels
from aca_warp.kernels.neighbours import build_neighbours
from aca_warp.scene import Scene

PRECISIONS = {"fp32": wp.float32, "fp64": wp.float64}


@dataclass
class PadModel:
    """Device arrays of the HF model; shapes: n = patch_count, P = pad_count, E = nnz of the CSR.

    Per patch (n,): ``area`` [m²], ``sqrt_area`` [m], ``height`` [m], ``radius`` (friction radius) [m], ``x``, ``y``
    (position in the disc plane) [m],
    ``inv_mass`` [1/kg], ``k_t`` and ``k_n`` [N/m], ``k_diag`` = k_T + Σ_j k_ij [N/m], ``damping``
    [N s/m], ``normal_force`` [N], ``patch_pad`` (int32).

    CSR: ``nbr_start`` (n+1,) int32, ``nbr_index`` (E,) int32, ``nbr_inv_dist`` (E,) [1/m],
    ``nbr_stiffness`` k_ij (E,) [N/m].

    Per pad (P,): ``pad_kc`` (K_C) [N/m²], ``pad_omega`` [rad/s], ``pad_mu_scale`` (M/π), ``pad_slope``
    and ``pad_decay`` [s/m], ``pad_mu_pad``, ``pad_load`` (F_N) [N], ``pad_matrix_force`` [N],
    ``pad_matrix_radius`` [m]; for growth also ``pad_growth`` [m per event], ``pad_k_t``/``pad_k_n``
    (K_T, K_N) [N/m²], ``pad_mass_per_area`` [kg/m²], ``pad_zeta``, and float64 ``pad_area`` [m²],
    ``pad_moment`` [m³], ``pad_k_m`` [N/m³], ``pad_gap`` [m].
    """

    scenes: list[Scene]
    device: wp.Device
    dtype: Any
    pad_patch_start_host: np.ndarray
    contacts: list[ContactSolution]
    nbr_count: int
    arrays: dict[str, wp.array] = field(default_factory=dict)

    def __getattr__(self, name: str) -> wp.array:
        try:
            return self.__dict__["arrays"][name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def pad_count(self) -> int:
        """Number of pads in the batch."""
        return len(self.scenes)

    @property
    def patch_count(self) -> int:
        """Total number of patches."""
        return int(self.pad_patch_start_host[-1])

    @property
    def nnz(self) -> int:
        """Number of directed neighbour links."""
        return self.nbr_count

    @property
    def has_coupling(self) -> bool:
        """Whether any patch has a neighbour (else no coupling stage runs)."""
        return self.nnz > 0

    @property
    def precision(self) -> str:
        """``"fp32"`` or ``"fp64"``."""
        return "fp64" if self.dtype == wp.float64 else "fp32"

    def args(self, names: tuple[str, ...]) -> list[wp.array]:
        """The arrays ``names``, in that order (a kernel's model arguments)."""
        return [self.arrays[k] for k in names]

    def host(self, name: str) -> np.ndarray:
        """A copy of a model array on the host (``numpy()`` of a CPU array is a view of the live array)."""
        return self.arrays[name].numpy().copy()


def build_model(scenes: list[Scene], *, device: str | wp.Device = "cpu", precision: str = "fp64") -> PadModel:
    """Build the device model of a batch of scenes (one pad each): contact solve, neighbours, arrays."""
    if not scenes:
        raise SceneError("a batch needs at least one scene")
    if precision not in PRECISIONS:
        raise SceneError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    init_warp()
    try:
        dev = wp.get_device(device)
    except (ValueError, RuntimeError) as e:
        raise SceneError(f"device {device!r} is not available: {e}") from None
    load_kernels([neighbours_kernels, hf_kernels], dev)
    T = PRECISIONS[precision]
    counts = np.array([s.patches.count for s in scenes])
    limits.check_int32("the patches of the batch", int(counts.sum()), "run fewer or smaller pads")
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    host = _patch_arrays(scenes, counts)
    x, y, pad_of = host["x"], host["y"], host["patch_pad"]
    radius = np.array([s.material.coupling_radius for s in scenes])
    # refuse what int32 offsets or the memory cannot hold before the links are counted (lower bound), then made
    n, r_max = len(x), float(radius.max())
    limits.check_model_memory(n, limits.links_lower_bound(x, y, pad_of, radius), dev, r_max, exact=False)
    contacts = [solve_scene_contact(s) for s in scenes]
    nbr_start, nbr_index, nbr_inv = build_neighbours(
        x, y, pad_of, radius, dev, check=lambda links: limits.check_model_memory(n, links, dev, r_max, exact=True)
    )
    k_ij = _edge_stiffness(scenes, host["sqrt_area"], pad_of, nbr_start, nbr_index, nbr_inv)
    rows = np.repeat(np.arange(n), np.diff(nbr_start))
    host.update(
        {
            "pad_patch_start": start,
            "normal_force": np.concatenate([c.patch_force for c in contacts]),
            "nbr_start": nbr_start,
            "nbr_index": nbr_index if len(nbr_index) else np.zeros(1),
            "nbr_inv_dist": nbr_inv if len(nbr_inv) else np.zeros(1),
            "nbr_stiffness": k_ij,
            "k_diag": host["k_t"] + np.bincount(rows, k_ij[: len(nbr_index)], minlength=n),
        }
    )
    host.update(_pad_arrays(scenes, contacts))
    wide = {"pad_area", "pad_moment", "pad_k_m", "pad_gap"}  # float64 whatever the precision (the growth re-solve)
    arrays = {k: _device_array(a, _INT32 if k in _INT32_NAMES else wp.float64 if k in wide else T, dev)
              for k, a in host.items()}  # fmt: skip
    return PadModel(
        scenes=list(scenes),
        device=dev,
        dtype=T,
        pad_patch_start_host=start,
        contacts=contacts,
        nbr_count=len(nbr_index),
        arrays=arrays,
    )


_INT32 = wp.int32
_INT32_NAMES = frozenset({"patch_pad", "pad_patch_start", "nbr_start", "nbr_index"})


def _device_array(a: np.ndarray, dtype: Any, device: wp.Device) -> wp.array:
    """A host array on ``device`` as ``dtype`` (int32, float64 or the state precision)."""
    np_dtype = {wp.int32: np.int32, wp.float64: np.float64, wp.float32: np.float32}[dtype]
    return wp.array(np.ascontiguousarray(a, dtype=np_dtype), dtype=dtype, device=device)


def _patch_arrays(scenes: list[Scene], counts: np.ndarray) -> dict[str, np.ndarray]:
    """Per-patch host arrays of a batch: pad index, geometry [m, m²], mass, stiffnesses and damping (SI)."""
    cat = lambda f: np.concatenate([f(s) for s in scenes])  # noqa: E731
    x, y = cat(lambda s: s.patches.x), cat(lambda s: s.patches.y)
    area = cat(lambda s: s.patches.area)
    mat = {
        k: np.repeat([getattr(s.material, k) for s in scenes], counts)
        for k in ("K_T", "K_N", "mass_per_area", "damping_ratio")
    }
    sq = np.sqrt(area)
    mass = mat["mass_per_area"] * area
    k_t = mat["K_T"] * sq
    return {
        "patch_pad": np.repeat(np.arange(len(scenes), dtype=np.int32), counts),
        "area": area,
        "sqrt_area": sq,
        "height": cat(lambda s: s.patches.height),
        "radius": np.hypot(x, y),
        "x": x,
        "y": y,
        "inv_mass": 1.0 / mass,
        "k_t": k_t,
        "k_n": mat["K_N"] * sq,
        "damping": 2.0 * mat["damping_ratio"] * np.sqrt(k_t * mass),
    }


def _pad_arrays(scenes: list[Scene], contacts: list[ContactSolution]) -> dict[str, np.ndarray]:
    """Per-pad host arrays: coupling, disc, friction law, load and matrix; for growing batches the growth law and
    the float64 contact terms its re-solve needs."""
    per_pad = lambda f: np.array([f(s) for s in scenes], dtype=np.float64)  # noqa: E731
    out = {
        "pad_kc": per_pad(lambda s: s.material.K_C),
        "pad_omega": per_pad(lambda s: s.angular_velocity),
        "pad_mu_scale": per_pad(lambda s: s.friction.M / np.pi),
        "pad_slope": per_pad(lambda s: s.friction.slope),
        "pad_decay": per_pad(lambda s: s.friction.decay),
        "pad_mu_pad": per_pad(lambda s: s.friction.mu_pad),
        "pad_load": per_pad(lambda s: s.normal_force),
        "pad_matrix_force": np.array([c.matrix_force.sum() for c in contacts]),
        "pad_matrix_radius": np.array([_matrix_radius(s, c) for s, c in zip(scenes, contacts, strict=True)]),
    }
    growth = [s.growth for s in scenes]
    if any(g is not None for g in growth):
        out.update(
            {
                "pad_growth": np.array([g.increment if g else 0.0 for g in growth]),
                "pad_k_t": per_pad(lambda s: s.material.K_T),
                "pad_k_n": per_pad(lambda s: s.material.K_N),
                "pad_mass_per_area": per_pad(lambda s: s.material.mass_per_area),
                "pad_zeta": per_pad(lambda s: s.material.damping_ratio),
                "pad_area": per_pad(lambda s: s.pad.area),
                "pad_moment": per_pad(lambda s: s.pad.first_moment),
                "pad_k_m": per_pad(lambda s: s.material.matrix_stiffness),
                "pad_gap": np.array([c.gap if np.isfinite(c.gap) else 0.0 for c in contacts]),
            }
        )
    return out


def _edge_stiffness(
    scenes: list[Scene], sq: np.ndarray, pad_of: np.ndarray, start: np.ndarray, index: np.ndarray, inv_d: np.ndarray
) -> np.ndarray:
    """k_ij = K_C √A_i √A_j / D0_ij per CSR link [N/m] (paper Eq. 3); one dummy entry when there are none."""
    if len(index) == 0:
        return np.zeros(1)
    rows = np.repeat(np.arange(len(sq)), np.diff(start))
    kc = np.array([s.material.K_C for s in scenes])[pad_of[rows]]
    return kc * sq[rows] * sq[index] * inv_d


def _matrix_radius(scene: Scene, contact: ContactSolution) -> float:
    """Radius of the centroid of the matrix normal (hence Coulomb friction) forces [m]."""
    f = contact.matrix_force
    if f.sum() > 0:
        return float(np.sum(f * scene.matrix.radius) / f.sum())
    a = scene.matrix.area
    if a.sum() > 0:
        return float(np.sum(a * scene.matrix.radius) / a.sum())
    return float(np.mean(scene.matrix.radius))  # no matrix area, no matrix force: finite, unused (was 0/0 = NaN)


def coupling_matrix(model: PadModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Host CSR (start, index, k_ij [N/m]) of the coupling springs at the model's current areas."""
    start = model.host("nbr_start")
    return start, model.host("nbr_index")[: model.nnz], model.host("nbr_stiffness")[: model.nnz].astype(np.float64)
