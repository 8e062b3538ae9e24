#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.work_precision``: the study, its options and examples are documented there
(``python3 scripts/work_precision.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.work_precision import main

if __name__ == "__main__":
    sys.exit(main())
