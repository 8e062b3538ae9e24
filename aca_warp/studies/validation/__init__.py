"""Validation against the paper's statements from seed ensembles.

Modules, in the order of an experiment and of the page:

* :mod:`~aca_warp.studies.validation.base`: settings, the registries of experiments and rows, and the helpers that
  turn saved per-pad results into intervals over seeds;
* :mod:`~aca_warp.studies.validation.settings`: the integrator, step and precision of every kind of experiment, in
  one place (``STEPPING``);
* :mod:`~aca_warp.studies.validation.verdicts`: the verdicts and their criteria (value, equivalence, direction with
  a margin, threshold, not comparable; undetermined where the Φ rules disagree);
* :mod:`~aca_warp.studies.validation.plan`: the scenes of an experiment's pads and the plan of its run (segments,
  per-patch windows, track windows);
* :mod:`~aca_warp.studies.validation.experiments`: batches of experiments run as one, in segments, and the
  checkpoints; :mod:`~aca_warp.studies.validation.analysis`: the saturation and analysis of their records;
* :mod:`~aca_warp.studies.validation.measures` and :mod:`~aca_warp.studies.validation.sync_measures`: the measures of
  one pad (the quantities the paper's figures show);
* :mod:`~aca_warp.studies.validation.hf_experiments`: the §3.1 experiments; their rows in
  :mod:`~aca_warp.studies.validation.hf_patterns` (Figs. 4–7), :mod:`~aca_warp.studies.validation.hf_peaks`
  (Fig. 8; :mod:`~aca_warp.studies.validation.peaks_figure` its first peaks as a figure) and
  :mod:`~aca_warp.studies.validation.hf_sync` (Fig. 9, §5);
* :mod:`~aca_warp.studies.validation.area` and :mod:`~aca_warp.studies.validation.area_rows`: §3.2 (the varying-area
  growth at the paper's rate), :mod:`~aca_warp.studies.validation.area_figure` its CWT as a figure;
* :mod:`~aca_warp.studies.validation.multiscale` and :mod:`~aca_warp.studies.validation.multiscale_rows`: §3.3 and
  §4 (HF pads on the LF states);
* :mod:`~aca_warp.studies.validation.appendix`: §2.2's filtered extremes of Eq. 6, §5's permutation test and Table
  A.2;
* :mod:`~aca_warp.studies.validation.causes`: the candidate causes of open verdicts, run as variants, and every row
  from rest at the paper's length;
* :mod:`~aca_warp.studies.validation.tracks`: the runs from rest over time;
* :mod:`~aca_warp.studies.validation.cost`: the time estimates of a run;
* :mod:`~aca_warp.studies.validation.results`: the compact ``results.json`` (or its gzip) a page section is rendered
  from; :mod:`~aca_warp.studies.validation.compare` two such files side by side and
  :mod:`~aca_warp.studies.validation.draws` every row on each disjoint draw of fewer seeds;
* :mod:`~aca_warp.studies.validation.page`: the generated part of docs/validation.md;
  :mod:`~aca_warp.studies.validation.verdicts_figure` its verdicts per section as a figure
  (``scripts/validation_figures.py``, which draws the page's figures);
* :mod:`~aca_warp.studies.validation.cli`: the command line (``scripts/validation.py``).

Importing the package registers every experiment and row, in the order of the runs and of the table.

The paper's findings (§3) describe the HF state of the friction instability; a single run stopped in its linear
growth says nothing about them. Every number here comes from an **experiment**: N pads that differ in their seed
(patch layout, areas and heights, ``[patches] seed``; initial perturbation, ``[initial] seed``), run with the one run
loop (engine ``auto``: on-chip on CUDA and on the CPU) until every pad has saturated (or for the paper's length
from rest), then analysed over the saturated part only. Experiments of one **batch** run as one batch of pads. A
**row** compares one statement of the paper with an ensemble measure: the mean over seeds with its 95 % Student-t
interval (``ensemble_interval``), the paper's value and a verdict whose criterion is fixed in advance
(:data:`~aca_warp.studies.validation.verdicts.CRITERIA`).

Stages of a batch (:func:`~aca_warp.studies.validation.experiments.run_batch`):

1. **Scenes**: the preset (or a changed copy: another M, another mean patch area, another initial state) with
   seed ``first_seed + k`` for pad k; ``--patches`` fewer patches on a sector of the pad of the same patch
   density and pressure (``reduced_pad``).
2. **Plan** (:func:`~aca_warp.studies.validation.plan.plan_run`): the predicted linear growth rate σ_i of every
   patch (``predicted_growth_rate``); the run lasts ``settle_safety · ln(v_sat / v_0) / σ_25`` plus the measurement
   window (or the paper's length); the batch as long as its longest member. Global outputs every ``sample_dt``
   over the whole run, per-patch velocities every ``decimation`` samples over the windows only: the run is stepped
   in segments, recording the patches only in the segments that hold a window.
3. **Run** through :func:`aca_warp.studies.runs.run_engine` with the stepping of
   :data:`~aca_warp.studies.validation.settings.STEPPING`; the first segment is a probe of the step time that
   stops a batch the budget cannot hold, after a warm-up from a spare state has taken the one-off costs of the
   batch's first launches.
4. **Saturation** per pad (``saturation``) on Σ|u̇| (envelope: window mean) and on μ (window standard deviation
   over 64 windows of the record); a pad counts when Σ|u̇| has a growth phase (from rest: without one) and a
   saturated part that starts at least half a window before the end.
5. **Measures** per pad: its global outputs over its own saturated span (Fig. 8's spectra, the first velocity peak
   from Σu̇, the coherence of Σu̇ with μ, μ's STFT) and its per-patch velocities over the common window (S(f) under
   both Φ rules, the patterns of motion, the radial imbalance, the permutation test); the track windows of a run
   from rest.
6. **Checkpoint**: ``<out>/<experiment>/result.json`` and ``arrays.npz`` as soon as the batch is done; a rerun with
   the same settings reuses them; at the end every result goes into the compact ``results.json``, from which the
   page is rendered.

Examples::

    python3 scripts/validation.py --device cuda:0 --out DIR --results RESULTS --max-wall 450   # GPU, one call
    python3 scripts/validation.py --quick --out DIR                                              # CPU smoke check
    python3 scripts/validation.py --report RESULTS/results.json --page docs/validation.md       # the page, no run
    python3 scripts/validation.py --device cuda:0 --dry-run                                    # the cost, runs nothing
"""

from __future__ import annotations

from aca_warp.studies.validation import (
    appendix,
    area,
    area_rows,
    hf_experiments,
    hf_patterns,
    hf_peaks,
    hf_sync,
    multiscale,
    multiscale_rows,
)

hf_experiments.register()  # §3.1: the equilibrium batch and the runs from rest at the paper's length
area.register()  # §3.2: va_full and va_full_rest
multiscale.register()  # §3.3: the LF-state groups and ms_order
appendix.register_method()  # the rows, in the paper's order: §2.2's Eq. 6
hf_patterns.register()  # §3.1 Figs. 4–7, Fig. 8, Fig. 9
hf_peaks.register()
hf_sync.register()
area_rows.register()  # §3.2
multiscale_rows.register()  # §3.3, §4
hf_sync.register_conclusions()  # §5
appendix.register()  # §5, Table A.2
area.register_variants()  # the variants run after the experiments of the rows
hf_experiments.register_variants()
multiscale.register_variants()
