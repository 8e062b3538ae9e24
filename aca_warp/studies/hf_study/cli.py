"""The paper's stand-alone HF study (§3.1, Figs. 8-9) and a patch-area sweep, with summaries beside the paper's.

Its command line (``scripts/hf_study.py``): the options, the defaults that depend on ``--quick`` and on the machine,
their checks, and :func:`main`, which runs the stages of :mod:`aca_warp.studies.hf_study` in order.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aca_warp.common.argtypes import int_at_least, nonneg, positive
from aca_warp.hf.options import INTEGRATORS
from aca_warp.studies.hf_study.base import (
    DEFAULT_PRESSURE,
    FULL_DURATION,
    FULL_TRANSIENT,
    NOMINAL_PATCHES,
    PRESET_NAMES,
    QUICK_DURATION,
    QUICK_TRANSIENT,
)
from aca_warp.studies.hf_study.page import write_archive, write_outputs
from aca_warp.studies.hf_study.stages import new_study, run_presets, run_sweep
from aca_warp.studies.report import Log


class _Help(argparse.ArgumentDefaultsHelpFormatter):
    """Shows defaults, except None (those helps say what None means)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        return action.help if action.default is None else super()._get_help_string(action)


def build_parser() -> argparse.ArgumentParser:
    """The command line of the study."""
    p = argparse.ArgumentParser(
        prog="hf_study.py",
        description=__doc__.split("\n\n")[0] + " Writes run files, figures, study.json and results.md into --outdir.",
        epilog="Full study on an H100: about 9 runs of 2e5 steps each plus analysis and figures (a few minutes). "
        "--quick on a 2-core CPU: a few minutes. See the docstring of aca_warp.studies.hf_study for the stages.",
        formatter_class=_Help,
    )
    p.add_argument("--outdir", type=Path, default=Path("out/hf_study"), help="output folder (created)")
    p.add_argument("--device", default="auto", help="Warp device: cpu, cuda:0, or auto (cuda:0 when present)")
    p.add_argument("--precision", choices=("fp64", "fp32"), default="fp64", help="floating-point precision")
    p.add_argument("--integrator", default="strang", choices=INTEGRATORS, help="HF integrator (see aca-warp hf --help)")
    p.add_argument("--dt", type=positive, default=1.0e-8, help="time step [s]")
    p.add_argument(
        "--quick",
        action="store_true",
        help=f"short CPU version: --duration {QUICK_DURATION:g}, --transient {QUICK_TRANSIENT:g} unless given",
    )
    p.add_argument(
        "--duration",
        type=positive,
        default=None,
        help=f"simulated time per run [s] (default {FULL_DURATION:g}; {QUICK_DURATION:g} with --quick)",
    )
    p.add_argument(
        "--transient",
        type=nonneg,
        default=None,
        help="start of the per-patch velocity record [s]; earlier samples are left out of the per-patch "
        f"spectra and S(f) (default {FULL_TRANSIENT:g}; {QUICK_TRANSIENT:g} with --quick)",
    )
    p.add_argument("--sample-dt", type=positive, default=2.0e-7, help="sampling interval of the global outputs [s]")
    p.add_argument(
        "--decimation", type=int_at_least(1), default=1, help="record per-patch velocities every N-th global sample"
    )
    p.add_argument(
        "--band",
        type=nonneg,
        nargs=2,
        default=(1.0e3, 5.0e5),
        metavar=("FMIN", "FMAX"),
        help="band of S(f), the CWT and the peak search [Hz]",
    )
    p.add_argument("--rule", choices=("relative", "snr"), default="relative", help="Phi rule of S(f)")
    p.add_argument(
        "--phi-min",
        type=int_at_least(0),
        default=10,
        help="prevalence level: S statistics use the bins with Phi >= this",
    )
    _add_run_selection(p)
    _add_sweep_options(p)
    _add_file_options(p)
    return p


def _add_run_selection(p: argparse.ArgumentParser) -> None:
    """Which presets run, with how many patches, and which figures they get."""
    p.add_argument(
        "--presets",
        nargs="*",
        choices=PRESET_NAMES,
        default=list(PRESET_NAMES),
        help="presets to run (none: only the sweep)",
    )
    p.add_argument(
        "--patches",
        type=int_at_least(2),
        default=None,
        help=f"patches per pad instead of {NOMINAL_PATCHES} (loads scaled to keep the pressure); for tests",
    )
    p.add_argument(
        "--figures",
        nargs="*",
        default=None,
        help="figures of plot_run per preset (default: all; none: no figures); e.g. spectra sync",
    )


def _add_sweep_options(p: argparse.ArgumentParser) -> None:
    """The area sweep: its points, friction factor, speed, pressure and patch seed."""
    p.add_argument("--skip-sweep", action="store_true", help="leave out the area sweep")
    p.add_argument(
        "--sweep-areas",
        type=positive,
        nargs="+",
        default=[0.05, 0.125, 0.3, 0.6, 1.25],
        metavar="MM2",
        help="mean patch areas of the sweep [mm²], each range [0.4, 1.6] x mean",
    )
    p.add_argument("--sweep-M", type=positive, default=0.8, help="friction factor M of the sweep")
    p.add_argument("--sweep-speed", type=positive, default=10.0, help="sliding speed of the sweep at r = 0.13 m [m/s]")
    p.add_argument(
        "--sweep-pressure",
        type=positive,
        default=DEFAULT_PRESSURE,
        help="mean patch pressure of the sweep F_N / (N mean area) [Pa] (hf1's)",
    )
    p.add_argument("--seed", type=int_at_least(0), default=1, help="patch generator seed of the sweep (presets: 1)")


def _add_file_options(p: argparse.ArgumentParser) -> None:
    """Run files kept, reused or deleted; the archive; progress bars."""
    p.add_argument(
        "--reuse",
        action="store_true",
        help="reuse complete run files found in <outdir>/runs (analysis and figures are redone)",
    )
    p.add_argument("--delete-runs", action="store_true", help="delete each run file once analysed and plotted")
    p.add_argument(
        "--archive",
        type=Path,
        default=None,
        help="also write a .tar.gz of the outdir without run files (figures, study.json, results.md); split into "
        "ARCHIVE-part1.tar.gz, -part2, ... when the files exceed --archive-max-mib",
    )
    p.add_argument("--archive-max-mib", type=positive, default=15.0, help="largest archive part [MiB]")
    p.add_argument("--progress", action="store_true", help="show a progress bar per simulation")


def resolve(args: argparse.Namespace, wp: Any) -> argparse.Namespace:
    """Fill in the defaults that depend on --quick and on the machine; validate (one line on stderr and exit code 2,
    or 4 for an output folder that takes no file, before anything is written)."""
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import AcaError
    from aca_warp.common.files import check_output_folder
    from aca_warp.plots import FIGURES

    if args.duration is None:
        args.duration = QUICK_DURATION if args.quick else FULL_DURATION
    if args.transient is None:
        args.transient = QUICK_TRANSIENT if args.quick else FULL_TRANSIENT
    if args.device == "auto":
        args.device = "cuda:0" if wp.is_cuda_available() else "cpu"
    problems, code = [], 2
    if args.figures is None:
        args.figures = list(FIGURES)
    unknown = [f for f in args.figures if f not in FIGURES]
    if unknown:
        problems.append(f"unknown figure(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    if not args.transient < args.duration:
        problems.append("--transient must lie in [0, duration)")
    if not args.band[1] > args.band[0]:
        problems.append("--band needs 0 <= FMIN < FMAX")
    per_patch = (args.duration - args.transient) / (args.sample_dt * args.decimation)
    if per_patch < 16:
        problems.append(f"the per-patch record would hold {per_patch:.0f} samples; need >= 16")
    for check, value in ((get_device, args.device), (check_output_folder, args.outdir)):
        try:
            check(value)
        except AcaError as e:
            problems.append(str(e))
            code = max(code, e.exit_code)
    if problems:
        print("hf_study.py: error: " + "; ".join(problems), file=sys.stderr)
        raise SystemExit(code)
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the study; returns 0 when every run completed, 1 otherwise."""
    from aca_warp.studies.report import init_warp

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    wp = init_warp()
    args = resolve(args, wp)
    log = Log()
    outdir: Path = args.outdir
    (outdir / "runs").mkdir(parents=True, exist_ok=True)
    study = new_study(args, argv, wp.get_device(args.device))
    log(
        f"hf_study: {len(args.presets)} preset(s), {0 if args.skip_sweep else len(args.sweep_areas)} sweep point(s) "
        f"on {study['machine']['device_name']} ({args.device}), Warp {wp.__version__}, {args.precision}, "
        f"{args.integrator} "
        f"dt {args.dt:g} s, {args.duration:g} s per run, per-patch record {args.transient:g}–{args.duration:g} s "
        f"-> {outdir}"
    )
    all_ok = run_presets(study, args, log)
    if not args.skip_sweep:
        all_ok &= run_sweep(study, args, log)
    study["complete"] = all_ok
    write_outputs(study, outdir, log)
    log(f"wrote {outdir / 'study.json'} and {outdir / 'results.md'}")
    if args.archive is not None:
        write_archive(outdir, args.archive, args.archive_max_mib, log)
    for c in study["comparisons"]:
        verdict = "n/a" if c["result"] is None else ("yes" if c["result"] else "no")
        print(f"  {verdict:3}  {c['claim']}: {c['numbers']}")
    log("done" if all_ok else "done, but some runs stopped early (see study.json)")
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main())
