"""Import a file of ``scripts/`` as a module, for the tests of the benchmark and profiling scripts
(the studies are library code, ``aca_warp.studies``, imported directly)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

SCRIPTS = Path(__file__).resolve().parent.parent / "scripts"


def load_script(name: str) -> ModuleType:
    """``scripts/<name>.py`` as a fresh module named ``name``; ``scripts/`` on ``sys.path``, as when a script runs, so
    that the scripts import one another."""
    if str(SCRIPTS) not in sys.path:
        sys.path.append(str(SCRIPTS))
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the script runs
    spec.loader.exec_module(module)
    return module


def exit_code(name: str, argv: list[str]) -> object:
    """The exit code of ``scripts/<name>.py`` run with ``argv``: its ``main()`` called while ``sys.argv`` is
    ``[<name>.py, *argv]`` (a ``main(argv=None)`` reads it there too), the value it returns or the code of the
    SystemExit it raises (``argparse``'s errors)."""
    module = load_script(name)
    saved = sys.argv
    sys.argv = [f"{name}.py", *argv]
    try:
        return module.main()
    except SystemExit as stop:
        return stop.code
    finally:
        sys.argv = saved
