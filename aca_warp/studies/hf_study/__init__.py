"""The paper's stand-alone HF study (§3.1, Figs. 8-9) and a patch-area sweep, with summaries beside the paper's.

Stages, each printed with the elapsed time:

1. **Presets** ``hf1``-``hf4`` (paper Table 1): each is simulated (default ``strang``, dt = 1e-8 s, fp64),
   recording the global outputs every ``--sample-dt`` and the per-patch velocities after ``--transient``;
   then ``analyze_run`` (spectra, Synchronization Index in ``--band``, peaks) and ``plot_run`` (figures
   ``<outdir>/<preset>_<figure>.png/.pdf/.gif``).
2. **Area sweep** (``--sweep-areas``, mean patch areas in mm², each a uniform range [0.4, 1.6] x mean;
   M, speed and the mean patch pressure fixed): the first velocity-spectrum peak of each point, a fit of the
   exponent b in f = c A^b (paper: -1/4) and the isolated-patch frequency sqrt(K_T sqrt(A) / (rho_A A)) / 2 pi
   as reference (``area_sweep.png/.pdf``).
3. **Summaries**: ``study.json`` (all numbers), ``results.md`` (our numbers beside the paper's, each claim as a
   measured yes/no, relative links to the figures). Both are rewritten after every run, so an interrupted
   study leaves what it had.

Run files go to ``<outdir>/runs/``. Examples::

    python3 scripts/hf_study.py --device cuda:0                       # full study (GPU, a few minutes)
    python3 scripts/hf_study.py --quick                               # short version on the CPU
    python3 scripts/hf_study.py --quick --presets hf1 --skip-sweep    # one preset only
    python3 scripts/hf_study.py --device cuda:0 --archive /tmp/hf_study.tar.gz   # plus one archive of the results

Modules, in the order of the study:

* :mod:`~aca_warp.studies.hf_study.base`: the constants, the paper's numbers and tolerances,
  :func:`~aca_warp.studies.hf_study.base.isolated_frequency` and
  :func:`~aca_warp.studies.hf_study.base.fit_power_law`;
* :mod:`~aca_warp.studies.hf_study.scenes`: :func:`~aca_warp.studies.hf_study.scenes.preset_scene` and
  :func:`~aca_warp.studies.hf_study.scenes.sweep_scene`, the scenes of the presets and of the sweep;
* :mod:`~aca_warp.studies.hf_study.one_run`: one run simulated (or reused), analysed
  (:func:`~aca_warp.studies.hf_study.one_run.analyse`: one run file's numbers) and plotted;
* :mod:`~aca_warp.studies.hf_study.sweep_figure`: ``area_sweep.png/.pdf``;
* :mod:`~aca_warp.studies.hf_study.claims`: :func:`~aca_warp.studies.hf_study.claims.comparisons`, the paper's
  claims against a ``study.json``;
* :mod:`~aca_warp.studies.hf_study.page`: ``results.md``, ``study.json`` and the archive;
* :mod:`~aca_warp.studies.hf_study.stages`: the study's record, the presets and the sweep;
* :mod:`~aca_warp.studies.hf_study.cli`: the command line, :func:`~aca_warp.studies.hf_study.cli.main` (takes
  it as a list).
"""
