"""Seeded patch layouts: :class:`PatchGenerator` places non-overlapping patches uniformly over a pad and draws their
heights (docs/model.md §2.9 for the placement, §2.6 for the heights)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aca_warp.common.errors import SceneError
from aca_warp.scene.parts import HEIGHT_LAWS, Pad, Patches, _finite

MAX_TRIES = 100_000_000  # largest max_tries: its trials per patch, ×10, fit the native loop's int32 counter


@dataclass(frozen=True)
class PatchGenerator:
    """Seeded generator of non-overlapping patches, uniform over the pad (docs/model.md §2.9).

    Positions and areas come from ``np.random.default_rng(seed)``; heights from a separate stream of the
    same seed (:meth:`heights`), so a height law never moves a patch. Heights are h_i = height + height_spread·z_i
    with z_i drawn independently of position and area:

    * ``"normal"``: z standard normal truncated to [−height_truncation, height_truncation] (Gaussian summit
      heights, Greenwood–Williamson; the cut bounds the lowest patch, hence the load that brings every patch
      into contact, independently of the patch count);
    * ``"uniform"``: z uniform in [−1, 1] (height_spread is the half-width).

    ``height_spread = 0`` gives equal heights (no height is drawn).

    Attributes:
        count: Number of patches.
        area_min: Smallest area [m²]; areas are uniform in [area_min, area_max].
        area_max: Largest area [m²].
        height: Centre (mean) of the free heights above the matrix [m].
        seed: Seed of the generator (NumPy PCG64).
        height_spread: Spread of the heights [m]: standard deviation before truncation (normal law) or
            half-width (uniform law).
        height_law: ``"normal"`` (truncated) or ``"uniform"``.
        height_truncation: Cut of the normal law in standard deviations [1] (ignored by the uniform law).
    """

    count: int = 1758
    area_min: float = 2.0e-8
    area_max: float = 8.0e-8
    height: float = 3.0e-6
    seed: int = 1
    height_spread: float = 0.0
    height_law: str = "normal"
    height_truncation: float = 2.0

    def __post_init__(self) -> None:
        if isinstance(self.count, bool) or not isinstance(self.count, int) or self.count < 1:
            raise SceneError(f"patches.count must be a positive integer, got {self.count!r}")
        _finite("patches.area_min", self.area_min, low=0.0, strict=True)
        _finite("patches.area_max", self.area_max, low=0.0, strict=True)
        _finite("patches.height", self.height, low=0.0)
        if self.area_max < self.area_min:
            raise SceneError(f"patches.area_max ({self.area_max:g}) must be >= patches.area_min ({self.area_min:g})")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SceneError(f"patches.seed must be a non-negative integer, got {self.seed!r}")
        _finite("patches.height_spread", self.height_spread, low=0.0)
        if self.height_law not in HEIGHT_LAWS:
            raise SceneError(f"patches.height_law must be one of {', '.join(HEIGHT_LAWS)}, got {self.height_law!r}")
        _finite("patches.height_truncation", self.height_truncation, low=0.0, strict=True)
        if self.height_bounds[0] < 0.0:
            raise SceneError(
                f"patches.height ({self.height:g} m) minus the law's reach ({self.height - self.height_bounds[0]:g} m) "
                "must be >= 0: the lowest patch would lie below the matrix; lower height_spread or height_truncation"
            )

    @property
    def height_bounds(self) -> tuple[float, float]:
        """Smallest and largest height the law can draw [m]."""
        reach = self.height_spread * (self.height_truncation if self.height_law == "normal" else 1.0)
        return self.height - reach, self.height + reach

    def heights(self) -> np.ndarray:
        """Free heights of the patches in placement order [m], shape (count,).

        Drawn from ``np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])`` (a stream independent
        of the one that places the patches), one uniform u_i per patch: z_i = 2u_i − 1 (uniform law) or
        z_i = Φ⁻¹(Φ(−c) + u_i (Φ(c) − Φ(−c))) (normal law cut at c = height_truncation, inverse CDF).
        """
        if self.height_spread == 0.0:
            return np.full(self.count, self.height)
        from scipy.special import ndtr, ndtri

        u = np.random.default_rng(np.random.SeedSequence(self.seed).spawn(1)[0]).random(self.count)
        if self.height_law == "uniform":
            z = 2.0 * u - 1.0
        else:
            c = self.height_truncation
            lo = ndtr(-c)
            z = np.clip(ndtri(lo + u * (ndtr(c) - lo)), -c, c)
        return np.clip(self.height + self.height_spread * z, *self.height_bounds)

    def generate(self, pad: Pad, *, max_tries: int = 200) -> Patches:
        """Place the patches by random sequential addition; sorted row-major by coupling-size cells. They fit
        ``pad`` by the generator's own tests, and are marked as fitting it, so that a scene does not test them
        again: inside the pad by :meth:`Pad.disc_fits`, as the scene's check; apart by ``math.hypot`` of the centres'
        differences, where the check takes ``np.hypot``, which can differ in the last place (in about 0.6 % of
        pairs): a pair that touches to within that rounding (≈ 1e-19 m here) stays as the generator placed it."""
        if isinstance(max_tries, bool) or not isinstance(max_tries, int) or not 1 <= max_tries <= MAX_TRIES:
            raise SceneError(f"max_tries must be an integer in [1, {MAX_TRIES}], got {max_tries!r}")
        if self.count * self.area_min > pad.area:  # cannot fit; also keeps absurd counts from allocating
            raise SceneError(
                f"could not place {self.count} non-overlapping patches of {self.area_min:g}-{self.area_max:g} m² on "
                f"the pad: count × area_min = {self.count * self.area_min:g} m² exceeds its area {pad.area:g} m²; "
                "use fewer or smaller patches"
            )
        rng = np.random.default_rng(self.seed)
        area = rng.uniform(self.area_min, self.area_max, self.count)
        xy = self._place(pad, rng, np.sqrt(area / np.pi), max_tries)
        order = _spatial_order(xy[:, 0], xy[:, 1], 5.0e-3)
        patches = Patches(xy[order, 0], xy[order, 1], area[order], self.heights()[order], source=self.describe())
        object.__setattr__(patches, "_fits", pad)  # the mark of Scene._check_geometry (docstring)
        return patches

    def describe(self) -> str:
        """The ``source`` of the patches this generator makes: ``generator(count=…, area=[…] m2, height=… m,
        seed=…[, height_spread=… m, law=…[, cut=…]])``, the numbers to 6 significant digits."""
        desc = (
            f"generator(count={self.count}, area=[{self.area_min:g}, {self.area_max:g}] m2, "
            f"height={self.height:g} m, seed={self.seed})"
        )
        if self.height_spread > 0.0:
            cut = f", cut={self.height_truncation:g}" if self.height_law == "normal" else ""
            desc = desc[:-1] + f", height_spread={self.height_spread:g} m, law={self.height_law}{cut})"
        return desc

    def _place(self, pad: Pad, rng: np.random.Generator, rad: np.ndarray, max_tries: int) -> np.ndarray:
        """Centres (count, 2) [m] of discs of radii ``rad`` [m] by random sequential addition inside the pad.

        A trial position is r = √U(r_inner², r_outer²), θ = π/2 + U(−half span, half span), the two uniforms drawn
        in that order per trial; a trial is kept when the disc lies inside the pad and overlaps no disc placed
        before (centre distance, ``math.hypot``, < the sum of the radii), among those of the 3 × 3 cells of width
        max(2 max(rad), 1e-4) m around it. Disc i gets ``max_tries`` × 10 trials. The trials come from
        :class:`_Trials`; the loop over them runs natively on the CPU (``aca_warp.kernels.placement``), which leaves
        to :meth:`_overlaps` the trials whose distance it cannot tell from the sum of the radii: the decisions of
        the loop in Python, one trial at a time."""
        from aca_warp.common.devices import init_warp
        from aca_warp.kernels import placement

        init_warp()
        cell = max(2.0 * float(rad.max()), 1e-4)
        if pad.r_outer / cell >= 2.0**30:
            raise SceneError(
                f"the pad (r_outer {pad.r_outer:g} m) is too large against its patches (cells of {cell:g} m) for the "
                "placement grid: use a smaller pad or larger patches"
            )
        trials = _Trials(pad, rng)
        trials.draw(-(-(self.count + self.count // 8 + 1) // _Trials.BLOCK))
        loop = placement.DiscPlacement(rad, cell, pad.fit_bounds)
        while True:
            placed, k, _, status, _ = loop.run(trials.x, trials.y, trials.dist, trials.edge, max_tries * 10)
            if status == placement.DONE:
                return np.column_stack(loop.placed())
            if status == placement.MORE_TRIALS:
                trials.draw(max(8, len(trials.x) // (2 * _Trials.BLOCK)))
            elif status == placement.AMBIGUOUS:
                loop.decide(not _overlaps(trials.x[k], trials.y[k], int(placed), rad, *loop.placed(), cell))
            else:
                raise SceneError(
                    f"could not place {self.count} non-overlapping patches of {self.area_min:g}-{self.area_max:g} m² "
                    f"on the pad (placed {placed}); use fewer or smaller patches"
                )


def _overlaps(px: float, py: float, i: int, rad: np.ndarray, xs: np.ndarray, ys: np.ndarray, cell: float) -> bool:
    """Whether disc ``i`` at (px, py) [m] overlaps one of the discs placed before it (centres ``xs``, ``ys`` [m]) in
    the 3 × 3 cells around it: ``math.hypot`` of the centres' differences against the sum of the radii."""
    cx, cy = math.floor(px / cell), math.floor(py / cell)
    near = np.flatnonzero((np.abs(np.floor(xs / cell) - cx) <= 1) & (np.abs(np.floor(ys / cell) - cy) <= 1))
    ri = float(rad[i])
    return any(math.hypot(px - float(xs[j]), py - float(ys[j])) < ri + float(rad[j]) for j in near)


class _Trials:
    """The trial positions of :meth:`PatchGenerator._place` in draw order, made in blocks of :data:`BLOCK`.

    Per trial two uniforms of ``rng`` (``low + (high − low) · u``, the arithmetic of ``Generator.uniform``, from
    ``Generator.random``: the same stream as scalar ``uniform`` calls), the radius and angle with NumPy's
    elementwise arithmetic (each operation rounded once, as in scalars), ``math.cos`` and ``math.sin``, and the
    distances to the pad's bounds (:meth:`Pad.edge_distances`, elementwise: the values of one trial at a time, as the
    tests check). Attributes ``x``, ``y`` [m] and ``dist``, ``edge`` [m], shape (trials drawn,)."""

    BLOCK = 64

    def __init__(self, pad: Pad, rng: np.random.Generator) -> None:
        self.pad, self.rng = pad, rng
        self.x = self.y = self.dist = self.edge = np.empty(0)

    def draw(self, blocks: int) -> None:
        """Append ``blocks`` blocks of trials."""
        pad, n = self.pad, self.BLOCK * blocks
        u = self.rng.random(2 * n)
        lo2, hi2, hs = pad.r_inner**2, pad.r_outer**2, pad.half_span
        r = np.sqrt(lo2 + (hi2 - lo2) * u[0::2])
        th = (math.pi / 2 + (-hs + (hs - -hs) * u[1::2])).tolist()
        x = r * np.fromiter(map(math.cos, th), np.float64, n)
        y = r * np.fromiter(map(math.sin, th), np.float64, n)
        dist, edge = pad.edge_distances(x, y)
        self.x, self.y = np.concatenate((self.x, x)), np.concatenate((self.y, y))
        self.dist, self.edge = np.concatenate((self.dist, dist)), np.concatenate((self.edge, edge))


def _spatial_order(x: np.ndarray, y: np.ndarray, cell: float) -> np.ndarray:
    """Row-major order of square cells of width ``cell`` [m], then x: neighbours end up close in memory."""
    cx = np.floor((x - x.min()) / cell).astype(np.int64)
    cy = np.floor((y - y.min()) / cell).astype(np.int64)
    return np.lexsort((x, cx, cy))
