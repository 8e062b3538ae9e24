"""The §3.1 experiments (stand-alone HF, Table 1): the four presets HF1–HF4 from equilibrium, the patch-area sweep,
the presets with every height 3 µm, the presets from rest at the paper's length (tracked over time), and the
linear phase of the single runs; with the batches they run in.

* ``hf1`` … ``hf4``, ``sweep_0p125``/``0p3``/``0p6`` and ``hf1_equal`` … ``hf4_equal`` run as one batch (``s31``:
  1758-patch pads, each from equilibrium + the seeded perturbation until saturated; the run as long as the slowest,
  hf3/hf4 at M = 0.4);
* ``hf1_rest`` … ``hf4_rest``: the presets released from rest and run for the paper's length (``Config.paper_length``,
  0.36 s: the varying-area run is "about as long as HF₁"), analysed over the final window like the others and over
  ``Config.track_windows`` windows on the way (batch ``rest``): which state the paper's figures show — the patches
  released together from rest, or the state reached from equilibrium + noise — the paper does not say, so both are
  judged, side by side;
* ``hf*_lin`` and ``hf*_equal_lin``: the single runs' conditions (4 ms from rest, analysed over 0.2–4 ms
  unsaturated; batch ``lin``), a candidate cause of open verdicts (:mod:`~aca_warp.studies.validation.causes`).
"""

from __future__ import annotations

from aca_warp.studies.validation.base import EXPERIMENTS, Experiment, register_experiment

PRESETS = ("hf1", "hf2", "hf3", "hf4")
SWEEP_AREAS_MM2 = (0.125, 0.3, 0.6)  # between hf1 (0.05) and hf2 (1.25): five mean areas with the presets
SWEEP = ("hf1", *(f"sweep_{a:g}".replace(".", "p") for a in SWEEP_AREAS_MM2), "hf2")
REST = tuple(f"{p}_rest" for p in PRESETS)
LIN_DURATION = 4.0e-3  # s: the single runs of results_hf.md (4 ms from rest, per-patch velocities from 0.2 ms)
LIN_START = 0.2e-3
TABLE_1 = {
    "hf1": "HF1: 0.02–0.08 mm², M = 0.8, 487.2 N",
    "hf2": "HF2: 0.5–2 mm², M = 0.8, 12.37 kN",
    "hf3": "HF3: 0.02–0.08 mm², M = 0.4, 487.2 N",
    "hf4": "HF4: 0.5–2 mm², M = 0.4, 12.37 kN",
}


def _experiments() -> tuple[Experiment, ...]:
    out = [Experiment(p, "§3.1", TABLE_1[p], p, batch="s31") for p in PRESETS]
    out += [
        Experiment(f"sweep_{a:g}".replace(".", "p"), "§3.1",
                   f"area sweep: mean {a:g} mm² (uniform 0.4–1.6 × mean), hf1 pressure, M = 0.8", "hf1",
                   mean_area_mm2=a, batch="s31")
        for a in SWEEP_AREAS_MM2
    ]  # fmt: skip
    out += [
        Experiment(f"{p}_equal", "§3.1", f"{p.upper()} with every height 3 µm (preset {p}_equal; height-spread "
                   "variant)", f"{p}_equal", quick=False, batch="s31")
        for p in PRESETS
    ]  # fmt: skip
    out += [
        Experiment(f"{p}_rest", "§3.1", f"{p.upper()} from rest for the paper's length, tracked over time", p,
                   initial="rest", tracks=True, batch="rest")
        for p in PRESETS
    ]  # fmt: skip
    for p in PRESETS:
        lin = {"initial": "rest", "kind": "window", "duration": LIN_DURATION, "window_start": LIN_START, "batch": "lin"}
        out.append(Experiment(f"{p}_lin", "§3.1", f"{p.upper()} from rest for 4 ms, analysed over 0.2–4 ms "
                              "unsaturated (run-length variant: the single run's window)", p, **lin))  # fmt: skip
        out.append(Experiment(f"{p}_equal_lin", "§3.1", f"{p.upper()} with equal heights from rest for 4 ms, over "
                              "0.2–4 ms (the single runs' conditions)", f"{p}_equal", **lin))  # fmt: skip
    return tuple(out)


HF_EXPERIMENTS = _experiments()


def register() -> None:
    """Register the §3.1 experiments (once), in their run order: the equilibrium batch, the paper-length runs from
    rest, then the linear-phase variants."""
    if PRESETS[0] in EXPERIMENTS:
        return
    for exp in HF_EXPERIMENTS:
        if not exp.name.endswith("_lin"):
            register_experiment(exp)


def register_variants() -> None:
    """Register the linear-phase variants (run after the §3.2 and §3.3 experiments of the rows)."""
    for exp in HF_EXPERIMENTS:
        if exp.name.endswith("_lin"):
            register_experiment(exp)
