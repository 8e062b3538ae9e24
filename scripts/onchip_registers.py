#!/usr/bin/env python3
"""Registers, stack frame and code size of the on-chip HF kernels, per configuration, without a GPU.

Builds :func:`aca_warp.kernels.hf_onchip.onchip_kernel` (``--kernel strang``) or
:func:`aca_warp.kernels.hf_onchip_adaptive.onchip_dp5_kernel` (``--kernel adaptive``, with the lanes and block size
the on-chip adaptive engine picks on CUDA) for one pad size, compiles each configuration to an sm_90 cubin with Warp's
NVRTC (``wp.compile_aot_module``, into Warp's kernel cache, so a configuration compiles once per machine; no CUDA
driver needed) and reads from the cubin's ``.nv.info`` attributes the registers per thread (EIATTR_REGCOUNT) and the
stack frame per thread in bytes (EIATTR_FRAME_SIZE: registers spilled to local memory and local arrays), and the size
of the kernel's machine code (its ``.text`` section, 16 bytes per sm_90 instruction). A frame > 0 in a kernel that
runs millions of steps means spill traffic in the step loop (docs/onchip.md, "Growing pads"). Two versions of the
kernels that give the same three numbers in every configuration compiled to the same code up to the order of
instructions.

The register file of an SM is split over four schedulers of 16 384 registers each: a block of B threads gets at
most 16384 / (32 · ceil(B / 128)) registers per thread (rounded down to 8): 128 for B = 385…512, 168 for B = 384.

Example::

    python scripts/onchip_registers.py                      # the hf1 pad size, K = 1, 2, 4, 8, with and without growth
    python scripts/onchip_registers.py --blocks 384 512 --clusters 1 --json regs.json
    python scripts/onchip_registers.py --kernel adaptive --clusters 1 2 --precisions fp64
"""

from __future__ import annotations

import argparse
import json
import struct
import sys
from pathlib import Path

from aca_warp.common.argtypes import int_at_least, int_between
from aca_warp.hf.onchip_layout import MAX_BLOCK, MAX_CLUSTER

H100_SMEM_PER_BLOCK = 232448  # opt-in shared memory per block of an H100 / H200 (227 KB)
EIATTR_REGCOUNT = 0x2F
EIATTR_FRAME_SIZE = 0x11


def cubin_info(path: Path) -> dict[str, int]:
    """{"registers", "frame_bytes", "text_bytes"} of the (one) kernel in a cubin, from its .nv.info and .text
    sections."""
    d = path.read_bytes()
    if d[:4] != b"\x7fELF":
        raise ValueError(f"{path} is not an ELF cubin")
    shoff = struct.unpack_from("<Q", d, 0x28)[0]
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", d, 0x3A)
    secs = [struct.unpack_from("<IIQQQQIIQQ", d, shoff + i * shentsize) for i in range(shnum)]
    names = secs[shstrndx][4]
    out: dict[str, int] = {}
    for sec in secs:
        name = d[names + sec[0] : d.index(b"\0", names + sec[0])].decode()
        if name.startswith(".text."):
            out["text_bytes"] = sec[5]
        if not name.startswith(".nv.info"):
            continue
        p, end = sec[4], sec[4] + sec[5]
        while p < end:
            fmt, attr = d[p], d[p + 1]
            if fmt == 0x04:  # EIFMT_SVAL: u16 size, then the value (symbol index u32, value u32 for these two)
                size = struct.unpack_from("<H", d, p + 2)[0]
                if attr in (EIATTR_REGCOUNT, EIATTR_FRAME_SIZE) and size >= 8:
                    key = "registers" if attr == EIATTR_REGCOUNT else "frame_bytes"
                    out[key] = struct.unpack_from("<I", d, p + 8)[0]
                p += 4 + size
            elif fmt in (0x02, 0x03):  # EIFMT_BVAL / EIFMT_HVAL: 4 bytes in all
                p += 4
            elif fmt == 0x01:  # EIFMT_NVAL
                p += 2
            else:
                break
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kernel", choices=["strang", "adaptive"], default="strang", help="which on-chip kernel")
    ap.add_argument("--preset", default="hf1", help="scene preset whose pad size is used (default hf1)")
    ap.add_argument(
        "--clusters",
        type=int_between(1, MAX_CLUSTER),
        nargs="+",
        default=[1, 2, 4, 8],
        help="blocks per pad (default 1 2 4 8)",
    )
    ap.add_argument(
        "--blocks",
        type=int_between(1, MAX_BLOCK),
        nargs="*",
        help="threads per block (default: the on-chip engine's choice)",
    )
    ap.add_argument("--precisions", nargs="+", default=["fp32", "fp64"], choices=["fp32", "fp64"])
    ap.add_argument(
        "--smem-per-block",
        type=int_at_least(1),
        default=H100_SMEM_PER_BLOCK,
        help="shared memory per block the device offers [bytes], which decides as the on-chip engine does whether the "
        f"neighbour lists are kept on chip (default {H100_SMEM_PER_BLOCK}, H100 and H200)",
    )
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args(argv)

    import warp as wp

    from aca_warp.common.devices import init_warp
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_path
    from aca_warp.hf.model import build_model
    from aca_warp.scene import Growth, preset

    try:  # every refusal before the first compile: nothing compiled, nothing written
        preset(args.preset)
        if args.json is not None:
            check_output_path(args.json, overwrite=True)
    except AcaError as e:
        ap.error(str(e))
    init_warp()  # quietly: no CUDA-driver note on a machine without a GPU

    rows = []
    scene = preset(args.preset)
    for prec in args.precisions:
        # the pad without growth and growing (the preset's growth, else Eq. 10's): the layout the engine picks for each
        models = {
            growth: build_model(
                [scene.replace(growth=(scene.growth or Growth()) if growth else None)], device="cpu", precision=prec
            )
            for growth in (False, True)
        }
        for k in args.clusters:
            for growth, model in models.items():
                configs = (_strang if args.kernel == "strang" else _adaptive)(model, k, growth, args)
                for row, kernel in configs:
                    # into Warp's kernel cache, keyed by the module's hash: a configuration compiles once per machine
                    cubin = wp.compile_aot_module(kernel.module, arch=90, use_ptx=False)[-1]
                    info = cubin_info(Path(cubin))
                    row = {"kernel": args.kernel, "precision": prec, "cluster": k, "growth": growth, **row, **info}
                    rows.append(row)
                    print(
                        f"{args.kernel} {prec} K={k} {'growth   ' if growth else 'no growth'} "
                        f"block {row['block_dim']:4d} CSR {'on chip' if row['csr_shared'] else 'global '}"
                        + (f" lanes {row['lanes']}" if "lanes" in row else "")
                        + f": {info.get('registers', '?')} registers, stack frame {info.get('frame_bytes', 0)} B, "
                        f"code {info.get('text_bytes', 0)} B",
                        flush=True,
                    )
    if args.json:
        meta = {"preset": args.preset, "warp_version": wp.__version__, "arch": "sm_90", "rows": rows}
        args.json.write_text(json.dumps(meta, indent=1))
    return 0


def _strang(model, cluster: int, growth: bool, args) -> list:
    """(row, kernel) of the on-chip strang kernel per block size (default: the engine's choice)."""
    from aca_warp.kernels.hf_onchip import onchip_kernel

    from aca_warp.hf.onchip_layout import (
        default_block,
        grown_tiles,
        kernel_tiles,
        pad_sizes,
        shared_bytes,
        smem_limit,
    )

    out = []
    fp64 = model.precision == "fp64"
    for b in args.blocks or [default_block(pad_sizes(model, cluster)[0], cluster, growth, fp64)]:
        csr = shared_bytes(model, True, cluster, b, args.smem_per_block) <= smem_limit(model, args.smem_per_block)
        tiles = kernel_tiles(model, cluster, b, args.smem_per_block)  # the engine's tiles for that device's limit
        kernel = onchip_kernel(
            model.dtype, *tiles, csr, b, growth=growth, cluster=cluster, lanes=min(b, 32),
            grown_tiles=grown_tiles(model, cluster, args.smem_per_block),
        )  # fmt: skip
        kernel.module.options["block_dim"] = b
        out.append(({"block_dim": b, "csr_shared": csr}, kernel))
    return out


def _adaptive(model, cluster: int, growth: bool, args) -> list:
    """(row, kernel) of the on-chip adaptive kernel with the lanes per patch and the block size that
    :func:`aca_warp.hf.onchip_adaptive.layout` picks on CUDA (``--blocks``: those block sizes instead)."""
    import numpy as np
    from aca_warp.kernels.hf_onchip_adaptive import onchip_dp5_kernel

    from aca_warp.hf.onchip_adaptive import BLOCK, EVAL_LANES
    from aca_warp.hf.onchip_layout import adaptive_shared_bytes, pad_sizes, smem_limit

    per_block = -(-int(np.diff(model.pad_patch_start_host).max()) // cluster)
    lanes = EVAL_LANES if per_block * EVAL_LANES <= BLOCK else 1
    nmax = -(-pad_sizes(model)[0] // 32) * 32
    links = -(-pad_sizes(model, cluster)[1] // 32) * 32
    links = links if adaptive_shared_bytes(model, cluster, links) <= smem_limit(model, args.smem_per_block) else 0
    out = []
    for b in args.blocks or [min(BLOCK, -(-per_block * lanes // 32) * 32)]:
        kernel = onchip_dp5_kernel(model.dtype, cluster, b, lanes, nmax, links, frozenset(), growth)
        kernel.module.options["block_dim"] = b
        out.append(({"block_dim": b, "csr_shared": links > 0, "lanes": lanes}, kernel))
    return out


if __name__ == "__main__":
    sys.exit(main())
