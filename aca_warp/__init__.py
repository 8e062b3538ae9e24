"""aca_warp: the Abstract Cellular Automaton of the brake pad-disc boundary layer in NVIDIA Warp.

After Merlis & Ostermeyer 2019 (doi 10.24352/UB.OVGU-2019-025). Public entry points::

    from aca_warp.scene import preset, load_scene, Scene
    from aca_warp.hf.runner import run_scene        # one scene -> one HDF5 run file
    from aca_warp.hf.model import build_model       # batched pads on a Warp device
    from aca_warp.hf.solver import run_hf, stable_step   # integrators, recording
"""

__version__ = "0.1.0"
