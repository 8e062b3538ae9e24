"""aca_warp: the Abstract Cellular Automaton of the brake pad-disc boundary layer in NVIDIA Warp.

After Merlis & Ostermeyer 2019 (doi 10.24352/UB.OVGU-2019-025). The public names are importable from the top
level; they load their modules (and Warp) only when first used, so that ``import aca_warp`` stays cheap::

    from aca_warp import Scene, preset, load_scene        # scenes and the paper's presets
    from aca_warp import RunOptions, run_scene, resume_run  # one scene -> one HDF5 run file
    from aca_warp import build_model, initial_state, run_hf, EngineTuning  # batched pads in memory
    from aca_warp import AcaError, SceneError, SimulationFault

The package map is in docs/architecture.md.
"""

from __future__ import annotations

from aca_warp.common.lazy import lazy_names

__version__ = "0.1.0"

_PUBLIC = {
    "Scene": "aca_warp.scene",
    "preset": "aca_warp.scene",
    "load_scene": "aca_warp.scene",
    "RunOptions": "aca_warp.hf.options",
    "run_scene": "aca_warp.hf.runner",
    "resume_run": "aca_warp.hf.runner",
    "build_model": "aca_warp.hf.model",
    "initial_state": "aca_warp.hf.state",
    "run_hf": "aca_warp.hf.loop",
    "EngineTuning": "aca_warp.hf.engine",
    "RunResult": "aca_warp.hf.loop",
    "AcaError": "aca_warp.common.errors",
    "SceneError": "aca_warp.common.errors",
    "SimulationFault": "aca_warp.common.errors",
    "open_run": "aca_warp.dataset",
}
__all__ = sorted(_PUBLIC)


__getattr__, __dir__ = lazy_names(__name__, _PUBLIC)
