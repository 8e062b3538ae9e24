#!/usr/bin/env python3
"""Command line of ``aca_warp.studies.friction_crossing``: zero-slip crossings at large steps on full hf1 pads, the
package's strang and the prototype's sub-steps against a fine step (``python3 scripts/friction_crossing.py --help``)."""

from __future__ import annotations

import sys

from aca_warp.studies.friction_crossing import main

if __name__ == "__main__":
    sys.exit(main())
