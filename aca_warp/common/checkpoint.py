"""Checkpoints of HF runs: the full solver state, stored inside the run file's ``.partial`` so a killed run resumes.

Design (one file, double-buffered slots). A run with ``--checkpoint-interval`` keeps, next to its samples, a
group ``/checkpoint`` with two slots ``slot0`` and ``slot1`` and an attribute ``active`` (−1: none yet)::

    /checkpoint                 attrs: format (int), active (−1, 0 or 1), sim_time [s] of the active slot
    /checkpoint/slotK/sim_time          ()        simulated time reached [s]
    /checkpoint/slotK/rows/global       ()        rows of /global/* written when the checkpoint was taken
    /checkpoint/slotK/rows/patches      ()        rows of /patches/time, velocity, displacement
    /checkpoint/slotK/counters/NAME     ()        host loop counters (int64): samples, steps, rejected, started,
                                                  sample_index
    /checkpoint/slotK/arrays/NAME       (...)     device arrays in their own dtype, e.g. state/u [m] (n,),
                                                  state/v [m/s] (n,), state/force [N] (n,),
                                                  recorder/counters (4,), watchdog/bound [m/s] (pads,),
                                                  adaptive/ctl [s] (pads, 6), adaptive/mode (pads, 5),
                                                  adaptive/stats (pads, 2), adaptive/done (3,), adaptive/ku and
                                                  adaptive/kv (7, n), growth/step (1,) or, adaptive, growth/event
                                                  (1,), model/area [m²] (n,), ... (each engine's ``saved()``)

A checkpoint is written into the slot that is *not* active (raw data of fixed shape, rewritten in place), the
file is flushed, then ``active`` flips to the new slot and the file is flushed again. A kill while the new slot
is being written leaves the old slot and its pointer intact. The sample datasets are only flushed at
checkpoints (the run loop's writer skips its per-chunk flush when checkpointing), so what is on disk between
checkpoints is the state of the last checkpoint plus raw chunk data beyond it; resuming truncates every sample
dataset back to the active slot's ``rows`` and continues from its state. HDF5 has no journal: a kill *during*
one of the two flushes (milliseconds per checkpoint) can still leave a file HDF5 cannot open; resuming then
fails with one line, and ``aca-warp rerun`` repeats the run from the start.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from aca_warp.common.errors import AcaError, SceneError, option

FORMAT = 2  # 2: LF global-scalar layout without the contact sums and flag (2026-11-23)
GROUP = "checkpoint"


@dataclass
class Checkpoint:
    """The state of a run at the end of a recorded chunk: enough to continue it bit for bit.

    Attributes:
        sim_time: Simulated time reached [s].
        arrays: Host copies of the device arrays that change during a run, by name (module docstring), each in
            the device array's own dtype and shape.
        counters: Host loop counters: ``samples`` (global samples after sample 0), ``steps``, ``rejected``,
            ``started`` (1 once the opening step ran: strang keeps a staggered velocity), ``sample_index``.
        rows: Rows of the run file's sample datasets that belong to the checkpointed run (``global``,
            ``patches``); filled by the writer.
    """

    sim_time: float
    arrays: dict[str, np.ndarray]
    counters: dict[str, int]
    rows: dict[str, int] = field(default_factory=dict)


def _put(g: h5py.Group, name: str, value: np.ndarray) -> None:
    """Write ``value`` into dataset ``name`` in place when its shape and dtype match, else (re)create it."""
    value = np.asarray(value)
    if name in g:
        d = g[name]
        if isinstance(d, h5py.Dataset) and d.shape == value.shape and d.dtype == value.dtype:
            d[...] = value
            return
        del g[name]
    g.create_dataset(name, data=value)


def checkpoint_room(f: h5py.File, ckpt: Checkpoint) -> int:
    """Bytes :func:`write_checkpoint` adds to ``f``: the arrays, unless the slot it writes holds them already."""
    g = f.get(GROUP)
    slot = 0 if g is None or int(g.attrs.get("active", -1)) != 0 else 1
    if g is not None and f"slot{slot}/arrays" in g:
        return 4096
    return sum(np.asarray(a).nbytes for a in ckpt.arrays.values()) + 4096


def write_checkpoint(f: h5py.File, ckpt: Checkpoint, flush: Callable[[], None] | None = None) -> int:
    """Store ``ckpt`` into the inactive slot of ``f``, flush, flip ``active``, flush; returns the slot. ``flush``
    replaces ``f.flush`` (a :class:`~aca_warp.common.storage.GuardedFile` reserves room first)."""
    flush = flush or f.flush
    g = f.require_group(GROUP)
    active = int(g.attrs.get("active", -1))
    slot = 0 if active != 0 else 1
    s = g.require_group(f"slot{slot}")
    _put(s, "sim_time", np.float64(ckpt.sim_time))
    for k, v in ckpt.rows.items():
        _put(s, f"rows/{k}", np.int64(v))
    for k, v in ckpt.counters.items():
        _put(s, f"counters/{k}", np.int64(v))
    for k, v in ckpt.arrays.items():
        _put(s, f"arrays/{k}", v)
    g.attrs["format"] = FORMAT
    flush()
    g.attrs["active"] = slot
    g.attrs["sim_time"] = float(ckpt.sim_time)
    flush()
    return slot


def has_checkpoint(f: h5py.File) -> bool:
    """Whether ``f`` holds a usable checkpoint slot."""
    return GROUP in f and int(f[GROUP].attrs.get("active", -1)) in (0, 1)


def read_checkpoint(f: h5py.File, path: str = "") -> Checkpoint:
    """The active checkpoint of ``f`` (SceneError with one line when there is none or it is damaged)."""
    if not has_checkpoint(f):
        raise SceneError(
            f"{path or 'the run file'} holds no checkpoint (was it run with "
            f"{option('checkpoint_interval', '--checkpoint-interval')}?); "
            f"{option('run it again with run_scene', 'repeat it with aca-warp rerun')}"
        )
    g = f[GROUP]
    if int(g.attrs.get("format", -1)) != FORMAT:
        raise SceneError(f"{path}: checkpoint format {g.attrs.get('format')} is not {FORMAT}")
    try:
        s = g[f"slot{int(g.attrs['active'])}"]
        arrays: dict[str, np.ndarray] = {}

        def visit(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                arrays[name] = obj[()]

        s["arrays"].visititems(visit)
        return Checkpoint(
            sim_time=float(s["sim_time"][()]),
            arrays=arrays,
            counters={k: int(d[()]) for k, d in s["counters"].items()},
            rows={k: int(d[()]) for k, d in s["rows"].items()},
        )
    except (KeyError, OSError, ValueError, TypeError, RuntimeError) as e:
        raise SceneError(f"{path}: the checkpoint is damaged ({e}); repeat the run with 'aca-warp rerun'") from None


@contextmanager
def closed_on_failure(
    f: h5py.File, path: str | Path, scene_error: bool = True, close: Callable[[], None] | None = None
) -> Iterator[None]:
    """Close ``f`` if the body raises (a resume must not leave the partial file open); ``close`` replaces
    ``f.close`` (:meth:`~aca_warp.common.storage.GuardedFile.abandon`: a failed resume writes nothing). With
    ``scene_error``, the errors of a malformed file (KeyError, ValueError, TypeError, OSError, RuntimeError, and
    AttributeError: a group where a dataset belongs) become one SceneError naming ``path``."""
    close = close or f.close
    try:
        yield
    except AcaError:  # already one line
        close()
        raise
    except (KeyError, ValueError, TypeError, OSError, RuntimeError, AttributeError) as e:
        close()
        if not scene_error:
            raise
        raise SceneError(
            f"cannot resume {path}: its datasets are damaged or do not match its checkpoint ({e})"
        ) from None
    except BaseException:
        close()
        raise


def drop_checkpoint(f: h5py.File) -> None:
    """Remove the checkpoint group (a completed run needs none)."""
    if GROUP in f:
        del f[GROUP]


AUTO_WALL_S = 5.0  # automatic checkpoints: at least this much wall time between two [s]
AUTO_SHARE = 0.02  # ... and at least 1 / AUTO_SHARE times the wall time the last one took


def frequent_note(interval: float | None, period: float, period_words: str, each: str) -> list[str]:
    """The note for a checkpoint ``interval`` [s] shorter than the run's ``period`` [s] (an LF step, a sample
    interval: ``period_words`` names it, ``each`` what a checkpoint then follows), as a list of one; [] otherwise."""
    if interval is None or not 0 < interval < period:
        return []
    return [
        f"a checkpoint interval of {interval:g} s is shorter than {period_words} ({period:g} s): a checkpoint follows "
        f"every {each}, which makes the run many times slower (the automatic interval, the default, costs at most "
        f"{AUTO_SHARE * 100:g} %)"
    ]


def next_multiple(t: float, interval: float) -> float:
    """The first multiple of ``interval`` after ``t`` [s]; a ``t`` within 1e-9 intervals below a multiple counts as
    on it (sample times are sums of rounded steps: 9.999999999999999e-05 is the checkpoint at 1e-4, and the next
    one is 2e-4, not 1e-4 again)."""
    return (math.floor(t / interval + 1e-9) + 1) * interval


class CheckpointClock:
    """When a run writes its checkpoints, from its ``checkpoint_interval`` [s]:

    * ``None`` (the default of ``aca-warp hf`` and ``lf``): automatic. The first chunk (HF) or step (LF) end at least
      :data:`AUTO_WALL_S` of wall time after the run started, then after the previous checkpoint, and at least
      1 / :data:`AUTO_SHARE` times as long as that checkpoint took to write: checkpoints cost at most
      :data:`AUTO_SHARE` of the run's wall time (``scripts/checkpoint_cost.py`` measures it), and an interrupt loses
      at most that spacing and the chunk or step then running. A run that ends or stops before its first checkpoint
      resumes from its start.
    * ``> 0``: the first chunk or step end at or past each multiple of it in simulated time (the HF loop ends its
      chunks there).
    * ``0``: none.

    Attributes:
        count: Checkpoints written.
        seconds: Wall time spent writing them [s].
    """

    def __init__(self, interval: float | None, sim_time: float) -> None:
        self.interval = interval
        self.count = 0
        self.seconds = 0.0
        self.next_sim = next_multiple(sim_time, interval) if interval else math.inf
        self.next_wall = time.perf_counter() + AUTO_WALL_S if interval is None else math.inf

    @property
    def bound(self) -> float:
        """Simulated time [s] a chunk should not run past (the next checkpoint of a fixed interval, else inf)."""
        return self.next_sim

    def due(self, sim_time: float) -> bool:
        """Whether a checkpoint is due at this chunk or step end (``sim_time`` [s] reached)."""
        if self.interval is None:
            return time.perf_counter() >= self.next_wall
        return sim_time >= self.next_sim * (1 - 1e-12)

    def write(self, write: Callable[[], None], sim_time: float) -> None:
        """Run ``write`` (the checkpoint at ``sim_time`` [s]) and set the next one."""
        t = time.perf_counter()
        write()
        took = time.perf_counter() - t
        self.count += 1
        self.seconds += took
        if self.interval is None:
            self.next_wall = time.perf_counter() + max(AUTO_WALL_S, took / AUTO_SHARE)
        else:
            self.next_sim = next_multiple(sim_time, self.interval)
