"""``aca-warp hf`` and ``aca-warp rerun``: simulate one pad into a run file, resume it, or repeat a run.

Only argument parsing happens at import; the handlers import the simulation code when they run.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aca_warp.common.argtypes import (
    add_checkpoint_arguments,
    int_at_least,
    nonneg,
    positive,
    refuse_with_resume,
    spacing,
)
from aca_warp.common.errors import SceneError
from aca_warp.hf.options import (
    CROSSING_HELP,
    CROSSINGS,
    DEFAULT_DT,
    DEFAULT_INTEGRATOR,
    DEFAULT_SPLIT_TOLERANCE,
    DEFAULT_TOLERANCE,
    ENGINES,
    FAST_MATH_HELP,
    INTEGRATORS,
    PRESET_STEP,
    SOLVE_TOL_HELP,
    STATISTICS_STEP,
    STEP_CONTROLLED,
    THREE_STEP,
    crossing_words,
    growth_words,
    solve_tol_words,
)


def run_epilog(resume: str, lf: bool = False) -> str:
    """The help epilog of ``aca-warp`` and ``aca-warp hf``: SCENE, an example, the units and the exit codes;
    ``resume``: the command that continues an interrupted run (docs/faults.md); ``lf``: the LF scenes too."""
    scenes = (
        "\nThe LF automaton (aca-warp lf) takes the preset multiscale or a TOML file with an [lf] table"
        "\n(docs/lf_model.md); aca-warp hf LF.h5 --snapshot NAME runs HF on a state it saved."
        if lf
        else ""
    )
    return f"""\
SCENE is a preset (hf1, hf2, hf3, hf4, varying_area, and each as NAME_equal: every patch 3 µm high, docs/presets.md)
or a TOML scene file (docs/scenes.md).{scenes}
Example:  aca-warp hf hf1 --duration 1e-3 -o run.h5
Units are SI throughout: seconds, metres, newtons. Exit codes: 0 done, 2 bad input (nothing written),
3 the run stopped on a fault or an unphysical result (the file holds everything before it, marked incomplete),
4 the output cannot be written (read-only or full file system, no permission: found before the run, nothing
written; disk full or file-size limit during the run: the .partial keeps its last checkpoint),
130 interrupted by Ctrl-C, 143 by SIGTERM (the file closed and marked incomplete; {resume}
continues it from its last checkpoint, or from its start if it has none; docs/faults.md).
"""


EPILOG = run_epilog("aca-warp hf --resume RUN.h5") + (
    "Values far outside a brake pad's range are refused as likely unit mistakes unless --allow-implausible.\n"
)


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp hf`` and ``aca-warp rerun``."""
    hf = sub.add_parser(
        "hf",
        help="simulate the high-frequency patch vibrations of one pad into a run file",
        description="Simulate the HF vibrations of every patch of one pad (paper §2.1.2, §3.1) and "
        "write global mu, torque, friction radius and velocity sums (and per-patch histories "
        "when asked) to an HDF5 run file.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    _add_run_arguments(hf)
    _add_record_arguments(hf)
    _add_safety_arguments(hf)
    _add_file_arguments(hf)
    hf.set_defaults(handler=_cmd_hf)
    _add_rerun(sub)


def _add_run_arguments(hf: argparse.ArgumentParser) -> None:
    """``aca-warp hf``: the scene, output, duration, device and the solver's options."""
    hf.add_argument("scene", metavar="SCENE", nargs="?", help="preset name or TOML scene file (not with --resume)")
    hf.add_argument("-o", "--output", metavar="RUN.h5", help="run file to write (required unless --resume)")
    hf.add_argument("--duration", type=positive, metavar="S", help="simulated time [s] (default: the scene's)")
    hf.add_argument("--device", default="cpu", help="Warp device: cpu (default) or cuda:0, cuda:1, ...")
    hf.add_argument(
        "--integrator",
        choices=INTEGRATORS,
        default=DEFAULT_INTEGRATOR,
        help=f"time integrator (default {DEFAULT_INTEGRATOR}); step-controlled per pad: adaptive (explicit DP5), "
        "controlled (strang's step with an error-controlled step), auto (adaptive while every patch slides, "
        "controlled once a patch sticks); see docs/numerics.md",
    )
    hf.add_argument(
        "--dt",
        type=positive,
        metavar="S",
        help=f"fixed step [s]; default for strang with a preset's physics {THREE_STEP:.3g} (three steps a 1 us sample) "
        f"for hf1, hf3, hf4 and hf1-hf3 at equal heights, {PRESET_STEP:g} for hf2, hf4_equal, varying_area and the "
        f"multiscale LF states app1_end, app3_*, app4_*, and {STATISTICS_STEP:g} otherwise, the steps at which the "
        f"saturated statistics hold (the first two with --crossing mean, its default there; docs/numerics.md); "
        f"{DEFAULT_DT:g} for the other fixed-step integrators; the "
        f"first trial step of adaptive, controlled and auto; shortened to fit whole steps in a sample interval (a "
        f"shorter sample interval is refused, but strang's default follows one down to {STATISTICS_STEP:g})",
    )
    hf.add_argument(
        "--tolerance",
        type=positive,
        metavar="X",
        help=f"relative error tolerance of the explicit pair: adaptive, and auto while a pad slides (default "
        f"{DEFAULT_TOLERANCE:g}); refused with the other integrators",
    )
    hf.add_argument(
        "--split-tolerance",
        type=positive,
        metavar="X",
        help=f"tolerance of the error-controlled split step: controlled, and auto once a patch sticks (default "
        f"{DEFAULT_SPLIT_TOLERANCE:g}: the rms over a pad of each step's local velocity errors, relative to the "
        "patches' velocity scales); refused with the other integrators",
    )
    hf.add_argument(
        "--precision",
        choices=("fp32", "fp64"),
        help="state precision (default: fp32 for strang, where the saturated statistics were shown to hold at its "
        "default step, docs/work_precision_statistics.md; fp64 for the other integrators)",
    )
    hf.add_argument(
        "--engine",
        choices=ENGINES,
        default="auto",
        help="onchip: one thread block per pad (a cluster of up to 16 on sm_90+ for a few pads), many strang "
        "steps or adaptive trials per launch (faster than general; both grow patches too); general: per-step kernels "
        "(every integrator); auto (default): onchip where the run allows it (strang and adaptive, a pad that fits "
        "a block's shared memory), on CUDA and on the CPU (the same bits as general there, faster; docs/onchip.md)",
    )
    hf.add_argument("--fast-math", action="store_true", help=FAST_MATH_HELP)
    hf.add_argument("--crossing", choices=CROSSINGS, help=CROSSING_HELP)
    hf.add_argument("--solve-tol", type=positive, metavar="X", help=SOLVE_TOL_HELP)
    hf.add_argument(
        "--growth-dt",
        type=spacing,
        metavar="S",
        help="simulated time between the growth events of a growing scene [s] (default with strang: 5e-6, where "
        "the statistics of growing pads keep every measure at --dt 5e-8 and 1e-7 but the STFT maximum, which the "
        "pads that turn tonal leave undecided (docs/work_precision_statistics.md), or the scene's growth interval "
        "if longer or the run shorter; with the other integrators, or 'scene', the scene's interval, the paper's "
        "clock of 2.02e-7 s for varying_area); each event adds the increment scaled to the spacing, so growth per "
        "simulated time stays the scene's (docs/model.md 2.10); events come every whole number of steps, at least "
        "one (the summary line gives the spacing taken); events cost several steps each; refused for a scene that "
        "does not grow",
    )


def _add_record_arguments(hf: argparse.ArgumentParser) -> None:
    """``aca-warp hf``: what the run file records (sample interval, per-patch histories)."""
    hf.add_argument(
        "--sample-dt",
        type=positive,
        metavar="S",
        help="interval of the recorded samples [s] (default: the scene's, 1e-6 for the presets)",
    )
    hf.add_argument(
        "--record-patches",
        metavar="VARS",
        help="record per-patch histories: velocity, displacement or velocity,displacement; none: no per-patch "
        "histories (a scene's own per-patch record off); default: the scene's (none for the presets)",
    )
    hf.add_argument(
        "--patch-window",
        type=nonneg,
        nargs=2,
        metavar=("T0", "T1"),
        help="time window of the per-patch histories [s] (default: the scene's, the whole run for the presets)",
    )
    hf.add_argument(
        "--patch-decimation",
        type=int_at_least(1),
        metavar="N",
        help="record per-patch histories every N-th sample (default: the scene's, 1 for the presets)",
    )


def _add_safety_arguments(hf: argparse.ArgumentParser) -> None:
    """``aca-warp hf``: the overrides of the run's limits and checks, and the LF snapshot to start from."""
    hf.add_argument(
        "--force",
        action="store_true",
        help="run a step beyond the stable-step estimate (warns), or a run beyond the size limits (1e10 steps, "
        "50 GB of samples)",
    )
    hf.add_argument(
        "--accept-unphysical",
        action="store_true",
        help="run on, with a warning, where the physical sanity checks would stop the run (normal forces that do "
        "not carry the load, mu beyond its bound; docs/faults.md)",
    )
    hf.add_argument(
        "--snapshot", metavar="NAME", help="SCENE is an LF run file (.h5): run HF on its snapshot NAME (aca-warp lf)"
    )
    hf.add_argument(
        "--allow-implausible",
        action="store_true",
        help="run values far outside a brake pad's range (pad radius beyond 2 m, patch areas beyond 1e-3 m^2, loads "
        "beyond 1e6 N, ...), refused otherwise as likely unit mistakes; sets the scene's allow_implausible "
        "(docs/scenes.md)",
    )


def _add_file_arguments(hf: argparse.ArgumentParser) -> None:
    """``aca-warp hf``: overwriting, progress, checkpoints and resuming."""
    hf.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    hf.add_argument("--no-progress", action="store_true",
                    help="no progress: no bar on a terminal, no line every 30 s where stderr is a log")  # fmt: skip
    add_checkpoint_arguments(hf, "solver")
    hf.add_argument(
        "--resume",
        metavar="RUN.h5",
        help="continue a killed or stopped run (RUN.h5 or RUN.h5.partial) from its last checkpoint (from its start "
        "if it has none), with the run's own scene and settings; the finished file equals an uninterrupted run",
    )


def _cmd_hf(args: argparse.Namespace) -> int:
    from aca_warp.common.files import check_not_input, check_output_path
    from aca_warp.hf.options import SCENE_CLOCK, RunOptions
    from aca_warp.hf.runner import run_scene

    if args.resume is not None:
        return _resume_hf(args)
    if args.scene is None or args.output is None:
        raise SceneError("hf needs SCENE and -o RUN.h5 (or --resume RUN.h5 to continue a run)")
    for flag, value, takes in (
        ("--tolerance", args.tolerance, ("adaptive", "auto")),
        ("--split-tolerance", args.split_tolerance, ("controlled", "auto")),
    ):
        if value is not None and args.integrator not in takes:
            kind = "chooses its steps otherwise" if args.integrator in STEP_CONTROLLED else "takes fixed steps (--dt)"
            raise SceneError(
                f"{flag} applies to --integrator {' or '.join(takes)} only; {args.integrator} {kind}: drop {flag} "
                f"or choose one of those"
            )
    what = "LF run file" if args.snapshot is not None else "scene file"
    check_not_input(args.output, {what: args.scene}, "hf")
    check_output_path(args.output, overwrite=args.overwrite)
    scene, duration = _hf_scene(args)
    check_not_input(args.output, {"patch file": scene.patches.source}, "hf")
    if args.growth_dt == SCENE_CLOCK:  # the scene's own clock, written out (run_scene writes out the defaults)
        if scene.growth is None:
            raise SceneError("--growth-dt scene sets the spacing of growth events; the scene does not grow")
        args.growth_dt = scene.growth.interval
    options = RunOptions(
        duration=duration,
        integrator=args.integrator,
        dt=args.dt,
        tolerance=DEFAULT_TOLERANCE if args.tolerance is None else args.tolerance,
        split_tolerance=DEFAULT_SPLIT_TOLERANCE if args.split_tolerance is None else args.split_tolerance,
        force=args.force,
        engine=args.engine,
        checkpoint_interval=args.checkpoint_interval,
        accept_unphysical=args.accept_unphysical,
        fast_math=args.fast_math,
        growth_dt=args.growth_dt,
        crossing=args.crossing,
        solve_tol=args.solve_tol,
    )
    result = run_scene(
        scene,
        args.output,
        options,
        device=args.device,
        precision=args.precision,
        overwrite=args.overwrite,
        progress=not args.no_progress,
        announce=_announce(args.output, not args.no_progress, lambda plan: _run_notes(plan, scene, duration, args)),
    )
    return _summarise_hf(args, scene, result, duration)


def _hf_scene(args: argparse.Namespace) -> tuple[Any, float]:
    """The scene of ``aca-warp hf`` (preset, TOML file or LF snapshot) with the command line's duration and
    recording options applied, and its duration [s]; SceneError where they contradict each other."""
    import dataclasses

    from aca_warp.scene import Record, load_scene

    if args.snapshot is not None or str(args.scene).endswith(".h5"):
        from aca_warp.lf.io import scene_from_snapshot

        if args.snapshot is None:
            from aca_warp.lf.io import snapshot_names

            names = snapshot_names(args.scene)  # one line of its own for a file that is no LF run
            held = f" (it holds {', '.join(names)})" if names else " (it holds none)"
            raise SceneError(f"{args.scene} is an LF run file: name a snapshot with --snapshot NAME{held}")
        if not Path(args.scene).exists() and not str(args.scene).endswith(".h5"):
            raise SceneError(
                f"--snapshot takes a pad from an LF run file: SCENE is then LF.h5, not {args.scene!r} (an LF run "
                "writes one: 'aca-warp lf multiscale -o LF.h5')"
            )
        scene = scene_from_snapshot(args.scene, args.snapshot, allow_implausible=args.allow_implausible)
    else:
        scene = load_scene(args.scene, allow_implausible=args.allow_implausible)
    rec = scene.record
    changes = _record_changes(args)
    if not changes.get("patches", rec.patches) and (args.patch_window or args.patch_decimation):
        given = "--patch-window" if args.patch_window else "--patch-decimation"
        raise SceneError(
            f"{given} applies to per-patch histories, which this run does not record: add --record-patches velocity "
            "(or velocity,displacement)"
        )
    duration = args.duration if args.duration is not None else scene.duration
    record = Record(**{**dataclasses.asdict(rec), **changes})
    # before the scene's check, naming the flags given and the scene's fields for what the scene set
    record.check_duration(
        duration,
        "--sample-dt" if args.sample_dt is not None else "the scene's record.sample_dt",
        "--duration" if args.duration is not None else "the scene's run.duration",
    )
    scene = scene.replace(duration=duration, record=record)
    return scene, duration


def _patch_variables(given: str) -> tuple[str, ...]:
    """The per-patch variables of ``--record-patches`` (comma-separated, each once; ``none`` alone: none); an empty
    value is refused, so that a stray quoting mistake does not silently turn a scene's per-patch record off."""
    from aca_warp.scene.parts import check_patch_variables

    if given.strip() == "none":
        return ()
    names = tuple(dict.fromkeys(v.strip() for v in given.split(",") if v.strip()))  # in order, each once
    if not names:
        raise SceneError(
            "--record-patches: give velocity, displacement or velocity,displacement, or none for no per-patch histories"
        )
    if "none" in names:
        raise SceneError(f"--record-patches {given}: none stands alone (no per-patch histories); or name the variables")
    check_patch_variables(names, "--record-patches")
    return names


def _record_changes(args: argparse.Namespace) -> dict:
    """The fields of the scene's Record that the command line sets (--sample-dt, --record-patches, --patch-window,
    --patch-decimation)."""
    changes: dict = {}
    if args.sample_dt is not None:
        changes["sample_dt"] = args.sample_dt
    if args.record_patches is not None:
        changes["patches"] = _patch_variables(args.record_patches)
    if args.patch_window is not None:
        t0, t1 = args.patch_window
        if not t1 > t0:
            raise SceneError(f"--patch-window: the end T1 must exceed the start T0, got {t0:g} {t1:g} [s]")
        changes["window"] = (t0, t1)
    if args.patch_decimation is not None:
        changes["decimation"] = args.patch_decimation
    return changes


def _summarise_hf(args: argparse.Namespace, scene: Any, result: Any, duration: float) -> int:
    """Print the summary line of a finished or stopped ``aca-warp hf`` run (its precision and growth spacing as
    its file records them, the defaults written out); the exit code (0 done, 3 stopped)."""
    import h5py
    import numpy as np

    from aca_warp.common.files import attr_value

    with h5py.File(args.output, "r") as f:
        mu = f["global/mu"][()]
        precision = attr_value(f.attrs["precision"])
        stored = attr_value(f.attrs["run_options"])
        growth_dt, crossing = stored.get("growth_dt"), stored.get("crossing")
    n = scene.patches.count
    rate = n * result.steps / max(result.wall_time, 1e-12)
    line = (
        f"{args.output}: {len(mu)} samples over {result.sim_time:.4g} s, {result.steps} steps "
        f"({result.dt:.3g} s{_default_step_words(args, scene, result.dt)}, {args.integrator}, {precision}"
        f"{', fast math' if args.fast_math else ''}"
        f"{crossing_words(crossing)}"
        f"{solve_tol_words(args.solve_tol)}"
        f"{growth_words(growth_dt, None if args.integrator in STEP_CONTROLLED else result.dt)}), "
        f"mean mu {np.mean(mu):.4f}, "
        f"{rate:.3g} patch-steps/s"
    )
    if result.fault is not None:
        print(f"aca-warp: run stopped: {result.fault}", file=sys.stderr)
        print(line + stopped_at(result.sim_time, duration))
        return 3
    print(line)
    return 0


def _default_step_words(args: argparse.Namespace, scene: Any, dt: float) -> str:
    """Why a ``strang`` run without ``--dt`` took its step ``dt`` [s], for the summary line (nothing when --dt was
    given): the default step, the sample interval where that is shorter, or the default shortened so that whole
    steps fill a sample interval."""
    if args.dt is not None or args.integrator != "strang":
        return ""
    from aca_warp.hf.options import default_step
    from aca_warp.scene.regimes import preset_regime

    regime = preset_regime(scene)
    whose = f"{regime}'s physics" if regime else "a scene outside the regimes the statistics measured"
    default = default_step("strang", [scene])
    if math.isclose(dt, default, rel_tol=1e-9):
        return f", the default step for {whose}"
    if math.isclose(dt, scene.record.sample_dt, rel_tol=1e-9):
        return f", the sample interval, shorter than the default step for {whose} ({default:.3g} s)"
    return f", the default step for {whose} ({default:.3g} s) shortened to fill the sample interval in whole steps"


def stopped_at(sim_time: float, duration: float | None) -> str:
    """The end of the summary line of a run that stopped early: where it stopped, of what was asked."""
    asked = "" if duration is None else f" of the requested {duration:.4g} s"
    return f"; stopped at t = {sim_time:.4g} s{asked} (incomplete)"


LARGE_OUTPUT_BYTES = 1e9  # a run that records this much says so before it starts, on a terminal or not [B]


def _run_notes(plan: Any, scene: Any, duration: float, args: argparse.Namespace) -> list[str]:
    """What the run of ``plan`` (:class:`~aca_warp.hf.runner.RunPlan`) on ``scene`` does otherwise than asked, in
    words: a ``duration`` [s] that its whole sample intervals round, a ``--dt`` shortened so that whole steps fill a
    sample interval, a ``--checkpoint-interval`` shorter than a sample interval (a checkpoint then follows every
    sample). A default step shortened so is named by the summary line."""
    from aca_warp.common.checkpoint import frequent_note

    sample_dt, checkpoint_interval = scene.record.sample_dt, args.checkpoint_interval
    n = plan.samples - 1  # whole sample intervals
    notes = []
    if args.dt is not None and plan.step is not None and not math.isclose(plan.step, args.dt, rel_tol=1e-9):
        notes.append(f"--dt {args.dt:g} s is run as {plan.step:.3g} s, so that whole steps fill a sample interval "
                     f"of {sample_dt:g} s")  # fmt: skip
    if abs(n * sample_dt - duration) > 1e-9 * duration:
        whole = f"{n} whole sample interval{'s' if n != 1 else ''}"
        notes.append(f"{duration:g} s is run as {whole} of {sample_dt:g} s: {n * sample_dt:.6g} s")
    return notes + frequent_note(checkpoint_interval, sample_dt, "a sample interval", "sample")


def _announce(output: str, progress: bool, notes: Callable[[Any], list[str]]) -> Any:
    """What to do with the plan of a validated run: its ``notes`` on stderr (:func:`_run_notes`), then a line on
    stderr before it starts, on a terminal with progress shown (before the bar), and wherever stderr goes for a run
    that records :data:`LARGE_OUTPUT_BYTES` or more (a log then says what is coming; otherwise the summary line at
    the end says the same)."""
    shown = progress and sys.stderr.isatty()

    def say(plan: Any) -> None:
        for note in notes(plan):
            print(f"aca-warp: note: {note}", file=sys.stderr, flush=True)
        if shown or plan.output_bytes >= LARGE_OUTPUT_BYTES:
            print(f"aca-warp: {output}: {plan.describe()}", file=sys.stderr, flush=True)

    return say


def _resume_hf(args: argparse.Namespace) -> int:
    """``aca-warp hf --resume RUN.h5``: the run's own settings; only --device, --checkpoint-interval, --no-progress."""
    from aca_warp.hf.options import DEFAULT_INTEGRATOR
    from aca_warp.hf.runner import resume_run

    refuse_with_resume(
        (
            ("SCENE", args.scene, None),
            ("-o", args.output, None),
            ("--duration", args.duration, None),
            ("--dt", args.dt, None),
            ("--sample-dt", args.sample_dt, None),
            ("--record-patches", args.record_patches, None),
            ("--patch-window", args.patch_window, None),
            ("--patch-decimation", args.patch_decimation, None),
            ("--integrator", args.integrator, DEFAULT_INTEGRATOR),
            ("--tolerance", args.tolerance, None),
            ("--split-tolerance", args.split_tolerance, None),
            ("--precision", args.precision, None),
            ("--force", args.force, False),
            ("--accept-unphysical", args.accept_unphysical, False),
            ("--allow-implausible", args.allow_implausible, False),
            ("--overwrite", args.overwrite, False),
            ("--engine", getattr(args, "engine", "auto"), "auto"),
            ("--fast-math", args.fast_math, False),
            ("--crossing", args.crossing, None),
            ("--solve-tol", args.solve_tol, None),
            ("--growth-dt", args.growth_dt, None),
        ),
        "the run",
    )
    from aca_warp.common.files import find_resumable, resumed_from

    final, part = find_resumable(args.resume)
    if _is_lf(part if part.exists() else final):
        raise SceneError(f"{args.resume} is an LF run: continue it with 'aca-warp lf --resume {args.resume}'")
    start = resumed_from(args.resume)  # before the resume writes its own checkpoints
    result, path = resume_run(
        args.resume,
        progress=not args.no_progress,
        checkpoint_interval=args.checkpoint_interval,
        device=None if args.device == "cpu" else args.device,
    )
    line = f"{path}: resumed{' ' + start if start else ''}, {result.steps} steps over {result.sim_time:.4g} s"
    import h5py
    import numpy as np

    with h5py.File(path, "r") as f:  # the whole run's, as a fresh run's summary gives it
        mu = f["global/mu"][()]
    line += f", {len(mu)} samples, mean mu {np.mean(mu):.4f}"
    if result.fault is not None:
        print(f"aca-warp: run stopped: {result.fault}", file=sys.stderr)
        from aca_warp.hf.rerun import read_settings

        print(line + stopped_at(result.sim_time, read_settings(path).options.duration))
        return 3
    print(line)
    return 0


def _add_rerun(sub: Any) -> None:
    """Register ``aca-warp rerun`` (HF and LF run files)."""
    p = sub.add_parser(
        "rerun",
        help="repeat a run from its run file (HF or LF: scene, patches, integrator, precision, device)",
        description="Repeat the run stored in RUN.h5 into NEW.h5: same scene (patches from the file), integrator, "
        "run options, precision and device. On the same device and precision the samples are bit-identical. "
        "Stored options that relax a check (force, the watchdog off, accept_unphysical, allow_implausible) are "
        "applied and named on stderr; the size limits hold unless --force is given here.",
    )
    p.add_argument("run", metavar="RUN.h5", help="run file to repeat")
    p.add_argument("-o", "--output", required=True, metavar="NEW.h5", help="run file to write")
    p.add_argument("--device", help="Warp device (default: the one the run used)")
    add_checkpoint_arguments(p, "solver")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.add_argument("--no-progress", action="store_true", help="no progress (as for aca-warp hf)")
    p.add_argument(
        "--force",
        action="store_true",
        help="repeat a run beyond the size limits (1e10 steps, 50 GB of samples, the free space, a sample interval "
        "shorter than the step); a force stored in the run file does not lift them",
    )
    p.set_defaults(handler=_cmd_rerun)


def _is_lf(path: str | Path) -> bool:
    """Whether ``path`` is an LF run file (root attribute ``kind = "lf"``); False when it cannot be read."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("kind") == "lf"
    except (OSError, ValueError, RuntimeError, KeyError):
        return False


def _cmd_rerun(args: argparse.Namespace) -> int:
    import dataclasses

    from aca_warp.analysis.groups import missing_run_message
    from aca_warp.analysis.pads import shard_pads
    from aca_warp.common.files import check_not_input, check_output_path, version_changes
    from aca_warp.hf.rerun import read_settings, relaxed_checks
    from aca_warp.hf.runner import run_scene

    said = missing_run_message(args.run)  # a folder, a pipe, a killed run's .partial: before anything opens it
    if said is not None:
        raise SceneError(said)
    pads = shard_pads(args.run)
    if pads is not None:
        from aca_warp.sweep.spec import pad_list

        raise SceneError(
            f"{args.run} is a sweep shard (pads {pad_list(pads)}), not a run: run its sweep again with "
            "'aca-warp sweep SPEC -o DIR' (finished shards are skipped; remove this one's file to redo it), or take "
            f"one pad out as a run file with 'aca-warp analyze {args.run} --pad K' and rerun that"
        )
    if _is_lf(args.run):
        from aca_warp.lf.commands import rerun_lf

        return rerun_lf(
            args.run, args.output, device=args.device, checkpoint_interval=args.checkpoint_interval,
            overwrite=args.overwrite, progress=not args.no_progress,
        )  # fmt: skip
    check_not_input(args.output, {"run file": args.run}, "rerun")
    check_output_path(args.output, overwrite=args.overwrite)
    s = read_settings(args.run)
    changed = version_changes(s.versions)
    if changed:
        print(f"aca-warp: note: versions differ from the run's: {', '.join(changed)}", file=sys.stderr)
    relaxed = relaxed_checks(s)
    if relaxed:
        print(f"aca-warp: note: {args.run} stores, and the rerun applies: {'; '.join(relaxed)}", file=sys.stderr)
    options = s.options
    if args.checkpoint_interval is not None:
        options = dataclasses.replace(options, checkpoint_interval=args.checkpoint_interval)
    result = run_scene(
        s.scene,
        args.output,
        options,
        device=s.device_for(args.device, args.run),
        precision=s.precision,
        overwrite=args.overwrite,
        progress=not args.no_progress,
        force_limits=args.force,
    )
    line = f"{args.output}: rerun of {args.run}, {result.steps} steps over {result.sim_time:.4g} s"
    if result.fault is not None:
        print(f"aca-warp: run stopped: {result.fault}", file=sys.stderr)
        print(line + stopped_at(result.sim_time, options.duration))
        return 3
    print(line)
    return 0
