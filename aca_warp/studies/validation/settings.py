"""How the validation's experiments are integrated: integrator, step and precision per kind of scene, in one place.

Every experiment names one entry of :data:`STEPPING` (``Experiment.stepping``); a batch of experiments runs with the
entry's integrator and precision, and with its fixed step or, when the entry gives none, ``bound_fraction`` × the
batch's friction step (:func:`~aca_warp.hf.solver.friction_step`: the step at which h γ_max = 4, γ_max = (c + F_N
max|f′|)/m the fastest friction relaxation of its patches), capped at ``dt_max``. No stability bound of ``strang``
depends on it (only the springs bound its step); it is the resolution of the friction relaxation at which the
LF-state runs are made, which the statistical work-precision rule (docs/work_precision_statistics.md) does not let
coarsen. The run then shortens the step to a whole number of steps per sample interval (``fitted_step``). ``--dt``
and ``--precision`` replace the table's values for every experiment.

Friction steps of the presets at their start: hf1 9.65e-8 s, hf2 9.50e-8 s, hf3 1.93e-7 s, hf4 1.90e-7 s,
varying_area 1.34e-8 s (hf1's patches under the HF2 load: a few patches carry large loads at the start), LF states
of the multiscale schedule 1.5e-8 … 5.3e-7 s (LF seed 1; 5.3e-7 s the low-load state of ``ms_order``). A batch
takes the smallest of its pads.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Stepping:
    """Integrator, step and precision of a kind of experiment, with the reason.

    Attributes:
        integrator: HF integrator (``strang``: the one the on-chip engine runs).
        precision: "fp32" or "fp64".
        dt: Fixed step [s]; None: ``bound_fraction`` × the batch's friction step
            (:func:`~aca_warp.hf.solver.friction_step`), at most ``dt_max``.
        bound_fraction: Share of the friction step taken when ``dt`` is None.
        dt_max: Largest step taken by the friction-step rule [s]; None: no cap.
        force: Run a step beyond the bounds (with a warning): the quick variant's coarse smoke-check step only.
        reason: Why these settings (the measurements behind them).
    """

    integrator: str = "strang"
    precision: str = "fp32"
    dt: float | None = None
    bound_fraction: float = 0.9
    dt_max: float | None = 8.0e-8
    force: bool = False
    reason: str = ""

    def step(self, friction_step: float) -> float:
        """The step asked for [s]: ``dt``, or ``bound_fraction`` × ``friction_step`` [s] capped at ``dt_max``."""
        if self.dt is not None:
            return self.dt
        step = self.bound_fraction * friction_step
        return step if self.dt_max is None else min(step, self.dt_max)

    def describe(self) -> str:
        """One line: integrator, step rule, precision."""
        step = f"dt = {self.dt:g} s" if self.dt is not None else f"dt = {self.bound_fraction:g} × the friction step"
        if self.dt is None and self.dt_max is not None:
            step += f" ≤ {self.dt_max:g} s"
        return f"{self.integrator}, {step}{' (forced)' if self.force else ''}, {self.precision}"


STEPPING: dict[str, Stepping] = {
    "hf": Stepping(
        dt=5.0e-8,
        reason="the §3.1 presets, the area sweep and their variants: the statistical work-precision on one H200 (32 "
        "saturated hf1 and hf2 pads each, 30 ms, a 10 ms window; docs/work_precision_statistics.md) keeps every "
        "validation measure within a quarter of the spread between seeds with strang fp32 at 5e-8 s and at no "
        "coarser step (at 1e-7 s the velocity-sum peak moves in hf1, μ std and S − S_null in hf2); hf4 keeps every "
        "measure up to 5e-7 s; in hf3 (no pad saturated in 30 ms) fp32 moves S − S_null against fp64 by "
        "0.29–0.33 σ at every step from 1e-8 to 5e-8 s, just past the quarter and flat in the step (a precision "
        "effect); 20 steps per µs sample; fp32 also keeps the neighbour lists on chip",
    ),
    "growth": Stepping(
        dt=5.0e-8,
        reason="the varying-area growth (§3.2): the statistical work-precision on one H200 (32 va pads, growth "
        "compressed × 10, 36 ms, against strang fp32 at 1e-8 s; docs/work_precision_statistics.md) keeps every "
        "growth measure within a quarter of the spread between seeds at 5e-8 s (at 1e-7 s the STFT maximum's "
        "frequency leaves the resolution, at 5e-7 s the first line's fall); the paper-clock record (0.36 s) grows "
        "10× slower through the same saturated stick-slip, so it takes the same step: 20 steps per µs sample, "
        "7.2e6 steps, where 0.9 × the friction step (1.2e-8 s) took 3.0e7; fp32 as the on-chip record",
    ),
    "lf_states": Stepping(
        reason="the HF pads on the LF states (§3.3): their friction steps lie at 1.5e-8 … 4.1e-7 s (patches carrying "
        "large loads at the high-pressure applications), so a batch runs at 0.9 × its smallest; the statistical "
        "work-precision on one H200 (32 app2_start pads, 20 ms) lets no coarser step through: against fp64 at 1e-8 s "
        "fp32 at 2e-8 s moves the growth rate by 0.27 σ, at 5e-8 s the velocity-sum peak by 0.4 σ; the other LF "
        "states keep fp32 at 5e-8 s (ms_short) and 1e-7 s (ms_mid, ms_app3), but one rule serves every LF state; fp32 "
        "keeps the dense states' neighbour lists (up to 31 links per patch) on chip where fp64 does not"
    ),
}
"""The stepping of every kind of experiment (``Experiment.stepping``)."""

QUICK_STEPPING = Stepping(
    dt=1.0e-7,
    force=True,
    reason="the quick CPU smoke check: one coarse step for every experiment (forced where it exceeds a bound); "
    "not the validation",
)
"""The stepping of every experiment in the quick variant."""


def stepping(kind: str, quick: bool, dt: float | None = None, precision: str | None = None) -> Stepping:
    """The stepping of an experiment of ``kind`` (a key of :data:`STEPPING`): the quick variant's, or the table's,
    with ``dt`` [s] and ``precision`` replacing its own when given (``--dt``, ``--precision``)."""
    import dataclasses

    base = QUICK_STEPPING if quick else STEPPING[kind]
    over = {k: v for k, v in (("dt", dt), ("precision", precision)) if v is not None}
    return dataclasses.replace(base, **over)
