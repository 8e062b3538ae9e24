"""How an HF run advances: :class:`RunOptions`, one typed and validated object from the command line to the loop.

The run file stores it as JSON (root attribute ``run_options``), so that ``rerun`` and ``--resume`` repeat a
run from what its file says. The model-build choices (device, precision) are not run options: they belong to
the model (:func:`aca_warp.hf.model.build_model`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, fields, replace
from typing import TYPE_CHECKING, Any

from aca_warp.common.errors import SceneError, option

if TYPE_CHECKING:
    from aca_warp.scene import Scene

INTEGRATORS = ("symplectic-euler", "implicit-friction", "strang", "adaptive", "controlled", "auto")
# integrators that choose their own steps per pad (dt is only the first trial)
STEP_CONTROLLED = ("adaptive", "controlled", "auto")
DEFAULT_INTEGRATOR = "strang"
DEFAULT_DT = 1.0e-8  # s: the default step of the fixed-step integrators other than strang
# strang's default step [s] (but for the regimes of REGIME_STEPS, below) and crossing treatment for a batch whose every
# pad is of a measured regime: a shipped preset's physics (hf1–hf4, varying_area and their equal-height variants, any
# patch seed; aca_warp.scene.regimes) or a marked LF state of the multiscale preset
# (aca_warp.lf.io.STATES_AT_PRESET_STEP). With the zero-slip crossings averaged, the statistical work-precision
# (docs/work_precision_statistics.md) keeps every validation measure at 2.5e-7 s in fp32 in the saturated ensembles of
# hf1–hf4, of their equal-height variants and of the two LF groups (32–160 seeds each; since samples read the next
# step's solve, ms_app3's Φ is undecided at 0.256 σ, 0.006 σ beyond the rule); the growing pads (va, va_equal, growth
# events every 5 µs) keep every measure but the STFT maximum there, as at 1e-7 s with the point treatment. With the
# point treatment 2.5e-7 s moves Φ in hf1, hf3, hf1_equal and hf3_equal, μ mean in hf2. The validation's committed
# ensembles ran at 1e-7 s with the point treatment, which keeps every measure too
# (aca_warp.studies.validation.settings).
PRESET_STEP = 2.5e-7
# the measured regimes whose statistics keep every measure at three steps a 1 µs sample as well (1e-6/3 s, the
# crossings averaged, the same seeds and references; docs/figures/work_precision_statistics/three_steps/): hf1, hf3,
# hf4 and the equal-height hf1-hf3 take that step by default (:func:`regime_step`). There hf2 and hf4_equal leave
# S − S_null undecided (0.28 and 0.31 σ), the growing pads their μ mean and rise (0.27-0.36 σ), the LF groups their
# velocity-sum peak (ms_app3, undecided) and f1 (ms_mid, moved 0.41 σ): they keep PRESET_STEP. hf1's μ mean error
# (0.11 σ at 2.5e-7 s) reaches 0.21 σ there, its 95 % bound 0.24 σ.
THREE_STEP = 1.0e-6 / 3.0
REGIME_STEPS = dict.fromkeys(("hf1", "hf3", "hf4", "hf1_equal", "hf2_equal", "hf3_equal"), THREE_STEP)
PRESET_CROSSING = "mean"
# strang's default step [s] for any other scene: every measured regime kept its measures at 5e-8 s in fp32 before
# the fp32 damping fix, the LF states too (one of their groups, ms_short, not at 1e-7 s; another, ms_fast, was
# measured at 5e-8 s only); on the fixed kernels fp32 at 5e-8 s misses one measure each in ms_fast and ms_short
# (Φ 0.27 σ, S − S_null 0.33 σ against the rule's 0.25 σ), where fp64 keeps them and the validation runs fp64; the
# default stays fp32, whose misses lie just past the rule and whose cause is not found (docs/numerics.md)
STATISTICS_STEP = 5.0e-8
# strang's default state precision: the same study kept every one of those measures in fp32 at that step (every
# regime's pick was fp32); the other integrators compute in fp64 unless asked (pointwise μ to 1e-7 and below)
STATISTICS_PRECISION = "fp32"
POINTWISE_PRECISION = "fp64"
# strang's default spacing of a growing pad's growth events [s]: on the kernels with the fp32 fix the statistics of
# growing pads keep every measure with events every 5 µs at 5e-8 s and 1e-7 s over 96 seeds of the 0.36 s record, and
# every measure but the STFT maximum over 128 seeds of the compressed regime, which a pad that turns tonal leaves
# undecided (docs/work_precision_statistics.md, "Growth events"); each event adds the increment scaled to its
# spacing, so the growth rate stays the scene's
STATISTICS_GROWTH_DT = 5.0e-6
DEFAULT_TOLERANCE = 1.0e-5  # adaptive: μ errors ≤ 1e-7 on hf1 and stick-slip (docs/time_to_solution.md)
# controlled: the rms over a pad of the per-patch local velocity errors of a step, relative to the patch's velocity
# scale V_i; 1e-2 meets the saturated-statistics targets on hf1 sectors (docs/friction_step.md §5.2)
DEFAULT_SPLIT_TOLERANCE = 1.0e-2
# the implicit friction solve's tolerance per state precision, of its velocity increment's scale (kernels/physics.py,
# solve_velocity); RunOptions.solve_tol sets another
NEWTON_TOL = {"fp32": 1.0e-6, "fp64": 1.0e-9}
SOLVE_TOL_HELP = (
    "tolerance of the per-patch implicit friction solve, relative to the scale of the step's velocity change "
    f"(default {NEWTON_TOL['fp32']:g} in fp32, {NEWTON_TOL['fp64']:g} in fp64; between 0 and 1; not with "
    "--crossing mean, so with --crossing point on a preset's physics, where mean is the default): a numerical "
    "setting for studies of the solve's own error (docs/numerics.md)"
)
ENGINES = ("auto", "onchip", "general")
# strang's treatment of a step whose slip changes sign (docs/friction_step.md §8): "point", Eq. 4 at the midpoint
# velocity and μ read at the samples' velocities; "mean", the friction averaged along the step's slip segment
# and a crossing patch's μ read at an instant of the sub-step its sample reads
CROSSINGS = ("point", "mean")
CROSSING_HELP = (
    "strang's treatment of the steps on which a patch's slip changes sign: mean, the friction averaged along the "
    "step's slip segment and a crossing patch's friction read at a random instant of the sub-step its sample reads, "
    "which removes the step error of Phi at large steps and costs more per step; point, Eq. 4 at the midpoint "
    "velocity and mu read at the samples' velocities (docs/friction_step.md, section 8). Default: mean for a shipped "
    "preset's physics and the marked LF states, point for any other scene"
)
ONCHIP_INTEGRATORS = ("strang", "adaptive")  # the integrators the on-chip engine implements
FAST_MATH_HELP = (
    "compile the on-chip strang kernel with CUDA fast math (approximate fp32 division and square root, fast "
    "sin/cos/exp/log/pow; denormals flushed): fp32 on a CUDA device only; faster, and every result changes in its last "
    "bits: the saturated statistics of hf1-hf4, varying_area and the multiscale LF states that docs/onchip.md "
    "('Fast math') lists keep every measure wherever the exact kernel's do at the same step with the point treatment; "
    "at the presets' default stepping (2.5e-7 s, crossings averaged) they miss the LF group ms_mid's velocity-sum peak "
    "and varying_area_equal's mu mean and rise, which the exact kernel keeps"
)
WATCHDOG_FACTOR = 100.0  # watchdog bound = this × the scene's velocity scale (recorder.watchdog_bound)


def regime_step(regime: str) -> float:
    """strang's default step [s] for the pads of a measured regime (a name
    :func:`~aca_warp.scene.regimes.preset_regime` gives): :data:`THREE_STEP` for those of :data:`REGIME_STEPS`, else
    :data:`PRESET_STEP`."""
    return REGIME_STEPS.get(regime, PRESET_STEP)


def _regimes(scenes: Iterable[Scene]) -> list[str | None]:
    """The measured regime of each scene (:func:`~aca_warp.scene.regimes.preset_regime`), None where it has none."""
    from aca_warp.scene.regimes import preset_regime

    return [preset_regime(s) for s in scenes]


def _measured_batch(regimes: list[str | None], default: str, measured_value: str, other_value: str) -> bool:
    """Whether every pad is of a measured regime (``regimes``: :func:`_regimes` of the batch's scenes); False when
    none is or none is given. A batch of both is refused (SceneError, naming the ``default`` it would need and its
    two values), so that a pad's default never depends on the batch it shares."""
    measured = [r is not None for r in regimes]
    if any(measured) and not all(measured):
        names = sorted({r for r in regimes if r is not None})
        raise SceneError(
            f"this batch mixes {sum(measured)} pad(s) of a measured regime ({', '.join(names)}: strang's default "
            f"{default} {measured_value}) and {measured.count(False)} other pad(s) ({other_value}; the first is pad "
            f"{measured.index(False)}); give the {default} for all of them"
        )
    return bool(regimes) and all(measured)


def default_step(integrator: str, scenes: Iterable[Scene] = ()) -> float:
    """The step [s] a fixed-step run of the pads of ``scenes`` takes when none is asked for.

    ``strang``: when every scene is of a measured regime, the shortest of their regimes' steps (:func:`regime_step`:
    every regime's statistics were measured at :data:`PRESET_STEP`, so a batch of several keeps each one's);
    :data:`STATISTICS_STEP` when none is (or none is given); a batch of both is refused (:func:`_measured_batch`).
    The other fixed-step integrators: :data:`DEFAULT_DT` (explicit friction, or a friction step not measured for
    the statistics).
    """
    if integrator != "strang":
        return DEFAULT_DT
    regimes = _regimes(scenes)
    step = min((regime_step(r) for r in regimes if r is not None), default=PRESET_STEP)
    measured = _measured_batch(regimes, "step (dt)", f"{step:.3g} s", f"{STATISTICS_STEP:g} s")
    return step if measured else STATISTICS_STEP


def default_crossing(integrator: str, scenes: Iterable[Scene] = ()) -> str:
    """strang's treatment of zero-slip crossings for the pads of ``scenes`` when none is asked for, whatever the
    step: :data:`PRESET_CROSSING` when every scene is of a measured regime, ``point`` when none is (or none is given,
    or for another integrator); a batch of both is refused (:func:`_measured_batch`)."""
    if integrator != "strang":
        return "point"
    measured = _measured_batch(_regimes(scenes), "crossing treatment", PRESET_CROSSING, "point")
    return PRESET_CROSSING if measured else "point"


def crossing_asked(integrator: str, crossing: str | None, scenes: Iterable[Scene]) -> str:
    """The crossing treatment a run of ``integrator`` on ``scenes`` asks for, as its file or sweep records it:
    ``crossing``, or :func:`default_crossing` written out."""
    return default_crossing(integrator, scenes) if crossing is None else crossing


def default_precision(integrator: str) -> str:
    """The state precision of a run of ``integrator`` when none is asked for: :data:`STATISTICS_PRECISION` for
    ``strang`` (with its default step, the setting the saturated statistics were shown to hold at),
    :data:`POINTWISE_PRECISION` for the others."""
    return STATISTICS_PRECISION if integrator == "strang" else POINTWISE_PRECISION


def growth_asked(
    integrator: str, growth_dt: float | None, interval: float | None, duration: float | None = None
) -> float | None:
    """The spacing of growth events [s] a run of ``integrator`` over ``duration`` [s] asks for, as its file or sweep
    records it: ``growth_dt``; or, for ``strang`` on a growing scene (``interval``: its growth interval [s], None
    when it does not grow), :data:`STATISTICS_GROWTH_DT` written out, or the scene's interval where that is longer,
    or where the run is shorter than that spacing (it grows at its scene's clock, as its samples see). None keeps
    the scene's own interval (the other integrators, and the run files that store no spacing)."""
    if growth_dt is not None or interval is None or integrator != "strang":
        return growth_dt
    if duration is not None and duration < STATISTICS_GROWTH_DT:
        return interval
    return max(STATISTICS_GROWTH_DT, interval)


def step_asked(
    integrator: str, dt: float | None, scenes: Iterable[Scene], sample_dt: float | None = None
) -> float | None:
    """The step a run of ``integrator`` on ``scenes`` asks for, as its file or sweep records it: ``dt``, or for a
    fixed-step integrator :func:`default_step` written out; None stays None for the step-controlled integrators
    (their first trial is the solver's). A default longer than the sample interval ``sample_dt`` [s] becomes that
    interval where it is at least :data:`STATISTICS_STEP` (a step the statistics hold at in every measured regime),
    so that what ran under the one default of 5e-8 s still runs; a shorter interval is left to the refusal of a
    sample interval below the step."""
    if dt is not None or integrator in STEP_CONTROLLED:
        return dt
    step = default_step(integrator, scenes)
    least = default_follows(integrator, None, step)
    if sample_dt is not None and least is not None and least <= sample_dt < step:
        return sample_dt
    return step


def default_follows(integrator: str, asked: float | None, step: float) -> float | None:
    """The shortest sample interval [s] that the default ``step`` [s] of ``integrator`` becomes when none was
    ``asked`` (:func:`step_asked`): :data:`STATISTICS_STEP` where the default is longer; else None."""
    if asked is None and integrator == "strang" and STATISTICS_STEP < step:
        return STATISTICS_STEP
    return None


def fast_math_unfit(integrator: str, precision: str) -> str | None:
    """Why CUDA fast math cannot apply to a run of ``integrator`` in ``precision`` (None when it can): it compiles
    the on-chip ``strang`` kernel only, and changes single-precision operations only. The device and the engine
    are checked when the engine is chosen (:func:`~aca_warp.hf.onchip_layout.fast_math_refusal`)."""
    if integrator != "strang":
        return f"it compiles the on-chip strang kernel only (got {integrator})"
    if precision != "fp32":
        return f"it changes single-precision arithmetic only: choose fp32 (got {precision})"
    return None


SCENE_CLOCK = "scene"  # --growth-dt / run.growth_dt: the events at the scenes' own growth interval


def steps_per_event(spacing: float, h: float) -> int:
    """Steps of ``h`` [s] between growth events ``spacing`` [s] apart: the nearest whole number, at least one."""
    return max(1, round(spacing / h))


def growth_words(growth_dt: float | None, h: float | None = None) -> str:
    """The growth events' spacing for a summary line: ``, growth events every S s``, or nothing at the scenes' own
    interval (None). With the fixed step ``h`` [s] of the run, the spacing it took in whole steps
    (:func:`steps_per_event`), and the one asked beside it where the two differ."""
    if growth_dt is None:
        return ""
    every = growth_dt if h is None else steps_per_event(growth_dt, h) * h
    if math.isclose(every, growth_dt, rel_tol=1e-6):
        return f", growth events every {growth_dt:g} s"
    return f", growth events every {every:.3g} s ({growth_dt:.3g} s asked, in whole steps of {h:.3g} s)"


def crossing_words(crossing: str | None) -> str:
    """strang's crossing treatment for a summary line: ``, crossings averaged`` for ``mean``, nothing for ``point``
    (or None, not resolved)."""
    return ", crossings averaged" if crossing == "mean" else ""


def tolerance_keyword(integrator: str) -> str:
    """The option a study's single tolerance ``tol=`` sets for ``integrator``: ``tolerance`` for ``adaptive``,
    ``split_tolerance`` for ``controlled`` and ``auto`` (whose pair keeps its default)."""
    return "tolerance" if integrator == "adaptive" else "split_tolerance"


def _positive_or_none(name: str, value: float | None, unit: str) -> None:
    if value is not None and not (isinstance(value, int | float) and value > 0 and math.isfinite(value)):
        raise SceneError(f"{name} must be a positive number{unit}, got {value!r}")


def check_interval(interval: float | None) -> None:
    """SceneError unless ``interval`` is None (automatic checkpoints), 0 (none) or a positive number of seconds."""
    number = isinstance(interval, int | float) and not isinstance(interval, bool)
    if not (interval is None or (number and math.isfinite(interval) and interval >= 0)):
        raise SceneError(
            f"checkpoint interval must be a number of seconds >= 0 (0: no checkpoints) or None (automatic), got "
            f"{interval!r}"
        )


def check_crossing(crossing: str | None, integrator: str) -> None:
    """SceneError unless ``crossing`` is None (:func:`default_crossing`) or one of :data:`CROSSINGS`, and not
    ``mean`` for an integrator other than ``strang``."""
    if crossing is None:
        return
    if crossing not in CROSSINGS:
        raise SceneError(f"unknown crossing treatment {crossing!r}; choose from {', '.join(CROSSINGS)}")
    if crossing == "mean" and integrator != "strang":
        raise SceneError(f"crossing {crossing!r} is a treatment of strang's steps, not of {integrator}")


def check_solve_tol(solve_tol: float | None, crossing: str | None = "point") -> None:
    """Refuse a friction solve tolerance outside (0, 1), or one given with the ``mean`` crossing treatment, whose
    short-segment threshold (``SEGMENT_TOL`` in ``kernels/physics.py``) is the same tolerance times 1e3 and would
    move with it (SceneError); None is the precision's default. ``crossing`` None (not resolved yet) is checked
    where the solver resolves it."""
    if solve_tol is None:
        return
    if not (isinstance(solve_tol, int | float) and not isinstance(solve_tol, bool) and 0 < solve_tol < 1):
        raise SceneError(f"solve_tol must be a number between 0 and 1 (exclusive), got {solve_tol!r}")
    if crossing == "mean":
        raise SceneError(
            "solve_tol with crossing 'mean' (strang's default for the presets' physics): that treatment's "
            "short-segment threshold follows the solve's tolerance; keep the default tolerance with it, or add "
            + option("crossing='point'", "--crossing point")
        )


def solve_tol_words(solve_tol: float | None) -> str:
    """The friction solve's tolerance for a summary line: ``, solve tol X``, or nothing at the precision's default
    (None)."""
    return "" if solve_tol is None else f", solve tol {solve_tol:g}"


@dataclass(frozen=True)
class RunOptions:
    """Options of one HF run (all validated on construction; :class:`SceneError` names the bad one).

    Attributes:
        duration: Simulated time [s]; None: the scene's own duration.
        integrator: One of :data:`INTEGRATORS` (docs/numerics.md).
        dt: Fixed step [s] (shortened so that whole steps fit a sample interval); None: :func:`default_step`
            (``strang`` :func:`regime_step` for the shipped presets' physics and the measured LF states of the
            multiscale preset, else :data:`STATISTICS_STEP`; the other fixed-step integrators :data:`DEFAULT_DT`).
            For the step-controlled integrators (:data:`STEP_CONTROLLED`) the first trial step.
        tolerance: Relative tolerance of the explicit pair: ``adaptive`` and the sliding mode of ``auto`` [1].
        split_tolerance: Tolerance of the error-controlled split step: ``controlled`` and the sticking mode of
            ``auto`` [1] (the rms over a pad of each patch's local velocity error over its velocity scale V_i).
        force: Run a fixed step beyond the stable-step estimate, or a run beyond the size limits of
            :func:`~aca_warp.hf.runner.plan_run` (step count, recorded bytes).
        engine: ``auto``, ``general`` or ``onchip`` (docs/onchip.md).
        checkpoint_interval: Simulated time between checkpoints [s]; None (default): automatic, at most
            :data:`~aca_warp.common.checkpoint.AUTO_SHARE` of the run's wall time; 0: none
            (:class:`~aca_warp.common.checkpoint.CheckpointClock`).
        watchdog_factor: Watchdog bound in units of the scene's velocity scale; None: only non-finite checks.
        accept_unphysical: Run on, with a warning, where the physical sanity checks (:mod:`aca_warp.hf.sanity`:
            contact solution, μ bound) would stop the run.
        fast_math: Compile the on-chip ``strang`` kernel with CUDA fast math (approximate single-precision division
            and square root, fast sin/cos/exp/log/pow, denormals flushed to zero): fp32 on a CUDA device only
            (:func:`~aca_warp.hf.onchip_layout.fast_math_refusal`; docs/onchip.md, "Fast math").
        growth_dt: Simulated time between the growth events of a growing scene [s], a numerical setting like
            ``dt``: each event adds the scene's increment × growth_dt / ``growth.interval``, so that the growth per
            simulated time stays the scene's (docs/model.md §2.10); None: the scene's ``growth.interval`` (the
            paper's clock) where the options are run as they are (``run_hf``), while ``run_scene``, ``aca-warp hf``
            and a sweep first write out ``strang``'s default, :func:`growth_asked`. Refused for a scene that does
            not grow (:func:`~aca_warp.hf.solver.check_step`).
        crossing: ``strang``'s treatment of the steps on which a patch's slip changes sign (:data:`CROSSINGS`):
            ``point`` (Eq. 4 at the midpoint velocity; μ read at the samples' velocities) or ``mean`` (the
            friction averaged along the step's slip segment, and a crossing patch's friction read at a random
            instant of the sub-step its sample reads; docs/friction_step.md §8; ``strang`` only); None:
            :func:`default_crossing` (``mean`` for a measured regime, else ``point``), which a run file stores
            written out.
        solve_tol: Tolerance of the per-patch implicit friction solve (``solve_velocity`` in ``kernels/physics.py``),
            relative to the scale of the step's velocity change [1], in (0, 1); None: :data:`NEWTON_TOL` of the
            model's precision. ``symplectic-euler`` (explicit friction) ignores it; refused with ``crossing``
            ``mean``, whose short-segment threshold follows it (:func:`check_solve_tol`). Not a sweep option.
    """

    duration: float | None = None
    integrator: str = DEFAULT_INTEGRATOR
    dt: float | None = None
    tolerance: float = DEFAULT_TOLERANCE
    split_tolerance: float = DEFAULT_SPLIT_TOLERANCE
    force: bool = False
    engine: str = "auto"
    checkpoint_interval: float | None = None
    watchdog_factor: float | None = WATCHDOG_FACTOR
    accept_unphysical: bool = False
    fast_math: bool = False
    growth_dt: float | None = None
    crossing: str | None = None
    solve_tol: float | None = None

    def __post_init__(self) -> None:
        if self.integrator not in INTEGRATORS:
            raise SceneError(f"unknown integrator {self.integrator!r}; choose from {', '.join(INTEGRATORS)}")
        if self.engine not in ENGINES:
            raise SceneError(f"unknown engine {self.engine!r}; choose from {', '.join(ENGINES)}")
        check_crossing(self.crossing, self.integrator)
        _positive_or_none("duration", self.duration, " of seconds")
        _positive_or_none("dt", self.dt, " of seconds")
        _positive_or_none("growth_dt", self.growth_dt, " of seconds")
        check_interval(self.checkpoint_interval)
        if not isinstance(self.fast_math, bool):
            raise SceneError(f"fast_math must be true or false, got {self.fast_math!r}")
        _positive_or_none("watchdog_factor", self.watchdog_factor, "")
        check_solve_tol(self.solve_tol, self.crossing)
        for name in ("tolerance", "split_tolerance"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0 and math.isfinite(value)):
                raise SceneError(f"{name} must be a positive number, got {value!r}")

    def with_duration(self, duration: float) -> RunOptions:
        """A copy with ``duration`` [s] set."""
        return replace(self, duration=duration)

    def to_json(self) -> str:
        """The options as a JSON object (what the run file stores)."""
        return json.dumps(asdict(self))

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> RunOptions:
        """Options from a stored dict; unknown keys are an error, missing ones take their defaults."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(doc) - names)
        if unknown:
            raise SceneError(f"unknown run options {', '.join(unknown)}")
        return cls(**doc)
