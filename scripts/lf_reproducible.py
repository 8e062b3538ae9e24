#!/usr/bin/env python3
"""Run the LF automaton of the multi-timescale experiments several times per seed and compare the run files bit for
bit: the check that an LF run is reproducible on a device (docs/lf_model.md, "Reproducibility").

Each run is the ``multiscale`` preset with ``[lf] seed`` and ``[patches] seed`` set to the seed, as the §3.3
experiments make them (``aca_warp.studies.validation.multiscale.lf_scene``), written by ``aca_warp.lf.commands.run_lf``
into ``OUT/seed<S>_run<K>.h5``; every dataset of runs 2, 3, … is compared with run 1's (dtype, shape, every bit;
``scripts/compare_checkouts.py``). One line per seed; exit code 0 when every seed's runs are bit-identical, 1 when
any differ, 2 on bad arguments. Examples::

    python3 scripts/lf_reproducible.py --device cuda:0 --seeds 1 2 3 4 5 6 7 8 --runs 3 --out lf_repro
    python3 scripts/lf_reproducible.py --device cpu --seeds 1 --runs 2 --duration 0.5   # small, on the CPU

``--duration`` [s] runs only the first part of the schedule (default: the whole schedule, 55 s, 5500 steps).

``--digests RESULTS.json`` also checks each seed's first run against the LF runs a validation results file was cut
from: its §3.3 results record a content digest per LF run file (``lf_runs``; the whole preset schedule's files are
named ``lf_full_preset_seed<S>.h5``), and a run that reproduces the committed states bit for bit has the same
digest (a run cut short by ``--duration`` is compared with the same names, so it matches only digests of runs
as short; a seed whose file the results do not record is a bad argument, found before any run). Example (the
committed validation page's LF states, on the kind of device they were made on)::

    python3 scripts/lf_reproducible.py --device cuda:0 --seeds 1 2 3 4 5 6 7 8 --digests docs/validation/results.json
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from compare_checkouts import compare, file_line, same_results


def recorded_digests(path: Path) -> dict[str, str]:
    """File name → digest of every LF run that a validation results file's experiments record (``lf_runs``);
    a file recorded with two digests is an error (the results were not cut from one set of LF runs; the check the
    validation's join makes, :func:`~aca_warp.studies.validation.multiscale.lf_conflicts`); ``.json`` or its gzip."""
    import gzip
    import json

    from aca_warp.studies.validation.multiscale import lf_conflicts

    raw = path.read_bytes()
    results = json.loads(gzip.decompress(raw) if path.suffix == ".gz" else raw).get("results", {})
    runs = {name: res.get("lf_runs") or {} for name, res in results.items()}
    clash = lf_conflicts(runs)
    if clash:
        raise ValueError(f"{path}: LF runs recorded with two digests: {'; '.join(clash)}")
    return {file: digest for files in runs.values() for file, digest in files.items()}


def recorded_name(seed: int) -> str:
    """The name under which a validation results file records the LF run of ``seed`` (the preset's schedule)."""
    from aca_warp.studies.validation.base import Config
    from aca_warp.studies.validation.multiscale import lf_path

    return lf_path(Config(lf_dir=Path(".")), seed, None).name


def run_seed(
    seed: int, runs: int, out: Path, device: str, duration: float | None, recorded: dict[str, str] | None
) -> tuple[bool, str]:
    """``runs`` LF runs of ``seed`` into ``out``; (whether all are bit-identical to the first, and where
    ``recorded`` is given (it must hold :func:`recorded_name` of ``seed``), whether the first has the recorded
    digest; one line)."""
    from aca_warp.lf.commands import run_lf
    from aca_warp.studies.validation.multiscale import lf_file_digest, lf_scene

    paths, walls = [], []
    for k in range(runs):
        path = out / f"seed{seed}_run{k + 1}.h5"
        t0 = time.perf_counter()
        run_lf(lf_scene(seed, None, None), path, duration=duration, device=device, overwrite=True)
        walls.append(time.perf_counter() - t0)
        paths.append(path)
    reports = [compare(paths[0], p) for p in paths[1:]]
    same = all(same_results(r) for r in reports)
    lines = [f"run {k + 2}: {file_line(r)}" for k, r in enumerate(reports) if not same_results(r)]
    head = f"seed {seed}: {runs} runs ({', '.join(f'{w:.1f}' for w in walls)} s), "
    datasets = reports[0]["datasets"] if reports else 0
    line = head + (f"{datasets} datasets each, bit-identical" if same else "; ".join(lines))
    if recorded is None:
        return same, line
    name = recorded_name(seed)
    digest = lf_file_digest(paths[0])
    match = digest == recorded[name]
    return same and match, line + f"; digest {digest} {'==' if match else '!='} recorded {recorded[name]} ({name})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="seeds (default 1 2)")
    ap.add_argument("--runs", type=int, default=2, help="runs per seed, at least 2 (default 2)")
    ap.add_argument("--duration", type=float, help="simulated time [s] (default: the whole schedule)")
    ap.add_argument("--out", type=Path, help="folder for the run files (default: a temporary folder, removed)")
    ap.add_argument(
        "--digests",
        type=Path,
        metavar="RESULTS.json",
        help="also check each seed's first run against the LF run digests a validation results file records",
    )
    args = ap.parse_args(argv)
    if args.runs < 2:
        ap.error(f"--runs must be at least 2, not {args.runs}")
    if args.duration is not None and not args.duration > 0:
        ap.error(f"--duration must be a positive number of seconds, not {args.duration}")
    if any(s < 0 for s in args.seeds):
        ap.error("--seeds must be non-negative integers")
    recorded = None
    if args.digests is not None:
        try:
            recorded = recorded_digests(args.digests)
        except (OSError, ValueError, AttributeError) as e:
            ap.error(f"--digests: {e}")
        if not recorded:
            ap.error(f"--digests: {args.digests} records no LF runs")
        missing = [recorded_name(s) for s in args.seeds if recorded_name(s) not in recorded]
        if missing:
            ap.error(f"--digests: {args.digests} records no LF run {', '.join(missing)}")
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_folder

    try:  # every refusal before the first run: nothing run, nothing written
        get_device(args.device)
        if args.out is not None:
            check_output_folder(args.out)
    except AcaError as e:
        ap.error(str(e))
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        ok = True
        for seed in args.seeds:
            same, line = run_seed(seed, args.runs, out, args.device, args.duration, recorded)
            print(line, flush=True)
            ok = ok and same
    if ok:
        print("all bit-identical" + (", with the recorded digests" if recorded else ""), flush=True)
    else:
        print("runs DIFFER" + (" or do not have the recorded digests" if recorded else ""), flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
