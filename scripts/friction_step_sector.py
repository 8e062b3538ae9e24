#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.friction_sector``: the package's integrators on saturated hf1 sectors against a
fine fixed step (``python3 scripts/friction_step_sector.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.friction_sector import main

if __name__ == "__main__":
    sys.exit(main())
