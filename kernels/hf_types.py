"""The parameter groups of the HF kernels as Warp structs, each declared once: the model's arrays (:data:`HFModel`),
the recorder's (:data:`HFRecorder`) and the adaptive integrator's (:data:`HFAdaptive`).

Every kernel and function that needs a group takes the whole struct (``model: Any``, the concrete struct of the
state precision T, :class:`~aca_warp.kernels.PrecisionStruct`) and reads its fields where it used them as separate
parameters before: a field access compiles to a load from the kernel's parameters, as a parameter of its own did. The
host builds each struct once per model or engine (:meth:`aca_warp.hf.model.PadModel.struct`); its arrays are updated
in place on the device (growth), so captured graphs stay valid.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import PrecisionStruct

wp.set_module_options({"enable_backward": False})


@PrecisionStruct
class HFModel:
    """The device arrays of an HF model (:class:`aca_warp.hf.model.PadModel`, whose docstring gives the units);
    n = patches, P = pads, E = neighbour links; T unless noted.

    The growth fields are read only by growth events (empty for a model that does not grow); ``pad_growth`` is the
    area increment per event of the engine's step, which the engine sets.
    """

    # per patch (n,)
    patch_pad: wp.array[wp.int32]
    area: wp.array[Any]
    sqrt_area: wp.array[Any]
    height: wp.array[Any]
    radius: wp.array[Any]
    x: wp.array[Any]
    y: wp.array[Any]
    inv_mass: wp.array[Any]
    k_t: wp.array[Any]
    k_n: wp.array[Any]
    damping: wp.array[Any]
    normal_force: wp.array[Any]
    k_diag: wp.array[Any]
    # neighbour links (CSR): row offsets (n + 1,), neighbour, 1/D0_ij and k_ij (E,)
    nbr_start: wp.array[wp.int32]
    nbr_index: wp.array[wp.int32]
    nbr_inv_dist: wp.array[Any]
    nbr_stiffness: wp.array[Any]
    # per pad: patch offsets (P + 1,), coupling, disc, friction law, load and matrix (P,)
    pad_patch_start: wp.array[wp.int32]
    pad_kc: wp.array[Any]
    pad_omega: wp.array[Any]
    pad_mu_scale: wp.array[Any]
    pad_slope: wp.array[Any]
    pad_decay: wp.array[Any]
    pad_mu_pad: wp.array[Any]
    pad_load: wp.array[Any]
    pad_matrix_force: wp.array[Any]
    pad_matrix_radius: wp.array[Any]
    # per pad, growth (P,); the contact terms of its re-solve in float64
    pad_growth: wp.array[Any]
    pad_k_t: wp.array[Any]
    pad_k_n: wp.array[Any]
    pad_mass_per_area: wp.array[Any]
    pad_zeta: wp.array[Any]
    pad_area: wp.array[wp.float64]
    pad_moment: wp.array[wp.float64]
    pad_k_m: wp.array[wp.float64]
    pad_gap: wp.array[wp.float64]


@PrecisionStruct
class HFRecorder:
    """The recorder's device buffers and per-patch window (:class:`aca_warp.hf.recorder.Recorder`).

    ``counters`` int32 (4,): the next sample's index, the globals rows and the per-patch rows written since the last
    flush, and (adaptive) the flag that a sample is due (slots in ``aca_warp.kernels.hf``: SAMPLE_INDEX …
    RECORD_FLAG). ``globals`` (rows, pads, 6) float64: the samples' global outputs. ``watch_bound`` (pads,) [m/s]:
    the watchdog's bound on a patch's energy speed; ``fault`` (pads, 3) int32: the first fault per pad [patch,
    sample, kind], ``fault_value`` (pads,) [m/s] its energy speed. ``velocity``, ``displacement`` (prows, n) in T:
    the per-patch histories (``displacement`` without rows when not recorded). Global sample k also records the
    per-patch histories when ``first`` ≤ k ≤ ``last`` and (k − ``first``) % ``every`` = 0.
    """

    counters: wp.array[wp.int32]
    globals: wp.array3d[wp.float64]
    watch_bound: wp.array[wp.float64]
    fault: wp.array2d[wp.int32]
    fault_value: wp.array[wp.float64]
    velocity: wp.array2d[Any]
    displacement: wp.array2d[Any]
    first: int
    last: int
    every: int


@PrecisionStruct
class HFAdaptive:
    """The adaptive integrator's device arrays (:class:`aca_warp.hf.adaptive.AdaptiveStepper`; column indices and
    the tableau in ``aca_warp.kernels.hf_adaptive``); n = patches, P = pads, S = 7 stages; T unless noted.

    ``coeff`` (S, S) and ``err_coeff`` (S,) float64: the Dormand–Prince 5(4) tableau a and e = b − b*. ``u_scale``
    [m], ``v_scale`` [m/s] (n,): the error norm's per-patch scales; ``tol``: its relative tolerance; ``h_max``,
    ``h_min`` [s]: the step's bounds. ``sample_dt``, ``interval`` (0: no growth), ``t_end`` [s]: the sample
    interval, the growth interval and the end of the run; ``t_stop`` (1,) [s]: where the host asked the pads to
    wait. Per pad: ``ctl`` (P, CTL) float64 and ``mode`` (P, MODE) int32, the control and mode columns; ``stats``
    (P, 2) int64: accepted and rejected trials; ``accepted`` (P,) int32: the last trial's verdict. ``done`` (3,)
    int32: run over, waiting at ``t_stop``, step underflow. ``ku``, ``kv`` (S, n): the stages k_s = (u̇, v̇);
    ``u_a``, ``v_a`` (n,): the even stages' states (y_6, the 5th-order solution, last), ``u_b``, ``v_b``: the odd
    stages'.

    The error-controlled split step (``controlled``, and ``auto``'s sticking mode; ``aca_warp.kernels.hf_controlled``)
    shares the per-pad control and the landing; its pads are flagged in ``mode`` and its trial state is ``u_a``,
    ``v_a`` (displacement, staggered velocity). ``tol_i``: its tolerance; ``h_max_i`` [s]: its largest step;
    ``switching``: 1 when pads change between the explicit pair and the split step at samples (``auto``).
    Per patch (n,): ``force_prev`` [N], the spring force of the accepted step before the state's (``state.force``);
    ``force_new`` [N], the spring force at the trial state; ``err_f`` [m/s], the sub-step's local error; ``v_rec``
    [m/s], the synchronous velocity a sample records.
    """

    coeff: wp.array2d[wp.float64]
    err_coeff: wp.array[wp.float64]
    u_scale: wp.array[Any]
    v_scale: wp.array[Any]
    tol: wp.float64
    h_max: wp.float64
    h_min: wp.float64
    sample_dt: wp.float64
    interval: wp.float64
    t_end: wp.float64
    t_stop: wp.array[wp.float64]
    ctl: wp.array2d[wp.float64]
    mode: wp.array2d[wp.int32]
    stats: wp.array2d[wp.int64]
    accepted: wp.array[wp.int32]
    done: wp.array[wp.int32]
    ku: wp.array2d[Any]
    kv: wp.array2d[Any]
    u_a: wp.array[Any]
    v_a: wp.array[Any]
    u_b: wp.array[Any]
    v_b: wp.array[Any]
    tol_i: wp.float64
    h_max_i: wp.float64
    switching: int
    force_prev: wp.array[Any]
    force_new: wp.array[Any]
    err_f: wp.array[Any]
    v_rec: wp.array[Any]
