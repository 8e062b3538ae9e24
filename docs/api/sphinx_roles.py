"""Griffe extension of the API reference (mkdocs.yml): the docstrings' Sphinx roles as links.

The docstrings name other objects as ``:func:`build_model```, ``:class:`~aca_warp.scene.Scene``` and so on. Each
role becomes an optional cross-reference: a link where the API reference renders the object, its name in code
type where it does not (a module left out of the reference is no broken link). A short name is resolved in the
scope of the object whose docstring holds it; ``~`` shows the last part of the name only.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:func|class|mod|data|meth|attr|exc|obj):`(?P<tilde>~?)(?P<target>[\w.]+)(?:\(\))?`")


def _full_name(obj: griffe.Object, target: str) -> str:
    """``target`` as a full dotted path, resolved from ``obj``'s scope; unchanged where that fails."""
    if target.startswith("aca_warp."):
        return target
    head, _, rest = target.partition(".")
    try:
        base = obj.resolve(head)
    except (griffe.NameResolutionError, griffe.AliasResolutionError, KeyError):
        return target
    return f"{base}.{rest}" if rest else base


def link_roles(text: str, obj: griffe.Object) -> str:
    """``text`` with every Sphinx role replaced by an optional autorefs cross-reference."""

    def replace(m: re.Match[str]) -> str:
        target = m["target"]
        shown = target.rpartition(".")[2] if m["tilde"] else target
        return f'<autoref identifier="{_full_name(obj, target)}" optional><code>{shown}</code></autoref>'

    return ROLE.sub(replace, text)


class SphinxRoles(griffe.Extension):
    """Rewrites the roles of every docstring once the package is loaded."""

    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = link_roles(obj.docstring.value, obj)
