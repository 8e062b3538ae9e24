"""Benchmark of the Synchronization Index on a large per-patch record (target size: 1758 patches × 2^20 samples).

Writes a synthetic run-file-like HDF5 dataset ``/patches/velocity`` (float32, samples × patches, chunks (1024, 64)
as in run files) of patches oscillating at a few shared frequencies with random phases plus noise, then times
``aca_warp.analysis.sync_index_from_signals`` over 10 Hz–200 kHz reading from that file, and reports wall time and
peak resident memory (``resource.getrusage``). The file is 7.4 GB at the default size.

    python3 scripts/bench_analysis.py --file /tmp/sync_bench.h5 [--patches 1758] [--log2-samples 20] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import h5py
import numpy as np
import warp as wp

from aca_warp.analysis import sync_index_from_signals
from aca_warp.common.argtypes import int_at_least, positive
from aca_warp.common.devices import init_warp
from aca_warp.common.errors import AcaError, SceneError
from aca_warp.common.files import check_output_path, check_room, machine, open_h5, partial_path

CHUNK = 1024  # samples per chunk, as in run files


def write_signals(path: Path, patches: int, samples: int, dt: float, seed: int) -> None:
    """Synthetic velocities [m/s]: three tones (72, 150, 31 kHz) with per-patch phases and amplitudes, plus noise."""
    rng = np.random.default_rng(seed)
    tones = np.array([72.0e3, 150.0e3, 31.0e3])
    phase = rng.uniform(-np.pi, np.pi, (len(tones), patches))
    phase[0] = rng.normal(0.0, 0.3, patches)  # the 72 kHz tone is nearly synchronous
    amp = rng.uniform(0.0, 1.0, (len(tones), patches))
    with h5py.File(path, "w") as f:
        d = f.create_dataset("velocity", (samples, patches), dtype="f4", chunks=(CHUNK, min(64, patches)))
        block = 1 << 16
        for start in range(0, samples, block):
            t = (np.arange(start, min(start + block, samples)) * dt)[:, None]
            x = 0.01 * rng.standard_normal((len(t), patches))
            for k, fk in enumerate(tones):
                x += amp[k] * np.sin(2 * np.pi * fk * t + phase[k])
            d[start : start + len(t)] = x.astype(np.float32)


def check_scratch(path: Path, shape: tuple[int, int]) -> None:
    """An existing scratch file must hold ``/velocity`` of ``shape`` (samples, patches): :class:`SceneError` if not."""
    with open_h5(path, "scratch file") as f:
        v = f.get("velocity")
        if not isinstance(v, h5py.Dataset):
            raise SceneError(f"{path} holds no /velocity dataset; give another --file (it is written when absent)")
        if v.shape != shape:
            raise SceneError(f"{path} holds shape {v.shape}; delete it or pass matching --patches/--log2-samples")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--file",
        type=Path,
        default=Path("/tmp/sync_bench.h5"),
        help="scratch HDF5 file: written when absent (its folder must exist), reused when present",
    )
    ap.add_argument("--patches", type=int_at_least(1), default=1758, help="patches (columns)")
    ap.add_argument(
        "--log2-samples", type=int_at_least(10), default=20, help="log2 of the number of samples (>= 10: one chunk)"
    )
    ap.add_argument("--dt", type=positive, default=2.0e-7, help="sampling interval [s]")
    ap.add_argument("--json", type=Path, help="write the result row as JSON")
    args = ap.parse_args()
    samples = 1 << args.log2_samples
    try:  # every refusal before the scratch file is written or read: nothing written
        if args.json:
            check_output_path(args.json, overwrite=True)
        if args.file.exists():
            check_scratch(args.file, (samples, args.patches))
        else:
            check_output_path(args.file, overwrite=True)
            check_room(args.file.parent, 4.0 * samples * args.patches, "fewer --patches or --log2-samples")
    except AcaError as e:
        ap.exit(e.exit_code, f"{ap.prog}: error: {e}\n")
    t0 = time.perf_counter()
    if not args.file.exists():
        part = partial_path(args.file)  # a stopped write leaves no file that looks whole
        try:
            write_signals(part, args.patches, samples, args.dt, seed=1)
            part.replace(args.file)
        finally:
            part.unlink(missing_ok=True)
    write_s = time.perf_counter() - t0
    with h5py.File(args.file, "r") as f:
        v = f["velocity"]
        t0 = time.perf_counter()
        res = sync_index_from_signals(v, args.dt, freq_range=(10.0, 200.0e3))
        wall = time.perf_counter() - t0
    init_warp()  # quietly: no CUDA-driver note on a machine without one
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: KiB
    i72 = int(np.argmin(np.abs(res.freq - 72.0e3)))
    row = {
        "machine": machine(wp.get_device("cpu")),
        "patches": args.patches,
        "samples": samples,
        "band_hz": [10.0, 200.0e3],
        "wall_s": wall,
        "peak_rss_gib": peak / 2**30,
        "write_s": write_s,
        "S_at_72kHz": float(res.S[i72]),
    }
    print(json.dumps(row, indent=1))
    if args.json:
        args.json.write_text(json.dumps(row, indent=1))


if __name__ == "__main__":
    main()
