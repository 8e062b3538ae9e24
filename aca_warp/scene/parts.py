"""The parts of a scene and the scene itself: pad, patches, material, friction, initial state, growth, record,
matrix cells and :class:`Scene`, each validated as it is made.

A scene holds everything one HF run of one pad needs (paper §2.1.2, §3.1; ``docs/model.md`` §1–2). Every value is
checked here, before any simulation starts; errors are :class:`~aca_warp.common.errors.SceneError` with a one-line
message. All quantities are SI (m, m², kg, N, s, rad).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aca_warp.common import plausible
from aca_warp.common.errors import SceneError

INITIAL_STATES = ("rest", "equilibrium")
PATCH_VARIABLES = ("velocity", "displacement")
HEIGHT_LAWS = ("normal", "uniform")


def check_patch_variables(names: tuple[str, ...], setting: str = "record.patches") -> None:
    """Refuse a per-patch variable of ``names`` that is not one of :data:`PATCH_VARIABLES` (:class:`SceneError`
    naming ``setting``: the scene's field, or the command line's flag)."""
    for v in names:
        if v not in PATCH_VARIABLES:
            raise SceneError(f"{setting}: unknown variable {v!r}; choose from {', '.join(PATCH_VARIABLES)}")


def _finite(name: str, value: Any, *, low: float | None = None, strict: bool = False) -> float:
    """Return ``value`` as float after checking it is a finite number (and ≥ / > ``low``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SceneError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise SceneError(f"{name} must be finite, got {v}")
    if low is not None and (v <= low if strict else v < low):
        raise SceneError(f"{name} must be {'>' if strict else '>='} {low:g}, got {v:g}")
    return v


@dataclass(frozen=True)
class Material:
    """Constants of the HF model (docs/model.md §2.1); each overridable in a scene's ``[material]`` table.

    Attributes:
        K_N: Normal stiffness constant, k_N = K_N √A [N m⁻²] (paper Eq. 1).
        K_T: Tangential stiffness constant, k_T = K_T √A [N m⁻²] (paper Eq. 2).
        K_C: Coupling constant, k_ij = K_C √(A_i A_j) / D0_ij [N m⁻²] (paper Eq. 3).
        coupling_radius: Patches at a centre distance of at most this are coupled [m].
        damping_ratio: Damping ratio ζ of each patch, c = 2ζ√(k_T m) [1].
        mass_per_area: Effective mass per patch area, m = ρ_A A [kg m⁻²].
        matrix_stiffness: Winkler stiffness of the pad matrix per area, E_m/H_m [N m⁻³].
    """

    K_N: float = 2.39e9
    K_T: float = 1.87e9
    K_C: float = 7.96e8
    coupling_radius: float = 5.0e-3
    damping_ratio: float = 1.0e-6
    mass_per_area: float = 37.5
    matrix_stiffness: float = 1.85e11

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            nonneg = f.name in ("damping_ratio", "coupling_radius")
            _finite(f"material.{f.name}", getattr(self, f.name), low=0.0, strict=not nonneg)


@dataclass(frozen=True)
class Friction:
    """Friction laws (paper Eq. 4 on patches, Coulomb on the matrix).

    f(v) = (M/π) atan(slope·v) (1/(decay·|v| + 1) + 1), signed in the sliding velocity v; μ_p = |f|.

    Attributes:
        M: Multiplicative factor of Eq. 4 [1].
        mu_pad: Coulomb coefficient of the pad matrix [1].
        slope: Regularisation slope of Eq. 4 (200 in the paper) [s m⁻¹].
        decay: Velocity decay constant of Eq. 4 (0.25 in the paper) [s m⁻¹].
    """

    M: float = 0.8
    mu_pad: float = 0.3
    slope: float = 200.0
    decay: float = 0.25

    def __post_init__(self) -> None:
        _finite("friction.M", self.M, low=0.0)
        _finite("friction.mu_pad", self.mu_pad, low=0.0)
        _finite("friction.slope", self.slope, low=0.0, strict=True)
        _finite("friction.decay", self.decay, low=0.0)

    def coefficient(self, v: np.ndarray | float) -> np.ndarray:
        """Signed friction coefficient f(v) of Eq. 4 for sliding velocity ``v`` [m/s]."""
        v = np.asarray(v, dtype=np.float64)
        return self.M / np.pi * np.arctan(self.slope * v) * (1.0 / (self.decay * np.abs(v) + 1.0) + 1.0)

    def derivative(self, v: np.ndarray | float) -> np.ndarray:
        """Slope df/dv [s m⁻¹] of the signed Eq. 4 at sliding velocity ``v`` [m/s] (negative where f falls)."""
        v = np.asarray(v, dtype=np.float64)
        q = 1.0 / (self.decay * np.abs(v) + 1.0)
        da = self.slope / (1.0 + (self.slope * v) ** 2)
        return self.M / np.pi * (da * (q + 1.0) - np.arctan(self.slope * v) * self.decay * np.sign(v) * q * q)

    def max_slope(self) -> float:
        """Largest |df/dv|, reached at v = 0: 2·slope·M/π [s m⁻¹]."""
        return 2.0 * self.slope * self.M / np.pi


@dataclass(frozen=True)
class Pad:
    """Pad outline: an annular sector centred on +y, disc axis at the origin.

    Attributes:
        r_inner: Inner radius [m].
        r_outer: Outer radius [m].
        span_deg: Angular span of the sector, centred on +y [deg].
    """

    r_inner: float = 0.100
    r_outer: float = 0.160
    span_deg: float = 81.5

    def __post_init__(self) -> None:
        _finite("pad.r_inner", self.r_inner, low=0.0)
        _finite("pad.r_outer", self.r_outer, low=0.0, strict=True)
        _finite("pad.span_deg", self.span_deg, low=0.0, strict=True)
        if self.r_outer <= self.r_inner:
            raise SceneError(f"pad.r_outer ({self.r_outer:g} m) must exceed pad.r_inner ({self.r_inner:g} m)")
        if self.span_deg > 360.0:
            raise SceneError(f"pad.span_deg must be <= 360, got {self.span_deg:g}")
        try:
            finite = math.isfinite(self.first_moment)  # ∝ r_outer³, the largest power used
        except OverflowError:
            finite = False
        if not finite:
            raise SceneError(f"pad.r_outer = {self.r_outer:g} m is too large: the pad's area and moments overflow")

    @property
    def half_span(self) -> float:
        """Half the angular span [rad]."""
        return math.radians(self.span_deg) / 2.0

    @property
    def area(self) -> float:
        """Pad area [m²]."""
        return self.half_span * (self.r_outer**2 - self.r_inner**2)

    @property
    def mean_radius(self) -> float:
        """Mean radius (r_inner + r_outer)/2, where ``sliding_speed`` is measured [m]."""
        return 0.5 * (self.r_inner + self.r_outer)

    @property
    def first_moment(self) -> float:
        """∫ r dA over the pad [m³]."""
        return self.half_span * 2.0 / 3.0 * (self.r_outer**3 - self.r_inner**3)

    def contains_disc(self, x: np.ndarray, y: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """True where the disc of ``radius`` [m] centred at (x, y) [m] lies inside the pad (shape of x)."""
        return self.disc_fits(*self.edge_distances(x, y), radius)

    def edge_distances(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance from the disc axis, distance to the nearest straight edge measured perpendicular to it) [m] of
        the points (x, y) [m]; the second is +inf on a full ring."""
        r = np.hypot(x, y)
        if self.span_deg >= 360.0:
            return r, np.full(np.shape(r), np.inf)
        ang = np.abs(np.arctan2(x, y))  # angle from +y
        return r, r * np.sin(np.clip(self.half_span - ang, -np.pi / 2, np.pi / 2))

    @property
    def fit_bounds(self) -> tuple[float, float, float]:
        """The operands of :meth:`disc_fits`: r_inner (1 − 1e-12) [m], r_outer (1 + 1e-12) [m] and the factor
        1 − 1e-12 on the radius against the straight edges [1]."""
        return self.r_inner * (1 - 1e-12), self.r_outer * (1 + 1e-12), 1 - 1e-12

    def disc_fits(self, r: Any, edge: Any, radius: Any) -> Any:
        """Whether a disc of ``radius`` [m] at distances ``r`` and ``edge`` [m] (:meth:`edge_distances`) lies inside
        the pad: arrays elementwise, or scalars (the same IEEE operations either way)."""
        inner, outer, shrink = self.fit_bounds
        return (r - radius >= inner) & (r + radius <= outer) & (edge >= radius * shrink)


@dataclass(frozen=True)
class Patches:
    """A patch coverage state: one rigid disc per patch.

    Attributes:
        x: Patch centre x [m], shape (n,).
        y: Patch centre y [m], shape (n,).
        area: Contact area [m²], shape (n,).
        height: Free height of the patch top above the unloaded matrix surface [m], shape (n,).
        source: Where the patches came from (file path or generator description).
    """

    x: np.ndarray
    y: np.ndarray
    area: np.ndarray
    height: np.ndarray
    source: str = "python"

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("x", "y", "area", "height"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.ndim != 1:
                raise SceneError(f"patches.{name} must be one-dimensional, got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                bad = int(np.flatnonzero(~np.isfinite(a))[0])
                raise SceneError(f"patches.{name} has a non-finite value at patch {bad}")
            arrays[name] = a
            object.__setattr__(self, name, a)
        n = {len(a) for a in arrays.values()}
        if len(n) != 1:
            raise SceneError(f"patch arrays x, y, area, height must have equal lengths, got {sorted(n)}")
        if len(self.x) == 0:
            raise SceneError("a scene needs at least one patch")
        if np.any(self.area <= 0.0):
            raise SceneError(f"patch areas must be > 0 m² (patch {int(np.flatnonzero(self.area <= 0)[0])})")
        if np.any(self.height < 0.0):
            raise SceneError(f"patch heights must be >= 0 m (patch {int(np.flatnonzero(self.height < 0)[0])})")

    @property
    def count(self) -> int:
        """Number of patches."""
        return len(self.x)

    @property
    def radius(self) -> np.ndarray:
        """Radius of the patch disc √(A/π) [m], shape (n,)."""
        return np.sqrt(self.area / np.pi)

    @property
    def friction_radius(self) -> np.ndarray:
        """Distance from the disc axis [m], shape (n,)."""
        return np.hypot(self.x, self.y)


@dataclass(frozen=True)
class Initial:
    """Initial state of the HF run: a base state plus optional seeded perturbations.

    Perturbations are independent N(0, σ²) draws per patch, added to the base state: velocities from
    ``np.random.default_rng(seed)``, displacements from ``np.random.default_rng(np.random.SeedSequence(seed)
    .spawn(1)[0])`` (a separate stream: switching one on does not change the other's draws).

    Attributes:
        state: ``"rest"`` (u = u̇ = 0) or ``"equilibrium"`` (static balance of springs and steady friction, u̇ = 0).
        perturbation: Standard deviation σ of random initial patch velocities added to the state [m/s].
        seed: Seed of the perturbations.
        displacement_perturbation: Standard deviation σ of random initial patch displacements added to the
            state [m].
    """

    state: str = "rest"
    perturbation: float = 0.0
    seed: int = 0
    displacement_perturbation: float = 0.0

    def __post_init__(self) -> None:
        if self.state not in INITIAL_STATES:
            raise SceneError(f"initial.state must be one of {', '.join(INITIAL_STATES)}, got {self.state!r}")
        _finite("initial.perturbation", self.perturbation, low=0.0)
        _finite("initial.displacement_perturbation", self.displacement_perturbation, low=0.0)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise SceneError(f"initial.seed must be a non-negative integer, got {self.seed!r}")


@dataclass(frozen=True)
class Growth:
    """Patch growth of the varying-area study (paper Eq. 10, docs/model.md §2.10).

    Every ``interval`` of simulated time each area grows by ΔA = increment·√A. Eq. 10 (A in mm²,
    +1e-6·√A every 202 steps of ~1 ns) is increment = 1e-9 m and interval = 2.02e-7 s.

    Attributes:
        increment: Growth constant [m] (ΔA [m²] = increment · √(A [m²])).
        interval: Simulated time between growth events [s].
    """

    increment: float = 1.0e-9
    interval: float = 2.02e-7

    def __post_init__(self) -> None:
        _finite("growth.increment", self.increment, low=0.0)
        _finite("growth.interval", self.interval, low=0.0, strict=True)


@dataclass(frozen=True)
class Record:
    """What to record (docs/model.md §2.8): nothing else is computed or stored.

    Attributes:
        sample_dt: Interval between samples of the global outputs [s].
        patches: Per-patch histories to record: any of ``"velocity"``, ``"displacement"``.
        window: Time window (start, end) of the per-patch histories [s].
        decimation: Record per-patch histories every ``decimation``-th global sample.
    """

    sample_dt: float = 1.0e-6
    patches: tuple[str, ...] = ()
    window: tuple[float, float] = (0.0, math.inf)
    decimation: int = 1

    def __post_init__(self) -> None:
        _finite("record.sample_dt", self.sample_dt, low=0.0, strict=True)
        object.__setattr__(self, "patches", tuple(self.patches))
        check_patch_variables(self.patches)
        if isinstance(self.window, (str, bytes)) or not hasattr(self.window, "__len__") or len(self.window) != 2:
            raise SceneError(f"record.window must be [start, end] in seconds, got {self.window!r}")
        t0 = _finite("record.window start", self.window[0], low=0.0)
        t1 = self.window[1]
        if isinstance(t1, bool) or not isinstance(t1, (int, float, np.floating, np.integer)):
            raise SceneError(f"record.window end must be a number of seconds, got {t1!r}")
        t1 = float(t1)
        if math.isnan(t1) or t1 <= t0:
            raise SceneError(f"record.window end must exceed its start, got {self.window!r}")
        object.__setattr__(self, "window", (t0, t1))
        if isinstance(self.decimation, bool) or not isinstance(self.decimation, int) or self.decimation < 1:
            raise SceneError(f"record.decimation must be a positive integer, got {self.decimation!r}")

    def check_duration(self, duration: float, sample: str = "record.sample_dt", length: str = "run.duration") -> None:
        """Refuse a run of ``duration`` [s] shorter than one sample interval (:class:`SceneError`), naming the two
        settings as ``sample`` and ``length`` (the scene's fields, or the command line's flags). A duration made as
        the difference of two times (a run in segments) is a whole number of samples to ~1e-10: allowed."""
        if self.sample_dt > duration * (1 + 1e-9):
            raise SceneError(
                f"sample interval {self.sample_dt:g} s ({sample}) exceeds the duration {duration:g} s ({length}): "
                f"give a longer duration or a shorter sample interval"
            )

    def patch_rows(self, duration: float) -> int:
        """Rows of per-patch histories a run of ``duration`` [s] records: the global samples k·sample_dt, k = 0 …
        round(duration / sample_dt), inside the window, every ``decimation``-th (0 when nothing is recorded)."""
        if not self.patches:
            return 0
        n = max(1, round(duration / self.sample_dt))
        first = math.ceil(self.window[0] / self.sample_dt - 1e-9)
        last = min(self.window[1] / self.sample_dt + 1e-9, n)
        return max(0, math.floor((last - first) / self.decimation) + 1) if last >= first else 0


@dataclass(frozen=True)
class Matrix:
    """Pad matrix contact elements (Winkler cells), docs/model.md §2.6.

    Attributes:
        area: Uncovered area of each cell [m²], shape (c,).
        radius: Friction radius of each cell's centroid [m], shape (c,).
        height: Surface elevation z_e of each cell (0 when new) [m], shape (c,).
    """

    area: np.ndarray
    radius: np.ndarray
    height: np.ndarray

    def __post_init__(self) -> None:
        arrays = [np.atleast_1d(np.asarray(getattr(self, k), dtype=np.float64)) for k in ("area", "radius", "height")]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1 or len(arrays[0]) == 0:
            raise SceneError("matrix area, radius and height must be non-empty 1-D arrays of equal length")
        for name, a in zip(("area", "radius", "height"), arrays, strict=True):
            if not np.all(np.isfinite(a)):
                raise SceneError(f"matrix.{name} has a non-finite value")
            if name != "height" and np.any(a < 0):
                raise SceneError(f"matrix.{name} must be >= 0")
            object.__setattr__(self, name, a)

    @property
    def is_flat(self) -> bool:
        """True when the matrix is one cell (a fresh pad): the contact can be re-solved on the device."""
        return len(self.area) == 1

    @staticmethod
    def fresh(pad: Pad, patches: Patches) -> Matrix:
        """One flat cell: the pad area not covered by patches, at elevation 0, at its centroid radius."""
        free = pad.area - patches.area.sum()
        if free <= 0.0:
            raise SceneError(f"patches cover {patches.area.sum():g} m² of a {pad.area:g} m² pad: no matrix left")
        moment = pad.first_moment - np.sum(patches.area * patches.friction_radius)
        return Matrix(np.array([free]), np.array([moment / free]), np.zeros(1))


@dataclass(frozen=True)
class Scene:
    """One pad's HF problem. Build from Python or with :func:`load_scene` / :func:`preset`.

    Attributes:
        name: Label written into run files.
        pad: Pad outline.
        patches: Patch coverage state.
        material: HF model constants.
        friction: Friction laws.
        normal_force: Clamp force F_N [N].
        angular_velocity: Disc angular velocity ω [rad/s]; v_d = ω r at each patch.
        initial: Initial state.
        record: What to record.
        duration: Default simulated duration of a run [s].
        growth: Patch growth (varying-area study), or None.
        matrix: Matrix contact cells; None means a fresh flat matrix (:meth:`Matrix.fresh`).
        origin: The table-of-tables this scene was read from (for run files), or None; for an LF state of a measured
            regime its mark (:func:`~aca_warp.scene.regimes.measured_origin`).
        allow_implausible: Accept values far outside the physical range of a brake pad (a pad radius beyond
            2 m, patch areas beyond 1e-3 m², ...; :mod:`aca_warp.common.plausible`), which are refused otherwise
            as likely unit mistakes.
    """

    name: str
    pad: Pad
    patches: Patches
    material: Material = field(default_factory=Material)
    friction: Friction = field(default_factory=Friction)
    normal_force: float = 487.2
    angular_velocity: float = 10.0 / 0.13
    initial: Initial = field(default_factory=Initial)
    record: Record = field(default_factory=Record)
    duration: float = 1.0e-3
    growth: Growth | None = None
    matrix: Matrix | None = None
    origin: dict | None = None
    allow_implausible: bool = False

    def __post_init__(self) -> None:
        _finite("load.normal_force", self.normal_force, low=0.0)
        _finite("disc.angular_velocity", self.angular_velocity)
        _finite("run.duration", self.duration, low=0.0, strict=True)
        self.record.check_duration(self.duration)
        plausible.flag(self.allow_implausible)
        self._check_plausible()
        self._check_window()
        if self.matrix is None:
            object.__setattr__(self, "matrix", Matrix.fresh(self.pad, self.patches))
        if self.growth is not None and not self.matrix.is_flat:
            raise SceneError("patch growth needs a flat (fresh) matrix; this scene's matrix has several cells")
        self._check_geometry()

    def _check_plausible(self) -> None:
        """Refuse values far outside a brake pad's range (likely unit mistakes) unless ``allow_implausible``."""
        if self.allow_implausible:
            return
        check_pad_plausible(self.pad)
        m = self.material
        plausible.check("material.coupling_radius", m.coupling_radius, "length")
        for k in ("K_N", "K_T", "K_C"):
            plausible.check(f"material.{k}", getattr(m, k), "stiffness")
        plausible.check("material.matrix_stiffness", m.matrix_stiffness, "winkler")  # as LF scenes check it
        p = self.patches
        for i in (int(np.argmax(p.area)), int(np.argmin(p.area))):
            plausible.check(f"patch area (patch {i})", p.area[i], "area")
        i = int(np.argmax(p.height))
        plausible.check(f"patch height (patch {i})", p.height[i], "height")
        plausible.check("load.normal_force", self.normal_force, "force")
        plausible.check("friction.M", self.friction.M, "friction")
        plausible.check("friction.mu_pad", self.friction.mu_pad, "friction")
        plausible.check("the sliding speed at the mean radius", self.sliding_speed, "speed")
        plausible.check("run.duration", self.duration, "hf_duration")
        plausible.check("record.sample_dt", self.record.sample_dt, "sample_dt")

    def _check_window(self) -> None:
        """Per-patch histories whose window holds no sample of the run are refused (they would record nothing)."""
        rec = self.record
        if rec.patches and rec.patch_rows(self.duration) == 0:
            raise SceneError(
                f"the per-patch window [{rec.window[0]:g}, {rec.window[1]:g}] s holds no sample of the run "
                f"(0 to {self.duration:g} s, every {rec.sample_dt:g} s): nothing would be recorded; choose a window "
                "inside the run"
            )

    def _check_geometry(self) -> None:
        """Refuse patches outside the pad or overlapping each other. Patches found fitting a pad remember it
        (``_fits``), so that the many scenes of a sweep that share one layout check it once."""
        p = self.patches
        if p.__dict__.get("_fits") == self.pad:
            return
        inside = self.pad.contains_disc(p.x, p.y, p.radius)
        if not np.all(inside):
            bad = np.flatnonzero(~inside)
            raise SceneError(
                f"{len(bad)} patch(es) lie (partly) outside the pad, first is patch {int(bad[0])} at "
                f"({p.x[bad[0]]:.6g}, {p.y[bad[0]]:.6g}) m"
            )
        pairs = overlapping_pairs(p)
        if len(pairs):
            i, j = pairs[0]
            d = math.hypot(p.x[i] - p.x[j], p.y[i] - p.y[j])
            raise SceneError(
                f"{len(pairs)} pair(s) of patches overlap, first patches {i} and {j}: centre distance {d:.4g} m "
                f"< sum of radii {p.radius[i] + p.radius[j]:.4g} m (overlap {p.radius[i] + p.radius[j] - d:.3g} m)"
            )
        object.__setattr__(p, "_fits", self.pad)

    @property
    def sliding_speed(self) -> float:
        """Disc surface speed at the pad's mean radius [m/s]."""
        return self.angular_velocity * self.pad.mean_radius

    def replace(self, **changes: Any) -> Scene:
        """A copy with some fields changed (validated again).

        A new ``pad`` or ``patches`` without a new ``matrix`` rebuilds the fresh matrix (the old one described
        other patches); new ``patches`` without a new ``origin`` drop it (it named the old patches' source).
        """
        if ("patches" in changes or "pad" in changes) and "matrix" not in changes:
            changes["matrix"] = None
        if "patches" in changes:
            changes.setdefault("origin", None)
        return dataclasses.replace(self, **changes)


def overlapping_pairs(p: Patches) -> np.ndarray:
    """Index pairs (i < j) of patches whose discs overlap, shape (k, 2), sorted.

    Candidates come from square cells of width 2·max(radius) (a disc overlaps only discs of its own and the eight
    surrounding cells; NumPy only: the command line's start-up imports no SciPy for it), each then kept where the
    centre distance is below the sum of the radii."""
    pts = np.column_stack([p.x, p.y])
    rad = p.radius
    i, j = close_pairs(pts, 2.0 * float(rad.max()) * (1.0 + 1e-9)) if len(rad) > 1 else (np.zeros(0, np.int64),) * 2
    d = np.hypot(*(pts[i] - pts[j]).T)
    hit = np.column_stack([i, j])[d < rad[i] + rad[j]]
    hit = np.sort(hit, axis=1)
    return hit[np.lexsort((hit[:, 1], hit[:, 0]))]


def pairs_within(x: np.ndarray, y: np.ndarray, radius: float) -> int:
    """How many pairs of points (x, y) [m] lie within ``radius`` [m] of each other (distance ≤ radius), each pair
    counted once; NumPy only (no SciPy import in a sweep worker's first task)."""
    if len(x) < 2:
        return 0
    pts = np.column_stack([x, y])
    i, j = close_pairs(pts, radius * (1.0 + 1e-9))
    return int(np.count_nonzero(np.hypot(*(pts[i] - pts[j]).T) <= radius))


def close_pairs(pts: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Every pair (i, j), i != j, once, of points (n, 2) [m] in the same or adjacent square cells of width ``cell``
    [m]: a superset of the pairs closer than ``cell``. Returns the index arrays (i, j)."""
    c = np.floor((pts - pts.min(axis=0)) / cell).astype(np.int64)
    rows = int(c[:, 1].max()) + 3  # a key per cell; rows apart from the last row's neighbours
    key = c[:, 0] * rows + c[:, 1] + 1
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    firsts, seconds = [], []
    for dx, dy in ((0, 0), (1, -1), (1, 0), (1, 1), (0, 1)):  # half the neighbourhood: each pair of cells once
        target = key + dx * rows + dy
        lo = np.searchsorted(sorted_key, target, side="left")
        count = np.searchsorted(sorted_key, target, side="right") - lo
        first = np.repeat(np.arange(len(key)), count)
        start = np.repeat(lo - np.cumsum(count) + count, count)
        second = order[start + np.arange(int(count.sum()))]
        keep = first < second if (dx, dy) == (0, 0) else np.ones(len(first), dtype=bool)  # a cell with itself
        firsts.append(first[keep])
        seconds.append(second[keep])
    return np.concatenate(firsts), np.concatenate(seconds)


def check_pad_plausible(pad: Pad) -> None:
    """Refuse pad radii beyond the range of a brake pad (:func:`aca_warp.common.plausible.check`)."""
    plausible.check("pad.r_inner", pad.r_inner, "length")
    plausible.check("pad.r_outer", pad.r_outer, "length")
