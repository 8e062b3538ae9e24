"""``aca-warp lf SCENE -o LF.h5 [--duration S]``: run the LF automaton over a load schedule into an LF run file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aca_warp.common.argtypes import add_checkpoint_arguments, positive, refuse_with_resume

EPILOG = """\
SCENE is the preset multiscale (paper §3.3: 10 s applications at 10/30/5/15 bar, 5 s pauses, 10 m/s, M = 0.8)
or an LF TOML scene file (docs/lf_model.md). The run file holds /global/time, mu, torque, friction_radius,
patch_count, coverage, temperatures (one row per 0.01 s step) and /snapshots/NAME (start and end of every
application); run HF on one with:  aca-warp hf LF.h5 --snapshot app2_end -o hf.h5
Example:  aca-warp lf multiscale -o lf.h5
"""


def run_lf(
    scene: Any,
    output: str | Path,
    *,
    duration: float | None = None,
    device: str = "cpu",
    overwrite: bool = False,
    progress: bool = False,
    graph: bool | None = None,
    checkpoint_interval: float | None = None,
) -> Any:
    """Run an LF scene over its schedule (or ``duration`` [s]) into ``output``; returns the simulation.

    A ``duration`` beyond the schedule's end is run (the pad unloaded, the disc at rest) with a note on stderr.
    The file keeps the full state of the last checkpoint (``checkpoint_interval`` [s of simulated time]; None:
    automatic, :class:`~aca_warp.common.checkpoint.CheckpointClock`; 0: none), so that a killed or stopped run
    continues with :func:`resume_lf` (docs/faults.md)."""
    from aca_warp.common.checkpoint import frequent_note
    from aca_warp.common.files import OutputLock, check_output_path
    from aca_warp.common.runfile import busy
    from aca_warp.hf.options import check_interval
    from aca_warp.lf.io import LFRunWriter
    from aca_warp.lf.solver import LFSimulation

    check_output_path(output, overwrite=overwrite)
    check_interval(checkpoint_interval)
    lock = OutputLock.acquire(output, what=busy())  # held from here until the file has its final name
    try:
        check_output_path(output, overwrite=overwrite)
        sim = LFSimulation(scene, device=device, duration=duration, graph=graph)
    except BaseException:
        lock.release()
        raise
    notes = _duration_notes(scene, duration, sim.table.steps)  # once the duration is known to be runnable
    notes += _snapshots_not_taken(scene, sim.table)
    notes += frequent_note(checkpoint_interval, scene.lf.dt, "an LF step", "step")
    for note in notes:
        print(f"aca-warp: note: {note}", file=sys.stderr, flush=True)
    run = {"duration": duration, "checkpoint_interval": checkpoint_interval, "graph": graph}
    writer = LFRunWriter(output, sim, overwrite=overwrite, run=run, lock=lock)
    return _execute(sim, writer, progress=progress, checkpoint_interval=checkpoint_interval)


def _duration_notes(scene: Any, duration: float | None, steps: int) -> list[str]:
    """What a ``duration`` [s] asked of the LF scene ``scene`` does that the user may not expect, in words: a run past
    the schedule's end, a duration that whole LF steps (``steps`` of them) round."""
    if duration is None:
        return []
    notes = []
    if duration > scene.duration * (1 + 1e-9):
        notes.append(
            f"the run's {duration:g} s go {duration - scene.duration:.4g} s past the end of the scene's schedule "
            f"({scene.duration:g} s): the pad then stands unloaded, the disc at rest (it only cools)"
        )
    ran = steps * scene.lf.dt
    if abs(ran - duration) > 1e-9 * ran:
        whole = f"{steps} whole LF step{'s' if steps != 1 else ''}"
        notes.append(f"{duration:g} s is run as {whole} of {scene.lf.dt:g} s: {ran:.6g} s")
    return notes


def _snapshots_not_taken(scene: Any, table: Any) -> list[str]:
    """A note for the ``[snapshots] times`` of ``scene`` that its run (``table``: its steps and snapshots) ends
    before, in words; [] when every one is taken."""
    from aca_warp.lf.scene import snapshot_name

    taken = {name for name, _ in table.snapshots}
    late = [t for t in scene.snapshot_times if snapshot_name(t) not in taken]
    if not late:
        return []
    end = table.steps * scene.lf.dt
    times = ", ".join(f"{t:g} s" for t in late)
    return [f"the run ends at {end:.6g} s, before the snapshot time(s) {times} of the scene: not taken"]


def _execute(sim: Any, writer: Any, *, progress: bool, checkpoint_interval: float | None) -> Any:
    """Run ``sim`` to the end of its schedule into ``writer``; close the file complete, interrupted or failed (a
    storage failure leaves the ``.partial`` as it was at its last checkpoint and raises a one-line StorageError)."""
    from aca_warp.common.interrupts import deferred, undivided

    start = sim.step_index  # a resumed run starts at its checkpoint's step
    with writer.closed_when_stopped():
        wall = sim.run(
            on_snapshot=undivided(writer.snapshot),
            progress=progress,
            checkpoint_every=checkpoint_interval,
            on_checkpoint=undivided(writer.checkpoint),
        )
        attrs = {"wall_time": wall, "steps_per_second": (sim.step_index - start) / wall}
        with deferred():
            writer.close(complete=True, status="complete", attrs=attrs)
    sim.wall_time = wall
    sim.steps_per_second = attrs["steps_per_second"]  # of the steps this process ran
    return sim


def read_lf_settings(path: str | Path) -> dict[str, Any]:
    """What an LF run file says about how it was made: ``scene`` (rebuilt from the stored JSON, initial patches
    from /initial_patches), ``duration`` [s] or None, ``checkpoint_interval`` [s] or None, ``graph``, ``device``,
    ``versions``, ``complete``. SceneError with one line when the file cannot be rerun."""

    import numpy as np

    from aca_warp.common.bounds import json_attribute
    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import open_h5, reading
    from aca_warp.lf.scene import lf_scene_from_dict
    from aca_warp.scene import Patches

    p = Path(path)
    with reading(p, "LF run file"), open_h5(p, "LF run file") as f:
        try:
            if f.attrs.get("kind") != "lf":
                hint = f"; an HF run is continued with 'aca-warp hf --resume {p}'" if "run_options" in f.attrs else ""
                raise SceneError(f"{p} is not an LF run file (no kind = 'lf' attribute){hint}")
            doc = json_attribute(f.attrs["scene"], f"{p}: attribute 'scene'")
            run = json_attribute(f.attrs["lf_run"], f"{p}: attribute 'lf_run'") if "lf_run" in f.attrs else {}
            scene = lf_scene_from_dict(doc, name=str(doc.get("scene", {}).get("name", p.stem)))
            if "initial_patches" in f:
                g = f["initial_patches"]
                patches = Patches(*(np.asarray(g[k][()], np.float64) for k in ("x", "y", "area", "height")),
                                  source=f"{p}:/initial_patches")  # fmt: skip
                scene = scene.replace(patches=patches)
            elif scene.patches is not None:
                raise SceneError(f"{p} lacks /initial_patches; an LF file too old to rerun")
            dur = run.get("duration")
            ci = run.get("checkpoint_interval")
            return {
                "scene": scene,
                "duration": None if dur is None else float(dur),
                "checkpoint_interval": None if ci is None else float(ci),
                "graph": run.get("graph"),
                "device": str(f.attrs["device"]),
                "versions": json_attribute(f.attrs["versions"], f"{p}: attribute 'versions'")
                if "versions" in f.attrs
                else {},
                "complete": bool(f.attrs.get("complete", False)),
            }
        except SceneError as e:
            raise SceneError(f"{p}: the stored LF scene cannot be rerun: {e}") from None
        except (KeyError, TypeError, ValueError, AttributeError, OSError) as e:
            raise SceneError(f"{p}: the stored LF scene is incomplete or damaged ({type(e).__name__}: {e})") from None


def resume_lf(
    path: str | Path, *, progress: bool = False, checkpoint_interval: float | None = None, device: str | None = None
) -> tuple[Any, Path]:
    """Continue the killed or stopped LF run ``path`` (``NAME`` or ``NAME.partial``) from its last checkpoint (from
    its start when it has none); returns the simulation and the final file name. Same scene, duration and device
    as the run (``device`` overrides it); on the same CPU the finished file equals an uninterrupted run's,
    snapshots included."""
    import json

    from aca_warp.common.runfile import reopen_resumable
    from aca_warp.lf.io import LFRunWriter
    from aca_warp.lf.solver import LFSimulation

    def prepare(src: Path) -> tuple[dict[str, Any], Any]:
        s = read_lf_settings(src)
        return s, LFSimulation(s["scene"], device=device or s["device"], duration=s["duration"], graph=s["graph"])

    (s, sim), writer, final = reopen_resumable(
        path, prepare, lambda prepared, part, lock: LFRunWriter.reopen(part, prepared[1], lock=lock)
    )
    interval = s["checkpoint_interval"] if checkpoint_interval is None else checkpoint_interval
    if checkpoint_interval is not None:
        run = json.loads(writer.f.attrs["lf_run"])
        writer.f.attrs["lf_run"] = json.dumps({**run, "checkpoint_interval": checkpoint_interval})
    return _execute(sim, writer, progress=progress, checkpoint_interval=interval), final


def rerun_lf(run: str | Path, output: str | Path, *, device: str | None, checkpoint_interval: float | None,
             overwrite: bool, progress: bool) -> int:  # fmt: skip
    """``aca-warp rerun LF.h5 -o NEW.h5``: repeat an LF run from its file (scene, initial patches, duration,
    device); on the same CPU the new file's datasets equal the old one's bit for bit."""
    from aca_warp.common.files import check_not_input, version_changes

    check_not_input(output, {"run file": run}, "rerun")
    s = read_lf_settings(run)
    changed = version_changes(s["versions"])
    if changed:
        print(f"aca-warp: note: versions differ from the run's: {', '.join(changed)}", file=sys.stderr)
    sim = run_lf(
        s["scene"], output, duration=s["duration"], device=device or s["device"], overwrite=overwrite,
        progress=progress, graph=s["graph"],
        checkpoint_interval=s["checkpoint_interval"] if checkpoint_interval is None else checkpoint_interval,
    )  # fmt: skip
    print(_summary(output, sim).replace(": ", f": rerun of {run}, ", 1))
    return 0


def _summary(output: Any, sim: Any) -> str:
    import numpy as np

    h = sim.history()
    loaded = h["normal_force"] > 0
    mu = float(np.mean(h["mu"][loaded])) if loaded.any() else 0.0
    return (
        f"{output}: {sim.step_index} LF steps over {sim.step_index * sim.scene.lf.dt:.4g} s, "
        f"{len(sim.table.snapshots)} snapshots, mean mu (loaded) {mu:.4f}, final patches "
        f"{int(h['patch_count'][-1])}, coverage {h['coverage'][-1]:.4f}, {sim.steps_per_second:.3g} steps/s"
    )


def _cmd_lf(args: argparse.Namespace) -> int:
    import dataclasses

    from aca_warp.common.errors import SceneError
    from aca_warp.common.files import check_not_input
    from aca_warp.lf.scene import load_lf_scene

    if args.resume is not None:
        refuse_with_resume(
            (
                ("SCENE", args.scene, None),
                ("-o", args.output, None),
                ("--duration", args.duration, None),
                ("--coulomb", args.coulomb, False),
                ("--seed", args.seed, None),
                ("--overwrite", args.overwrite, False),
                ("--eager", args.eager, False),
                ("--allow-implausible", args.allow_implausible, False),
            ),
            "the LF run",
        )
        from aca_warp.common.files import resumed_from

        start = resumed_from(args.resume)  # before the resume writes its own checkpoints
        sim, path = resume_lf(
            args.resume, progress=not args.no_progress, checkpoint_interval=args.checkpoint_interval,
            device=None if args.device == "cpu" else args.device,
        )  # fmt: skip
        print(_summary(path, sim).replace(": ", f": resumed{' ' + start if start else ''}, ", 1))
        return 0
    if args.scene is None or args.output is None:
        raise SceneError("lf needs SCENE and -o LF.h5 (or --resume LF.h5 to continue a run)")
    check_not_input(args.output, {"scene file": args.scene}, "lf")
    scene = load_lf_scene(args.scene, allow_implausible=args.allow_implausible)
    if args.coulomb:
        scene = scene.replace(lf=dataclasses.replace(scene.lf, coulomb=1))
    if args.seed is not None:
        scene = scene.with_seed(args.seed)
    sim = run_lf(
        scene, args.output, duration=args.duration, device=args.device, overwrite=args.overwrite,
        progress=not args.no_progress, graph=False if args.eager else None,
        checkpoint_interval=args.checkpoint_interval,
    )  # fmt: skip
    print(_summary(args.output, sim))
    return 0


def add_parsers(sub: Any) -> None:
    """Register ``aca-warp lf``."""
    p = sub.add_parser(
        "lf",
        help="simulate the low-frequency automaton (patches, wear, temperatures) over a load schedule",
        description="Run the LF automaton (0.01 s steps; docs/lf_model.md) over the scene's schedule of brake "
        "applications and pauses, writing global time series and patch-state snapshots to an HDF5 file.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=EPILOG,
    )
    p.add_argument("scene", metavar="SCENE", nargs="?", help="preset (multiscale) or LF TOML file (not with --resume)")
    p.add_argument("-o", "--output", metavar="LF.h5", help="LF run file to write (required unless --resume)")
    p.add_argument("--duration", type=positive, metavar="S", help="simulated time [s] (default: the whole schedule)")
    p.add_argument("--device", default="cpu", help="Warp device: cpu (default) or cuda:0, ...")
    p.add_argument("--coulomb", action="store_true", help="constant patch friction (lf.mu_coulomb) for a TEI check")
    p.add_argument(
        "--seed",
        type=int,
        help="seed of the automaton's random events (births, deaths; default: the scene's lf.seed); the initial "
        "patches keep the scene's [patches] seed, so runs of different --seed agree until the first random event",
    )
    p.add_argument(
        "--allow-implausible",
        action="store_true",
        help="run values far outside a brake pad's range (loads beyond 1e6 N, speeds beyond 200 m/s, ...), refused "
        "otherwise as likely unit mistakes; sets the scene's allow_implausible (docs/scenes.md)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress lines on stderr (every 2 s on a terminal, every 30 s in a log)")  # fmt: skip
    p.add_argument("--eager", action="store_true", help="no graph capture of the step (debugging)")
    add_checkpoint_arguments(p, "full LF")
    p.add_argument(
        "--resume",
        metavar="LF.h5",
        help="continue a killed or stopped LF run (LF.h5 or LF.h5.partial) from its last checkpoint (from its start "
        "if it has none), with the run's own scene and settings; the finished file equals an uninterrupted run",
    )
    p.set_defaults(handler=_cmd_lf)
