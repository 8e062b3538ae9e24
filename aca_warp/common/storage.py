"""HDF5 outputs on a full disk: room reserved before HDF5 writes, a failed file left as it was at its last flush.

HDF5 has no journal: a flush writes many metadata blocks, some in place and some at new addresses past the end of
the file. When the device fills up (ENOSPC), a file-size limit is reached (EFBIG, ``ulimit -f``) or a quota is
exhausted (EDQUOT) in the middle of a flush, the writes in place succeed and those that extend the file fail, and
the file on disk points at blocks that were never written ("bad local heap signature", "truncated file"). Closing
it after the error only adds more such writes.

:class:`GuardedFile` keeps this from happening to the files a run writes:

* before every batch of appends, every checkpoint and every flush it *reserves* the blocks HDF5 may write
  (``posix_fallocate`` up to HDF5's end of file plus the chunks begun since the last flush, up to the raw-data
  chunk cache, plus :data:`SLACK`; the whole file the first time, only the new range after that), so that a full
  device, a size limit or a quota shows up in the reservation, before HDF5 writes anything, and HDF5's own writes
  land in blocks that are already allocated;
* after every flush it trims the reservation (``ftruncate`` to HDF5's own end of file), so a finished file holds
  no padding;
* on a storage error, from a reservation or from HDF5 itself, :meth:`GuardedFile.abandon` closes the HDF5 file
  without writing another byte to it (its descriptor is first pointed at an anonymous in-memory file), so the file
  on disk stays as it was at its last flush: for a checkpointed run, its last checkpoint.

Limits: the reservation is an estimate of what HDF5 allocates (measured: a flush allocated at most the new chunks
plus a few KiB of index nodes, well inside :data:`SLACK`); filesystems without ``fallocate`` support are written
unguarded. Under a file-size limit (``ulimit -f``) the in-memory file obeys the limit too, so a failure inside HDF5
itself (an estimate too small) can still make the abandoning close fail.

The writers (:class:`~aca_warp.hf.runfile.RunWriter`, :class:`~aca_warp.lf.io.LFRunWriter`, sweep shards) then
raise :class:`~aca_warp.common.errors.StorageError` (exit 4), whose one line names the cause and how to continue.
"""

from __future__ import annotations

import errno
import math
import os
import re
from pathlib import Path

import h5py

from aca_warp.common.errors import StorageError

STORAGE_ERRNOS = {
    errno.ENOSPC: "no space left on device",
    errno.EFBIG: "file size limit reached",
    errno.EDQUOT: "disk quota exceeded",
}
SLACK = 64 * 1024  # bytes reserved past the estimate: metadata a flush allocates (index nodes, 2 KiB aggregator blocks)
_HDF5_ERRNO = re.compile(r"errno = (\d+)")


def storage_errno(e: BaseException) -> int | None:
    """The errno of a storage failure (ENOSPC, EFBIG, EDQUOT) behind ``e``, else None. h5py reports HDF5's write
    failures as OSError or RuntimeError whose message carries the C errno (``errno = 28``)."""
    if isinstance(e, StorageError):
        return getattr(e, "errno", errno.ENOSPC)
    if isinstance(e, OSError) and e.errno in STORAGE_ERRNOS:
        return e.errno
    if isinstance(e, (OSError, RuntimeError)):
        for m in _HDF5_ERRNO.finditer(str(e)):
            if int(m.group(1)) in STORAGE_ERRNOS:
                return int(m.group(1))
    return None


def storage_error(code: int, path: str | Path, advice: str) -> StorageError:
    """A :class:`StorageError` with one line: the cause, the file, what to do."""
    e = StorageError(f"{STORAGE_ERRNOS.get(code, os.strerror(code))} while writing {path}; {advice}")
    e.errno = code  # type: ignore[attr-defined]
    return e


def write_failed(e: BaseException, path: str | Path, advice: str) -> StorageError:
    """A :class:`StorageError` for a write that HDF5 refused for another reason than room (a damaged file)."""
    detail = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return StorageError(f"writing {path} failed inside HDF5 ({detail}; is the file damaged?); {advice}")


class GuardedFile:
    """An HDF5 file open for writing whose writes cannot leave it inconsistent on a full device (module docstring).

    Attributes:
        f: The h5py file.
        path: Its name on disk (for messages).
        raw_cache: Size of its raw-data chunk cache [bytes] (the most unwritten chunk data a flush writes).
    """

    def __init__(self, f: h5py.File, path: str | Path, *, raw_cache: int = 1024 * 1024) -> None:
        self.f = f
        self.path = Path(path)
        self.raw_cache = raw_cache
        self.fd: int | None = None
        if f.driver == "sec2":
            handle = f.id.get_vfd_handle()
            self.fd = handle if isinstance(handle, int) else None
        self.can_reserve = self.fd is not None and hasattr(os, "posix_fallocate")
        self._rows: dict[str, list] = {}  # dataset name -> [dataset, axis, extent at the last flush, reserved, now]
        self._solid = 0  # bytes from the start of the file known to be allocated (no holes below)

    def touch(self, d: h5py.Dataset, start: int, stop: int, axis: int = 0) -> None:
        """Entries ``start:stop`` along ``axis`` of the chunked dataset ``d`` are about to be written (appended).
        The extent ``d`` has when it is first touched counts as written before the last flush (true of every
        writer here)."""
        entry = self._rows.setdefault(d.name, [d, axis, start, start, start])
        entry[4] = max(entry[4], stop)

    @staticmethod
    def _begun(d: h5py.Dataset, axis: int, a: int, b: int) -> int:
        """Bytes of the chunks of ``d`` that begin between extents ``a`` and ``b`` along ``axis``."""
        c = d.chunks
        if c is None or b <= a:
            return 0
        new = -(-b // c[axis]) - (-(-a // c[axis]))
        across = math.prod(math.ceil(n / k) for i, (n, k) in enumerate(zip(d.shape, c, strict=True)) if i != axis)
        return max(new, 0) * across * math.prod(c) * d.dtype.itemsize

    @property
    def pending(self) -> int:
        """Bytes of the chunks begun since the last flush that HDF5 may not have written yet: those of earlier
        appends up to the chunk cache (the rest were evicted, i.e. written), plus all of the appends not yet
        reserved for (an append larger than the cache writes chunks while it runs)."""
        old = sum(self._begun(d, ax, flushed, reserved) for d, ax, flushed, reserved, _ in self._rows.values())
        new = sum(self._begun(d, ax, reserved, now) for d, ax, _, reserved, now in self._rows.values())
        return min(old, self.raw_cache) + new

    def reserve(self, extra: int = 0) -> None:
        """Make sure the device holds the blocks HDF5 may write next (``extra`` bytes of new datasets besides the
        chunks begun since the last flush); :class:`StorageError` when it does not, before anything is written.

        Reserved: from the end of what is known to be allocated (the start of the file the first time: a hole
        anywhere below HDF5's end of file would need a block when HDF5 fills it) to HDF5's end of file plus the
        estimate plus :data:`SLACK`. HDF5 punches no holes and a trim only shortens the file, so each later call
        reserves only the new range (``fallocate`` over allocated blocks costs time on tmpfs)."""
        if not self.can_reserve:
            return
        eoa = int(self.f.id.get_filesize())
        start = min(self._solid, eoa)
        end = eoa + self.pending + extra + SLACK
        try:
            os.posix_fallocate(self.fd, start, end - start)  # type: ignore[arg-type]
        except OSError as e:
            if e.errno in STORAGE_ERRNOS:
                raise storage_error(e.errno, self.path, "nothing more was written to it") from None
            if e.errno in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENODEV, errno.ESPIPE):
                self.can_reserve = False  # a filesystem without preallocation: write unguarded
                return
            raise
        self._solid = max(self._solid, end)
        for entry in self._rows.values():
            entry[3] = entry[4]

    def trim(self) -> None:
        """Give back the reserved room past HDF5's end of file (after a flush)."""
        if self.fd is None:
            return
        end = int(self.f.id.get_filesize())
        if os.fstat(self.fd).st_size > end:
            os.ftruncate(self.fd, end)
        self._solid = min(self._solid, os.fstat(self.fd).st_size)  # HDF5 may have truncated at its flush too

    def flush(self, extra: int = 0) -> None:
        """Reserve, flush, trim."""
        self.reserve(extra)
        self.f.flush()
        for entry in self._rows.values():
            entry[2] = entry[3] = entry[4]
        self.trim()

    def close(self) -> None:
        """Flush (guarded) and close."""
        self.flush()
        self.f.close()

    def abandon(self) -> None:
        """Close the HDF5 file without writing to it again: what is on disk stays as it was at the last flush.

        HDF5 flushes its caches when a file is closed, even after an error; the file's descriptor is therefore
        first replaced by an anonymous in-memory file (``memfd_create``), which receives that last flush."""
        if not self.f.id.valid:
            return
        if self.fd is not None and hasattr(os, "memfd_create"):
            try:
                sink = os.memfd_create("aca-warp-abandoned", os.MFD_CLOEXEC)
                os.dup2(sink, self.fd)
                os.close(sink)
            except OSError:
                pass
        try:
            self.f.close()
        except Exception:  # noqa: BLE001  (a close after a failed write may fail; nothing reaches the file)
            pass
