#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.validation`` (``aca_warp.studies.validation.cli``): the experiments, rows,
options and examples are documented there (``python3 scripts/validation.py --help``, ``--list``)."""

from __future__ import annotations

import sys

from aca_warp.studies.validation.cli import main

if __name__ == "__main__":
    sys.exit(main())
