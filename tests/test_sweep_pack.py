"""Sweeps of pads of unequal size: pads packed into shards by patch count, results independent of the packing."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from aca_warp.hf.recorder import GLOBAL_NAMES
from aca_warp.sweep import SweepError, load_spec, load_sweep, pack_order, run_sweep

# 2 M x 2 seeds x 3 patch counts = 12 pads (count varies fastest: in spec order every shard mixes sizes), shards of 4
SIZES = {
    "sweep": {"base": "hf1", "shard_size": 4, "name": "sizes"},
    "run": {"duration": 3e-6, "precision": "fp32"},
    "parameters": {
        "friction.M": [0.6, 0.8],
        "patches.seed": [1, 2],
        "patches.count": [12, 40, 25],
    },
}


def _spec(pack: str | None = None, **parameters: list) -> object:
    doc = json.loads(json.dumps(SIZES))
    doc["parameters"].update(parameters)
    if pack is not None:
        doc["sweep"]["pack"] = pack
    return load_spec(doc, base_dir=Path.cwd())


def test_pack_order() -> None:
    """Pads sorted by patch count, stably (equal counts keep the spec's order); None where nothing would move."""
    order = pack_order({"patches.count": [40, 12, 25, 12, 40], "friction.M": [0.1] * 5}, "size")
    assert order.tolist() == [1, 3, 2, 0, 4] and order.dtype == np.int64
    assert pack_order({"patches.count": [25, 25]}, "size") is None
    assert pack_order({"friction.M": [0.6, 0.7]}, "size") is None
    assert pack_order({"patches.count": [40, 12]}, "none") is None


def test_shards_hold_pads_of_one_size() -> None:
    """Packed by size, each shard's pads share a patch count; in the spec's order (pack = "none") every shard mixes
    the three counts. Every pad is in exactly one shard either way."""
    packed, plain = _spec(), _spec("none")
    for spec, alike in ((packed, True), (plain, False)):
        shards = [spec.shard_pads(i) for i in range(spec.shard_count)]
        assert sorted(np.concatenate(shards).tolist()) == list(range(12))
        counts = [{spec.parameters["patches.count"][p] for p in pads} for pads in shards]
        assert all(len(c) == 1 for c in counts) == alike, counts
    assert plain.shard_pads(1).tolist() == [4, 5, 6, 7]
    assert [packed.scene(int(p)).patches.count for p in packed.shard_pads(0)] == [12] * 4


def test_hash_names_the_packing_only_where_it_moves_pads() -> None:
    """The hash of a sweep whose pads all have one size does not depend on ``pack`` (directories of earlier sweeps
    are continued); where packing moves pads between shards, the two packings are different sweeps."""
    assert _spec().hash != _spec("none").hash
    same = {"patches.count": [25]}
    assert _spec(**same).hash == _spec("none", **same).hash
    with pytest.raises(SweepError, match="sweep.pack must be one of size, none"):
        _spec("bogus")


def test_results_do_not_depend_on_packing(tmp_path: Path) -> None:
    """The same pads run packed by size and in the spec's order give the same outputs bit for bit (load_sweep puts
    the pads of both in global order); a shard file names its pads and their parameters row by row, and a rerun
    finds every packed shard finished."""
    out = {}
    for pack in ("size", "none"):
        spec = _spec(pack)
        res = run_sweep(spec, tmp_path / pack, workers=0)
        assert res.ran == [0, 1, 2] and not res.failed and not res.faults
        out[pack] = load_sweep(tmp_path / pack)
    a, b = out["size"], out["none"]
    assert a["pad_index"].tolist() == b["pad_index"].tolist() == list(range(12))
    for k in GLOBAL_NAMES:
        assert a[k].shape == (12, 4) and a[k].tobytes() == b[k].tobytes(), k
    for k, v in a["parameters"].items():
        assert np.array_equal(v, b["parameters"][k]), k
    assert a["parameters"]["patches.count"].tolist() == _spec().parameters["patches.count"]
    spec = _spec()
    with h5py.File(tmp_path / "size" / "shard-00001.h5") as f:
        pads = f["pads/index"][()]
        assert pads.tolist() == spec.shard_pads(1).tolist() != [4, 5, 6, 7]
        assert f["parameters/patches.count"][()].tolist() == [spec.parameters["patches.count"][p] for p in pads]
        assert f["pads/patch_count"][()].tolist() == [25] * 4
        assert (f.attrs["pad_start"], f.attrs["pad_stop"]) == (4, 8)
    manifest = json.loads((tmp_path / "size" / "manifest.json").read_text())
    assert manifest["pad_order"] == "patch_count" and manifest["spec_hash"] == spec.hash
    again = run_sweep(_spec(), tmp_path / "size", workers=0)
    assert again.ran == [] and again.skipped == [0, 1, 2]
