"""Parameter sweeps: a TOML spec expanded into many pads, run in shards (serially, overlapped, or through Dask),
resumable; the ``aca-warp sweep`` command.

A sweep spec (``docs/sweeps.md``) names a base scene (a preset, a TOML scene file, or inline tables) and grids
or lists of scene parameters (``friction.M``, ``load.normal_force``, ``disc.sliding_speed``, ``patches.seed``,
``patches.area_min``, ``material.K_C``, ...), combined as a Cartesian product or zipped. Every combination is
one pad. Pads are cut into shards of a fixed size; each shard is one batched HF run (one model,
one :func:`aca_warp.hf.loop.run_hf` with the engine ``auto``: the on-chip kernel on CUDA, else the general one;
split only when the estimated device memory says the batch does not fit) and one HDF5 file::

    DIR/manifest.json            spec, spec hash, shards and their state (written only by the client)
    DIR/shard-00000.h5           /global/time (samples,) [s]
                                 /global/mu, torque, friction_radius, sum_velocity, sum_abs_velocity, friction_centroid
                                     (pads, samples), unit attributes as in run files
                                 /parameters/<key> (pads,) one dataset per swept parameter, unit attribute
                                 /pads/index (pads,) global pad index, /pads/patch_count (pads,)
                                 attrs: spec (JSON), spec_hash, shard, pad_start, pad_stop, complete,
                                     finished, status, device, integrator, precision, dt, steps, timings, ...

A shard file is written as ``NAME.partial`` and renamed when its run ends: a final name always holds a whole
shard. A rerun skips a shard only when the manifest *and* the file agree that it finished under the same spec
hash; everything else (a ``.partial`` left by a killed worker, a missing or foreign file, a shard marked
``interrupted``) is run again.

The code lives in modules of one concern each, re-exported here (``from aca_warp.sweep import run_sweep`` etc.; each
loaded when one of its names is first used):

* :mod:`aca_warp.sweep.spec`: the spec, its pads and hash (:func:`load_spec`, :class:`SweepSpec`);
* :mod:`aca_warp.sweep.shard`: one shard task and its file (:func:`run_shard`, :func:`shard_finished`);
* :mod:`aca_warp.sweep.overlap`: the writer thread, the device's turns and the cancel event of a shard task;
* :mod:`aca_warp.sweep.manifest`: the sweep directory, its manifest and :func:`load_sweep`;
* :mod:`aca_warp.sweep.cluster`: Dask (a loopback-only local cluster, a scheduler or a client);
* :mod:`aca_warp.sweep.run`: :func:`run_sweep` and the in-process paths;
* :mod:`aca_warp.sweep.commands`: the command line (signals: one line, exit 130 / 143, shards marked
  ``interrupted``).
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

# public name -> its module, imported when the name is first used: ``import aca_warp.sweep`` (as the command line's
# parser does for every command) loads no sweep code, Dask or Warp
_PUBLIC = {
    "LOOPBACK": "aca_warp.sweep.cluster",
    "cuda_ordinals": "aca_warp.sweep.cluster",
    "local_cluster": "aca_warp.sweep.cluster",
    "warm_workers": "aca_warp.sweep.cluster",
    "add_parsers": "aca_warp.sweep.commands",
    "MANIFEST": "aca_warp.sweep.manifest",
    "SHARD_STATES": "aca_warp.sweep.manifest",
    "SweepResult": "aca_warp.sweep.manifest",
    "load_sweep": "aca_warp.sweep.manifest",
    "prepare_dir": "aca_warp.sweep.manifest",
    "read_manifest": "aca_warp.sweep.manifest",
    "PIPELINE_DEPTH": "aca_warp.sweep.overlap",
    "ChunkWriter": "aca_warp.sweep.overlap",
    "KernelTurn": "aca_warp.sweep.overlap",
    "ShardCancelled": "aca_warp.sweep.overlap",
    "ShardContext": "aca_warp.sweep.overlap",
    "batch_capacity": "aca_warp.sweep.prepare",
    "device_memory": "aca_warp.sweep.prepare",
    "pad_bytes": "aca_warp.sweep.prepare",
    "run_sweep": "aca_warp.sweep.run",
    "TIMING_DOC": "aca_warp.sweep.shard",
    "TIMING_PHASES": "aca_warp.sweep.shard",
    "run_shard": "aca_warp.sweep.shard",
    "shard_finished": "aca_warp.sweep.shard",
    "shard_name": "aca_warp.sweep.shard",
    "DEFAULT_SHARD_SIZE": "aca_warp.sweep.spec",
    "FORMAT": "aca_warp.sweep.spec",
    "MAX_PADS": "aca_warp.sweep.spec",
    "MAX_STEPS": "aca_warp.sweep.spec",
    "MODES": "aca_warp.sweep.spec",
    "PACKINGS": "aca_warp.sweep.spec",
    "PARAMETERS": "aca_warp.sweep.spec",
    "SweepError": "aca_warp.sweep.spec",
    "SweepSpec": "aca_warp.sweep.spec",
    "apply_parameters": "aca_warp.sweep.spec",
    "hf1_product_doc": "aca_warp.sweep.spec",
    "load_spec": "aca_warp.sweep.spec",
    "pack_order": "aca_warp.sweep.spec",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        return getattr(import_module(_PUBLIC[name]), name)
    raise AttributeError(f"module 'aca_warp.sweep' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
