"""Seeded patch layouts: :class:`PatchGenerator` places non-overlapping patches uniformly over a pad and draws their
heights (docs/model.md §2.9)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aca_warp.common.errors import SceneError
from aca_warp.scene.parts import HEIGHT_LAWS, Pad, Patches, _finite


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
        """Place the patches by random sequential addition; sorted row-major by coupling-size cells."""
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
        return Patches(xy[order, 0], xy[order, 1], area[order], self.heights()[order], source=self.describe())

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
        before. The trials come from :class:`_Trials`, which draws the uniforms in blocks and tests the pad's
        bounds for a block at once: the same positions, the same decisions as one trial at a time."""
        cell = max(2.0 * rad.max(), 1e-4)
        grid: dict[tuple[int, int], list[int]] = {}
        xs, ys, radii = [0.0] * self.count, [0.0] * self.count, rad.tolist()  # Python floats: the same values
        trials = _Trials(pad, rng)
        for i in range(self.count):
            ri = radii[i]
            for _ in range(max_tries * 10):
                px, py, inside = trials.next(ri)
                if not inside:
                    continue
                cx, cy = int(math.floor(px / cell)), int(math.floor(py / cell))
                if not any(
                    math.hypot(px - xs[j], py - ys[j]) < ri + radii[j]
                    for gx in (cx - 1, cx, cx + 1)
                    for gy in (cy - 1, cy, cy + 1)
                    for j in grid.get((gx, gy), ())
                ):
                    xs[i], ys[i] = px, py
                    grid.setdefault((cx, cy), []).append(i)
                    break
            else:
                raise SceneError(
                    f"could not place {self.count} non-overlapping patches of {self.area_min:g}-{self.area_max:g} m² "
                    f"on the pad (placed {i}); use fewer or smaller patches"
                )
        return np.column_stack((xs, ys))


class _Trials:
    """The trial positions of :meth:`PatchGenerator._place` in draw order, made in blocks of :data:`BLOCK`.

    Per trial two uniforms of ``rng`` (``low + (high − low) · u``, the arithmetic of ``Generator.uniform``, from one
    ``Generator.random`` block: the same stream as scalar ``uniform`` calls) and the position with the scalar
    ``math`` functions; a block's distances to the pad's bounds at once (:meth:`Pad.edge_distances`, NumPy's
    elementwise functions, the same for a block as for one value), and per trial :meth:`Pad.disc_fits` in scalars:
    the decisions of :meth:`Pad.contains_disc` one trial at a time."""

    BLOCK = 64

    def __init__(self, pad: Pad, rng: np.random.Generator) -> None:
        self.pad, self.rng = pad, rng
        self.x: list[float] = []
        self.y: list[float] = []
        self.r: list[float] = []
        self.edge: list[float] = []
        self.k = 0

    def _refill(self) -> None:
        pad, n = self.pad, self.BLOCK
        u = self.rng.random(2 * n).tolist()
        lo2, hi2, hs = pad.r_inner**2, pad.r_outer**2, pad.half_span
        x, y = [], []
        for t in range(n):
            r = math.sqrt(lo2 + (hi2 - lo2) * u[2 * t])
            th = math.pi / 2 + (-hs + (hs - -hs) * u[2 * t + 1])
            x.append(r * math.cos(th))
            y.append(r * math.sin(th))
        dist, edge = pad.edge_distances(np.array(x), np.array(y))
        self.x, self.y, self.r, self.edge, self.k = x, y, dist.tolist(), edge.tolist(), 0

    def next(self, radius: float) -> tuple[float, float, bool]:
        """The next trial position (x, y) [m] and whether a disc of ``radius`` [m] there lies inside the pad."""
        if self.k == len(self.x):
            self._refill()
        k = self.k
        self.k += 1
        return self.x[k], self.y[k], bool(self.pad.disc_fits(self.r[k], self.edge[k], radius))


def _spatial_order(x: np.ndarray, y: np.ndarray, cell: float) -> np.ndarray:
    """Row-major order of square cells of width ``cell`` [m], then x: neighbours end up close in memory."""
    cx = np.floor((x - x.min()) / cell).astype(np.int64)
    cy = np.floor((y - y.min()) / cell).astype(np.int64)
    return np.lexsort((x, cx, cy))
