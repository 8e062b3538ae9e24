"""Packages whose public names load their modules when first used: ``import aca_warp`` and the command line's parser
stay cheap (no Warp, SciPy or Dask until a name that needs them is looked up)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from importlib import import_module
from typing import Any


def lazy_names(package: str, names: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` (PEP 562) of ``package``: ``names`` maps each public name to the
    module that defines it, imported when the name is first looked up; any other name is an AttributeError (so that
    ``from package import submodule`` imports the submodule)."""

    def get(name: str) -> Any:
        if name in names:
            return getattr(import_module(names[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def listing() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(names))

    return get, listing
