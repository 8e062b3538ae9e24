"""Validation against the paper's statements from seed ensembles of saturated runs.

Modules, in the order of an experiment and of the page:

* :mod:`~aca_warp.studies.validation.base`: settings, the registries of experiments and rows, intervals over seeds
  and verdicts;
* :mod:`~aca_warp.studies.validation.plan`: the scenes of an experiment's pads and the plan of its run;
* :mod:`~aca_warp.studies.validation.experiments`: running an experiment, the saturation of its pads, their
  analysis and the checkpoints;
* :mod:`~aca_warp.studies.validation.measures`: the measures of one pad over its analysis segment;
* :mod:`~aca_warp.studies.validation.hf_rows`: §3.1 (the presets HF1–HF4 and the patch-area sweep);
* :mod:`~aca_warp.studies.validation.area`: §3.2 (the varying-area growth runs);
* :mod:`~aca_warp.studies.validation.multiscale`: §3.3 and §4 (HF pads on the LF states);
* :mod:`~aca_warp.studies.validation.causes`: the candidate causes of open verdicts, run as variants;
* :mod:`~aca_warp.studies.validation.page`: the generated part of docs/validation.md;
* :mod:`~aca_warp.studies.validation.cli`: the command line (``scripts/validation.py``).

Importing the package registers every experiment and row, in the order of the table.

The paper's findings (§3) describe the saturated state of the friction instability; a single run stopped in its
linear growth says nothing about them. Every number here comes from an **experiment**: one batch of N pads that
differ in their seed (patch layout, areas and heights, ``[patches] seed``; initial perturbation, ``[initial]
seed``), run with the one run loop (engine ``auto``: on-chip on CUDA, general on the CPU) until every pad has
saturated, then analysed over the saturated part only. A **row** compares one statement of the paper with an
ensemble measure: the mean over seeds with its 95 % Student-t interval (``ensemble_interval``), the paper's value
and a verdict whose criterion is fixed in advance (:data:`~aca_warp.studies.validation.base.CRITERIA`).

Stages of an experiment (:func:`~aca_warp.studies.validation.experiments.run_experiment`):

1. **Scenes**: the preset (or a changed copy: another M, another mean patch area, another initial state) with
   seed ``first_seed + k`` for pad k; ``--patches`` fewer patches on a sector of the pad of the same patch
   density and pressure (``reduced_pad``).
2. **Plan** (:func:`~aca_warp.studies.validation.plan.plan_run`): the predicted linear growth rate σ_i of every
   patch (``predicted_growth_rate``); the run lasts ``settle_safety · ln(v_sat / v_0) / σ_25`` (e-folds from the
   initial velocity amplitude v_0 to the disc speed v_sat, at the 25th percentile of σ_i, because Σ|u̇| settles
   only when most patches have saturated) plus the measurement window. Global outputs every ``sample_dt`` over
   the whole run, per-patch velocities every ``decimation`` samples over the window only.
3. **Run** through :func:`aca_warp.studies.runs.run_engine`, samples collected by a sink (per-patch velocities
   as float32).
4. **Saturation** per pad (``saturation``) on Σ|u̇| (envelope: window mean) and on μ (window standard deviation
   over 64 windows of the record); a pad counts only when Σ|u̇| has a growth phase and a saturated part that
   starts at least half a window before the end. The analysis segment of the experiment starts at the latest
   saturated start of its pads (and no earlier than the window), so that every pad gives spectra on one grid.
5. **Measures** per pad (:func:`~aca_warp.studies.validation.measures.pad_measures`): spectra of the global
   outputs and of the patch velocities, the first velocity-spectrum peak, the Fig. 8 shape measures, S(f) under
   the ``relative`` and the ``snr`` rule with the random-phase null level, S at equal Φ, the spatial correlation
   of the directions of motion (Figs. 4/6) and of the spectral phases at the first peak, the STFT maximum of μ
   over windows of 2^12 … 2^17 samples.
6. **Checkpoint**: ``<out>/<experiment>/result.json`` and ``arrays.npz`` as soon as the experiment is done; a
   rerun with the same settings reuses them.

Experiments of other kinds follow the same stages: ``"window"`` (a fixed run analysed over its per-patch window
whether saturated or not: the linear phase of the single-run studies) and ``"growth"`` (the varying-area runs,
analysed from the global outputs after the first saturation, :mod:`~aca_warp.studies.validation.area`); an
experiment with members (the LF states of §3.3) has one pad per member and seed, its run sized by the slowest
member. Rows (:data:`~aca_warp.studies.validation.base.ROWS`) read only the saved results, so the table can be
rebuilt from checkpoints, and a row that fails is marked, not fatal. New experiments and rows plug in with
:func:`~aca_warp.studies.validation.base.register_experiment` and
:func:`~aca_warp.studies.validation.base.register_row`.

Examples::

    python3 scripts/validation.py --device cuda:0 --seeds 8 --out DIR --page docs/validation.md   # GPU, full size
    python3 scripts/validation.py --quick --out DIR --page docs/validation.md                    # CPU smoke check
    python3 scripts/validation.py --device cuda:0 --out DIR --only hf1 hf3 --max-wall 300
    python3 scripts/validation.py --device cuda:0 --seeds 8 --workers 8 --dry-run         # the cost, runs nothing
"""

from __future__ import annotations

from aca_warp.studies.validation import (  # hf_rows registers the §3.1 experiments and rows on import
    area,
    causes,
    hf_rows,  # noqa: F401
    multiscale,
)

area.register()
multiscale.register()
causes.register()
area.register_variants()
multiscale.register_variants()
