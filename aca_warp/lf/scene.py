"""LF scenes: pad, constants of every LF rule, initial patches, load schedule, snapshot times (TOML or Python).

An LF scene file has the tables ``[scene]``, ``[pad]``, ``[material]``, ``[friction]`` (as HF scenes,
docs/scenes.md), ``[patches]`` (initial population from the seeded generator; ``count = 0`` for a bare pad),
``[lf]`` (every constant of :class:`LFConstants`), ``[[schedule]]`` (applications and pauses, in order) and
``[snapshots]``. The built-in preset ``multiscale`` (``aca_warp/data/multiscale.toml``) is the paper's
multi-timescale load procedure (§3.3; docs/model.md §2.9, §4). All quantities SI.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common import plausible
from aca_warp.common.errors import SceneError, did_you_mean, option
from aca_warp.scene import (
    GENERATOR_KINDS,
    PAD_KINDS,
    PRESETS,
    Friction,
    Material,
    Pad,
    Patches,
    PatchGenerator,
    check_numbers_plausible,
    check_pad_plausible,
    preset_document,
    read_scene_toml,
)
from aca_warp.scene.parts import _finite

LF_PRESETS = ("multiscale",)
# size limits (refused with one line before anything is allocated; int32 indices on the device)
MAX_CAPACITY = 2**24  # patch slots
MAX_CELLS = 2**24  # pad matrix cells (rings × columns)
MAX_STEPS = 10**7  # LF steps of one run (the history alone is steps × 14 × 8 B on the device)
MAX_CONTACT_ITERATIONS = 1000
SEED_LIMIT = 2**64  # the LF random numbers hash a 64-bit seed


@dataclass(frozen=True)
class LFConstants:
    """Constants of the LF rules (docs/lf_model.md gives each one's status and calibration target).

    Attributes (SI):
        dt: LF step [s] (paper §2.1.3: 0.01 s).
        seed: Seed of the counter-based random numbers (0 to 2^64 − 1).
        cell: Size of the pad matrix cells and disc rings (radial and arc length at the ring) [m].
        capacity: Patch slots (fixed capacity of the dynamic patch set).
        coulomb: 1 = constant patch coefficient ``mu_coulomb`` (TEI check), 0 = paper Eq. 4 at v = ω r.
        mu_coulomb: Patch friction coefficient under ``coulomb = 1`` [1].
        newton_per_bar: Clamp force per line pressure [N/bar].
        contact_iterations: Newton iterations of the contact solve per step (it stops early when converged).
        contact_tol: Relative force-balance tolerance of the contact solve [1].
        gamma_disc: Fraction of the friction heat into the disc (effusivity partition) [1].
        T_amb: Ambient / initial temperature [K].
        rho_d, c_d, k_d: Disc density [kg m⁻³], heat capacity [J kg⁻¹ K⁻¹], conductivity [W m⁻¹ K⁻¹].
        d_d: Disc cheek thickness (ring heat capacity, radial conduction, bulge) [m].
        h_conv: Disc convection coefficient, both faces [W m⁻² K⁻¹].
        rho_p, c_p, k_p: Pad density, heat capacity, conductivity (thermal) [SI].
        t_eff: Thermal depth of a pad cell or patch [m].
        L_b: Conduction length from the surface layer to the pad bulk (at T_amb) [m].
        h_pd: Contact conductance matrix cell ↔ disc ring while in contact [W m⁻² K⁻¹].
        alpha_d, kappa_d: Disc expansion coefficient [K⁻¹] and restraint factor [1] of the ring bulge.
        wear_m, wear_p: Energy wear coefficients of matrix and patches [m³ J⁻¹].
        wear_T: Temperature scale of wear acceleration exp((T − T_amb)/wear_T) [K]; 0 = off.
        rho_m: Matrix density (worn volume → debris mass) [kg m⁻³].
        rho_patch: Patch (compacted debris) density [kg m⁻³].
        f_ret: Fraction of wear debris retained in the boundary layer [1].
        p_cap, p_store, p_remob: Capture / storage / re-mobilisation fractions of the debris sweep [1].
        s_max_thick: Storage capacity of a cell as a layer thickness of patch material [m].
        A0, A_min, A_max: Patch area at birth, death threshold, growth cap [m²].
        t0, t_min: Patch thickness at birth, worn-through threshold [m].
        k_shrink: Shrink coefficient, dA/dt = −k_shrink P / t [m³ J⁻¹].
        p_comp: Matrix pressure needed to compact stored debris into a patch [Pa].
        p_birth: Probability per step of a birth where the conditions hold [1].
        lam0, T_c, T_s: Thermal destruction hazard λ = lam0 exp((T − T_c)/T_s) [s⁻¹, K, K].
        T_kill: Certain death at or above this patch temperature [K].
        cand_margin: Extra radius of the merge-candidate and birth neighbourhoods [m].
        compact_every: Compact the patch slots every this many steps (0 = never).
    """

    dt: float = 0.01
    seed: int = 1
    cell: float = 1.0e-3
    capacity: int = 8192
    coulomb: int = 0
    mu_coulomb: float = 0.45
    newton_per_bar: float = 370.0
    contact_iterations: int = 40
    contact_tol: float = 1.0e-13
    gamma_disc: float = 0.89
    T_amb: float = 293.15
    rho_d: float = 7200.0
    c_d: float = 460.0
    k_d: float = 50.0
    d_d: float = 0.02
    h_conv: float = 100.0
    rho_p: float = 2500.0
    c_p: float = 1000.0
    k_p: float = 1.0
    t_eff: float = 3.0e-5
    L_b: float = 1.0e-3
    h_pd: float = 1.0e4
    alpha_d: float = 1.2e-5
    kappa_d: float = 0.1
    wear_m: float = 2.0e-13
    wear_p: float = 5.0e-15
    wear_T: float = 0.0
    rho_m: float = 2500.0
    rho_patch: float = 5000.0
    f_ret: float = 0.7
    p_cap: float = 0.5
    p_store: float = 0.05
    p_remob: float = 0.002
    s_max_thick: float = 3.0e-6
    A0: float = 2.0e-8
    A_min: float = 1.0e-8
    A_max: float = 4.0e-6
    t0: float = 3.0e-6
    t_min: float = 0.5e-6
    k_shrink: float = 1.0e-15
    p_comp: float = 3.0e5
    p_birth: float = 0.1
    lam0: float = 0.1
    T_c: float = 673.15
    T_s: float = 30.0
    T_kill: float = 973.15
    cand_margin: float = 0.5e-3
    compact_every: int = 500

    def __post_init__(self) -> None:
        ints = ("seed", "capacity", "coulomb", "contact_iterations", "compact_every")
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "seed":
                object.__setattr__(self, "seed", check_seed(v, "lf.seed"))
            elif f.name in ints:
                if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                    raise SceneError(f"lf.{f.name} must be a non-negative integer, got {v!r}")
                object.__setattr__(self, f.name, int(v))
            elif f.name in ("T_amb", "T_c", "T_kill") and v == 0:  # 0 typed for 0 °C (the plausible range skips 0)
                raise SceneError(f"lf.{f.name} = 0 K is absolute zero: temperatures are in kelvin (0 °C = 273.15 K)")
            else:
                strict = f.name in ("dt", "cell", "rho_d", "c_d", "d_d", "rho_p", "c_p", "t_eff", "L_b", "rho_patch")
                strict |= f.name in ("A0", "t0", "T_s", "newton_per_bar", "contact_tol")
                _finite(f"lf.{f.name}", v, low=0.0, strict=strict)
        for name in ("f_ret", "p_cap", "p_store", "p_remob", "p_birth", "gamma_disc"):
            if getattr(self, name) > 1.0:
                raise SceneError(f"lf.{name} must be <= 1, got {getattr(self, name):g}")
        if self.capacity < 1 or self.contact_iterations < 1:
            raise SceneError("lf.capacity and lf.contact_iterations must be >= 1")
        if self.capacity > MAX_CAPACITY:
            raise SceneError(f"lf.capacity = {self.capacity} exceeds the limit of {MAX_CAPACITY} patch slots")
        if self.contact_iterations > MAX_CONTACT_ITERATIONS:
            raise SceneError(f"lf.contact_iterations = {self.contact_iterations} exceeds {MAX_CONTACT_ITERATIONS}")
        if self.coulomb not in (0, 1):
            raise SceneError(f"lf.coulomb must be 0 or 1, got {self.coulomb}")
        if not self.A_min < self.A0 <= self.A_max:
            raise SceneError(f"lf areas need A_min < A0 <= A_max, got {self.A_min:g}, {self.A0:g}, {self.A_max:g}")


def check_seed(value: Any, name: str) -> int:
    """``value`` as the seed of the LF random numbers: an integer from 0 to 2^64 − 1 (SceneError naming ``name``)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value < SEED_LIMIT:
        raise SceneError(f"{name} must be a non-negative integer below 2^64 = {SEED_LIMIT}, got {value!r}")
    return int(value)


# the plausible range (aca_warp.common.plausible.RANGES) of every [lf] constant with a unit; the others are
# counts, switches, fractions and probabilities, bounded by their own checks
LF_KINDS: dict[str, str] = {
    "dt": "lf_step", "cell": "lf_cell", "cand_margin": "lf_cell", "newton_per_bar": "newton_per_bar",
    "T_amb": "temperature", "T_c": "temperature", "T_kill": "temperature",
    "T_s": "temperature_scale", "wear_T": "temperature_scale",
    "rho_d": "density", "rho_p": "density", "rho_m": "density", "rho_patch": "density",
    "c_d": "heat_capacity", "c_p": "heat_capacity", "k_d": "conductivity", "k_p": "conductivity",
    "d_d": "thermal_length", "t_eff": "thermal_length", "L_b": "thermal_length",
    "h_conv": "heat_transfer", "h_pd": "heat_transfer", "alpha_d": "expansion",
    "wear_m": "wear", "wear_p": "wear", "k_shrink": "wear",
    "s_max_thick": "height", "t0": "height", "t_min": "height", "A0": "area", "A_min": "area", "A_max": "area",
    "p_comp": "pressure", "lam0": "rate",
}  # fmt: skip
# the plausible range of each number of a [[schedule]] entry
SEGMENT_KINDS: dict[str, str] = {
    "duration": "lf_duration", "ramp": "lf_duration", "normal_force": "force", "sliding_speed": "speed",
}  # fmt: skip


@dataclass(frozen=True)
class Segment:
    """One entry of the load schedule.

    Attributes:
        kind: ``"application"`` or ``"pause"``.
        duration: Length [s].
        normal_force: Clamp force of an application [N] (0 for a pause).
        sliding_speed: Disc speed at the pad's mean radius during an application [m/s].
        ramp: Linear load ramp at the start of an application [s].
    """

    kind: str
    duration: float
    normal_force: float = 0.0
    sliding_speed: float = 10.0
    ramp: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ("application", "pause"):
            raise SceneError(f"schedule kind must be 'application' or 'pause', got {self.kind!r}")
        _finite("schedule.duration", self.duration, low=0.0, strict=True)
        _finite("schedule.normal_force", self.normal_force, low=0.0, strict=self.kind == "application")
        _finite("schedule.sliding_speed", self.sliding_speed, low=0.0)
        _finite("schedule.ramp", self.ramp, low=0.0)
        if self.ramp >= self.duration:
            raise SceneError(f"schedule.ramp ({self.ramp:g} s) must be shorter than the duration ({self.duration:g} s)")


@dataclass(frozen=True)
class LFScene:
    """One pad's LF problem.

    Attributes:
        name: Label written into run files.
        pad: Pad outline (annular sector).
        material: Stiffness constants (K_N of the patches, matrix Winkler stiffness; the rest is for HF hand-off).
        friction: Friction laws (Eq. 4 factor M, μ_pad, ...).
        lf: Constants of the LF rules.
        schedule: Applications and pauses, in order.
        patches: Initial patches (None = a bare pad).
        snapshot_applications: Save the state at the start (after the ramp) and end of every application.
        snapshot_times: Extra snapshot times [s] (saved after the step that ends at or after each; each within the
            schedule, no two alike, in any order).
        origin: The TOML-shaped dict the scene came from (for run files), or None.
        allow_implausible: Accept values far outside the physical range of a brake pad (as HF scenes:
            :mod:`aca_warp.common.plausible`; here also loads, speeds and lengths of the schedule, the matrix
            stiffness and every ``lf`` constant with a unit: :data:`LF_KINDS`).
    """

    name: str
    pad: Pad = field(default_factory=Pad)
    material: Material = field(default_factory=Material)
    friction: Friction = field(default_factory=Friction)
    lf: LFConstants = field(default_factory=LFConstants)
    schedule: tuple[Segment, ...] = ()
    patches: Patches | None = None
    snapshot_applications: bool = True
    snapshot_times: tuple[float, ...] = ()
    origin: dict | None = None
    allow_implausible: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "schedule", tuple(self.schedule))
        if not self.schedule:
            raise SceneError("an LF scene needs a [[schedule]] with at least one application")
        if not any(s.kind == "application" and s.sliding_speed > 0 for s in self.schedule):
            raise SceneError(
                'an LF scene needs a [[schedule]] with at least one application (kind = "application", a '
                "normal_force or pressure_bar and a sliding_speed > 0); this one only "
                + ("pauses" if all(s.kind == "pause" for s in self.schedule) else "pauses or loads a disc at rest")
            )
        if not plausible.flag(self.allow_implausible):
            self._check_plausible()
        if self.pad.span_deg >= 360.0:
            raise SceneError("the LF grid needs an annular sector pad (span_deg < 360)")
        check_grid(self.pad, self.lf)
        object.__setattr__(self, "snapshot_times", self._checked_snapshot_times())

    def _checked_snapshot_times(self) -> tuple[float, ...]:
        """The snapshot times as floats: each a number > 0, no two of the same name (the run file's
        /snapshots/NAME). A time past the run's end is left to the run, which says that it is not taken (a run may
        go past the schedule: ``duration``)."""
        times = self.snapshot_times
        if isinstance(times, (str, bytes)) or not isinstance(times, (list, tuple, np.ndarray)):
            raise SceneError(f"snapshots.times must be a list of seconds, got {times!r}")
        out = tuple(_finite("snapshots.times", t, low=0.0, strict=True) for t in times)
        names: dict[str, float] = {}
        for t in out:
            name = snapshot_name(t)
            if name in names and names[name] == t:
                raise SceneError(f"snapshots.times lists {t:g} s twice; give each time once")
            if name in names:
                raise SceneError(
                    f"snapshots.times {names[name]!r} s and {t!r} s both name the snapshot {name}; make them differ "
                    "within 6 significant digits"
                )
            names[name] = t
        return out

    def _check_plausible(self) -> None:
        """Refuse values far outside a brake pad's range (likely unit mistakes; docs/scenes.md)."""
        check_pad_plausible(self.pad)
        plausible.check("material.coupling_radius", self.material.coupling_radius, "length")
        for k in ("K_N", "K_T", "K_C"):
            plausible.check(f"material.{k}", getattr(self.material, k), "stiffness")
        if self.patches is not None:
            p = self.patches
            for i in (int(np.argmax(p.area)), int(np.argmin(p.area))):
                plausible.check(f"patch area (patch {i})", p.area[i], "area")
            plausible.check("patch height", float(np.max(p.height)), "height")
        plausible.check("material.matrix_stiffness", self.material.matrix_stiffness, "winkler")
        for key, kind in LF_KINDS.items():
            plausible.check(f"lf.{key}", getattr(self.lf, key), kind)
        for i, s in enumerate(self.schedule):
            for key, kind in SEGMENT_KINDS.items():
                plausible.check(f"schedule[{i}].{key}", getattr(s, key), kind)

    @property
    def duration(self) -> float:
        """Total schedule length [s]."""
        return float(sum(s.duration for s in self.schedule))

    def replace(self, **changes: Any) -> LFScene:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def with_seed(self, seed: int) -> LFScene:
        """A copy whose LF random numbers come from ``seed`` (``aca-warp lf --seed``), an integer from 0 to
        2^64 − 1; the initial patches are kept."""
        return self.replace(lf=dataclasses.replace(self.lf, seed=check_seed(seed, option("seed", "--seed"))))


def snapshot_name(t: float) -> str:
    """The name of the snapshot at time ``t`` [s] of ``[snapshots] times`` in the run file: ``t<T>s``."""
    return f"t{t:g}s"


def check_grid(pad: Pad, lf: LFConstants) -> None:
    """Refuse an LF grid of more than :data:`MAX_CELLS` cells (before patches are generated or arrays allocated)."""
    try:
        rings = (pad.r_outer - pad.r_inner) / lf.cell
        columns = 2.0 * pad.half_span * (pad.r_outer + pad.r_inner) / 2.0 / lf.cell
        ok = max(rings, 1.0) * max(columns, 1.0) <= MAX_CELLS
    except ArithmeticError:
        ok, rings, columns = False, math.inf, math.inf
    if not ok:
        raise SceneError(
            f"the LF grid of lf.cell = {lf.cell:g} m over this pad has {rings:.3g} × {columns:.3g} cells, "
            f"more than {MAX_CELLS}; choose a larger lf.cell or a smaller pad"
        )


@dataclass(frozen=True)
class StepTable:
    """The schedule sampled per LF step.

    Attributes:
        load: Clamp force of each step [N], shape (n,).
        omega: Disc angular velocity of each step [rad/s], shape (n,).
        application: 1-based application number of each step, 0 in pauses, shape (n,).
        snapshots: (name, step index) pairs; the snapshot is taken after that step.
    """

    load: np.ndarray
    omega: np.ndarray
    application: np.ndarray
    snapshots: tuple[tuple[str, int], ...]

    @property
    def steps(self) -> int:
        """Number of steps."""
        return len(self.load)


def step_table(scene: LFScene, duration: float | None = None) -> StepTable:
    """Sample the schedule at step midpoints; the run covers ``duration`` [s] (default: the whole schedule)."""
    dt = scene.lf.dt
    total = scene.duration if duration is None else duration
    if not (total > 0 and math.isfinite(total)):
        raise SceneError(f"duration must be a positive number of seconds, got {total}")
    if not total / dt <= MAX_STEPS:
        raise SceneError(f"{total:g} s of {dt:g} s LF steps is more than {MAX_STEPS} steps; shorten the run")
    n = max(int(round(total / dt)), 1)
    t_mid = (np.arange(n) + 0.5) * dt
    load = np.zeros(n)
    omega = np.zeros(n)
    app = np.zeros(n, dtype=np.int32)
    snaps: list[tuple[str, int]] = []
    t0 = 0.0
    k = 0
    rm = scene.pad.mean_radius
    for seg in scene.schedule:
        sel = (t_mid >= t0) & (t_mid < t0 + seg.duration)
        if seg.kind == "application":
            k += 1
            ramp = np.ones(int(sel.sum())) if seg.ramp == 0 else np.minimum((t_mid[sel] - t0) / seg.ramp, 1.0)
            load[sel] = seg.normal_force * ramp
            omega[sel] = seg.sliding_speed / rm
            app[sel] = k
            if scene.snapshot_applications:
                s_start = int(math.ceil((t0 + seg.ramp) / dt - 0.5 - 1e-9))
                s_end = int(round((t0 + seg.duration) / dt)) - 1
                if s_start < n:
                    snaps.append((f"app{k}_start", s_start))
                if s_end < n:
                    snaps.append((f"app{k}_end", s_end))
        t0 += seg.duration
    for t in scene.snapshot_times:
        s = int(math.ceil(t / dt - 1e-9)) - 1
        if 0 <= s < n:  # a shorter run (duration) leaves out the later ones
            snaps.append((snapshot_name(t), s))
    snaps.sort(key=lambda p: p[1])
    return StepTable(load, omega, app, tuple(snaps))


# ----------------------------------------------------------------------------------------------- TOML

_TABLES: dict[str, tuple[str, ...]] = {
    "scene": ("name", "allow_implausible"),
    "pad": tuple(f.name for f in dataclasses.fields(Pad)),
    "material": tuple(f.name for f in dataclasses.fields(Material)),
    "friction": tuple(f.name for f in dataclasses.fields(Friction)),
    "patches": ("count", "area_min", "area_max", "height", "seed"),
    "lf": tuple(f.name for f in dataclasses.fields(LFConstants)),
    "snapshots": ("applications", "times"),
    "schedule": (),
}
_SEGMENT_KEYS = ("kind", "duration", "normal_force", "pressure_bar", "sliding_speed", "ramp")


def lf_scene_from_dict(doc: dict, *, name: str = "lf", allow_implausible: bool = False) -> LFScene:
    """Build and validate an LF scene from a TOML-shaped dict (keys: module docstring, docs/lf_model.md);
    ``allow_implausible`` as the key ``[scene] allow_implausible``."""
    for table, value in doc.items():
        if table not in _TABLES:
            raise SceneError(f"unknown table [{table}]; allowed: {', '.join('[' + t + ']' for t in _TABLES)}")
        if table == "schedule":
            continue
        if not isinstance(value, dict):
            raise SceneError(f"[{table}] must be a table")
        for key in value:
            if key not in _TABLES[table]:
                raise SceneError(f"unknown key {key!r} in [{table}]; allowed: {', '.join(_TABLES[table])}")
    t = {k: dict(doc.get(k, {})) for k in _TABLES if k != "schedule"}
    allow = plausible.flag(t["scene"].get("allow_implausible", False)) or allow_implausible
    try:
        if not allow:  # before the pad's own checks (r_inner = 100 is a unit mistake before an ordering one)
            check_numbers_plausible(t["pad"], "pad", PAD_KINDS)
            check_numbers_plausible(t["patches"], "patches", GENERATOR_KINDS)
            check_numbers_plausible(t["lf"], "lf", LF_KINDS)
        pad = Pad(**t["pad"])
        lf = LFConstants(**t["lf"])
        check_grid(pad, lf)
        sched = doc.get("schedule", [])
        if not isinstance(sched, list):
            raise SceneError("[[schedule]] must be an array of tables")
        segs = []
        for i, s in enumerate(sched):
            if not isinstance(s, dict):
                raise SceneError("each [[schedule]] entry must be a table")
            bad = sorted(set(s) - set(_SEGMENT_KEYS))
            if bad:
                raise SceneError(
                    f"unknown key(s) {', '.join(bad)} in [[schedule]]; allowed: {', '.join(_SEGMENT_KEYS)}"
                )
            s = dict(s)
            if not allow:  # before the segment's own checks (a ramp in ms is a unit mistake before an ordering one)
                check_numbers_plausible(s, f"schedule[{i}]", SEGMENT_KINDS)
            if "pressure_bar" in s:
                if "normal_force" in s:
                    raise SceneError("[[schedule]] takes normal_force or pressure_bar, not both")
                bar = _finite("schedule.pressure_bar", s.pop("pressure_bar"), low=0.0)
                plausible.check("schedule.pressure_bar", bar, "pressure_bar", allow=allow)
                s["normal_force"] = bar * lf.newton_per_bar
            segs.append(Segment(**s))
        pt = t["patches"]
        patches = None
        if pt.get("count", 0) != 0:
            patches = PatchGenerator(**pt).generate(pad)
        sn = t["snapshots"]
        times = sn.get("times", [])
        if not isinstance(times, list):
            raise SceneError("snapshots.times must be a list of seconds")
        applications = sn.get("applications", True)
        if not isinstance(applications, bool):
            raise SceneError(f"snapshots.applications must be true or false, got {applications!r}")
        return LFScene(
            name=str(t["scene"].get("name", name)),
            pad=pad,
            material=Material(**t["material"]),
            friction=Friction(**t["friction"]),
            lf=lf,
            schedule=tuple(segs),
            patches=patches,
            snapshot_applications=applications,
            snapshot_times=tuple(times),
            origin=doc,
            allow_implausible=allow,
        )
    except (TypeError, ArithmeticError) as e:
        raise SceneError(f"invalid LF scene value: {e}") from None


def load_lf_scene(spec: str | Path, overrides: dict | None = None, *, allow_implausible: bool = False) -> LFScene:
    """The preset ``multiscale`` or the path of an LF TOML file; ``overrides`` ({table: {key: value}}) on top;
    ``allow_implausible`` as the key ``[scene] allow_implausible``."""
    s = str(spec)
    if s in LF_PRESETS:
        doc = preset_document(s)
        name = s
    else:
        p = Path(s)
        if not p.is_file() and s in PRESETS:
            raise SceneError(
                f"{s!r} is an HF scene: run it with 'aca-warp hf {s} -o RUN.h5'; LF presets: {', '.join(LF_PRESETS)}"
            )
        if not p.is_file():
            raise SceneError(
                f"LF scene {s!r} is neither a preset ({', '.join(LF_PRESETS)}) nor an existing TOML file"
                f"{did_you_mean(s, LF_PRESETS)}"
            )
        doc = read_scene_toml(p, "LF scene file")
        if not doc:
            raise SceneError(f"LF scene file {p} is empty; start from the preset file aca_warp/data/multiscale.toml")
        name = p.stem
    for table, vals in (overrides or {}).items():
        if table == "schedule":
            doc["schedule"] = vals
        else:
            doc.setdefault(table, {}).update(vals)
    return lf_scene_from_dict(doc, name=name, allow_implausible=allow_implausible)


def lf_scene_to_dict(scene: LFScene) -> dict:
    """The scene as a TOML-shaped dict with every constant explicit (stored in run files as JSON)."""
    origin = scene.origin or {}
    return {
        "scene": {"name": scene.name, **({"allow_implausible": True} if scene.allow_implausible else {})},
        "pad": dataclasses.asdict(scene.pad),
        "material": dataclasses.asdict(scene.material),
        "friction": dataclasses.asdict(scene.friction),
        "patches": dict(origin.get("patches", {})) or {"count": 0},
        "lf": dataclasses.asdict(scene.lf),
        "schedule": [dataclasses.asdict(s) for s in scene.schedule],
        "snapshots": {"applications": scene.snapshot_applications, "times": list(scene.snapshot_times)},
    }
