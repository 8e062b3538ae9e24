#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.work_precision_stats`` (``python3 scripts/work_precision_stats.py --help``)."""

from __future__ import annotations

from aca_warp.studies.work_precision_stats import main

if __name__ == "__main__":
    raise SystemExit(main())
