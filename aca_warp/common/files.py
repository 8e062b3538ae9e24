"""Files shared by HF and LF runs: output paths, the ``.partial`` convention, the one-writer lock, opening HDF5
files, provenance."""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import platform
import socket
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from contextvars import ContextVar
from pathlib import Path
from typing import Any, BinaryIO

import h5py
import numpy as np

from aca_warp.common.checkpoint import has_checkpoint
from aca_warp.common.errors import AcaError, SceneError, StorageError, option, with_article
from aca_warp.common.interrupts import deferred
from aca_warp.common.links import NOFOLLOW, clear_name, open_lock_file, private_dir

# why a folder cannot take a new file, by errno (the probe and the lock file; docs/faults.md "Output folders")
UNWRITABLE = {
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file size limit reached",
}


def versions() -> dict[str, str]:
    """Versions of Python and of the packages a run depends on, and the digest of the Warp kernels' sources
    (``kernels``, :func:`kernels_digest`): the package's version does not change when a kernel does."""
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("aca-warp", "warp-lang", "numpy", "scipy", "h5py", "matplotlib"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    out["kernels"] = kernels_digest()
    return out


def kernels_digest(folder: Path | None = None) -> str:
    """The first 12 hex digits of the SHA-256 of the Warp kernels' sources (``folder``/*.py by name and content;
    default the package's ``kernels/``): which kernels a result's numbers came from. Any edit of a kernel file gives
    another digest, a comment's too (two digests may name the same arithmetic, never one digest two); the host-side
    Python (e.g. the recorder) is not in it."""
    import importlib.util

    if folder is None:  # the package's folder, found without running its __init__ (which imports Warp)
        spec = importlib.util.find_spec("aca_warp.kernels")
        assert spec is not None and spec.submodule_search_locations
        folder = Path(list(spec.submodule_search_locations)[0])
    h = hashlib.sha256()
    for p in sorted(folder.glob("*.py")):
        h.update(p.name.encode() + b"\0" + p.read_bytes())
    return h.hexdigest()[:12]


def attr_value(value: Any) -> Any:
    """An HDF5 attribute as a Python value: bytes → str, NumPy scalars → Python scalars, text holding a JSON list
    or object → that object (other text unchanged; nested beyond :data:`~aca_warp.common.bounds.MAX_NESTING`:
    SceneError)."""
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, str) and value[:1] in "[{":
        from aca_warp.common.bounds import check_nesting

        check_nesting(value, "an attribute")  # a crafted attribute nested 20 000 deep: one line, not a RecursionError
        try:
            return json.loads(value)
        except json.JSONDecodeError:
            return value
    return value


def host_cpu() -> str:
    """This host's CPU model (from /proc/cpuinfo where there is one) and core count, e.g. "AMD EPYC, 2 cores"."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores"


def machine(device: Any) -> dict[str, str]:
    """The device and host that ran something: ``device`` (Warp alias), ``device_name``, ``host``, ``platform``."""
    host = host_cpu()
    name = device.name if device.is_cuda else f"CPU ({host}; Warp CPU kernels run on one thread)"
    return {"device": str(device), "device_name": name, "host": host, "platform": platform.platform()}


def partial_path(path: str | Path) -> Path:
    """The name a run file has while it is written: ``NAME.partial``."""
    p = Path(path)
    return p.with_name(p.name + ".partial")


UNNAMED = "another process"  # the holder of a lock file that names none
TRANSIENT_S = 0.5  # s a lock held by no named writer is tried again before it is taken for a live writer's


def lock_path(path: str | Path) -> Path:
    """The lock file of the output ``path``: ``NAME.lock`` next to it."""
    p = Path(path)
    return p.with_name(p.name + ".lock")


class OutputLock:
    """The one writer of an output (a run file with its ``.partial``, or a sweep folder's manifest).

    ``flock(LOCK_EX | LOCK_NB)`` on ``NAME.lock``, a file that holds the holder's pid, host and command for the
    refusal message. The kernel drops the lock when its holder exits, however it exits (SIGKILL included), so a
    killed run leaves no stale lock; the lock is independent of HDF5's own file locking
    (``HDF5_USE_FILE_LOCKING``). :meth:`release` removes the file while still holding the lock, and
    :meth:`acquire` checks after locking that the path still names the file it locked (else it lost a race with a
    release and tries again), so two processes never both hold the lock of one name. On NFS ``flock`` is carried
    by byte-range locks (lockd); where a filesystem has no locks at all the output is written unlocked, with a note.
    The lock file is opened without following a link (:func:`~aca_warp.common.links.open_lock_file`).

    One writer per *file*, not per name: :meth:`own` also locks the identity (device and inode) of the file being
    written, in the user's private folder (:func:`~aca_warp.common.links.private_dir`), so that a symbolic or hard
    link of a live file, or the file moved to another name, is refused as a second writer too.
    """

    def __init__(self, path: Path, fd: int | None) -> None:
        self.path = path
        self.fd = fd
        self.identity: list[tuple[Path, int]] = []  # (lock file, fd) of the files this writer owns

    @classmethod
    def acquire(cls, path: str | Path, *, what: str = "output") -> OutputLock:
        """Lock ``path`` for writing; :class:`SceneError` naming the holder when another process holds it, one
        for a path that names a folder (:func:`check_output_name`) or a link planted at ``NAME.lock``,
        :class:`StorageError` (exit 4) when its folder takes no new file (:func:`unwritable`)."""
        p = check_output_name(path)
        lp = lock_path(p)
        try:
            fd = _take(lp, p, what)
        except FileNotFoundError:
            raise SceneError(f"output folder {p.parent} does not exist") from None
        except NotADirectoryError:
            raise SceneError(f"output folder {p.parent} is not a folder") from None
        except OSError as e:
            raise unwritable(p.parent, e) from None
        if fd is None:
            print(f"aca-warp: note: {lp.parent} has no file locks; {p} is written unlocked: "
                  "make sure no other process writes it", file=sys.stderr)  # fmt: skip
        return cls(lp, fd)

    def own(self, file: str | Path, *, what: str = "output") -> None:
        """Lock the identity of ``file`` (the file this writer writes, reached through whatever name):
        :class:`SceneError` naming the holder when another process writes the same file under another name. Where
        the user has no private folder, only the name is locked (a note says so)."""
        st = os.stat(file)
        try:
            folder = private_dir("files")
            lp = folder / f"{st.st_dev:x}-{st.st_ino}.lock"
            fd = _take(lp, Path(file), what)
        except AcaError:
            raise
        except OSError as e:
            print(f"aca-warp: note: no private lock folder ({e.strerror or e}); {file} is locked by its name only",
                  file=sys.stderr)  # fmt: skip
            return
        if fd is not None:
            self.identity.append((lp, fd))
            _drop_stale(folder, keep=lp)

    @property
    def held(self) -> bool:
        """Whether this object still holds the lock."""
        return self.fd is not None

    def release(self) -> None:
        """Remove the lock files and drop the locks (idempotent)."""
        for lp, fd in self.identity:
            _drop(lp, fd)
        self.identity = []
        if self.fd is None:
            return
        _drop(self.path, self.fd)
        self.fd = None


def _take(lp: Path, p: Path, what: str) -> int | None:
    """Take ``flock(LOCK_EX | LOCK_NB)`` on the lock file ``lp`` of ``p`` (created if missing, never through a
    link) and write this process into it; the descriptor, or None on a filesystem without locks. SceneError naming
    the holder when another process holds it; OSError when the file cannot be created.

    A lock held by no named writer (the file holds no pid yet) is held only for a moment: by a sweep of stale
    identity locks (:func:`_drop_stale`, which may lock a file another writer has just created before that writer
    locks it), by :func:`holder`'s probe, or by a writer between its lock and its note. Such a lock is tried again
    for up to :data:`TRANSIENT_S` before the refusal; a named writer is refused at once."""
    deadline = time.monotonic() + TRANSIENT_S
    while True:
        fd = open_lock_file(lp)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            if holder == UNNAMED and time.monotonic() < deadline:
                time.sleep(0.005)
                continue
            raise SceneError(f"{p} is being written by {holder}; {what}") from None
        except OSError as e:
            os.close(fd)
            if e.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
                raise
            return None
        try:
            same = os.path.samestat(os.fstat(fd), os.lstat(lp))
        except FileNotFoundError:
            same = False
        if not same:  # the holder released (and removed) it between our open and flock: try again
            os.close(fd)
            continue
        command = " ".join(sys.argv).replace("\n", " ")[:200]  # one line: the holder's note is read back as one
        try:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()} {socket.gethostname()} {command}\n".encode())
        except OSError:  # a full device: no lock held, none left behind (the file is ours while we hold it)
            lp.unlink(missing_ok=True)
            os.close(fd)
            raise
        return fd


def _drop_stale(folder: Path, keep: Path) -> None:
    """Remove the identity lock files in ``folder`` that no process holds (left by killed writers), ``keep``
    aside: each is locked first and removed while locked, so a live one is never touched."""
    for lp in folder.glob("*.lock"):
        if lp == keep:
            continue
        try:
            fd = open_lock_file(lp)
        except (AcaError, OSError):
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)  # held by a live writer
            continue
        try:
            stale = os.path.samestat(os.fstat(fd), os.lstat(lp))
        except FileNotFoundError:  # removed meanwhile by its owner or another sweep of the folder
            stale = False
        if stale:
            _drop(lp, fd)
        else:
            os.close(fd)


def _drop(lp: Path, fd: int) -> None:
    """Remove the lock file ``lp`` while still holding its lock, then drop the lock."""
    try:
        os.unlink(lp)
    except OSError:
        pass
    os.close(fd)


def _read_holder(fd: int) -> str:
    """'pid P on HOST (COMMAND)' from a lock file's content, or :data:`UNNAMED`."""
    try:
        parts = os.pread(fd, 512, 0).decode(errors="replace").split(maxsplit=2)
        if len(parts) >= 2:
            cmd = f" ({parts[2].strip()})" if len(parts) > 2 else ""
            return f"pid {parts[0]} on {parts[1]}{cmd}"
    except OSError:
        pass
    return UNNAMED


def holder(path: str | Path) -> str | None:
    """Who holds the lock of the output ``path`` ('pid P on HOST (COMMAND)'), or None when no other live process
    does (this process holding it counts as none: :meth:`OutputLock.acquire` guards against itself)."""
    try:
        fd = os.open(lock_path(path), os.O_RDONLY | os.O_CLOEXEC | os.O_NONBLOCK | NOFOLLOW)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        who = _read_holder(fd)
        return None if who.startswith(f"pid {os.getpid()} on {socket.gethostname()}") else who
    except OSError:
        return None
    finally:
        os.close(fd)
    return None


@contextmanager
def locked_output(path: str | Path, *, what: str = "output") -> Iterator[OutputLock]:
    """:meth:`OutputLock.acquire` for the body; released when it ends."""
    lock = OutputLock.acquire(path, what=what)
    try:
        yield lock
    finally:
        lock.release()


def new_path(partial: str | Path) -> Path:
    """Where a file is created before it is renamed into ``NAME.partial``: ``NAME.partial.new``."""
    p = Path(partial)
    return p.with_name(p.name + ".new")


def create_h5(tmp: Path, lock: OutputLock, **kw: Any) -> h5py.File:
    """Create the HDF5 file ``tmp`` (``NAME.partial.new``) for the writer holding ``lock``: exclusively and never
    through a link (:func:`~aca_warp.common.links.clear_name`, then HDF5's ``mode="x"``), its identity locked
    (:meth:`OutputLock.own`). ``kw`` go to ``h5py.File``."""
    clear_name(tmp, "temporary file")
    f = h5py.File(tmp, "x", **kw)
    try:
        lock.own(tmp)
    except BaseException:
        f.close()
        tmp.unlink(missing_ok=True)
        raise
    return f


def check_output_name(path: str | Path, *, flag: str = "output", example: str = "run.h5") -> Path:
    """``path`` as the name of an output file, refused in one line naming ``flag`` and a name like ``example``:
    an empty name; a name that ends in a path separator or is ``.``/``..``, which names a folder (``Path`` would drop
    the separator and write a file named like the folder); an existing folder."""
    text = os.fspath(path)
    if not text.strip():
        raise SceneError(f"{flag} {text!r} names no file; give a file name such as {example}")
    if text.endswith(("/", os.sep)) or Path(text).name in ("", ".", ".."):
        base = text.rstrip("/" + os.sep) or "."
        raise SceneError(f"{flag} {text!r} names a folder; give a file name such as {Path(base) / example}")
    if Path(text).is_dir():
        raise SceneError(f"{flag} {text} is a folder; give a file name such as {Path(text) / example}")
    return Path(text)


def unwritable(folder: str | Path, e: OSError) -> AcaError:
    """The one-line error for a folder that takes no new file: :class:`StorageError` (exit 4) for a read-only file
    system, missing permission, a full device or quota; :class:`SceneError` (exit 2) for anything else."""
    why = UNWRITABLE.get(e.errno or 0)
    if why is None:
        return SceneError(f"cannot create a file in {folder}: {e.strerror or e}")
    err = StorageError(f"cannot write into {folder} ({why}); nothing was written: choose another output folder")
    err.errno = e.errno  # type: ignore[attr-defined]
    return err


def probe_folder(folder: str | Path) -> None:
    """Check that ``folder`` takes a new file the honest way: create a small probe file there, write to it and
    delete it. Raises :func:`unwritable`'s error (a read-only file system, a folder without write permission, a full
    device; root passes permission checks, so ``os.access`` would not do)."""
    d = Path(folder)
    try:
        fd, name = tempfile.mkstemp(prefix=".aca-warp-probe.", dir=d)  # a new name: never another's file
        probe = Path(name)
    except FileNotFoundError:  # /proc, /sys: folders that take no file, and say so this way
        why = "does not exist" if not d.is_dir() else "takes no new file (a virtual file system)"
        raise SceneError(f"output folder {d} {why}") from None
    except NotADirectoryError:
        raise SceneError(f"output folder {d} is not a folder") from None
    except OSError as e:
        raise unwritable(d, e) from None
    try:
        os.write(fd, b"\0" * 4096)  # a full device takes an empty file, not a block
    except OSError as e:
        raise unwritable(d, e) from None
    finally:
        os.close(fd)
        probe.unlink(missing_ok=True)


def folder_named(path: str | Path, error: type[AcaError] = SceneError) -> None:
    """Refuse an output folder's empty name (``Path('')`` is the current folder: an unset variable in a script,
    ``-o "$OUT"``) in one ``error`` line."""
    if not os.fspath(path).strip():
        raise error(f"output folder {os.fspath(path)!r} names no folder; give one (. for the current folder)")


def check_output_folder(path: str | Path) -> Path:
    """An output folder (``plot -o DIR``, ``sweep -o DIR``; created later if missing): it must be named (an empty
    name would be the current folder: an unset variable in a script, ``-o "$OUT"``), must not be a file, and the
    folder that will hold it (itself, or its nearest existing parent) must take a new file (:func:`probe_folder`:
    exit 4 for a read-only or full file system, nothing written)."""
    folder_named(path)
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise SceneError(f"output {p} exists and is not a folder")
    parent = p
    while not parent.exists():
        if parent.parent == parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        raise SceneError(f"output {p} cannot be created: {parent} is not a folder")
    probe_folder(parent)
    return p


def check_room(
    folder: str | Path, need: float, what: str, *, whose: str = "the run's file", written: str = "nothing was written"
) -> None:
    """Refuse a run whose file (``need`` bytes on disk, as the run's plan estimates it) exceeds the space free to
    this user in ``folder``: :class:`StorageError` (exit 4) before anything is written. ``what`` names the run's
    options that shrink it, ``whose`` the files (a sweep's shards) and ``written`` what was written by then.
    Filesystems without ``statvfs`` figures pass."""
    try:
        st = os.statvfs(folder)
    except OSError:
        return
    free = st.f_bavail * st.f_frsize
    if st.f_blocks and need > free:
        err = StorageError(
            f"{whose} will take about {need / 1e6:.4g} MB but {folder} has {free / 1e6:.4g} MB free; {written}: "
            f"make room, choose another output folder or record less ({what})"
        )
        err.errno = errno.ENOSPC  # type: ignore[attr-defined]
        raise err


def resume_hint(kind: str, path: str | Path) -> str:
    """How to continue the unfinished ``kind`` run (``hf`` or ``lf``) of ``path``, for the reader of the message."""
    function = "resume_run" if kind == "hf" else "resume_lf"
    return option(f"{function}({str(path)!r})", f"'aca-warp {kind} --resume {path}'")


def recovery(path: str | Path) -> str:
    """What to do with the unfinished run ``path`` (``NAME``, or ``NAME.partial``), true of its file as it is now:
    continue it with ``--resume``, from its checkpoint, or from t = 0 when it holds none (it ran without checkpoints,
    or stopped before its first: :func:`~aca_warp.hf.runner.resume_run` then starts it again). The one piece of
    advice of every message that leaves a run unfinished: a storage failure, an interrupt, an output whose
    ``.partial`` is in the way."""
    final, src = _unfinished(path)
    try:
        with open_h5(src, "run file") as f:
            kind = "lf" if attr_value(f.attrs.get("kind")) == "lf" else "hf"
            at = _checkpoint_time(f)
            stored = attr_value(f.attrs.get("lf_run" if kind == "lf" else "run_options", "{}"))
            interval = stored.get("checkpoint_interval") if isinstance(stored, dict) else None
    except _UNREADABLE:
        return f"{src.name} cannot be read back (empty or damaged): run its scene again"
    if at is not None:
        return f"continue it from its checkpoint at t = {at:.6g} s with {resume_hint(kind, final)}"
    why = "it ran without checkpoints" if interval == 0 else "it stopped before its first one"
    return f"continue it from t = 0 with {resume_hint(kind, final)} (it holds no checkpoint: {why})"


_UNREADABLE = (AcaError, OSError, RuntimeError, KeyError, ValueError, TypeError)  # a run file that cannot be read


def _readable(path: Path) -> bool:
    """Whether the run file ``path`` opens as one (an unfinished run that does not has nothing to continue)."""
    try:
        with open_h5(path, "run file"):
            return True
    except _UNREADABLE:
        return False


def _unfinished(path: str | Path) -> tuple[Path, Path]:
    """(its final name, the file it is in now) of the unfinished run ``path`` (``NAME`` or ``NAME.partial``): the
    ``.partial`` where it exists, else ``NAME``."""
    p = Path(path)
    final = p.with_name(p.name.removesuffix(".partial"))
    part = partial_path(final)
    return final, part if part.exists() else final


def _interrupted(path: Path) -> bool:
    """Whether ``path`` is a run file that an interrupt (Ctrl-C, SIGTERM) closed unfinished."""
    try:
        with open_h5(path, "run file") as f:
            return str(attr_value(f.attrs.get("status", ""))).startswith("interrupted")
    except _UNREADABLE:
        return False


def _checkpoint_time(f: Any) -> float | None:
    """The simulated time of the open run file ``f``'s checkpoint [s], or None when it holds none."""
    return float(f["checkpoint"].attrs["sim_time"]) if has_checkpoint(f) else None


def resumed_from(path: str | Path) -> str:
    """Where a resume of the unfinished run ``path`` (``NAME`` or ``NAME.partial``) starts, for its summary line:
    "from its checkpoint at t = … s", or "again from t = 0 (it held no checkpoint)"; "" when the file cannot be
    read (the resume then says why)."""
    try:
        with open_h5(_unfinished(path)[1], "run file") as f:
            at = _checkpoint_time(f)
    except _UNREADABLE:
        return ""
    return "again from t = 0 (it held no checkpoint)" if at is None else f"from its checkpoint at t = {at:.6g} s"


def check_output_path(path: str | Path, *, overwrite: bool, flag: str = "output", example: str = "run.h5") -> Path:
    """Refuse to clobber an existing file (or a killed run's ``NAME.partial``) unless ``overwrite``, and an output
    that a live process writes (:class:`OutputLock`) in any case; the name must name a file
    (:func:`check_output_name`, with ``flag`` and ``example``), its folder must exist and take a new file
    (:func:`probe_folder`: exit 4 for a read-only or full file system)."""
    p = check_output_name(path, flag=flag, example=example)
    if p.exists() and not p.is_file():  # --overwrite would replace a device, pipe or socket with a regular file
        raise SceneError(f"{flag} {p} exists and is not a regular file (a device, pipe or socket); give another output")
    busy = holder(p)
    if busy is not None:
        raise SceneError(f"{p} is being written by {busy}; wait for it to finish or stop it")
    part = partial_path(p)
    if not overwrite and (p.exists() or part.exists()):
        again = option("overwrite=True", "--overwrite")
        if part.exists():  # an unfinished run: killed, or one that was to replace the output (an --overwrite)
            beside = f"output file {p} exists, and {part.name} beside it" if p.exists() else f"{part} exists"
            both = "both" if p.exists() else "it"
            if not _readable(part):
                raise SceneError(f"{beside} (an unfinished run that cannot be read back: empty or damaged); pass "
                                 f"{again} to replace {both}")  # fmt: skip
            raise SceneError(f"{beside} (an unfinished run): {recovery(p)}; or pass {again} to replace {both}")
        if _interrupted(p):
            why = f"output file {p} exists (an interrupted run): {recovery(p)}"
            raise SceneError(f"{why}; or pass {again} to replace it")
        raise SceneError(f"output file {p} exists; pass {again} to replace it")
    if not p.parent.exists():
        raise SceneError(f"output folder {p.parent} does not exist")
    if not p.parent.is_dir():
        raise SceneError(f"output folder {p.parent} is not a folder")
    probe_folder(p.parent)
    return p


@contextmanager
def whole(path: Path, what: str = "temporary file") -> Iterator[BinaryIO]:
    """Yield a file open for writing under a temporary name next to ``path`` (hidden, same suffix; its ``name`` is
    that path) and move it to ``path`` when the body ends; on any failure or interrupt the temporary file is
    removed. A file written so (a figure, a benchmark's results) is never half written. The temporary file is created
    exclusively and never through a link (:func:`~aca_warp.common.links.create_new`: a link planted there is
    refused, naming it ``what``) and written through this descriptor only, so nothing another user plants in the
    folder is followed."""
    from aca_warp.common.links import create_new  # looked up per call (tests put a failing one in its place)

    if path.is_dir():  # os.replace would fail late, after the drawing, with a traceback
        raise SceneError(f"{path} is a folder where a file of that name goes; move it away or choose another folder")
    tmp = path.with_name(f".{path.stem}.partial{path.suffix}")
    fh = open(tmp, "wb", opener=lambda name, flags: create_new(Path(name), what))  # noqa: SIM115
    try:
        with fh:
            yield fh
        book = _WRITES.get()
        if book is not None:
            book.before_replacing(path)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class _Writes:
    """The files :func:`whole` wrote inside :func:`all_or_nothing`, and the earlier files they replaced, each kept
    under a hidden name beside it until the block ends."""

    def __init__(self) -> None:
        self.written: list[Path] = []
        self.earlier: dict[Path, Path] = {}  # a replaced file -> where it is kept

    def before_replacing(self, path: Path) -> None:
        """Before ``path`` is replaced: the file (or link) there moved aside under a name of its own, unless this
        block wrote it or there is none, and ``path`` counted as written (each noted before its step: an interrupt
        between the steps still finds it)."""
        if path in self.written:
            return
        if path.is_file() or path.is_symlink():
            kept = path.with_name(f".aca-earlier-{os.getpid()}-{os.urandom(4).hex()}{path.suffix}")  # any name's length
            self.earlier[path] = kept
            os.replace(path, kept)  # a link is moved as a link, not followed
        self.written.append(path)

    def undo(self) -> list[str]:
        """Remove every file this block wrote and put back every earlier file, each on its own; returns a line for
        each earlier file that could not be put back (it stays under its kept name)."""
        for path in self.written:
            with suppress(OSError):
                path.unlink(missing_ok=True)
        stranded = []
        for path, kept in self.earlier.items():
            try:
                os.replace(kept, path)
            except FileNotFoundError:  # the move aside itself failed: the earlier file never left
                pass
            except OSError as e:
                stranded.append(f"the earlier {path} could not be put back ({e.strerror}); it is kept as {kept}")
        return stranded

    def commit(self) -> None:
        """Let the earlier files go."""
        for kept in self.earlier.values():
            with suppress(OSError):
                kept.unlink(missing_ok=True)


_WRITES: ContextVar[_Writes | None] = ContextVar("aca_warp_writes", default=None)


@contextmanager
def all_or_nothing() -> Iterator[None]:
    """A block whose files written by :func:`whole` stand or fall together: when the block raises (an error, Ctrl-C),
    every file it wrote is removed and every earlier file one of them replaced is put back, neither cut short by a
    signal; when it ends, the earlier files are let go and the command's output is final: a SIGINT or SIGTERM that
    comes then or later is one that did not stop the command (:func:`~aca_warp.common.interrupts.deferred` with
    ``completes``). Figures named with ``plot --only`` are written so."""
    book = _Writes()
    token = _WRITES.set(book)
    try:
        yield
    except BaseException:
        with deferred():  # a signal cannot cut the putting back, nor the lines on what it could not, short
            for line in book.undo():
                print(f"aca-warp: {line}", file=sys.stderr)
        raise
    else:
        with deferred(completes=True):  # the new files are final: a signal from here on does not undo them
            book.commit()
    finally:
        _WRITES.reset(token)


def check_not_input(output: str | Path, inputs: dict[str, str | Path | None], command: str) -> None:
    """Refuse an ``output`` that is, or whose ``.partial`` is, one of the files ``command`` reads (``inputs``: what
    each is, e.g. "run file", → its path; None: none), however either is spelled (a link, ``./``, a relative path, a
    hard link): ``--overwrite`` would otherwise replace the input with the output. Checked before
    :func:`check_output_path`, so that a refusal never first suggests ``--overwrite``."""
    out = check_output_name(output)
    for what, src in inputs.items():
        if src is None or not Path(src).is_file():
            continue
        for name in (out, partial_path(out)):
            if name.exists() and os.path.samefile(name, src):
                raise SceneError(f"{command} writes a new file; {name} is its {what}: give another output")


HDF5_LOCKED = "unable to lock file"
"""What HDF5 says (with errno 11) when another process holds the file open in a way that excludes this opening."""


def open_h5(path: str | Path, what: str, *, mode: str = "r", text: tuple[str, ...] = ()) -> h5py.File:
    """Open an existing HDF5 input (read-only, or ``mode``) and check it before anything is read
    (:func:`~aca_warp.common.bounds.check_h5`: no soft or external links, declared sizes backed by the file and
    within memory, numbers outside the groups named in ``text``); :class:`SceneError` naming ``what`` ("run file",
    …) when it is missing, cannot be opened (one line of its own where another process holds it: HDF5's file lock)
    or fails a check."""
    from aca_warp.common.bounds import check_h5

    p = Path(path)
    if not p.is_file():
        expected = with_article(what)
        raise SceneError(f"{p} is not a regular file (expected {expected})" if p.exists() else f"{what} not found: {p}")
    if not h5py.is_hdf5(p):
        raise SceneError(f"{p} is not an HDF5 file (expected {with_article(what)} written by aca-warp)")
    try:
        f = h5py.File(p, mode)
    except (OSError, RuntimeError) as e:
        if HDF5_LOCKED in str(e) and "errno = 11" in str(e):  # EAGAIN: held; no locks at all (errno 38) passes on
            raise SceneError(
                f"another process has {p} open (HDF5's file lock): close it there (a notebook, a viewer, a running "
                "aca-warp), or wait for it to finish"
            ) from None
        detail = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        how = "" if mode == "r" else " for writing"
        raise SceneError(f"cannot open {what} {p}{how}: {detail}") from None
    try:
        with reading(p, what):
            check_h5(f, p, what, text=text)
    except BaseException:
        f.close()
        raise
    return f


def version_changes(stored: dict[str, str]) -> list[str]:
    """``name old -> new`` for every package whose version, or the kernels' digest, differs from the run file's."""
    now = versions()
    return [f"{k} {v} -> {now.get(k, 'missing')}" for k, v in stored.items() if now.get(k) != v]


def find_resumable(path: str | Path) -> tuple[Path, Path]:
    """(run file, its ``.partial``) of the run ``path`` names: ``NAME``, ``NAME.partial`` or a stopped ``NAME``.

    A killed run left ``NAME.partial``; a run stopped by Ctrl-C or a fault was moved to ``NAME`` (incomplete)
    and keeps its checkpoint, if it had one (without, it is resumed from its start). A run begun over a complete
    ``NAME`` (``--overwrite``) is marked :data:`REPLACES` and, interrupted, killed or stopped by a full device, stays
    ``NAME.partial`` beside it: that one is resumed, and replaces ``NAME`` when it completes; any other ``.partial``
    beside an existing ``NAME`` is refused (move one away). Raises SceneError when there is nothing to resume.
    """
    text = os.fspath(path)
    if not text or text.endswith(("/", os.sep)) or Path(text).name in ("", ".", ".."):
        raise SceneError(f"{text!r} names no run file; give the run file to continue, such as run.h5")
    p = Path(text)
    if p.name.endswith(".partial"):
        final, part = p.with_name(p.name.removesuffix(".partial")), p
    else:
        final, part = p, partial_path(p)
    if not part.exists() and not final.exists():
        raise SceneError(f"nothing to resume: neither {final} nor {part} exists")
    if part.exists():
        if final.exists() and not (is_complete(final) and _replaces(part)):
            raise SceneError(f"both {final} and {part} exist; move the one you do not want to resume away")
        return final, part
    try:
        with open_h5(final, "run file") as f:
            complete = bool(f.attrs.get("complete", False))
            kind = "LF" if f.attrs.get("kind") == "lf" else "HF"
    except AcaError:
        raise
    except (OSError, RuntimeError, KeyError, ValueError) as e:
        raise SceneError(f"cannot read run file {final}: {e}") from None
    if complete:
        raise SceneError(f"{final} is a complete {kind} run; nothing to resume")
    return final, part


REPLACES = "replaces_complete_run"  # the mark of a run begun over a complete NAME (--overwrite), until it completes


def is_complete(path: str | Path) -> bool:
    """Whether ``path`` is a readable run file that says it is complete (False for anything else)."""
    try:
        with open_h5(path, "run file") as f:
            return bool(f.attrs.get("complete", False))
    except _UNREADABLE:
        return False


def _replaces(partial: Path) -> bool:
    """Whether ``partial`` is a run begun over a complete run file, to replace it (:data:`REPLACES`)."""
    try:
        with open_h5(partial, "run file") as f:
            return bool(f.attrs.get(REPLACES, False))
    except _UNREADABLE:
        return False


def lock_resumable(path: str | Path) -> tuple[Path, Path, Path, OutputLock]:
    """:func:`find_resumable` under the output lock of the run: (run file, its ``.partial``, the one to resume: the
    ``.partial`` where it exists, else the run file; the lock). The lock also owns that file's identity
    (:meth:`OutputLock.own`), so a run that another process writes under another name (a link, a hard link, a moved
    file) is refused too."""
    final, part = find_resumable(path)
    what = "it cannot be resumed while it runs"
    lock = OutputLock.acquire(final, what=what)
    try:
        final, part = find_resumable(path)  # again, now that no other process can move it
        src = part if part.exists() else final
        lock.own(src, what=what)
    except BaseException:
        lock.release()
        raise
    return final, part, src, lock


def from_h5py(e: BaseException) -> bool:
    """Whether ``e`` was raised inside h5py (its innermost frame lies in the h5py package)."""
    tb = e.__traceback__
    if tb is None:
        return False
    while tb.tb_next is not None:
        tb = tb.tb_next
    return "h5py" in Path(tb.tb_frame.f_code.co_filename).parts


@contextmanager
def reading(path: str | Path, what: str = "file") -> Iterator[None]:
    """The read boundary of an input file: an error that h5py raises in the body (a bit flip in the file's metadata,
    a truncated file, a missing object) becomes one :class:`SceneError` line naming ``path``; errors of the
    program itself, storage errors and :class:`AcaError` pass through."""
    from aca_warp.common.storage import storage_errno

    try:
        yield
    except AcaError:
        raise
    except (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError) as e:
        if storage_errno(e) is not None or not from_h5py(e):
            raise
        detail = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise SceneError(f"cannot read {what} {path}: it is damaged or incomplete ({detail})") from None
