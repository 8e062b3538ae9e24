"""The life of a run file, shared by the HF (:class:`~aca_warp.hf.runfile.RunWriter`) and LF
(:class:`~aca_warp.lf.io.LFRunWriter`) writers; what a file holds is theirs.

One writer per output: a writer holds ``NAME.lock`` (:class:`~aca_warp.common.files.OutputLock`) from before it
looks at ``NAME`` until the file has its final name, so a second run, an ``--overwrite`` or a ``--resume`` of the
same name is refused while it runs. The file is created as ``NAME.partial.new``, its header written and flushed,
and only then renamed to ``NAME.partial``: a ``.partial`` is a readable HDF5 file from the moment it exists. When
the run ends, completed or not, the file is closed and renamed to ``NAME`` (then ``complete = False`` and
``status`` says why): the final name never holds a file that is half written. A run begun over a complete ``NAME``
(``--overwrite``) is marked :data:`~aca_warp.common.files.REPLACES`; interrupted, it stays ``.partial`` and the earlier
file stays until the run completes. A killed process leaves only the ``.partial`` behind, which
:func:`reopen_resumable` hands to the writer's ``reopen`` to continue it. On a full device the file is abandoned as it
was at its last flush (:mod:`aca_warp.common.storage`).
"""

from __future__ import annotations

import json
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import h5py
import numpy as np

from aca_warp.common import interrupts
from aca_warp.common.checkpoint import Checkpoint, checkpoint_room, has_checkpoint, read_checkpoint, write_checkpoint
from aca_warp.common.errors import AcaError, SceneError, option
from aca_warp.common.files import (
    REPLACES,
    OutputLock,
    create_h5,
    from_h5py,
    is_complete,
    lock_resumable,
    new_path,
    partial_path,
    recovery,
)
from aca_warp.common.storage import GuardedFile, storage_errno, storage_error, write_failed

P = TypeVar("P")
W = TypeVar("W")


def busy() -> str:
    """The advice of a refusal to write an output that a live process writes."""
    overwrite = option("overwrite=True", "--overwrite")
    return f"wait for it to finish or stop it ({overwrite} does not replace a run in progress)"


def write_attrs(f: h5py.File, attrs: dict[str, Any]) -> None:
    """Root attributes of a run file: text, numbers and booleans as they are, anything else as JSON text."""
    for k, v in attrs.items():
        f.attrs[k] = v if isinstance(v, (str, int, float, bool, np.number)) else json.dumps(v)


def interrupted_status(e: BaseException) -> str:
    """The ``status`` of a run file stopped by ``e``, a KeyboardInterrupt: Ctrl-C or SIGTERM."""
    return "interrupted (SIGTERM)" if isinstance(e, interrupts.Terminated) else "interrupted by the user"


class RunFileWriter(ABC):
    """The part of a run-file writer that is the same for HF and LF runs: creating the file, marking a reopened
    one running again, closing it complete or stopped, abandoning it after a storage failure (module docstring).

    A subclass writes its header (``header`` of :meth:`_create`), its samples and checkpoints, and the closing
    datasets and attributes (:meth:`_write_closing`).

    Attributes:
        lock: The output's lock, held until the file has its final name.
        path: The final name ``NAME``.
        partial: ``NAME.partial``, the name while the run is written.
        f: The open HDF5 file.
        out: Its guard against a full device.
    """

    RAW_CACHE = 1024 * 1024  # bytes of HDF5 chunk cache (HDF5's default)
    lock: OutputLock
    path: Path
    partial: Path
    f: h5py.File
    out: GuardedFile

    def _create(
        self,
        path: str | Path,
        check: Callable[..., Path],
        *,
        overwrite: bool,
        lock: OutputLock | None,
        header: Callable[[], None],
    ) -> None:
        """Take the output's lock (unless ``lock``, held, is given), check ``path`` (``check(path,
        overwrite=overwrite)``), create ``NAME.partial.new``, write ``header()`` into it, flush and rename it to
        ``NAME.partial``. A failure removes the new file and releases the lock (a storage failure raises a one-line
        StorageError)."""
        self.lock = lock or OutputLock.acquire(path, what=busy())
        tmp = new_path(partial_path(path))
        try:
            self.path = check(path, overwrite=overwrite)
            self.partial = partial_path(self.path)
            self.f = create_h5(tmp, self.lock, rdcc_nbytes=self.RAW_CACHE)  # a leftover .new replaced, a link refused
            self.out = GuardedFile(self.f, self.partial, raw_cache=self.RAW_CACHE)
            header()
            if is_complete(self.path):  # --overwrite of a complete file: kept until this run completes
                self.f.attrs[REPLACES] = True
            self.out.flush()
            os.replace(tmp, self.partial)  # readable from the moment it has this name
        except BaseException as e:
            if getattr(self, "out", None) is not None:
                self.out.abandon()
            elif getattr(self, "f", None) is not None:
                self.f.close()
            if getattr(self, "f", None) is not None:
                tmp.unlink(missing_ok=True)
            self.lock.release()
            code = storage_errno(e)
            if code is not None:
                raise storage_error(code, tmp, "nothing was written") from None
            raise

    def _open_partial(self, partial: str | Path, lock: OutputLock) -> None:
        """Open a killed or stopped run's ``NAME.partial`` for writing (``lock``: the lock of ``NAME``, held)."""
        self.lock = lock
        self.partial = Path(partial)
        self.path = self.partial.with_name(self.partial.name.removesuffix(".partial"))
        try:
            self.f = h5py.File(self.partial, "r+", rdcc_nbytes=self.RAW_CACHE)
        except (OSError, RuntimeError) as e:
            raise SceneError(f"cannot open {self.partial} to resume it: {e}") from None
        self.out = GuardedFile(self.f, self.partial, raw_cache=self.RAW_CACHE)

    def _mark_running(self, ckpt: Checkpoint | None) -> None:
        """Mark a reopened file running again, resumed from ``ckpt`` or (None) started again; a failure abandons it
        unchanged (a storage failure raises a one-line StorageError)."""
        resumed = (
            "started again from t = 0 (no checkpoint)"
            if ckpt is None
            else f"resumed from the checkpoint at t = {ckpt.sim_time:.6g} s"
        )
        try:
            self.f.attrs["complete"] = False
            self.f.attrs["status"] = f"running ({resumed})"
            self.out.flush()
        except BaseException as e:
            self.out.abandon()
            code = storage_errno(e)
            if code is not None:
                raise storage_error(code, self.partial, "it was not changed; make room and resume again") from None
            raise

    def _stored_checkpoint(self) -> Checkpoint | None:
        """The checkpoint of a reopened file, or None when it holds none."""
        return read_checkpoint(self.f, str(self.partial)) if has_checkpoint(self.f) else None

    def _store_checkpoint(self, ckpt: Checkpoint) -> None:
        """Write ``ckpt`` into the file's inactive checkpoint slot, its room reserved first
        (:func:`~aca_warp.common.checkpoint.write_checkpoint`: flush, flip, flush)."""
        self.out.reserve(checkpoint_room(self.f, ckpt))
        write_checkpoint(self.f, ckpt, flush=self.out.flush)

    @abstractmethod
    def _write_closing(self, complete: bool, status: str, attrs: dict[str, Any]) -> None:
        """Write what the file holds at its end: ``complete``, ``status``, ``attrs`` and the run's closing data."""

    def close(self, *, complete: bool, status: str, attrs: dict[str, Any] | None = None, rename: bool = True) -> Path:
        """Write the closing datasets and attributes (:meth:`_write_closing`), close, move the file to its final
        name (``rename``; else it stays ``NAME.partial``) and release the output. Returns where the file is. A
        failure abandons the file as it was at its last flush (a storage failure raises a one-line
        StorageError)."""
        try:
            self._write_closing(complete, status, attrs or {})
            if rename and REPLACES in self.f.attrs:  # it replaces NAME now: no more a run kept beside it
                del self.f.attrs[REPLACES]
            self.out.close()
            if not rename:
                self.lock.release()
                return self.partial
            os.replace(self.partial, self.path)
        except BaseException as e:
            self.abandon()
            code = storage_errno(e)
            if code is not None:
                raise storage_error(code, self.partial, f"make room, then {recovery(self.path)}") from None
            raise
        self.lock.release()
        return self.path

    def abandon(self) -> None:
        """Leave the ``.partial`` as it was at its last flush (after a failure) and release the output."""
        self.out.abandon()
        self.lock.release()

    def finish(self, error: BaseException, status: str) -> BaseException | None:
        """Close the file after ``error`` stopped the run: marked incomplete with ``status``, or abandoned when
        ``error`` is a storage failure. Returns the exception to raise instead of ``error`` (a one-line
        :class:`~aca_warp.common.errors.StorageError`), or None to raise ``error`` itself."""
        code = storage_errno(error)
        if code is None and not from_h5py(error):
            # an interrupted run that was to replace a complete earlier file (--overwrite, marked REPLACES when it
            # began) stays NAME.partial: the earlier file is kept until the run completes (find_resumable resumes it)
            keep = status.startswith("interrupted") and is_complete(self.path)
            try:
                self.close(complete=False, status=status, rename=not keep)
            except AcaError as e:
                return e
            return None
        self.abandon()
        if code is None:  # HDF5 failed to write (a damaged file): nothing more goes into it
            return write_failed(error, self.partial, f"make room, then {recovery(self.path)}")
        return storage_error(code, self.partial, f"make room, then {recovery(self.path)}")

    @contextmanager
    def closed_when_stopped(self) -> Iterator[None]:
        """The run loop's frame: an exception of the body closes the file marked interrupted (a KeyboardInterrupt:
        Ctrl-C, SIGTERM) or failed, and is raised again, or the one-line StorageError of a storage failure instead
        (:meth:`finish`, not interrupted half-way). A file the body closed already is left alone."""
        try:
            yield
        except BaseException as e:
            if not self.lock.held:  # closed already (close raised its own error)
                raise
            status = interrupted_status(e) if isinstance(e, KeyboardInterrupt) else "failed"
            with interrupts.deferred():
                replacement = self.finish(e, status)
            if replacement is not None:
                raise replacement from None
            raise


def reopen_resumable(
    path: str | Path, prepare: Callable[[Path], P], reopen: Callable[[P, Path, OutputLock], W]
) -> tuple[P, W, Path]:
    """Lock the killed or stopped run ``path`` (``NAME`` or ``NAME.partial``; :func:`lock_resumable`), make its
    simulation with ``prepare(file)`` (from the settings the file holds), give a stopped run's ``NAME`` back its
    ``.partial`` name and ``reopen(prepared, partial, lock)`` its writer. Returns what ``prepare`` made, the writer
    and the final name. On a failure the lock is released and a stopped run keeps its name."""
    final, part, src, lock = lock_resumable(path)
    try:
        prepared = prepare(src)
        if src == final:
            os.replace(final, part)  # a stopped run goes back to being written
    except BaseException:
        lock.release()
        raise
    try:
        writer = reopen(prepared, part, lock)
    except BaseException:
        if src == final and part.exists() and not final.exists():
            os.replace(part, final)  # not resumed: the stopped run keeps its name
        lock.release()
        raise
    return prepared, writer, final
