"""Static HF model of a batch of pads: per-patch and per-pad Warp arrays, CSR neighbours, normal forces.

Flat layout: the patches of all pads are concatenated; ``patch_pad`` (n,) gives each patch's pad and
``pad_patch_start`` (pads + 1,) the offsets. Per-pad parameters are arrays of length ``pad_count``.
Array dtype is the model's precision T (float32 or float64) unless noted. Built once per patch set by
:func:`build_model`; growth (varying-area study) updates the area-dependent arrays in place on the device.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import warp as wp

from aca_warp.common.devices import get_device, load_kernels
from aca_warp.common.errors import SceneError, option
from aca_warp.hf import limits
from aca_warp.hf.contact import ContactSolution, solve_scene_contact
from aca_warp.kernels import hf as hf_kernels
from aca_warp.kernels import neighbours as neighbours_kernels
from aca_warp.kernels.hf_types import HFModel
from aca_warp.kernels.neighbours import build_neighbours
from aca_warp.scene import Scene

PRECISIONS = {"fp32": wp.float32, "fp64": wp.float64}


FIXED_ARRAYS = frozenset({"nbr_start", "nbr_index", "patch_pad", "pad_patch_start"})  # no run changes them


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
    _struct: Any = field(default=None, repr=False)
    _fixed: dict[str, np.ndarray] = field(default_factory=dict, repr=False)  # host copies of FIXED_ARRAYS
    memo: dict[Any, Any] = field(default_factory=dict, repr=False)  # what is derived from FIXED_ARRAYS alone

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

    def struct(self, pad_growth: wp.array | None = None) -> Any:
        """The kernels' parameter group of this model (:data:`~aca_warp.kernels.hf_types.HFModel`), built once and
        kept; with ``pad_growth`` (the area increment per growth event of an engine's step, shape (pads,)) a new one
        that holds it."""
        if pad_growth is not None:
            return HFModel.of(self.dtype, {**self.arrays, "pad_growth": pad_growth})
        if self._struct is None:
            self._struct = HFModel.of(self.dtype, self.arrays)
        return self._struct

    def host(self, name: str) -> np.ndarray:
        """A copy of a model array on the host (``numpy()`` of a CPU array is a view of the live array); for the
        arrays no run changes (:data:`FIXED_ARRAYS`), one read-only copy, made once."""
        if name not in FIXED_ARRAYS:
            return self.arrays[name].numpy().copy()
        if name not in self._fixed:
            a = self.arrays[name].numpy().copy()
            a.setflags(write=False)
            self._fixed[name] = a
        return self._fixed[name]


@dataclass
class HostModel:
    """A batch's model before it is on a device: every array of :class:`PadModel` as a NumPy array of the type its
    device array has (the state precision T, float64 or int32), with the same names and shapes; picklable, so that
    another process can make it (:func:`host_model`) and this one put it on the device (:func:`upload`).

    Attributes:
        scenes: One scene per pad.
        precision: ``"fp32"`` or ``"fp64"``.
        pad_patch_start: Patch offsets of the pads, shape (pads + 1,) int32.
        contacts: The contact solution of every pad.
        nbr_count: Directed neighbour links of the batch.
        arrays: Name -> host array.
    """

    scenes: list[Scene]
    precision: str
    pad_patch_start: np.ndarray
    contacts: list[ContactSolution]
    nbr_count: int
    arrays: dict[str, np.ndarray]

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays [B]."""
        return int(sum(a.nbytes for a in self.arrays.values()))


def build_model(scenes: list[Scene], *, device: str | wp.Device = "cpu", precision: str = "fp64") -> PadModel:
    """Build the device model of a batch of scenes (one pad each): contact solve, neighbours, arrays
    (:func:`host_model` on ``device``, then :func:`upload` to it). The state precision is the model's, fp64 unless
    asked; a run file made by :func:`~aca_warp.hf.runner.run_scene` or ``aca-warp hf`` takes the integrator's
    default instead (fp32 for ``strang``: :func:`~aca_warp.hf.options.default_precision`)."""
    return upload(host_model(scenes, device=device, precision=precision), device)


def host_model(scenes: list[Scene], *, device: str | wp.Device = "cpu", precision: str = "fp64") -> HostModel:
    """The model of a batch of scenes on the host: contact solve, neighbours, arrays as NumPy.

    ``device``: where the neighbour search runs (its hash-grid kernel) and whose memory must hold the model (the
    limits are checked against it); a model made here for a device equals, bit for bit, the one
    :func:`build_model` makes on a device of the same kind (CPU, or a CUDA device of the same model). Pads that share
    a layout (the same patch positions and areas, coupling radius and K_C, as the pads of a sweep that differ in
    load, speed or friction) share one neighbour search and one computation of their coupling springs
    (:func:`_coupling`); the arrays are the same bit for bit as when every pad is searched on its own.
    """
    if not scenes:
        raise SceneError("a batch needs at least one scene")
    if precision not in PRECISIONS:
        raise SceneError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    dev = get_device(device)
    load_kernels([neighbours_kernels], dev)
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
    nbr_start, nbr_index, nbr_inv, k_ij, k_sum = _coupling(scenes, host, start, dev, _NP_DTYPES[T])
    host.update(
        {
            "pad_patch_start": start,
            "normal_force": np.concatenate([c.patch_force for c in contacts]),
            "nbr_start": nbr_start,
            "nbr_index": nbr_index if len(nbr_index) else np.zeros(1),
            "nbr_inv_dist": nbr_inv if len(nbr_inv) else np.zeros(1),
            "nbr_stiffness": k_ij if len(k_ij) else np.zeros(1),
            "k_diag": host["k_t"] + k_sum,
        }
    )
    host.update(_pad_arrays(scenes, contacts))
    wide = {"pad_area", "pad_moment", "pad_k_m", "pad_gap"}  # float64 whatever the precision (the growth re-solve)
    kind = lambda k: _INT32 if k in _INT32_NAMES else wp.float64 if k in wide else T  # noqa: E731
    if T == wp.float32:
        _check_fp32({k: a for k, a in host.items() if kind(k) == T})
    arrays = {k: np.ascontiguousarray(a, dtype=_NP_DTYPES[kind(k)]) for k, a in host.items()}
    return HostModel(list(scenes), precision, start, contacts, len(nbr_index), arrays)


# what the model's arrays that large inputs make large come from (for the fp32 refusal)
_FROM = {
    "k_n": "material.K_N",
    "pad_k_n": "material.K_N",
    "k_t": "material.K_T",
    "pad_k_t": "material.K_T",
    "pad_kc": "material.K_C",
    "nbr_stiffness": "material.K_C",
    "k_diag": "material.K_T and K_C",
    "normal_force": "load.normal_force",
    "pad_load": "load.normal_force",
}


def _check_fp32(arrays: dict[str, np.ndarray]) -> None:
    """Refuse a model whose values (float64 ``arrays``, by name) single precision cannot hold: a finite value beyond
    its largest, 3.4e38, would become infinite. The message names the scene's setting behind the array where known."""
    top = float(np.finfo(np.float32).max)
    fp64 = option("precision='fp64', run.precision in a sweep spec", "--precision fp64")
    for name, a in arrays.items():
        a = np.asarray(a)
        if a.size == 0:
            continue
        lo, hi = float(a.min()), float(a.max())
        if math.isfinite(lo) and math.isfinite(hi) and max(-lo, hi) <= top:
            continue  # every value finite, none beyond the largest (two passes, no copies)
        values = np.abs(a.astype(np.float64))
        big = float(values[np.isfinite(values)].max(initial=0.0))
        if big > top:
            source = f" (from {_FROM[name]})" if name in _FROM else ""
            raise SceneError(
                f"the model's {name}{source} reaches {big:.3g}, beyond what fp32 holds ({top:.3g}): run it in fp64 "
                f"({fp64})"
            )


def upload(host: HostModel, device: str | wp.Device, *, copy: bool = True) -> PadModel:
    """Put a :class:`HostModel` on ``device`` (its HF kernels loaded); ``copy=False`` on the CPU: the model's arrays
    are the host arrays themselves (a model to read, e.g. for the checks before a run, not to run)."""
    dev = get_device(device)
    if not copy and not dev.is_cpu:
        raise SceneError("a model shares the host arrays only on the CPU")
    if copy:
        load_kernels([hf_kernels], dev)
    T = PRECISIONS[host.precision]
    arrays = {k: wp.array(a, dtype=_WP_DTYPES[a.dtype.type], device=dev, copy=copy) for k, a in host.arrays.items()}
    return PadModel(
        scenes=list(host.scenes),
        device=dev,
        dtype=T,
        pad_patch_start_host=host.pad_patch_start,
        contacts=host.contacts,
        nbr_count=host.nbr_count,
        arrays=arrays,
    )


def layout_groups(scenes: list[Scene]) -> np.ndarray:
    """The coupling layout of each pad, shape (pads,) int: pads with equal patch positions and areas, coupling radius
    and K_C (hence equal neighbour lists and coupling springs) get the same number, numbered by first appearance."""
    keys: dict[tuple, int] = {}
    digests: dict[int, bytes] = {}  # per Patches object (the pads of a sweep share them)
    out = np.empty(len(scenes), dtype=np.int64)
    for p, s in enumerate(scenes):
        pt = s.patches
        if id(pt) not in digests:
            h = hashlib.blake2b(digest_size=16)
            for a in (pt.x, pt.y, pt.area):
                h.update(np.ascontiguousarray(a).tobytes())
            digests[id(pt)] = h.digest()
        key = (digests[id(pt)], s.material.coupling_radius, s.material.K_C)
        out[p] = keys.setdefault(key, len(keys))
    return out


def _coupling(
    scenes: list[Scene], host: dict[str, np.ndarray], start: np.ndarray, dev: wp.Device, dtype: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The batch's CSR neighbour lists (start (n+1,) int32, index (E,) int32, 1/D0 (E,) [1/m]), coupling springs k_ij
    (E,) [N/m] (both as ``dtype``, the state precision's NumPy type) and their sum per patch Σ_j k_ij (n,) [N/m]
    (float64, summed before the springs are rounded to ``dtype``).

    One neighbour search covers one pad of each layout (:func:`layout_groups`) with the batch's cell size (the largest
    coupling radius) and extent, so that every list is in the order and every 1/D0 has the bits of a search over the
    whole batch (the hash grid orders a pad's neighbours by cell and index, whatever the other pads); the springs and
    their row sums (in link order, as ``np.bincount``) are made once per layout; the pads' copies are joined.
    """
    n = int(start[-1])
    group = layout_groups(scenes)
    first = np.unique(group, return_index=True)[1]  # one pad per layout, in layout order
    counts = np.diff(start)
    sub = np.concatenate([np.arange(start[p], start[p + 1]) for p in first])
    sub_start = np.concatenate([[0], np.cumsum(counts[first])])
    radius = np.array([scenes[p].material.coupling_radius for p in first])
    sub_pad = np.repeat(np.arange(len(first), dtype=np.int32), counts[first])
    shared = len(first) < len(scenes)

    def check(links: int) -> None:  # the batch's links, or a lower bound of them while layouts are shared
        limits.check_model_memory(n, links, dev, float(radius.max()), exact=not shared)

    s_start, s_index, s_inv = build_neighbours(host["x"][sub], host["y"][sub], sub_pad, radius, dev, check=check)
    sq = host["sqrt_area"][sub]
    parts = []  # per layout: (row offsets, pad-local indices, 1/D0, k_ij, row sums of k_ij)
    for g, p in enumerate(first):
        a, b = sub_start[g], sub_start[g + 1]
        st = s_start[a : b + 1]
        index = s_index[st[0] : st[-1]] - a
        inv = s_inv[st[0] : st[-1]]
        rows = np.repeat(np.arange(b - a), np.diff(st))
        k_ij = scenes[p].material.K_C * sq[a:b][rows] * sq[a:b][index] * inv  # paper Eq. 3, left to right as a batch
        k_sum = np.bincount(rows, k_ij, minlength=b - a)
        parts.append((st - st[0], index, inv.astype(dtype), k_ij.astype(dtype), k_sum))
    links = np.array([len(parts[g][1]) for g in group], dtype=np.int64)
    if shared:
        limits.check_model_memory(n, int(links.sum()), dev, float(radius.max()), exact=True)
    link_start = np.concatenate([[0], np.cumsum(links)])
    nbr_start = np.concatenate(
        [parts[g][0][:-1] + link_start[p] for p, g in enumerate(group)] + [link_start[-1:]]
    ).astype(np.int32)
    index = np.concatenate([parts[g][1] + start[p] for p, g in enumerate(group)]).astype(np.int32)
    join = lambda k: np.concatenate([parts[g][k] for g in group])  # noqa: E731
    return nbr_start, index, join(2), join(3), join(4)


_INT32 = wp.int32
_INT32_NAMES = frozenset({"patch_pad", "pad_patch_start", "nbr_start", "nbr_index"})


_NP_DTYPES = {wp.int32: np.int32, wp.float64: np.float64, wp.float32: np.float32}
_WP_DTYPES = {v: k for k, v in _NP_DTYPES.items()}


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
    k_ij = model.arrays["nbr_stiffness"].numpy()[: model.nnz].astype(np.float64)  # astype copies
    return start, model.host("nbr_index")[: model.nnz], k_ij
