"""Parameter sweeps: a TOML spec expanded into many pads, run in shards (serially, overlapped, or through Dask),
resumable; the ``aca-warp sweep`` command.

A sweep spec (``docs/sweeps.md``) names a base scene (a preset, a TOML scene file, or inline tables) and grids
or lists of scene parameters (``friction.M``, ``load.normal_force``, ``disc.sliding_speed``, ``patches.seed``,
``patches.area_min``, ``material.K_C``, ...), combined as a Cartesian product or zipped. Every combination is
one pad. Pads are cut into shards of a fixed size; each shard is one batched HF run (one model,
one :func:`aca_warp.hf.loop.run_hf` with the engine ``auto``: the on-chip kernel where the model allows it, else the
general one; split only when the estimated device memory says the batch does not fit) and one HDF5 file::

    DIR/manifest.json            spec, spec hash, shards and their state (written only by the client)
    DIR/shard-00000.h5           /global/time (samples,) [s]
                                 /global/mu, torque, friction_radius, sum_velocity, sum_abs_velocity, friction_centroid
                                     (pads, samples), unit attributes as in run files
                                 /parameters/<key> (pads,) one dataset per swept parameter, unit attribute
                                 /pads/index (pads,) global pad index, /pads/patch_count (pads,)
                                 attrs: spec (JSON), spec_hash, shard, pad_start, pad_stop, complete,
                                     finished, status, device, integrator, precision, dt, steps, timings, ...,
                                     patch_data (the SHA-256 of a patch file's patches, where the base names one)

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

from aca_warp.common.lazy import lazy_names

# the public names by module, each module imported when one of its names is first used: ``import aca_warp.sweep`` (as
# the command line's parser does for every command) loads no sweep code, Dask or Warp
_MODULES = {
    "cluster": ("LOOPBACK", "cuda_ordinals", "local_cluster", "warm_workers"),
    "commands": ("add_parsers",),
    "manifest": ("MANIFEST", "SHARD_STATES", "SweepResult", "load_sweep", "prepare_dir", "read_manifest"),
    "overlap": ("PIPELINE_DEPTH", "ChunkWriter", "KernelTurn", "ShardCancelled", "ShardContext"),
    "prepare": ("batch_capacity", "device_memory", "keep_preparation_pool", "pad_bytes"),
    "run": ("run_sweep",),
    "shard": ("TIMING_DOC", "TIMING_PHASES", "run_shard", "shard_finished", "shard_name"),
    "spec": (
        "DEFAULT_SHARD_SIZE", "FORMAT", "MAX_PADS", "MAX_STEPS", "MODES", "PACKINGS", "PARAMETERS", "SweepError",
        "SweepSpec", "apply_parameters", "hf1_product_doc", "load_spec", "pack_order",
    ),
}  # fmt: skip
_PUBLIC = {name: f"{__name__}.{module}" for module, names in _MODULES.items() for name in names}
__all__ = sorted(_PUBLIC)


__getattr__, __dir__ = lazy_names(__name__, _PUBLIC)
