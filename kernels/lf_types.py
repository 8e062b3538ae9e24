"""The LF automaton's kernels (docs/lf_model.md; thin wrappers in ``aca_warp.lf.solver``): their shared constants,
indices and parameters, and the geometry helpers of more than one stage.

The automaton's state comes to the kernels in three structs, :class:`LFCells`, :class:`LFRings` and
:class:`LFPatches`, besides ``glob`` and the contact scratch. One module per stage:
:mod:`~aca_warp.kernels.lf_contact` (binning, contact, friction), :mod:`~aca_warp.kernels.lf_thermal`
(temperatures), :mod:`~aca_warp.kernels.lf_wear` (wear and its debris),
:mod:`~aca_warp.kernels.lf_patches` (life cycle, merges, births, merge candidates, compaction),
:mod:`~aca_warp.kernels.lf_record` (load schedule and outputs); :mod:`~aca_warp.kernels.lf_sums` puts the sums
of several elements' contributions into one place in a fixed order.

Three element sets, all float64 SoA arrays:

* matrix cells ``e`` of a polar grid over the pad (ring ``k`` = radial band, column ``j`` along the sliding
  direction, e = k·n_t + j), shape (C,);
* disc rings ``k`` (the same radial bands), shape (R,);
* patches ``i`` in a fixed-capacity slot array with ``alive`` flags, shape (P,).

Pad frame: pad centred on +y, φ = atan2(−x, y) ∈ [−half, +half]; the disc moves toward +φ, so column 0 is the
leading edge and column n_t − 1 the trailing edge. Global scalars live in ``glob`` (indices ``G_*`` below),
so that every kernel reads its inputs from the device and a step needs no host value but the topology flag.
Random numbers: a stateless counter hash keyed by (seed, step, element, stream), bit-identical on every device
(:mod:`~aca_warp.kernels.lf_patches`).
"""

from __future__ import annotations

import warp as wp
from aca_warp.kernels.tiles import tile_load_1d, tile_store_1d

wp.set_module_options({"enable_backward": False})

# threads of the block kernels (contact solve, debris sweep): Warp's default block size, so that no second
# module variant is compiled; also the chunk of elements per shared-memory load of the kernels that walk
# elements in order (debris sweep, patch statistics, ring powers, disc temperature)
LF_BLOCK = wp.constant(256)
# a thread's store into such a chunk tile (shape (LF_BLOCK,), float64), without a block barrier, and its read
put_chunk = tile_store_1d(wp.float64, LF_BLOCK)
get_chunk = tile_load_1d(wp.float64, LF_BLOCK)


# indices into the global scalar array ``glob`` (float64)
G_LOAD = wp.constant(0)  # clamp force F_N this step [N]
G_OMEGA = wp.constant(1)  # disc angular velocity [rad/s]
G_GAP = wp.constant(2)  # contact gap g [m]
G_FN = wp.constant(3)  # Σ F_N [N]
G_FF = wp.constant(4)  # Σ friction force [N]
G_TORQUE = wp.constant(5)  # Σ r F_F [N m]
G_FN_PATCH = wp.constant(6)  # Σ F_N on patches [N]
G_MATRIX_IN = wp.constant(7)  # retained matrix debris entering the boundary layer this step [kg]
G_PATCH_LOST = wp.constant(8)  # patch wear debris lost (not retained) this step [kg]
G_EMITTED = wp.constant(9)  # debris leaving at the trailing edge this step [kg]
G_TOPOLOGY = wp.constant(10)  # 1 when patches were born or merged this step (candidate lists to rebuild)
G_COUNT = wp.constant(11)  # alive patches
G_AREA = wp.constant(12)  # Σ patch area [m²]
G_TPATCH = wp.constant(13)  # Σ A T over patches [m² K]
G_STEP = wp.constant(14)  # step counter (float64 integer value)
G_BIRTHS = wp.constant(15)  # births this step
G_DEATHS = wp.constant(16)  # deaths this step (not merges)
G_MERGES = wp.constant(17)  # merges this step (absorbed patches)
G_MATRIX_LOST = wp.constant(18)  # matrix wear debris lost (not retained) this step [kg]
G_PASSES = wp.constant(19)  # contact-solve passes over the elements this step
G_SIZE = wp.constant(20)


@wp.struct
class LFParams:
    """Constants of one LF model (SI; meanings in docs/lf_model.md and ``aca_warp.lf.scene.LFConstants``)."""

    r_in: wp.float64
    dr: wp.float64
    half: wp.float64
    dphi: wp.float64
    n_r: wp.int32
    n_t: wp.int32
    dt: wp.float64
    seed: wp.uint64
    K_N: wp.float64
    k_m: wp.float64
    mu_pad: wp.float64
    coulomb: wp.int32
    mu_coulomb: wp.float64
    M: wp.float64
    slope: wp.float64
    decay: wp.float64
    gamma_disc: wp.float64
    T_amb: wp.float64
    rho_d: wp.float64
    c_d: wp.float64
    k_d: wp.float64
    d_d: wp.float64
    h_conv: wp.float64
    rho_p: wp.float64
    c_p: wp.float64
    k_p: wp.float64
    t_eff: wp.float64
    L_b: wp.float64
    h_pd: wp.float64
    alpha_d: wp.float64
    kappa_d: wp.float64
    wear_m: wp.float64
    wear_p: wp.float64
    wear_T: wp.float64
    rho_m: wp.float64
    rho_patch: wp.float64
    f_ret: wp.float64
    p_cap: wp.float64
    p_store: wp.float64
    p_remob: wp.float64
    s_max_thick: wp.float64
    A0: wp.float64
    A_min: wp.float64
    A_max: wp.float64
    t0: wp.float64
    t_min: wp.float64
    k_shrink: wp.float64
    p_comp: wp.float64
    p_birth: wp.float64
    lam0: wp.float64
    T_c: wp.float64
    T_s: wp.float64
    T_kill: wp.float64
    cand_margin: wp.float64


@wp.struct
class LFCells:
    """The matrix cells of the pad's polar grid, shape (C,) each, float64 (:class:`aca_warp.lf.solver.LFSimulation`
    holds the arrays as ``cell_*``)."""

    area: wp.array[wp.float64]  # exact annular-sector area A_e [m²] (constant)
    r: wp.array[wp.float64]  # area-weighted radius [m] (constant)
    z: wp.array[wp.float64]  # elevation [m] (worn)
    T: wp.array[wp.float64]  # temperature [K]
    store: wp.array[wp.float64]  # debris stored in the cell's gaps [kg]
    src: wp.array[wp.float64]  # debris released into the cell, pending the next sweep [kg]
    fn: wp.array[wp.float64]  # normal force this step [N]
    power: wp.array[wp.float64]  # friction power this step [W]
    cover: wp.array[wp.float64]  # area covered by the cell's patches [m²]
    chord: wp.array[wp.float64]  # Σ 2a over the cell's patches [m]
    capture: wp.array[wp.float64]  # debris the cell's patches captured this step [kg]


@wp.struct
class LFRings:
    """The disc rings (the grid's radial bands), shape (R,) each, float64 (held as ``ring_*``)."""

    r: wp.array[wp.float64]  # centre radius [m] (constant)
    T: wp.array[wp.float64]  # temperature [K]
    bulge: wp.array[wp.float64]  # thermal bulge toward the pad [m]
    power: wp.array[wp.float64]  # friction power into the ring this step [W]
    emit: wp.array[wp.float64]  # debris leaving the ring at the trailing edge this step [kg]


@wp.struct
class LFPatches:
    """The patch slots, shape (P,) each, float64 unless noted (held under these names, ``patch_fn``,
    ``patch_power``, ``patch_cell`` for the last three)."""

    alive: wp.array[wp.int32]  # 1 for a patch, 0 for an empty slot
    x: wp.array[wp.float64]  # centre in the pad frame [m]
    y: wp.array[wp.float64]
    area: wp.array[wp.float64]  # A [m²]
    thick: wp.array[wp.float64]  # thickness t [m]
    top: wp.array[wp.float64]  # free elevation of the top [m]
    temp: wp.array[wp.float64]  # temperature [K]
    mcap: wp.array[wp.float64]  # captured debris not yet grown into area [kg]
    age: wp.array[wp.float64]  # [s]
    fn: wp.array[wp.float64]  # normal force this step [N]
    power: wp.array[wp.float64]  # friction power this step [W]
    cell: wp.array[wp.int32]  # the cell of its centre


# ----------------------------------------------------------------------------------------------- helpers


@wp.func
def polar(x: wp.float64, y: wp.float64) -> wp.vec2d:
    """(r [m], φ [rad]) of a point in the pad frame: r = √(x² + y²), φ = atan2(−x, y)."""
    return wp.vec2d(wp.sqrt(x * x + y * y), wp.atan2(-x, y))


@wp.func
def disc_radius(area: wp.float64) -> wp.float64:
    """Radius a = √(A/π) [m] of a round patch of area A [m²]."""
    return wp.sqrt(area / wp.float64(wp.pi))


@wp.func
def block_end(blk: int, n: int) -> int:
    """One past the last of the ``n`` elements that block ``blk`` of a block kernel covers (LF_BLOCK consecutive
    elements per block; its threads take every ``threads``-th of them from their lane on)."""
    return wp.min(n, (blk + 1) * LF_BLOCK)
