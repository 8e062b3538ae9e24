"""How the validation's experiments are integrated: integrator, step and precision per kind of scene, in one place.

Every experiment names one entry of :data:`STEPPING` (``Experiment.stepping``), and a batch of experiments runs with
the entry's integrator, fixed step and precision. Each entry is the setting that the statistical work-precision rule
(docs/work_precision_statistics.md: every validation measure within a quarter of the spread between seeds from a tight
reference) picks for the regime the experiments belong to; a group of LF states and its variants (from rest, the
linear phase) take the group's. The run then shortens the step to a whole number of steps per sample interval
(``fitted_step``). Every entry runs ``strang`` with the point treatment of zero-slip crossings (the validation's runs
pass it, :func:`~aca_warp.studies.runs.run_engine`). The entries ``hf`` and ``growth`` hold the setting the
validation's committed ensembles ran at, 1e-7 s with the point treatment and growth events every
:data:`~aca_warp.hf.options.STATISTICS_GROWTH_DT`: ``strang``'s default for a shipped preset's physics until the
crossings were averaged (since, :data:`~aca_warp.hf.options.PRESET_STEP` with
:data:`~aca_warp.hf.options.PRESET_CROSSING`, which keeps every measure of these regimes too, the growing ones as
this setting does); ``ms_order`` holds ``strang``'s default for any other scene
(:data:`~aca_warp.hf.options.STATISTICS_STEP`), written out so that a change of a default does not move the
validation (a test holds it equal). ``--dt`` and ``--precision`` replace the table's values for every experiment,
``--growth-dt`` the growth events' spacing of the growing ones.

The friction step of each batch (:func:`~aca_warp.hf.solver.friction_step`, the step at which h γ_max = 4) is still
logged and stored with its results: it bounds no step of ``strang`` (only the springs do), but it says how stiff
the batch's friction is (hf1 9.65e-8 s, hf2 9.50e-8 s, hf3 1.93e-7 s, hf4 1.90e-7 s, varying_area 1.34e-8 s, the
LF states of the multiscale schedule 1.5e-8 … 5.3e-7 s for LF seed 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from aca_warp.hf.options import growth_words


@dataclass(frozen=True)
class Stepping:
    """Integrator, fixed step and precision of a kind of experiment, with the reason.

    Attributes:
        dt: Fixed step [s].
        integrator: HF integrator (``strang``: the one the on-chip engine runs).
        precision: "fp32" or "fp64".
        growth_dt: Simulated time between the growth events of growing pads [s] (``RunOptions.growth_dt``: the
            growth per simulated time stays the scene's); None: the scenes' own interval (the paper's clock).
        force: Run a step beyond the bounds (with a warning): the quick variant's coarse smoke-check step only.
        reason: Why these settings (the measurements behind them).
    """

    dt: float
    integrator: str = "strang"
    precision: str = "fp32"
    growth_dt: float | None = None
    force: bool = False
    reason: str = ""

    def describe(self) -> str:
        """One line: integrator, step, precision and, where set, the growth events' spacing (``growth_words``)."""
        forced = " (forced)" if self.force else ""
        return f"{self.integrator}, dt = {self.dt:g} s{forced}, {self.precision}{growth_words(self.growth_dt)}"


_LF_REGIME = (
    "(one pad per LF state of the group and LF seed, seeds 1–32, against strang fp64 at 1e-8 s; "
    "docs/work_precision_statistics.md)"
)

STEPPING: dict[str, Stepping] = {
    "hf": Stepping(
        dt=1.0e-7,
        reason="HF1–HF4, the area sweep and their variants: the statistical work-precision on H200s (30 ms, a 10 ms "
        "window, against strang fp64 at 1e-8 s; docs/work_precision_statistics.md) keeps every validation measure "
        "within a quarter of the spread between seeds with strang fp32 at 1e-7 s for hf1 and hf2 (96 saturated pads "
        "each) and hf3 (128 pads, none saturated within 30 ms), and up to 5e-7 s for hf4 (32 pads); at 2.5e-7 s Φ "
        "moves in hf1 and hf3, μ mean in hf2; the equal-height variants keep every measure at 1e-7 s too (128 seeds "
        "of hf1_equal and hf2_equal, 64 of hf3_equal and hf4_equal). The area sweep lies between hf1 and hf2, the "
        "from-rest and linear-phase variants are the same pads in other states: none is a regime of its own there. "
        "10 steps per µs sample; fp32 also keeps the neighbour lists on chip",
    ),
    "growth": Stepping(
        dt=1.0e-7,
        growth_dt=5.0e-6,
        reason="the varying-area growth (§3.2): the statistical work-precision on H200s (against strang fp32 at "
        '1e-8 s on the paper\'s clock; docs/work_precision_statistics.md, "Growth events"), on the kernels with the '
        "fp32 damping fix, picks strang fp32 at 1e-7 s with growth events every 5 µs (the growth rate kept) for the "
        "paper-clock record itself (96 pads, 0.36 s: every measure within a quarter of the spread between seeds, the "
        "STFT maximum's frequency at 0.23 σ the largest; μ's rise 0.20 σ low, as at 1e-7 s with every spacing). For "
        "va (128 pads, growth compressed × 10, 36 ms; the rule's pick there is 2.5e-7 s on the paper's clock) this "
        "setting keeps every measure but the STFT maximum, left undecided by a pad that turns tonal in one run and "
        "not the other (seed 3 in its runs, 15 σ from the reference; without that seed every measure is kept); before "
        "the fix it was va's pick too (96 pads). For va_equal (128 pads, made anew on the kernels with the fp32 "
        "damping fix) the rule keeps only its reference, by one seed: the STFT maximum is undecided at 1e-7 and "
        "5e-8 s (at 5e-8 s the tonality change too) because that seed's pad turns tonal in those runs and not in the "
        "reference, and without it both steps keep every measure; 10 steps per µs sample, an event every 50 steps; "
        "fp32 as the on-chip record",
    ),
    "ms_fast": Stepping(
        dt=5.0e-8,
        precision="fp64",
        reason="the densest LF states (app2_start, 3618–4374 patches), with their variants: the statistical "
        "work-precision on H200s (one pad per LF seed 1–128, against strang fp64 at 1e-8 s; "
        "docs/work_precision_statistics.md) picks strang fp64 at 5e-8 s (4.4× the reference; Φ 0.13 ± 0.13 σ). On "
        "the kernels with the fp32 damping fix fp32 at 5e-8 s misses Φ by 0.27 ± 0.18 σ (0.22 ± 0.18 σ before the "
        "fix, when the rule picked it), while fp32 − fp64 at 5e-8 s is +0.15 ± 0.18 σ in Φ and within its interval "
        "of 0 in every measure",
    ),
    "ms_short": Stepping(
        dt=5.0e-8,
        precision="fp64",
        reason="the LF states app1_start and app2_end: the statistical work-precision on H200s (one pad per LF seed "
        "1–64 and state, against strang fp64 at 1e-8 s; docs/work_precision_statistics.md) picks strang fp64 at "
        "5e-8 s. On the kernels with the fp32 damping fix fp32 at 5e-8 s moves S − S_null by +0.33 σ in the "
        "app1_start states (+0.29 and +0.37 σ in the two halves of the seeds; −0.10 σ before the fix, when the rule "
        "picked it), while fp32 at 1e-7 s and 2.5e-7 s keep it and miss μ mean by 0.33 and 1.52 σ. fp32 − fp64 at "
        "5e-8 s, +0.39 ± 0.30 σ in S − S_null there, is −0.02 ± 0.31 σ on LF seeds 65–128: not shown to be fp32's own",
    ),
    "ms_mid": Stepping(
        dt=1.0e-7,
        reason=f"the LF states app1_end, app4_start and app4_end: the statistical work-precision on two H200s, on the "
        f"kernels with the fp32 damping fix {_LF_REGIME}, picks strang fp32 at 1e-7 s (at 2.5e-7 s the first velocity "
        "peak, 0.25 σ in app1_end, and S − S_null, 0.33 σ, are undecided); fp32 − fp64 at 5e-8 s is within its "
        "interval of 0 in every measure but the growth rate, just outside (+0.07 ± 0.07 σ)",
    ),
    "ms_app3": Stepping(
        dt=1.0e-7,
        reason=f"the LF states app3_start and app3_end: the statistical work-precision on four H200s {_LF_REGIME} "
        "picks strang fp32 at 1e-7 s (at 2.5e-7 s Φ's error is 0.33 σ, undecided)",
    ),
    "ms_order": Stepping(
        dt=5.0e-8,
        reason="app2_start after the low-load schedule (about 200 patches, friction step 4.4e-7 s): not a regime of "
        "the statistical work-precision; strang fp32 at 5e-8 s, strang's default for a scene without a preset's "
        "physics, the step that kept every measure in every measured saturated regime before the fp32 damping fix "
        "(since, ms_fast and ms_short pick fp64 at that step, and ms_app3 leaves Φ undecided there)",
    ),
}
"""The stepping of every kind of experiment (``Experiment.stepping``)."""

QUICK_STEPPING = Stepping(
    dt=1.0e-7,
    force=True,
    reason="the quick CPU smoke check: one coarse step for every experiment (forced where it exceeds a bound); "
    "not the validation",
)
"""The stepping of every experiment in the quick variant (the growing ones with the table's growth spacing)."""

GROWING = ("growth",)
"""The kinds of :data:`STEPPING` whose experiments grow (``--growth-dt`` applies to them only)."""


def stepping(
    kind: str, quick: bool, dt: float | None = None, precision: str | None = None, growth_dt: float | str | None = None
) -> Stepping:
    """The stepping of an experiment of ``kind`` (a key of :data:`STEPPING`): the quick variant's (with the table's
    growth spacing), or the table's, with ``dt`` [s] and ``precision`` replacing its own when given (``--dt``,
    ``--precision``), and ``growth_dt`` [s] the growth spacing of a kind that has one ("scene": the scenes' own
    interval; ``--growth-dt``) of a :data:`GROWING` kind."""
    import dataclasses

    base = STEPPING[kind]
    if quick:
        base = dataclasses.replace(QUICK_STEPPING, growth_dt=base.growth_dt)
    over: dict[str, Any] = {k: v for k, v in (("dt", dt), ("precision", precision)) if v is not None}
    if growth_dt is not None and kind in GROWING:
        over["growth_dt"] = None if growth_dt == "scene" else growth_dt
    return dataclasses.replace(base, **over)
