#!/usr/bin/env python3
"""Compare the CUDA machine code of two checkouts of aca_warp, without a GPU: does a change leave the GPU's code alone?

A change meant for the CPU build only (a branch on ``cpu_build()``, ``kernels/tiles.py``), or a clean-up of the kernels'
source, should compile for CUDA to the code it had: then nothing on a GPU changes, neither the bits of a result nor the
speed. This script builds, in each checkout (its own Python process, package view and kernel cache, as
``scripts/compare_checkouts.py`` does), the HF kernels a run takes (``GROUPS``: the general engine's module, the
error-controlled split step's module, the strang kernels with the mean crossing treatment, and the on-chip strang and
DP5 kernels in the layouts the engine picks for one, 64 and 1024 hf1 pads on a GPU of 132 SMs, with growth and with the
crossing treatment), compiles each to a cubin for ``--arch`` with Warp's NVRTC (no CUDA driver needed) and compares
their machine code, the ``.text`` section of every forward kernel (what a run launches; overloads of one kernel, e.g.
fp32 and fp64, compared as a set), with its registers, stack frame and shared memory; ``--ptx``: their PTX instead,
what a driver at least as new as Warp's CUDA toolkit compiles itself. Reported per group: identical, or the kernels
whose code differs (with their sizes). Exit 0 when every kernel is identical, 1 otherwise. Example::

    mkdir -p build/base && git archive HEAD aca_warp kernels pyproject.toml | tar -x -C build/base
    python3 scripts/compare_cuda_code.py build/base . --out cuda_code.json
    python3 scripts/compare_cuda_code.py build/base . --ptx
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

from compare_checkouts import package_view, refuse_bad_checkouts, run_in_view

# builds every group's kernels in one checkout, compiles them and prints {group: [[kernel, sha256, bytes], ...]}
CHILD = r"""
import hashlib, json, re, struct
from pathlib import Path
import warp as wp
from aca_warp.common.devices import init_warp
init_warp()
arch, groups, out, ptx = int(sys.argv[2]), json.loads(sys.argv[3]), Path(sys.argv[4]), sys.argv[5] == "ptx"

KERNEL = re.compile(r"_[0-9a-f]{8}_cuda_kernel_forward")

def sections(cubin):  # {name: bytes} of a cubin's ELF sections
    b = cubin.read_bytes()
    shoff = struct.unpack_from("<Q", b, 0x28)[0]
    size, count, names_at = struct.unpack_from("<HHH", b, 0x3A)
    heads = [struct.unpack_from("<IIQQQQ", b, shoff + i * size) for i in range(count)]
    names = b[heads[names_at][4]:heads[names_at][4] + heads[names_at][5]]
    return {names[n:names.index(b"\0", n)].decode(): b[off:off + k] for n, _t, _f, _a, off, k in heads}

def nv_info(data):  # (attribute, value bytes) of an .nv.info section's entries
    p = 0
    while p + 2 <= len(data):
        fmt, attr = data[p], data[p + 1]
        if fmt == 0x04:  # EIFMT_SVAL: u16 size, then the value
            n = struct.unpack_from("<H", data, p + 2)[0]
            yield attr, data[p + 4:p + 4 + n]
            p += 4 + n
        elif fmt in (0x02, 0x03):  # EIFMT_BVAL / EIFMT_HVAL
            yield attr, data[p + 2:p + 4]
            p += 4
        else:  # EIFMT_NVAL
            yield attr, b""
            p += 2

# per symbol of the module's .nv.info: its registers (EIATTR_REGCOUNT), stack frame (EIATTR_FRAME_SIZE) and stack sizes
# (EIATTR_MIN_STACK_SIZE, EIATTR_MAX_STACK_SIZE), each a (symbol index, value) pair
PER_SYMBOL = (0x2F, 0x11, 0x12, 0x23)
PARAM_CBANK = 0x0A  # in a kernel's .nv.info: the symbol index of its parameter bank first (left out: an index)

# (kernel, sha256, bytes of code) per forward kernel (what a run launches), its hash over its code, its registers,
# frame and stack sizes, its .nv.info attributes (parameters, exits; symbol indices left out), the sizes of its
# static shared memory and parameter bank and its dynamic shared memory (the module's .meta); then ("module", sha256,
# 0) over the module's other code and constants (device functions not inlined, constant banks; adjoint kernels, never
# launched, left out); names without their content hashes
def machine_code(cubin, meta):
    secs = sections(cubin)
    sym = secs[".symtab"]
    strtab = secs[".strtab"]
    names = [strtab[n:strtab.index(b"\0", n)].decode()
             for n in (struct.unpack_from("<I", sym, i)[0] for i in range(0, len(sym), 24))]
    per_symbol = {}
    for attr, value in nv_info(secs.get(".nv.info", b"")):
        if attr in PER_SYMBOL and len(value) >= 8:
            index, v = struct.unpack_from("<II", value)
            per_symbol.setdefault(names[index], []).append((attr, v))
    smem = {KERNEL.sub("", k.removesuffix("_smem_bytes")): v for k, v in meta.items()}
    rows, rest = [], hashlib.sha256()
    for label in sorted(secs, key=lambda s: (KERNEL.sub("", s), secs[s])):
        code = secs[label]
        if label.startswith(".text.") and KERNEL.search(label):
            full = label[len(".text."):]
            k = KERNEL.sub("", full)
            h = hashlib.sha256(code)
            h.update(repr(sorted(per_symbol.get(full, []))).encode())
            for attr, value in nv_info(secs.get(".nv.info." + full, b"")):
                h.update(bytes([attr]) + (value[4:] if attr == PARAM_CBANK else value))
            for part in (".nv.shared.", ".nv.constant0."):
                h.update(len(secs.get(part + full, b"")).to_bytes(8, "little"))
            h.update(str(smem.get(k)).encode())
            rows.append([k, h.hexdigest(), len(code)])
        elif (label.startswith(".text.") and "_cuda_kernel_backward" not in label) or re.fullmatch(
            r"\.nv\.constant[1-9]\d*", label
        ):
            rest.update(KERNEL.sub("", label).encode() + code)
    if not rows:
        raise SystemExit(f"{cubin}: no forward kernel found (a Warp that names its kernels otherwise?)")
    return rows + [["module", rest.hexdigest(), 0]]

# (kernel, sha256, lines) per forward kernel entry of a PTX file, then ("module", sha256, 0) over the rest: content
# hashes taken out of every name, branch labels and virtual registers numbered per entry in their order of use
def ptx_code(path):
    text = path.read_text(errors="replace")
    text = re.sub(r"_[0-9a-f]{8}_[0-9a-f]{7}", "_M", text)  # a module of its own: kernel and content hashes
    text = re.sub(r"_[0-9a-f]{7}_cu_[0-9a-f]{8}", "_M_cu", text)  # a named module's hash, in its internal names
    text = re.sub(r"_cu_[0-9a-f]{8}", "_cu", text)
    text = KERNEL.sub("", text)
    lines = [line.rstrip() for line in text.splitlines() if line.strip() and not line.lstrip().startswith("//")]
    starts = r"(?m)^(?=\.visible \.entry|\.entry|\.visible \.func|\.func|\.weak \.func)"
    rows, rest = [], hashlib.sha256()
    for part in (p.strip() for p in re.split(starts, "\n".join(lines))):
        head = re.match(r"(?:\.visible |\.weak )?\.(entry|func)\s+(?:\([^)]*\)\s*)?(\w+)", part)
        if head and "}" in part.splitlines():  # the entry or function up to its closing brace; what follows is the rest
            end = part.splitlines().index("}") + 1
            rest.update("\n".join(part.splitlines()[end:]).encode())
            part = "\n".join(part.splitlines()[:end])
        if head and head.group(1) == "entry" and "_cuda_kernel_backward" not in head.group(2):
            seen = {}
            number = lambda m: m.group(1) + str(seen.setdefault(m.group(0), len(seen)))  # noqa: E731
            body = re.sub(r"\$L__BB\d+_(\d+)", r"L\1", re.sub(r"(%[a-z]+)\d+", number, part))
            rows.append([head.group(2), hashlib.sha256(body.encode()).hexdigest(), body.count("\n")])
        elif not (head and "_cuda_kernel_backward" in head.group(2)):
            rest.update(part.encode())
    if not rows:
        raise SystemExit(f"{path}: no forward kernel found (a Warp that names its kernels otherwise?)")
    return rows + [["module", rest.hexdigest(), 0]]

def kernels(group):
    from aca_warp.scene import Growth, preset
    from aca_warp.hf.model import build_model
    kind = group["kind"]
    if kind == "module":
        import importlib
        importlib.import_module(group["module"])
        return [wp.get_module(group["module"])]
    if kind == "strang_crossing":
        import aca_warp.kernels.hf as H
        return [kernel.module for kernel in H.STRANG_KERNELS[1]]
    from aca_warp.hf.onchip_layout import default_block, grown_tiles, kernel_tiles, pad_sizes, shared_bytes, smem_limit
    smem = 232448  # an H100's / H200's shared memory per block
    scene = preset("hf1")
    growth = bool(group.get("growth"))
    model = build_model([scene.replace(growth=(scene.growth or Growth()) if growth else None)], device="cpu",
                        precision=group["precision"])
    k = group["cluster"]
    if kind == "onchip_dp5":
        from aca_warp.kernels.hf_onchip_adaptive import onchip_dp5_kernel
        kernel = onchip_dp5_kernel(model.dtype, k, group["block"], 1, pad_sizes(model)[0], 0, frozenset(), growth)
        kernel.module.options["block_dim"] = group["block"]
        return [kernel.module]
    from aca_warp.kernels.hf_onchip import onchip_kernel
    fp64 = group["precision"] == "fp64"
    b = group.get("block") or default_block(pad_sizes(model, k)[0], k, growth, fp64)
    csr = shared_bytes(model, True, k, b, smem) <= smem_limit(model, smem)
    kernel = onchip_kernel(model.dtype, *kernel_tiles(model, k, b, smem), csr, b, growth=growth, cluster=k,
                           lanes=min(b, 32), grown_tiles=grown_tiles(model, k, smem),
                           crossing=bool(group.get("crossing")))
    kernel.module.options["block_dim"] = b
    return [kernel.module]

report = {}
for name, group in groups.items():
    rows = []
    for i, module in enumerate(kernels(group)):
        folder = out / f"{name}_{i}"
        for built in wp.compile_aot_module(module, arch=arch, use_ptx=ptx, module_dir=folder):
            if ptx:
                rows += ptx_code(Path(built))
                continue
            meta = {}
            for m in folder.glob("*.meta"):
                meta.update(json.loads(m.read_text()))
            rows += machine_code(Path(built), meta)
    report[name] = sorted(rows)
print(json.dumps(report))
"""

GROUPS: dict[str, dict] = {
    "general (aca_warp.kernels.hf)": {"kind": "module", "module": "aca_warp.kernels.hf"},
    "split step (aca_warp.kernels.hf_controlled)": {"kind": "module", "module": "aca_warp.kernels.hf_controlled"},
    "general, mean crossing": {"kind": "strang_crossing"},
    "on chip fp32, 1 block of 640 (1024 pads)": {"kind": "onchip", "precision": "fp32", "cluster": 1, "block": 640},
    "on chip fp32, 2 blocks of 896 (64 pads)": {"kind": "onchip", "precision": "fp32", "cluster": 2, "block": 896},
    "on chip fp32, 8 blocks of 224 (one pad)": {"kind": "onchip", "precision": "fp32", "cluster": 8},
    "on chip fp64, 2 blocks of 512 (64 pads)": {"kind": "onchip", "precision": "fp64", "cluster": 2},
    "on chip fp32, growing, 4 blocks": {"kind": "onchip", "precision": "fp32", "cluster": 4, "growth": True},
    "on chip fp32, mean crossing, 2 blocks": {"kind": "onchip", "precision": "fp32", "cluster": 2, "crossing": True},
    "on chip DP5 fp64, 16 blocks of 128": {"kind": "onchip_dp5", "precision": "fp64", "cluster": 16, "block": 128},
}


def build(checkout: Path, arch: int, groups: dict[str, dict], work: Path, ptx: bool = False) -> dict[str, list]:
    """Every group's kernels of ``checkout``, compiled in a process of its own (``ptx``: to PTX instead of a cubin):
    {group: [[kernel, sha256, size]]}."""
    view = package_view(checkout, Path(tempfile.mkdtemp(dir=work)))
    cache, into = (Path(tempfile.mkdtemp(dir=work)) for _ in range(2))
    try:
        out = run_in_view(view, CHILD, [str(arch), json.dumps(groups), str(into), "ptx" if ptx else "cubin"], cache)
    except RuntimeError as e:
        raise SystemExit(f"{checkout}: building the kernels failed ({e})") from None
    return json.loads(out.strip().splitlines()[-1])


def compare(a: dict[str, list], b: dict[str, list]) -> dict[str, dict]:
    """Per group: whether the two checkouts' kernels are the same machine code, and the kernels that differ."""
    out = {}
    for group in a:
        first, second = Counter(map(tuple, a[group])), Counter(map(tuple, b[group]))
        differ = sorted({k for k, *_ in (first - second) + (second - first)})
        sizes = {k: tuple(sorted(r[2] for r in c.elements() if r[0] == k) for c in (first, second)) for k in differ}
        kernels = sum(n for r, n in first.items() if r[0] != "module")
        out[group] = {"kernels": kernels, "identical": first == second, "differ": sizes}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("first", type=Path, help="first checkout (a folder with aca_warp/ and kernels/)")
    ap.add_argument("second", type=Path, help="second checkout")
    ap.add_argument("--arch", type=int, default=90, help="CUDA architecture to compile for (default 90: H100, H200)")
    ap.add_argument(
        "--ptx",
        action="store_true",
        help="compare the PTX instead of the machine code (what a driver at least as new as Warp's CUDA toolkit "
        "compiles itself): each forward kernel's entry, its virtual registers and branch labels numbered in order "
        "of use",
    )
    ap.add_argument("--groups", nargs="+", choices=sorted(GROUPS), metavar="GROUP", help="groups to compare (all)")
    ap.add_argument("--out", type=Path, help="also write the report here (JSON)")
    args = ap.parse_args(argv)
    refuse_bad_checkouts(ap, [args.first, args.second])
    import warp as wp

    from aca_warp.common.devices import init_warp
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_path

    try:  # before anything is compiled
        if args.out is not None:
            check_output_path(args.out, overwrite=True)
    except AcaError as e:
        ap.error(str(e))
    init_warp()
    if args.arch not in wp.get_cuda_supported_archs():
        ap.error(f"--arch {args.arch}: this Warp build compiles CUDA code for {sorted(wp.get_cuda_supported_archs())}")
    groups = {g: GROUPS[g] for g in (args.groups or GROUPS)}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        a, b = (build(c, args.arch, groups, work, args.ptx) for c in (args.first, args.second))
    result = compare(a, b)
    for group, r in result.items():
        unit = "lines" if args.ptx else "B"
        sizes = ", ".join(
            "the module's other code or constants" if k == "module" else f"{k} {s[0]} -> {s[1]} {unit}"
            for k, s in r["differ"].items()
        )
        what = "identical" if r["identical"] else f"differ: {sizes}"
        print(f"{group}: {r['kernels']} kernel(s), {what}")
    if args.out is not None:
        report = {"first": str(args.first), "second": str(args.second), "arch": args.arch, "ptx": args.ptx}
        report["groups"] = result
        args.out.write_text(json.dumps(report, indent=1))
    return 0 if all(r["identical"] for r in result.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
