#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.multiscale``: the study, its options and examples are documented there
(``python3 scripts/multiscale_study.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.multiscale import main

if __name__ == "__main__":
    sys.exit(main())
