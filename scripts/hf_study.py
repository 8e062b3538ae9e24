#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.hf_study`` (``aca_warp.studies.hf_study.cli``): the study, its options and
examples are documented there (``python3 scripts/hf_study.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.hf_study.cli import main

if __name__ == "__main__":
    sys.exit(main())
