"""Every call of the studies into the HF run API, in one place.

The studies build models and states, step them and write run files only through these functions; each passes
its arguments on unchanged, so a change of the run API is made here and nowhere else in ``aca_warp.studies``.

* :func:`model_at_rest`: ``build_model`` of one scene and its ``initial_state`` (varying_area, work_precision);
* :func:`model_from_state`: ``build_model`` of one scene, then model arrays and the state set from saved ones
  (work_precision: saturated and grown start states);
* :func:`batch_at_start`: ``build_model`` of a batch of scenes (one pad each) and its ``initial_state`` (validation);
* :func:`run_general`: ``run_hf`` on a model and state, general engine unless named (work_precision,
  time_to_solution);
* :func:`run_engine`: ``run_hf``, the engine chosen by name, samples to a sink if given (varying_area, validation,
  work_precision_stats);
* :func:`run_to_file`: ``run_scene``, a scene into a run file (hf_study, multiscale).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from aca_warp.hf.loop import RunResult, run_hf
from aca_warp.hf.model import PadModel, build_model
from aca_warp.hf.options import DEFAULT_INTEGRATOR, STEP_CONTROLLED, RunOptions
from aca_warp.hf.recorder import Chunk
from aca_warp.hf.runner import run_scene
from aca_warp.hf.state import HFState, initial_state
from aca_warp.scene import Record, Scene


def model_at_rest(scene: Scene, device: str, precision: str) -> tuple[PadModel, HFState]:
    """The model of the one pad ``scene`` on ``device`` in ``precision`` (fp32/fp64) and its initial state."""
    model = build_model([scene], device=device, precision=precision)
    return model, initial_state(model)


def model_from_state(
    scene: Scene,
    device: str,
    precision: str,
    u: np.ndarray,
    v: np.ndarray,
    arrays: dict[str, np.ndarray] | None = None,
) -> tuple[PadModel, HFState]:
    """The model of the one pad ``scene`` (its growth dropped: a frozen pad) on ``device`` in ``precision`` with the
    model ``arrays`` (name → values, e.g. the areas, stiffnesses and normal forces a growing run reached) assigned,
    and the state u [m], u̇ [m/s] (shape (patches,) each)."""
    model = build_model([scene.replace(growth=None)], device=device, precision=precision)
    for name, values in (arrays or {}).items():
        model.arrays[name].assign(np.asarray(values).astype(model.host(name).dtype))
    state = initial_state(model)
    state.u.assign(np.asarray(u).astype(state.u.numpy().dtype))
    state.v.assign(np.asarray(v).astype(state.v.numpy().dtype))
    return model, state


def batch_at_start(scenes: list[Scene], device: str, precision: str) -> tuple[PadModel, HFState]:
    """The model of a batch of pads (one per scene) on ``device`` in ``precision`` and its initial state (each
    pad's ``[initial]`` table: rest or equilibrium, seeded perturbations)."""
    model = build_model(scenes, device=device, precision=precision)
    return model, initial_state(model)


def run_general(
    model: PadModel,
    state: HFState,
    *,
    duration: float,
    integrator: str,
    record: Record,
    dt: float | None = None,
    tolerance: float | None = None,
    engine: str = "general",
    crossing: str | None = "point",
) -> RunResult:
    """``run_hf`` for ``duration`` [s] on ``engine`` (general, onchip, auto): a step-controlled integrator
    (``adaptive``, ``controlled``, ``auto``) with ``tolerance`` (the explicit pair's), a fixed-step integrator with
    ``dt`` [s] (forced: the work-precision study measures the error of every step, those beyond the stable-step
    estimate too) and ``strang``'s ``crossing`` treatment (the point treatment, as the studies' committed runs; None:
    the batch's default, :func:`~aca_warp.hf.options.default_crossing`)."""
    if integrator in STEP_CONTROLLED:
        kw: dict = {"tolerance": tolerance}
    else:
        kw = {"dt": dt, "force": integrator != "symplectic-euler", "crossing": crossing}
    options = RunOptions(duration=duration, integrator=integrator, engine=engine, **kw)
    return run_hf(model, state, options, record=record)


def run_engine(
    model: PadModel,
    state: HFState,
    *,
    engine: str,
    duration: float,
    integrator: str,
    dt: float | None,
    record: Record,
    sink: Callable[[Chunk], None] | None = None,
    force: bool = False,
    tolerance: float | None = None,
    split_tolerance: float | None = None,
    fast_math: bool = False,
    growth_dt: float | None = None,
    crossing: str = "point",
    solve_tol: float | None = None,
) -> RunResult:
    """``run_hf`` for ``duration`` [s] with step ``dt`` [s] (None: the integrator's default; an error-controlled
    integrator's first trial), ``tolerance``, ``split_tolerance`` (None: the defaults), ``fast_math``, the growth
    events' spacing ``growth_dt`` [s] (None: the scenes' growth interval), strang's ``crossing`` treatment and the
    friction solve's tolerance ``solve_tol`` (None: the precision's; :class:`~aca_warp.hf.options.RunOptions`);
    ``engine``: general, onchip or auto. With
    ``sink`` every recorded chunk goes there (the result then holds none); ``force``: a step beyond the stable-step
    estimate runs (with a warning)."""
    tol = {k: v for k, v in (("tolerance", tolerance), ("split_tolerance", split_tolerance)) if v is not None}
    options = RunOptions(
        engine=engine, duration=duration, integrator=integrator, dt=dt, force=force, fast_math=fast_math,
        growth_dt=growth_dt, crossing=crossing, solve_tol=solve_tol, **tol,
    )  # fmt: skip
    return run_hf(model, state, options, record=record, sink=sink)


def run_to_file(
    scene: Scene,
    path: Path,
    *,
    device: str,
    overwrite: bool,
    duration: float | None = None,
    integrator: str = DEFAULT_INTEGRATOR,
    dt: float | None = None,
    precision: str = "fp64",
    progress: bool = False,
) -> RunResult:
    """``run_scene``: simulate ``scene`` for ``duration`` [s] (None: the scene's) into the run file ``path``, with
    ``strang``'s point treatment of zero-slip crossings (the studies' committed runs)."""
    options = RunOptions(duration=duration, integrator=integrator, dt=dt, crossing="point")
    return run_scene(scene, path, options, device=device, precision=precision, overwrite=overwrite, progress=progress)
