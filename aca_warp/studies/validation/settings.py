"""How the validation's experiments are integrated: integrator, step and precision per kind of scene, in one place.

Every experiment names one entry of :data:`STEPPING` (``Experiment.stepping``); a batch of experiments runs with
the entry's integrator and precision, and with its fixed step or, when the entry gives none, ``bound_fraction``
× the sticking bound of ``strang`` over the batch's pads (``stable_step(model).sticking``: strang refuses a step
with h·γ > 4, where its friction step flips the sign of a sticking patch's velocity each step), so that the
step is one the run accepts without ``force``, capped at ``dt_max`` (8e-8 s: the step at which the ensemble
statistics were checked; hf3/hf4 and the low-load LF states would allow more). The run then shortens it to a
whole number of steps per sample interval (``fitted_step``). ``--dt`` and ``--precision`` replace the table's
values for every experiment.

Bounds of the presets at their start (``stable_step``): hf1 9.65e-8 s, hf2 9.50e-8 s, hf3 1.93e-7 s, hf4
1.90e-7 s, varying_area 1.34e-8 s (hf1's patches under the HF2 load: a few patches carry large loads at the start),
LF states of the multiscale schedule 1.5e-8 … 5.3e-7 s (LF seed 1; 5.3e-7 s the low-load state of ``ms_order``).
A batch takes the smallest bound of its pads.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Stepping:
    """Integrator, step and precision of a kind of experiment, with the reason.

    Attributes:
        integrator: HF integrator (``strang``: the one the on-chip engine runs).
        precision: "fp32" or "fp64".
        dt: Fixed step [s]; None: ``bound_fraction`` × strang's sticking bound of the batch, at most ``dt_max``.
        bound_fraction: Share of the sticking bound taken when ``dt`` is None (< 1: accepted without force).
        dt_max: Largest step taken by the bound rule [s] (the step at which the ensemble statistics were checked);
            None: no cap.
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

    def step(self, sticking_bound: float) -> float:
        """The step asked for [s]: ``dt``, or ``bound_fraction`` × ``sticking_bound`` [s] capped at ``dt_max``."""
        if self.dt is not None:
            return self.dt
        step = self.bound_fraction * sticking_bound
        return step if self.dt_max is None else min(step, self.dt_max)

    def describe(self) -> str:
        """One line: integrator, step rule, precision."""
        step = f"dt = {self.dt:g} s" if self.dt is not None else f"dt = {self.bound_fraction:g} × the sticking bound"
        if self.dt is None and self.dt_max is not None:
            step += f" ≤ {self.dt_max:g} s"
        return f"{self.integrator}, {step}{' (forced)' if self.force else ''}, {self.precision}"


_STATISTICS = (
    "on an H100, 64 saturated hf1 pads over 30 ms against strang 1e-8 s fp32: μ-spectrum rms log-ratio 0.023, "
    "velocity-sum peak unchanged, μ std within 2.4 % (seed spread 1.3 %) at strang 8e-8 s fp32, 2.0 s of stepping "
    "instead of 12.5 s (the statistical work-precision study, aca_warp/studies/work_precision_stats.py)"
)

STEPPING: dict[str, Stepping] = {
    "hf": Stepping(
        reason="the §3.1 presets, the area sweep and their variants: the bound over 8 seeds of hf1/hf2 is 8.8e-8 s, "
        "0.9 × that 7.92e-8 s (fitted to 7.69e-8 s, 13 steps per µs sample), at most the 8e-8 s at which the ensemble "
        f"statistics were checked: {_STATISTICS}; fp32 also keeps the neighbour lists on chip"
    ),
    "growth": Stepping(
        reason="the varying-area growth (§3.2): the bound at the start, 1.34e-8 s, gives 1.2e-8 s (84 steps per "
        "µs sample, 3.0e7 steps at the paper's 0.36 s); fp32 as the on-chip varying-area record of "
        "results_varying_area_onchip.md"
    ),
    "lf_states": Stepping(
        reason="the HF pads on the LF states (§3.3): their bounds lie at 1.5e-8 … 4.1e-7 s (patches carrying large "
        "loads at the high-pressure applications), so a batch runs at 0.9 × its smallest; fp32 keeps the dense "
        "states' neighbour lists (up to 31 links per patch) on chip where fp64 does not"
    ),
}
"""The stepping of every kind of experiment (``Experiment.stepping``)."""

QUICK_STEPPING = Stepping(
    dt=1.0e-7,
    force=True,
    reason="the quick CPU smoke check: one coarse step for every experiment (forced where it exceeds a bound: "
    "strang's friction solve is implicit and stays stable there, with μ errors ~1e-3 in stick-slip, "
    "docs/work_precision.md); not the validation",
)
"""The stepping of every experiment in the quick variant."""


def stepping(kind: str, quick: bool, dt: float | None = None, precision: str | None = None) -> Stepping:
    """The stepping of an experiment of ``kind`` (a key of :data:`STEPPING`): the quick variant's, or the table's,
    with ``dt`` [s] and ``precision`` replacing its own when given (``--dt``, ``--precision``)."""
    import dataclasses

    base = QUICK_STEPPING if quick else STEPPING[kind]
    over = {k: v for k, v in (("dt", dt), ("precision", precision)) if v is not None}
    return dataclasses.replace(base, **over)
