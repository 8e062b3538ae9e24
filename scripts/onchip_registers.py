#!/usr/bin/env python3
"""Registers and stack frame of the on-chip HF kernel, per configuration, without a GPU.

Builds :func:`aca_warp.kernels.hf_onchip.onchip_kernel` for one pad size, compiles each configuration to an
sm_90 cubin with Warp's NVRTC (``wp.compile_aot_module``; no CUDA driver needed) and reads from the cubin's
``.nv.info`` attributes the registers per thread (EIATTR_REGCOUNT) and the stack frame per thread in bytes
(EIATTR_FRAME_SIZE: registers spilled to local memory and local arrays). A frame > 0 in a kernel that runs
millions of steps means spill traffic in the step loop (docs/onchip.md, "Growing pads").

The register file of an SM is split over four schedulers of 16 384 registers each: a block of B threads gets at
most 16384 / (32 · ceil(B / 128)) registers per thread (rounded down to 8): 128 for B = 385…512, 168 for B = 384.

Example::

    python scripts/onchip_registers.py                      # the hf1 pad size, K = 1, 2, 4, 8, with and without growth
    python scripts/onchip_registers.py --blocks 384 512 --clusters 1 --json regs.json
"""

from __future__ import annotations

import argparse
import json
import struct
import sys
import tempfile
from pathlib import Path

H100_SMEM_PER_BLOCK = 232448  # opt-in shared memory per block of an H100 / H200 (227 KB)
EIATTR_REGCOUNT = 0x2F
EIATTR_FRAME_SIZE = 0x11


def cubin_info(path: Path) -> dict[str, int]:
    """{"registers", "frame_bytes"} of the (one) kernel in a cubin, from its .nv.info sections."""
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
    ap.add_argument("--preset", default="hf1", help="scene preset whose pad size is used (default hf1)")
    ap.add_argument("--clusters", type=int, nargs="+", default=[1, 2, 4, 8], help="blocks per pad (default 1 2 4 8)")
    ap.add_argument("--blocks", type=int, nargs="*", help="threads per block (default: the on-chip engine's choice)")
    ap.add_argument("--precisions", nargs="+", default=["fp32", "fp64"], choices=["fp32", "fp64"])
    ap.add_argument(
        "--smem-per-block",
        type=int,
        default=H100_SMEM_PER_BLOCK,
        help="shared memory per block the device offers [bytes], which decides as the on-chip engine does whether the "
        f"neighbour lists are kept on chip (default {H100_SMEM_PER_BLOCK}, H100 and H200)",
    )
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    wp.init()
    from aca_warp.kernels.hf_onchip import onchip_kernel

    from aca_warp.hf.model import build_model
    from aca_warp.hf.onchip_layout import default_block, pad_sizes, shared_bytes, smem_limit, tile_sizes
    from aca_warp.scene import preset

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for prec in args.precisions:
            model = build_model([preset(args.preset)], device="cpu", precision=prec)
            dtype = model.dtype
            for k in args.clusters:
                for growth in (False, True):
                    for b in args.blocks or [default_block(pad_sizes(model, k)[0], k, growth, prec == "fp64")]:
                        csr = shared_bytes(model, True, k, b) <= smem_limit(model, args.smem_per_block)
                        kernel = onchip_kernel(
                            dtype, *tile_sizes(model, k, b), csr, b, growth=growth, cluster=k, lanes=min(b, 32)
                        )
                        kernel.module.options["block_dim"] = b
                        out = Path(tmp) / f"{prec}_{k}_{int(growth)}_{b}"
                        wp.compile_aot_module(kernel.module, arch=90, module_dir=out, use_ptx=False)
                        info = cubin_info(next(out.glob("*.cubin")))
                        row = {"precision": prec, "cluster": k, "growth": growth, "block_dim": b, "csr_shared": csr}
                        row.update(info)
                        rows.append(row)
                        print(
                            f"{prec} K={k} {'growth   ' if growth else 'no growth'} block {b:4d} "
                            f"CSR {'on chip' if csr else 'global '}: "
                            f"{info.get('registers', '?')} registers, stack frame {info.get('frame_bytes', 0)} B",
                            flush=True,
                        )
    if args.json:
        meta = {"preset": args.preset, "warp_version": wp.__version__, "arch": "sm_90", "rows": rows}
        args.json.write_text(json.dumps(meta, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
