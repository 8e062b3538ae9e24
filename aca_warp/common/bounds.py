"""Inputs read within limits: an input file (a run file, a patch file, a sweep shard, a scene or a spec) is checked
before it is read, so that a crafted one costs a line on stderr, not the host's memory or a traceback.

* :func:`check_h5`: an HDF5 input holds only hard links (an external link would open another file, possibly not
  the user's, and a soft link can point anywhere in the file or at itself), and every dataset's declared size is
  backed by what the file stores (a chunked dataset can declare 2^40 rows in a 1 MB file: reading it would
  allocate 8 TiB) and fits the available memory; datasets are numbers unless named as text.
* :func:`check_nesting`: the arrays and tables of a JSON attribute (the stored scene) or a TOML file nest at most
  :data:`MAX_NESTING` deep (Python's parsers recurse once per level: 20 000 levels are a RecursionError);
  :func:`json_attribute` decodes a JSON attribute that way.
* :func:`read_toml`: a TOML file (a scene, an LF scene, a sweep spec) is read only up to :data:`MAX_TOML_BYTES`: a
  file named by mistake (a disc image, a log) is refused, not read into memory.

Each refusal is one :class:`~aca_warp.common.errors.SceneError` line (exit 2) naming the file and what is wrong.
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.errors import SceneError, with_article

MAX_NESTING = 64  # arrays and tables within each other in a JSON attribute or a TOML file (aca-warp writes 3)
MAX_TOML_BYTES = 64 * 2**20  # the largest TOML file read [bytes] (the presets' scenes are about 1 KiB)
TOML_HEAD_BYTES = 512  # the first bytes of a TOML file, shown to read_toml's ``refuse`` before the rest is read
MAX_PADS = 10**6  # pads of one sweep (its spec refused beyond, before the combinations are expanded; a shard file's)
# declared bytes a dataset may hold beyond what the file stores for it: rows appended to a killed run's dataset
# after its last flush, never written (at most the writer's chunk cache per dataset, 64 MiB), plus a chunk
UNSTORED_SLACK = 80 * 2**20
COMPRESSION_RATIO = 1000  # most a filtered (compressed) dataset may declare per stored byte


def available_memory(device: Any = None) -> int:
    """Bytes that may be used: the free memory of a CUDA ``device``, or the host's available memory
    (MemAvailable)."""
    if getattr(device, "is_cuda", False):
        free = getattr(device, "free_memory", None)
        if free:
            return int(free)
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 2**62  # unknown: do not refuse


def _size(b: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if b >= scale:
            return f"{b / scale:.3g} {unit}"
    return f"{b:.0f} B"


def check_h5(f: Any, path: str | Path, what: str, *, text: tuple[str, ...] = ()) -> None:
    """Refuse (one SceneError line) an HDF5 input ``f`` (open h5py File of ``path``, a ``what`` such as "run file")
    that holds a soft or external link, a dataset whose declared size the file does not back (more than
    :data:`UNSTORED_SLACK` beyond its stored bytes; :data:`COMPRESSION_RATIO` times them for a filtered dataset) or
    that exceeds the available memory, or a dataset that is not numbers (outside the groups named in ``text``).
    Links are listed without being followed; nothing is read but metadata."""
    import h5py

    where = f"{what} {path}"
    memory = available_memory()
    seen: set[Any] = set()
    groups: list[tuple[Any, str]] = [(f, "")]
    while groups:  # a walk by hand, not h5py's visit (a signal inside its C callback would be lost)
        g, prefix = groups.pop()
        for name in g:
            path_in = f"{prefix}{name}"
            link = g.get(name, getlink=True)
            if isinstance(link, (h5py.SoftLink, h5py.ExternalLink)):
                external = isinstance(link, h5py.ExternalLink)
                target = f"{link.filename}:{link.path}" if external else link.path
                raise SceneError(
                    f"{where}: /{path_in} is {'an external' if external else 'a soft'} link (to {target}); aca-warp "
                    "files hold none and it is not followed: a crafted or foreign file"
                )
            obj = g[name]
            if isinstance(obj, h5py.Group):
                if obj.id not in seen:  # a group hard-linked into itself is walked once
                    seen.add(obj.id)
                    groups.append((obj, f"{path_in}/"))
            elif isinstance(obj, h5py.Dataset):
                problem = _dataset_problem(obj, memory, numbers=path_in.split("/")[0] not in text)
                if problem:
                    raise SceneError(f"{where}: /{path_in} {problem}; it is not read (a crafted or damaged file)")


def _dataset_problem(d: Any, memory: int, *, numbers: bool) -> str | None:
    """What is wrong with dataset ``d`` as an input (:func:`check_h5`), or None."""
    dt = d.dtype
    if numbers and not (dt.kind in "biuf" and dt.fields is None and not dt.subdtype):
        return f"holds {dt} values, not numbers"
    declared = int(np.prod(d.shape or (0,), dtype=object)) * dt.itemsize
    stored = d.id.get_storage_size()
    backed = stored * COMPRESSION_RATIO if d.id.get_create_plist().get_nfilters() else stored
    says = f"declares {d.shape} ({_size(declared)})"
    if declared > backed + UNSTORED_SLACK:
        return f"{says} but the file stores {_size(stored)} of it"
    if declared > memory:
        return f"{says}, more than the {_size(memory)} of memory available"
    return None


def check_nesting(text: str, what: str, *, toml: bool = False) -> None:
    """Refuse JSON (or, ``toml``, TOML) ``text`` whose arrays and tables nest deeper than :data:`MAX_NESTING`
    (one SceneError line naming ``what``), before a parser recurses into it. Brackets inside strings (and TOML
    comments) do not count; TOML table headers count as one level."""
    depth = deepest = 0
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in "[{":
            depth += 1
            deepest = max(deepest, depth)
            if deepest > MAX_NESTING:
                raise SceneError(
                    f"{what} nests arrays or tables more than {MAX_NESTING} deep; it is not parsed (a crafted or "
                    "broken file)"
                )
        elif c in "]}":
            depth = max(depth - 1, 0)
        elif c == '"' or (toml and c == "'"):
            i = _string_end(text, i, toml)
        elif toml and c == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j
        i += 1


def _string_end(text: str, i: int, toml: bool) -> int:
    """Index of the last character of the string that starts at ``text[i]`` (a quote)."""
    q = text[i]
    if toml and text.startswith(q * 3, i):  # a multi-line string
        j = text.find(q * 3, i + 3)
        return len(text) if j < 0 else j + 2
    j = i + 1
    while j < len(text) and text[j] != q and not (toml and text[j] == "\n"):
        j += 2 if text[j] == "\\" and q == '"' else 1
    return j


def read_toml(path: Path, what: str, *, refuse: Callable[[bytes], None] | None = None) -> dict[str, Any]:
    """Parse the TOML file ``path`` (a ``what`` such as "scene file") within :data:`MAX_TOML_BYTES` and
    :data:`MAX_NESTING` levels: one SceneError line when it is larger, nests too deep, is not TOML or not UTF-8;
    OSError when it cannot be read. ``refuse``, if given, sees the file's first :data:`TOML_HEAD_BYTES` bytes
    before the rest is read (one open), and raises for a file of another kind."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    with open(path, "rb") as f:
        raw = f.read(TOML_HEAD_BYTES)
        if refuse is not None:
            refuse(raw)
        raw += f.read(MAX_TOML_BYTES + 1 - len(raw))
    if len(raw) > MAX_TOML_BYTES:
        raise SceneError(
            f"{what} {path} is larger than {MAX_TOML_BYTES // 2**20} MiB, more than any {what} holds: not read "
            "(is it the file you meant?)"
        )
    try:
        text = io.StringIO(raw.decode("utf-8"), newline=None).read()  # newlines as a text file reads them
    except UnicodeDecodeError as e:
        noun = with_article(what)
        raise SceneError(f"cannot parse {path}: {noun} is TOML text, and byte {e.start} is not UTF-8") from None
    check_nesting(text, f"{what} {path}", toml=True)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"cannot parse {path}: {e}") from None


def json_attribute(value: Any, what: str) -> Any:
    """A JSON attribute (text, or bytes) decoded within :data:`MAX_NESTING` levels; SceneError naming ``what``
    (e.g. "RUN.h5: attribute 'scene'") when it is not text, nests too deep or is not JSON."""
    if isinstance(value, (bytes, np.bytes_)):
        value = bytes(value).decode(errors="replace")
    if not isinstance(value, str):
        raise SceneError(f"{what} is {type(value).__name__}, not JSON text (a crafted or damaged file)")
    check_nesting(value, what)
    try:
        return json.loads(value)
    except json.JSONDecodeError as e:
        raise SceneError(f"{what} is not valid JSON ({e})") from None
