"""The paper's studies as library code; ``scripts/<study>.py`` are their command-line entry points.

* :mod:`~aca_warp.studies.hf_study`: stand-alone HF presets HF1-HF4 and the patch-area sweep (§3.1, Figs. 8-9), a
  package: the constants and the fit (``base``), the scenes (``scenes``), one run (``one_run``), the sweep figure
  (``sweep_figure``), the paper's claims (``claims``), ``results.md`` and ``study.json`` (``page``), the stages
  (``stages``) and the command line (``cli``);
* :mod:`~aca_warp.studies.varying_area`: growing patch areas under the HF2 load (§3.2, Eq. 10, Figs. 10-11);
* :mod:`~aca_warp.studies.multiscale`: LF over the load procedure, HF on its saved states (§3.3, Figs. 12-13);
* :mod:`~aca_warp.studies.work_precision`: error against wall time of the HF integrators and SciPy's solvers, with
  ``work_precision_states`` (the start states, made once and cached) and ``work_precision_report`` (figures, page);
* :mod:`~aca_warp.studies.work_precision_stats`: the error of the validation's ensemble statistics against integrator,
  step and precision, relative to the spread between seeds, with ``work_precision_stats_rule`` (measures,
  statistics, the rule that picks the cheapest settings) and ``work_precision_stats_report`` (figure, page);
* :mod:`~aca_warp.studies.time_to_solution`: wall time of every solver (ours, SciPy DOP853, diffrax) to a μ error;
* :mod:`~aca_warp.studies.validation`: the paper's statements (§3.1–§5, Table A.2) from seed ensembles, a package
  with modules per section of the paper (``hf_*``, ``area*``, ``multiscale*``, ``appendix``), the stepping
  (``settings``), the verdicts (``verdicts``), the runs (``plan``, ``experiments``, ``analysis``, ``measures``,
  ``sync_measures``), the candidate causes of open verdicts (``causes``), the results file (``results``), the page
  (``page``, ``tracks``) and the command line (``cli``);
* :mod:`~aca_warp.studies.report`: what the studies share (progress lines, tables, JSON, docs sections, figures);
* :mod:`~aca_warp.studies.runs`: their calls into the HF run API, all in one module.

Each study has ``main(argv)`` (its command line) and functions a test or a notebook can call. Nothing outside
this package imports it.
"""
