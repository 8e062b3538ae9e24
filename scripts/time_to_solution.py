#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.time_to_solution``: the benchmark, its options and examples are documented
there (``python3 scripts/time_to_solution.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.time_to_solution import main

if __name__ == "__main__":
    sys.exit(main())
