"""Run the same HF and LF jobs from two checkouts of aca_warp and compare their run files dataset by dataset.

A restructuring must not change results: this script runs, from each checkout's own code, the CPU jobs

* ``hf hf1 --duration 2e-5``            (the paper's HF1 pad, 20 µs, in fp64 and in fp32)
* ``hf varying_area --duration 1e-5``   (growing patches, 10 µs, fp64, growth events at the scene's 2.02e-7 s)
* ``hf hf1 --integrator adaptive``      (100 µs at tolerance 1e-5; on the CPU the on-chip adaptive engine)
* ``lf multiscale``                     (the LF automaton over the whole load procedure)
* ``sweep aca_warp/data/sweep_hf1.toml`` (24 hf1 pads in 5 shards, 10 µs, in this process)
* ``sweep`` of pads of unequal size     (2 friction factors × 2 layouts × 3 patch counts, shards of 4)

(opt-in with ``--jobs``, ``EXTRA_JOBS``: the on-chip strang engine, the general adaptive engine, growth on every
engine, both Euler schemes, strang's mean crossing treatment on two hf1 pads whose disc turns at 0.5 and 1 m/s (their
patches stick, and cross zero slip, within 0.1 ms), the error-controlled split step, and
``sweep_pairs`` / ``sweep_pairs_fp64``: 64 hf1 pads of patch seeds 1–64 in one shard
over 100 µs in fp32 / fp64, which a GPU of 132 SMs runs on clusters of 2 blocks; ``sweep_va_pairs``: 32 growing
varying_area pads in fp32, growth events 5 µs apart, over 100 µs (``sweep_va_pairs_2ms``: over 2 ms); ``lf_seed7``
then ``hf_lf_state``: an HF pad on an LF state of 4196 patches, 100 µs in fp32; every job on ``--device``, the CPU
unless named) and reports, per job, every dataset that differs (shape, dtype or any bit) and the root attributes that
differ (wall times, versions and similar provenance are listed separately as expected differences); a sweep's shard
files are compared file by file, and its pads one by one (rows found through ``/pads/index``, so that the comparison
holds when the two checkouts cut the pads into shards differently). Exit code 0 when every dataset (every pad of a
sweep) is bit-identical. The `strang` jobs name their step, precision and spacing of growth events, so that two
checkouts on either side of a change of those defaults run the same job.

Each checkout is imported as it is on disk: a temporary folder holds a package ``aca_warp`` whose entries link
to the checkout's ``aca_warp/`` with ``kernels`` linked to the checkout's ``kernels/`` (the layout an install
makes), and each job runs in a fresh Python process with that folder first on ``sys.path``.

Usage::

    git worktree add /tmp/base <commit>
    python scripts/compare_checkouts.py /tmp/base . --out /tmp/cmp [--jobs hf1 varying_area lf]
    python scripts/compare_checkouts.py /tmp/base . --out /tmp/cmp --device cuda:0 --jobs hf1 hf1_onchip

``--cache DIR`` keeps the two checkouts' kernel caches (DIR/cache0, DIR/cache1) for later calls, so that an unchanged
first checkout compiles once.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np

# the strang jobs name their step and precision, and the growing ones their growth events' spacing, so that checkouts
# on either side of a change of strang's defaults (fp64, then fp32; events at the scene's 2.02e-7 s, then every 5e-6 s;
# 5e-8 s for every scene, then 1e-7 s for the presets' physics, then 2.5e-7 s) run the same job; one pair in each
# precision. The crossing treatment is not pinned (an option of later checkouts; the presets' default since 2026-12-02
# averages the crossings): these jobs' first 10-20 µs cross no zero slip, where both treatments step alike
PINNED_STEP = 5.0e-8  # s
STEP = ["--dt", f"{PINNED_STEP:g}"]
JOBS = {
    "hf1": ["hf", "hf1", "--duration", "2e-5", *STEP, "--precision", "fp64", "--no-progress"],
    "hf1_fp32": ["hf", "hf1", "--duration", "2e-5", *STEP, "--precision", "fp32", "--no-progress"],
    "varying_area": ["hf", "varying_area", "--duration", "1e-5", *STEP, "--precision", "fp64", "--growth-dt", "2.02e-7"]
    + ["--no-progress"],
    "hf1_adaptive": ["hf", "hf1", "--duration", "1e-4", "--integrator", "adaptive", "--tolerance", "1e-5"]
    + ["--no-progress"],
    "lf": ["lf", "multiscale", "--no-progress"],
    "sweep": ["sweep", "aca_warp/data/sweep_hf1.toml", "--workers", "0", "--duration", "1e-5", "--shard-size", "5"],
    "sweep_sizes": ["sweep", "{out}/sweep_sizes.toml", "--workers", "0"],
}


def sweep_spec(
    base: str,
    shard_size: int,
    duration: float,
    precision: str,
    parameters: str,
    growth_dt: float | None = None,
    crossing: str | None = None,
) -> str:
    """The TOML spec of a sweep job: ``base`` scene, pads per shard, simulated time [s], precision, the
    ``[parameters]`` table's lines and, for growing pads, the spacing of their growth events [s] (named, as the step
    is, :data:`PINNED_STEP`, so that two checkouts on either side of a change of their defaults run the same job);
    ``crossing``: strang's treatment of steps that cross zero slip."""
    run = f'duration = {duration!r}\ndt = {PINNED_STEP!r}\nprecision = "{precision}"'
    if growth_dt is not None:
        run += f"\ngrowth_dt = {growth_dt!r}"
    if crossing is not None:
        run += f'\ncrossing = "{crossing}"'
    return f'[sweep]\nbase = "{base}"\nshard_size = {shard_size}\n[run]\n{run}\n[parameters]\n{parameters}\n'


# the specs of the sweep jobs, written into the output folder: sweep_sizes, pads of unequal size; sweep_pairs (fp32)
# and sweep_pairs_fp64, 64 hf1 pads in one shard, and sweep_va_pairs, 32 growing varying_area pads in fp32 with
# growth events 5 µs apart, which a GPU of 132 SMs runs on clusters of 2 blocks
SPECS = {
    "sweep_sizes": sweep_spec(
        "hf1", 4, 2.0e-5, "fp32", '"friction.M" = [0.7, 0.8]\n"patches.seed" = [1, 2]\n"patches.count" = [60, 200, 120]'
    ),
    "sweep_pairs": sweep_spec("hf1", 64, 1.0e-4, "fp32", '"patches.seed" = { range = [1, 65] }'),
    "stickslip_crossing": sweep_spec("hf1", 2, 1.0e-4, "fp32", '"disc.sliding_speed" = [0.5, 1.0]', crossing="mean"),
    "sweep_pairs_fp64": sweep_spec("hf1", 64, 1.0e-4, "fp64", '"patches.seed" = { range = [1, 65] }'),
    "sweep_va_pairs": sweep_spec("varying_area", 32, 1.0e-4, "fp32", '"patches.seed" = { range = [1, 33] }', 5.0e-6),
    # the same over 2 ms: 400 growth events, each with its contact re-solve, whose block sums feed back into the motion
    "sweep_va_pairs_2ms": sweep_spec(
        "varying_area", 32, 2.0e-3, "fp32", '"patches.seed" = { range = [1, 33] }', 5.0e-6
    ),
}
# opt-in jobs (--jobs): the engines and integrators the default jobs leave out on the CPU
EXTRA_JOBS = {
    "hf1_onchip": ["hf", "hf1", "--duration", "2e-5", "--engine", "onchip", "--record-patches", "velocity,displacement"]
    + [*STEP, "--precision", "fp64", "--no-progress"],
    "varying_area_onchip": ["hf", "varying_area", "--duration", "1e-5", "--engine", "onchip", "--precision", "fp64"]
    + [*STEP, "--growth-dt", "2.02e-7", "--no-progress"],
    "hf1_adaptive_general": ["hf", "hf1", "--duration", "1e-4", "--integrator", "adaptive", "--tolerance", "1e-5"]
    + ["--engine", "general", "--record-patches", "velocity", "--no-progress"],
    "varying_area_adaptive": ["hf", "varying_area", "--duration", "1e-5", "--integrator", "adaptive"]
    + ["--tolerance", "1e-5", "--no-progress"],
    "varying_area_adaptive_general": ["hf", "varying_area", "--duration", "1e-5", "--integrator", "adaptive"]
    + ["--tolerance", "1e-5", "--engine", "general", "--no-progress"],
    "hf1_euler": ["hf", "hf1", "--duration", "2e-6", "--integrator", "symplectic-euler", "--dt", "2e-10"]
    + ["--no-progress"],
    "hf1_imex": ["hf", "hf1", "--duration", "2e-5", "--integrator", "implicit-friction", "--no-progress"],
    "stickslip_crossing": ["sweep", "{out}/stickslip_crossing.toml", "--workers", "0"],
    "hf1_controlled": ["hf", "hf1", "--duration", "1e-4", "--integrator", "controlled", "--no-progress"],
    "sweep_pairs": ["sweep", "{out}/sweep_pairs.toml", "--workers", "0"],
    "sweep_pairs_fp64": ["sweep", "{out}/sweep_pairs_fp64.toml", "--workers", "0"],
    "sweep_va_pairs": ["sweep", "{out}/sweep_va_pairs.toml", "--workers", "0"],
    "sweep_va_pairs_2ms": ["sweep", "{out}/sweep_va_pairs_2ms.toml", "--workers", "0"],
    # an LF state of about 4200 patches (LF seed 7's app2_start), then one HF pad on it read from the first checkout's
    # LF file (run lf_seed7 first, in the same --jobs): on a GPU 8 blocks of 525 patches, more than 512 per block
    "lf_seed7": ["lf", "multiscale", "--seed", "7", "--no-progress"],
    "hf_lf_state": ["hf", "{out}/lf_seed7_0.h5", "--snapshot", "app2_start", "--duration", "1e-4"]
    + [*STEP, "--precision", "fp32", "--no-progress"],
}
# jobs that read what another job wrote, and that job, which must come earlier in --jobs
NEEDS = {"hf_lf_state": "lf_seed7"}
# root attributes that describe the machine, the package or the wall clock, not the results
PROVENANCE = {
    "versions",
    "wall_time",
    "compile_time",
    "steps_per_second",
    "host",
    "platform",
    "created",
    "device_name",
    "machine",
    "timings",
    "task_time",
    "batch_capacity",
}


def checkout_problem(checkout: Path) -> str | None:
    """Why ``checkout`` is not a checkout of aca_warp (no ``aca_warp/__init__.py`` or no ``kernels/``), or None."""
    for need in ("aca_warp/__init__.py", "kernels/__init__.py"):
        if not (checkout / need).is_file():
            return f"{checkout}: not a checkout of aca_warp (no {need})"
    return None


def refuse_bad_checkouts(ap: argparse.ArgumentParser, checkouts: list[Path]) -> None:
    """``ap.error`` (one line, exit 2) for the first of ``checkouts`` that is not a checkout of aca_warp."""
    for checkout in checkouts:
        if problem := checkout_problem(checkout):
            ap.error(problem)


def package_view(checkout: Path, into: Path) -> Path:
    """A folder with package ``aca_warp`` made of links into ``checkout`` (kernels/ as aca_warp/kernels)."""
    pkg = into / "aca_warp"
    pkg.mkdir(parents=True)
    for entry in (checkout / "aca_warp").iterdir():
        if entry.name != "__pycache__":
            (pkg / entry.name).symlink_to(entry.resolve())
    (pkg / "kernels").symlink_to((checkout / "kernels").resolve())
    return into


# what run_in_view puts before the code it runs: the package of the view (sys.argv[1]) first on the path, and checked
VIEW_PREAMBLE = (
    "import sys\nsys.path.insert(0, sys.argv[1])\nimport aca_warp\n"
    "assert aca_warp.__file__.startswith(sys.argv[1]), aca_warp.__file__\n"
)


def run_in_view(view: Path, code: str, args: list[str], cache: Path | None = None) -> str:
    """Run Python ``code`` in a process of its own with the package of ``view`` (:func:`package_view`; ``sys.argv[1]``,
    ``args`` after it), in ``view`` and with ``cache`` as its kernel cache (None: this process's); returns its
    stdout. RuntimeError naming its exit status and the end of its stderr when it fails."""
    env = {**os.environ, **({} if cache is None else {"WARP_CACHE_PATH": str(cache)})}
    cmd = [sys.executable, "-c", VIEW_PREAMBLE + code, str(view), *args]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=view)
    if done.returncode != 0:
        raise RuntimeError(f"exit {done.returncode}: {done.stderr.strip()[-2000:]}")
    return done.stdout


def run_job(view: Path, args: list[str], output: Path, cache: Path) -> None:
    """Run ``aca-warp ARGS -o OUTPUT`` with the package of ``view``; raise on a non-zero exit."""
    try:
        run_in_view(
            view, "from aca_warp.cli import main\nsys.exit(main(sys.argv[2:]))", [*args, "-o", str(output)], cache
        )
    except RuntimeError as e:
        raise RuntimeError(f"{' '.join(args)} failed ({e})") from None


def datasets(path: Path) -> dict[str, np.ndarray]:
    """Every dataset of an HDF5 file by path."""
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def root_attrs(path: Path) -> dict[str, str]:
    with h5py.File(path, "r") as f:
        return {k: str(v) for k, v in f.attrs.items()}


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind in "fc":
        return a.tobytes() == b.tobytes()
    return bool(np.array_equal(a, b))


def largest_relative(a: np.ndarray, b: np.ndarray) -> float | None:
    """max |a − b| / max |a| of two float arrays of one shape (0 where a is all zero and b equals it; inf where a is
    all zero and b is not, or where a NaN of one stands opposite a number of the other), None when they cannot be
    compared so (other shapes or not floats). NaNs in the same places are left out."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype.kind != "f" or b.dtype.kind != "f" or a.size == 0:
        return None
    if np.any(np.isnan(a) != np.isnan(b)):
        return float("inf")
    a = a.astype(np.float64)
    diff = np.abs(a - b.astype(np.float64))
    top, scale = np.nanmax(diff, initial=0.0), np.nanmax(np.abs(a), initial=0.0)
    if top == 0.0:
        return 0.0
    return float(top / scale) if scale > 0.0 else float("inf")


def compare_sweeps(a: Path, b: Path) -> dict:
    """Differences between two sweep directories: their pads one by one (``/pads/index`` gives a row's pad; every
    global output of every pad compared bit for bit) and their shard files (as :func:`compare`)."""
    names = sorted({p.name for p in a.glob("shard-*.h5")} | {p.name for p in b.glob("shard-*.h5")})
    rows: list[dict[int, dict[str, np.ndarray]]] = [{}, {}]
    files: dict[str, dict] = {}
    for name in names:
        pair = [a / name, b / name]
        if all(p.is_file() for p in pair):
            files[name] = compare(*pair)
        for side, path in zip(rows, pair, strict=True):
            if path.is_file():
                with h5py.File(path, "r") as f:
                    for r, pad in enumerate(f["pads/index"][()]):
                        side[int(pad)] = {k: d[r] for k, d in f["global"].items() if d.ndim == 2}
    both = rows[0].keys() & rows[1].keys()
    return {
        "pads": len(both),
        "pads_missing": sorted(rows[0].keys() ^ rows[1].keys()),
        "pads_different": sorted(
            p for p in both if any(not same_bits(v, rows[1][p][k]) for k, v in rows[0][p].items())
        ),
        "files": files,
        "files_only_one": sorted(set(names) - set(files)),
    }


def compare(a: Path, b: Path) -> dict:
    """Differences between two run files: datasets (missing, different) and root attributes."""
    da, db = datasets(a), datasets(b)
    only_a, only_b = sorted(da.keys() - db.keys()), sorted(db.keys() - da.keys())
    differ = sorted(k for k in da.keys() & db.keys() if not same_bits(da[k], db[k]))
    aa, ab = root_attrs(a), root_attrs(b)
    attr_diff = sorted(k for k in aa.keys() | ab.keys() if aa.get(k) != ab.get(k))
    return {
        "datasets": len(da.keys() & db.keys()),
        "only_first": only_a,
        "only_second": only_b,
        "different": differ,
        # how far each differing float dataset is off: max |second − first| / max |first| (None: not comparable so)
        "largest_relative": {k: largest_relative(da[k], db[k]) for k in differ},
        "attrs_different": [k for k in attr_diff if k not in PROVENANCE],
        "attrs_provenance": [k for k in attr_diff if k in PROVENANCE],
    }


def same_results(r: dict) -> bool:
    """Whether a job's report (:func:`compare` or :func:`compare_sweeps`) found every dataset (every pad) equal."""
    if "pads" in r:
        return not (r["pads_missing"] or r["pads_different"])
    return not (r["different"] or r["only_first"] or r["only_second"])


def _with_sizes(r: dict) -> str:
    """The differing datasets of a :func:`compare` report, each with its largest relative difference where known."""
    sizes = r.get("largest_relative", {})
    return ", ".join(k + (f" (≤ {sizes[k]:.2g} relative)" if sizes.get(k) is not None else "") for k in r["different"])


def file_line(r: dict) -> str:
    """One line on a run file's comparison."""
    return (
        f"{r['datasets']} datasets, {'bit-identical' if same_results(r) else 'DIFFERENT'}"
        + (f"; differ: {_with_sizes(r)}" if r["different"] else "")
        + (f"; only in first: {r['only_first']}" if r["only_first"] else "")
        + (f"; only in second: {r['only_second']}" if r["only_second"] else "")
        + (f"; attributes differ: {r['attrs_different']}" if r["attrs_different"] else "")
    )


def sweep_line(r: dict) -> str:
    """One line on a sweep's comparison: its pads, then its shard files."""
    files = [f"{n}: {file_line(f)}" for n, f in r["files"].items() if not same_results(f) or f["attrs_different"]]
    return (
        f"{r['pads']} pads, {'bit-identical' if same_results(r) else 'DIFFERENT'}"
        + (f"; pads differ: {r['pads_different']}" if r["pads_different"] else "")
        + (f"; pads in one only: {r['pads_missing']}" if r["pads_missing"] else "")
        + f"; {len(r['files'])} shard files in both"
        + (f", {len(r['files_only_one'])} in one only" if r["files_only_one"] else "")
        + (f", of which differ: {'; '.join(files)}" if files else ", bit-identical")
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("first", type=Path, help="first checkout (e.g. a worktree of the old commit)")
    ap.add_argument("second", type=Path, help="second checkout")
    ap.add_argument("--out", type=Path, required=True, help="folder for the run files and report.json")
    ap.add_argument(
        "--jobs", nargs="+", choices=sorted(JOBS | EXTRA_JOBS), default=list(JOBS), help="jobs to run (default: JOBS)"
    )
    ap.add_argument("--cache", type=Path, default=None, help="kernel caches kept here (default: a temporary folder)")
    ap.add_argument(
        "--device", default="cpu", help="Warp device of every job (default cpu; cuda:0 compares the GPU's results)"
    )
    args = ap.parse_args(argv)
    refuse_bad_checkouts(ap, [args.first, args.second])  # every refusal before --out is made: nothing written
    for job, need in NEEDS.items():
        if job in args.jobs and need not in args.jobs[: args.jobs.index(job)]:
            ap.error(f"--jobs: {job} runs on the file that {need} writes; name {need} before it")
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_folder

    try:
        for folder in (args.out, args.cache):
            if folder is not None:
                check_output_folder(folder)
    except AcaError as e:
        ap.error(str(e))
    args.out.mkdir(parents=True, exist_ok=True)
    report: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        views = [package_view(c.resolve(), Path(tmp) / f"v{i}") for i, c in enumerate((args.first, args.second))]
        for job in args.jobs:
            spec = (JOBS | EXTRA_JOBS)[job]
            sweep = spec[0] == "sweep"
            if job in SPECS:
                (args.out / f"{job}.toml").write_text(SPECS[job])
            outs = [args.out / (f"{job}_{i}" if sweep else f"{job}_{i}.h5") for i in (0, 1)]
            for view, path, i in zip(views, outs, (0, 1), strict=True):
                if path.is_dir():
                    shutil.rmtree(path)
                path.unlink(missing_ok=True)
                cli = [arg.format(out=args.out.resolve()) for arg in spec] + ["--device", args.device]
                run_job(view, cli + (["--quiet"] if sweep else []), path, (args.cache or Path(tmp)) / f"cache{i}")
            report[job] = r = compare_sweeps(*outs) if sweep else compare(*outs)
            print(f"{job}: " + (sweep_line(r) if sweep else file_line(r)))
    (args.out / "report.json").write_text(json.dumps(report, indent=1))
    bad = any(not same_results(r) for r in report.values())
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
