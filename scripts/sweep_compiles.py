#!/usr/bin/env python3
"""How many on-chip kernels a sweep over patch seeds compiles, and what that costs, for one or two checkouts.

The on-chip ``strang`` kernel takes its tile sizes (patches, neighbour-list slots) as compile-time constants. In a
sweep over ``patches.seed`` every shard's pads have other neighbour lists, so tiles sized exactly to each shard
compile one kernel per shard; bucketed tiles (``aca_warp.hf.onchip_layout.kernel_tiles``) let shards of about
the same size share one. Per checkout, in its own Python process with an empty kernel cache (as a first sweep on a
new machine, or after a Warp update), this runs ``aca-warp sweep`` in-process (``--workers 0``) over ``--shards``
shards of ``--pads`` hf1 pads with seeds 1, 2, … in fp32 for ``--duration`` [s], and reports the command's wall
time (compiles, runs and files together), the on-chip kernel modules the cache then holds and the distinct tile
sizes of the shards. Every dataset of every shard of the two checkouts is compared bit for bit (the tiles are
storage: the results must not change). JSON and a Markdown table into ``--out``. ``--tiles THREADS`` (no
checkout) runs nothing: it prints each shard's exact and bucketed tiles for blocks of THREADS threads, one block per
pad, against an H100's or H200's shared memory per block (a GPU's layout for batches of many fp32 hf1 pads: 640), as
this checkout computes them. Exit codes: 0 done, 1 the checkouts' results differ, 2 bad input, 3 a sweep failed.
Examples (the baseline checkout from ``git archive``)::

    python3 scripts/sweep_compiles.py build/base . --device cpu --shards 4 --pads 2 --out out/sweep_compiles
    python3 scripts/sweep_compiles.py --tiles 640 --shards 8 --pads 256 --out out/sweep_tiles
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from compare_checkouts import compare_sweeps, package_view, refuse_bad_checkouts, same_results

from aca_warp.cli import Parser
from aca_warp.common.argtypes import int_at_least, positive

# runs the sweep inside a checkout's package view; prints one JSON line (wall time, tile sizes per shard)
CHILD = """
import json, sys, time
sys.path.insert(0, sys.argv[1])
import aca_warp
assert aca_warp.__file__.startswith(sys.argv[1]), aca_warp.__file__
from aca_warp.cli import main
a = json.loads(sys.argv[2])
t = time.perf_counter()
code = main(["sweep", a["spec"], "-o", a["out"], "--device", a["device"], "--workers", "0", "--quiet"])
wall = time.perf_counter() - t
from aca_warp.hf import onchip_layout as L
from aca_warp.hf.model import build_model
from aca_warp.hf.onchip import cluster_size
from aca_warp.sweep.spec import load_spec
spec = load_spec(a["spec"])
tiles = []
for i in range(spec.shard_count):  # the tiles the engine compiles for the shard (kernel_tiles where it exists)
    model = build_model(spec.scenes(spec.shard_pads(i)), device=a["device"], precision="fp32")
    k = cluster_size(model, None)
    tiles.append(list(getattr(L, "kernel_tiles", L.tile_sizes)(model, k, L.block_config(model, k)[1])))
print(json.dumps({"exit": code, "wall_s": wall, "tiles": tiles}))
"""


def spec_text(shards: int, pads: int, duration: float) -> str:
    """The sweep spec: ``shards`` × ``pads`` hf1 pads, patch seeds 1, 2, …, fp32, ``duration`` [s]."""
    return (
        f'[sweep]\nname = "seeds"\nbase = "hf1"\nshard_size = {pads}\npack = "none"\n'
        f'[run]\nduration = {duration!r}\nprecision = "fp32"\nsample_dt = {duration / 2!r}\n'
        f'[parameters]\n"patches.seed" = {{ range = [1, {shards * pads + 1}] }}\n'
    )


GPU_SMEM_PER_BLOCK = 232448  # bytes: an H100's or H200's opt-in shared memory per block (227 KiB)


class SweepFailed(RuntimeError):
    """A checkout's sweep did not finish (its error in one line)."""


def run_checkout(checkout: Path, work: Path, spec: Path, device: str) -> dict:
    """One checkout's sweep into ``work/sweep`` with an empty kernel cache: wall time [s], kernel modules compiled,
    tiles per shard."""
    view = package_view(checkout, work / "view")
    cache = work / "cache"
    out = work / "sweep"
    arg = json.dumps({"spec": str(spec), "out": str(out), "device": device})
    env = {**os.environ, "WARP_CACHE_PATH": str(cache)}
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD, str(view), arg], capture_output=True, text=True, env=env)
    lines = done.stdout.strip().splitlines()
    row = json.loads(lines[-1]) if done.returncode == 0 and lines else {"exit": done.returncode}
    if row["exit"] != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise SweepFailed(f"{checkout}: the sweep failed (exit {row['exit']}): {last}")
    row["process_s"] = time.perf_counter() - t
    row["onchip_modules"] = sorted(p.name for p in cache.rglob("*") if p.is_dir() and "onchip" in p.name)
    return row


def print_tiles(args: argparse.Namespace, out: Path) -> int:
    """``--tiles``: every shard's exact (``tile_sizes``) and bucketed (``kernel_tiles``) tiles, one block per pad of
    ``args.tiles`` threads, into ``out/sweep_tiles.{json,md}``."""
    from aca_warp.hf.model import build_model
    from aca_warp.hf.onchip_layout import kernel_tiles, tile_sizes
    from aca_warp.sweep.spec import load_spec

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "seeds.toml"
        path.write_text(spec_text(args.shards, args.pads, args.duration))
        spec = load_spec(path)
        rows = []
        for i in range(spec.shard_count):
            model = build_model(spec.scenes(spec.shard_pads(i)), device="cpu", precision="fp32")
            exact = tile_sizes(model, 1, args.tiles)
            bucketed = kernel_tiles(model, 1, args.tiles, GPU_SMEM_PER_BLOCK)
            rows.append({"shard": i, "exact": exact, "bucketed": bucketed})
            print(f"shard {i}: exact {rows[-1]['exact']}, bucketed {rows[-1]['bucketed']}", flush=True)
    kinds = {k: len({tuple(r[k]) for r in rows}) for k in ("exact", "bucketed")}
    doc = {"threads": args.tiles, "shards": args.shards, "pads": args.pads, "rows": rows, "distinct": kinds}
    (out / "sweep_tiles.json").write_text(json.dumps(doc, indent=1) + "\n")
    lines = [
        f"Tiles (patches, CSR slots) of {args.shards} shards × {args.pads} fp32 hf1 pads with patch seeds 1, 2, …, one "
        f"block of {args.tiles} threads per pad, {GPU_SMEM_PER_BLOCK} B of shared memory per block "
        f"(`python3 scripts/sweep_compiles.py --tiles {args.tiles}`): "
        f"{kinds['exact']} distinct exact, {kinds['bucketed']} distinct bucketed.",
        "",
        "| shard | exact | bucketed |",
        "|---|---|---|",
        *(f"| {r['shard']} | {tuple(r['exact'])} | {tuple(r['bucketed'])} |" for r in rows),
    ]
    (out / "sweep_tiles.md").write_text("\n".join(lines) + "\n")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = Parser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("checkouts", nargs="*", type=Path, metavar="CHECKOUT", help="one or two checkouts (folders)")
    ap.add_argument("--device", default="cpu", help="Warp device of the sweep (default cpu)")
    ap.add_argument("--shards", type=int_at_least(1), default=4, help="shards (default 4)")
    ap.add_argument("--pads", type=int_at_least(1), default=2, help="hf1 pads per shard (default 2)")
    ap.add_argument("--duration", type=positive, default=1e-6, metavar="S", help="simulated time [s] (default 1e-6)")
    ap.add_argument("--out", default="out/sweep_compiles", help="folder of the JSON and Markdown results")
    ap.add_argument("--tiles", type=int_at_least(1), metavar="THREADS",
                    help="only print the shards' exact and bucketed tiles for blocks of THREADS threads")  # fmt: skip
    args = ap.parse_args(argv)
    if args.tiles is not None and (args.checkouts or args.tiles > 1024):
        ap.error("--tiles THREADS (1-1024) computes this checkout's tiles: give no CHECKOUT")
    if args.tiles is None and not 1 <= len(args.checkouts) <= 2:
        ap.error("give one or two checkouts")
    refuse_bad_checkouts(ap, args.checkouts)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.tiles is not None:
        return print_tiles(args, out)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "seeds.toml"
        spec.write_text(spec_text(args.shards, args.pads, args.duration))
        for k, checkout in enumerate(args.checkouts):
            try:
                row = run_checkout(checkout.resolve(), Path(tmp) / f"c{k}", spec, args.device)
            except SweepFailed as e:
                print(f"sweep_compiles: {e}", file=sys.stderr)
                return 3
            row["checkout"] = str(checkout)
            rows.append(row)
            print(f"{checkout}: {row['wall_s']:.1f} s, {len(row['onchip_modules'])} on-chip kernel modules, tiles "
                  f"{row['tiles']}", flush=True)  # fmt: skip
        same = None
        if len(rows) == 2:  # every pad's outputs and every dataset of every shard file (compare_checkouts)
            r = compare_sweeps(Path(tmp) / "c0" / "sweep", Path(tmp) / "c1" / "sweep")
            same = same_results(r) and not r["files_only_one"] and all(map(same_results, r["files"].values()))
            print(f"every dataset of every shard bit for bit the same: {same}")
    doc = {"device": args.device, "shards": args.shards, "pads": args.pads, "duration_s": args.duration,
           "rows": rows, "identical": same}  # fmt: skip
    (out / "sweep_compiles.json").write_text(json.dumps(doc, indent=1) + "\n")
    lines = [
        f"Sweep over patch seeds: {args.shards} shards × {args.pads} hf1 pads, fp32, {args.duration:g} s, device "
        f"{args.device}, empty kernel cache per checkout (`python3 scripts/sweep_compiles.py`).",
        "",
        "| checkout | wall [s] | on-chip kernel modules | distinct tiles |",
        "|---|---|---|---|",
        *(
            f"| {r['checkout']} | {r['wall_s']:.1f} | {len(r['onchip_modules'])} | {len(set(map(tuple, r['tiles'])))} |"
            for r in rows
        ),  # fmt: skip
    ]
    if same is not None:
        lines += ["", f"Every dataset of every shard bit for bit the same in both: {same}."]
    (out / "sweep_compiles.md").write_text("\n".join(lines) + "\n")
    return 0 if same in (None, True) else 1


if __name__ == "__main__":
    raise SystemExit(main())
