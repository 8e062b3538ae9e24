"""The paper's stand-alone HF study (§3.1, Figs. 8-9) and a patch-area sweep: :mod:`~aca_warp.studies.hf_study.page`."""

from aca_warp.studies.hf_study.page import *  # noqa: F403
