#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.friction_study``: the friction sub-step and error-control prototype, its parts,
options and examples are documented there (``python3 scripts/friction_schemes.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.friction_study import main

if __name__ == "__main__":
    sys.exit(main())
