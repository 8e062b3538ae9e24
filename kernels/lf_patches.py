"""LF kernels of the patches' life cycle: growth from captured debris, shrinking, death; merges of overlapping
patches over the merge-candidate lists; births in the cells; the candidate lists (CSR from ``wp.HashGrid``) and the
compaction of the slot arrays (docs/lf_model.md). Random numbers: a stateless counter hash keyed by (seed, step,
element, stream), bit-identical on every device.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels.lf_types import (
    G_BIRTHS,
    G_DEATHS,
    G_MERGES,
    G_STEP,
    G_TOPOLOGY,
    LFCells,
    LFParams,
    LFPatches,
    disc_radius,
    polar,
)

wp.set_module_options({"enable_backward": False})


@wp.func
def splitmix64(x: wp.uint64) -> wp.uint64:
    z = x + wp.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> wp.uint64(30))) * wp.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> wp.uint64(27))) * wp.uint64(0x94D049BB133111EB)
    return z ^ (z >> wp.uint64(31))


@wp.func
def uniform64(seed: wp.uint64, step: wp.uint64, idx: wp.uint64, stream: wp.uint64) -> wp.float64:
    """Uniform [0, 1) with 53 bits from (seed, step, element, stream); identical on CPU and GPU."""
    h = splitmix64(seed ^ splitmix64(step ^ splitmix64(idx ^ splitmix64(stream))))
    return wp.float64(h >> wp.uint64(11)) * wp.float64(1.0 / 9007199254740992.0)


@wp.func
def overlaps(x: wp.float64, y: wp.float64, a: wp.float64, xo: wp.float64, yo: wp.float64, ao: wp.float64) -> bool:
    """Whether the discs of radius a at (x, y) and ao at (xo, yo) overlap [m]."""
    dx = x - xo
    dy = y - yo
    return dx * dx + dy * dy < (a + ao) * (a + ao)


@wp.func
def clamp_inside(p: LFParams, x: wp.float64, y: wp.float64, a: wp.float64) -> wp.vec2d:
    """Move a disc of radius a centred at (x, y) the least amount radially/angularly to lie inside the pad."""
    rp = polar(x, y)
    r = rp[0]
    phi = rp[1]
    r_out = p.r_in + p.dr * wp.float64(p.n_r)
    r = wp.clamp(r, p.r_in + a, r_out - a)
    lim = p.half - wp.asin(wp.min(a / r, wp.float64(1.0)))
    phi = wp.clamp(phi, -lim, lim)
    return wp.vec2d(-r * wp.sin(phi), r * wp.cos(phi))


# ----------------------------------------------------------------------------------------------- life cycle


@wp.kernel
def life_cycle(
    p: LFParams,
    # State in/out:
    patches: LFPatches,
    glob: wp.array[wp.float64],
    # Out (per slot: the released debris mass [kg]; a death's flag and (age [s], area [m²])):
    src_out: wp.array[wp.float64],
    died_out: wp.array[wp.int32],
    died_at_out: wp.array[wp.vec2d],
):
    """Growth from captured debris, shrinking by friction power, death (dim = P); the released mass goes to
    ``src_out`` (then into the cell's source, :func:`~aca_warp.kernels.lf_sums.add_by_cell`), a death's record to
    ``died_out``/``died_at_out`` (appended to the calibration lists in slot order by
    :func:`~aca_warp.kernels.lf_record.patch_stats`).

    Growth ΔA = m_cap / (ρ_p t), capped at A_max (excess released). Shrink ΔA = k_shrink P Δt / t. Death when
    A < A_min, t < t_min, T ≥ T_kill, or with probability 1 − exp(−λ0 exp((T − T_c)/T_s) Δt).
    """
    i = wp.tid()
    src_out[i] = wp.float64(0.0)
    if patches.alive[i] == 0:
        return
    rho = p.rho_patch
    t = patches.thick[i]
    A = patches.area[i]
    released = wp.float64(0.0)
    if t > wp.float64(0.0):
        A_grow = A + patches.mcap[i] / (rho * t)
        A_new = wp.min(A_grow, wp.max(p.A_max, A))
        released = released + (A_grow - A_new) * rho * t
        ds = wp.min(p.k_shrink * patches.power[i] * p.dt / t, A_new)
        A = A_new - ds
        released = released + ds * rho * t
    else:
        released = released + patches.mcap[i]
    patches.mcap[i] = wp.float64(0.0)
    patches.age[i] = patches.age[i] + p.dt
    T = patches.temp[i]
    lam = p.lam0 * wp.exp(wp.min((T - p.T_c) / p.T_s, wp.float64(50.0)))
    u = uniform64(p.seed, wp.uint64(glob[G_STEP]), wp.uint64(i), wp.uint64(1))
    if A < p.A_min or t < p.t_min or T >= p.T_kill or u < wp.float64(1.0) - wp.exp(-lam * p.dt):
        released = released + rho * A * t
        patches.alive[i] = (
            0  # no G_TOPOLOGY: the grid and candidate lists may keep a dead slot (every query checks alive)
        )
        wp.atomic_add(glob, G_DEATHS, wp.float64(1.0))  # adds of 1: exact in any order
        died_out[i] = 1
        died_at_out[i] = wp.vec2d(patches.age[i], A)
        A = wp.float64(0.0)
    else:
        xy = clamp_inside(p, patches.x[i], patches.y[i], disc_radius(A))
        patches.x[i] = xy[0]
        patches.y[i] = xy[1]
    patches.area[i] = A
    src_out[i] = released


# ----------------------------------------------------------------------------------------------- merges


@wp.kernel
def merge_target(
    # Model (candidate CSR, rebuilt when the patch set changes):
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    # State in:
    patches: LFPatches,
    # Out:
    target_out: wp.array[wp.int32],
):
    """target[i] = the lowest-index alive patch j < i that overlaps i, else −1 (dim = P)."""
    i = wp.tid()
    target_out[i] = -1
    if patches.alive[i] == 0:
        return
    ai = disc_radius(patches.area[i])
    best = wp.int32(-1)
    for q in range(nbr_start[i], nbr_start[i + 1]):
        j = nbr_index[q]
        if j < i and patches.alive[j] != 0 and (best < 0 or j < best):
            if overlaps(patches.x[i], patches.y[i], ai, patches.x[j], patches.y[j], disc_radius(patches.area[j])):
                best = j
    target_out[i] = best


@wp.kernel
def merge_apply(
    p: LFParams,
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    target: wp.array[wp.int32],
    # State in/out (roots write only their own entries, read only absorbed ones):
    patches: LFPatches,
    glob: wp.array[wp.float64],
    # Out (per slot: the cut mass [kg]):
    src_out: wp.array[wp.float64],
):
    """A root (target −1) absorbs every neighbour whose target it is: area sum, area-weighted centroid, top,
    temperature; volume-weighted thickness (mass conserved); oldest age (dim = P). A merged area above
    max(A_max, the root's area) is cut back to it and the cut mass goes to ``src_out`` (then into the cell's
    debris source, :func:`~aca_warp.kernels.lf_sums.add_by_cell`)."""
    i = wp.tid()
    src_out[i] = wp.float64(0.0)
    if patches.alive[i] == 0 or target[i] != -1:
        return
    A = patches.area[i]
    sx = A * patches.x[i]
    sy = A * patches.y[i]
    sv = A * patches.thick[i]
    stop = A * patches.top[i]
    sT = A * patches.temp[i]
    ag = patches.age[i]
    n = int(0)
    for q in range(nbr_start[i], nbr_start[i + 1]):
        j = nbr_index[q]
        if target[j] == i:
            Aj = patches.area[j]
            A = A + Aj
            sx = sx + Aj * patches.x[j]
            sy = sy + Aj * patches.y[j]
            sv = sv + Aj * patches.thick[j]
            stop = stop + Aj * patches.top[j]
            sT = sT + Aj * patches.temp[j]
            ag = wp.max(ag, patches.age[j])
            n += 1
    if n == 0:
        return
    t_new = sv / A
    cap = wp.max(p.A_max, patches.area[i])
    if A > cap:
        src_out[i] = (A - cap) * t_new * p.rho_patch
        sx = sx * (cap / A)
        sy = sy * (cap / A)
        stop = stop * (cap / A)
        sT = sT * (cap / A)
        A = cap
    xy = clamp_inside(p, sx / A, sy / A, disc_radius(A))
    patches.x[i] = xy[0]
    patches.y[i] = xy[1]
    patches.area[i] = A
    patches.thick[i] = t_new
    patches.top[i] = stop / A
    patches.temp[i] = sT / A
    patches.age[i] = ag
    glob[G_TOPOLOGY] = wp.float64(1.0)
    wp.atomic_add(glob, G_MERGES, wp.float64(n))  # integer counts: exact in any order


@wp.kernel
def merge_kill(
    target: wp.array[wp.int32],
    patches: LFPatches,
):
    """Free the slots of absorbed patches (those whose target is a root) (dim = P)."""
    i = wp.tid()
    t = target[i]
    if t >= 0 and target[t] == -1:
        patches.alive[i] = 0
        patches.area[i] = wp.float64(0.0)
        patches.mcap[i] = wp.float64(0.0)


# ----------------------------------------------------------------------------------------------- births


@wp.struct
class LFBirths:
    """The births' bookkeeping of a step (:class:`aca_warp.lf.solver.LFSimulation` holds the arrays as ``want``,
    ``want_rank``, ``birth_xy``, ``free``, ``free_rank``, ``slot_list``). Per cell (C,): ``want`` int32, 1 where a
    birth is flagged; ``want_rank`` its rank among the flagged cells (an exclusive scan); ``xy`` vec2d, its centre
    [m]. Per slot (P,): ``free`` int32, 1 for an empty slot; ``free_rank`` its rank among them; ``slot`` the slot of
    each rank."""

    want: wp.array[wp.int32]
    want_rank: wp.array[wp.int32]
    xy: wp.array[wp.vec2d]
    free: wp.array[wp.int32]
    free_rank: wp.array[wp.int32]
    slot: wp.array[wp.int32]


@wp.kernel
def birth_want(
    p: LFParams,
    grid: wp.uint64,
    query_radius: wp.float64,
    # State in:
    cells: LFCells,
    patches: LFPatches,
    glob: wp.array[wp.float64],
    # Out (want, xy):
    births: LFBirths,
):
    """Flag a birth in cell e (dim = C): stored debris ≥ ρ_p t0 A0, matrix pressure ≥ p_comp, a draw < p_birth,
    and a free spot for a disc of A0 at a random point of the cell (at least a0 from its edges)."""
    e = wp.tid()
    births.want[e] = 0
    s_crit = p.rho_patch * p.t0 * p.A0
    free = wp.max(cells.area[e] - cells.cover[e], wp.float64(0.0))
    if cells.store[e] < s_crit or free <= wp.float64(0.0) or cells.fn[e] < p.p_comp * free:
        return
    step = wp.uint64(glob[G_STEP])
    if uniform64(p.seed, step, wp.uint64(e), wp.uint64(2)) >= p.p_birth:
        return
    a0 = disc_radius(p.A0)
    k = e / p.n_t
    j = e - k * p.n_t
    r = cells.r[e]
    u1 = uniform64(p.seed, step, wp.uint64(e), wp.uint64(3))
    u2 = uniform64(p.seed, step, wp.uint64(e), wp.uint64(4))
    rr = p.r_in + (wp.float64(k) * p.dr + a0) + u1 * wp.max(p.dr - wp.float64(2.0) * a0, wp.float64(0.0))
    arc = r * p.dphi
    s = wp.float64(j) * arc + a0 + u2 * wp.max(arc - wp.float64(2.0) * a0, wp.float64(0.0))
    phi = -p.half + s / r
    bx = -rr * wp.sin(phi)
    by = rr * wp.cos(phi)
    xy = clamp_inside(p, bx, by, a0)
    q = wp.vec3d(xy[0], xy[1], wp.float64(0.0))
    for i in wp.hash_grid_query(grid, q, query_radius):
        if patches.alive[i] != 0 and overlaps(
            patches.x[i], patches.y[i], disc_radius(patches.area[i]), xy[0], xy[1], a0
        ):
            return
    births.want[e] = 1
    births.xy[e] = xy


@wp.kernel
def free_slots(patches: LFPatches, births: LFBirths):
    """births.free[i] = 1 for an empty slot (dim = P)."""
    i = wp.tid()
    births.free[i] = 1 - wp.min(patches.alive[i], 1)


@wp.kernel
def free_list(births: LFBirths):
    """births.slot[rank] = slot for every empty slot (dim = P)."""
    i = wp.tid()
    if births.free[i] != 0:
        births.slot[births.free_rank[i]] = i


@wp.kernel
def birth_apply(
    p: LFParams,
    births: LFBirths,
    # State in/out:
    cells: LFCells,
    patches: LFPatches,
    glob: wp.array[wp.float64],
):
    """Create the flagged patches in the lowest free slots, in cell order (dim = C); the cell's store pays
    ρ_p t0 A0. Births beyond the capacity are dropped (and pay nothing)."""
    e = wp.tid()
    if births.want[e] == 0:
        return
    n = births.free.shape[0]
    n_free = births.free_rank[n - 1] + births.free[n - 1]
    r = births.want_rank[e]
    if r >= n_free:
        return
    i = births.slot[r]
    xy = births.xy[e]
    patches.alive[i] = 1
    patches.x[i] = xy[0]
    patches.y[i] = xy[1]
    patches.area[i] = p.A0
    patches.thick[i] = p.t0
    patches.top[i] = cells.z[e] + p.t0
    patches.temp[i] = cells.T[e]
    patches.mcap[i] = wp.float64(0.0)
    patches.age[i] = wp.float64(0.0)
    cells.store[e] = cells.store[e] - p.rho_patch * p.t0 * p.A0
    glob[G_TOPOLOGY] = wp.float64(1.0)
    wp.atomic_add(glob, G_BIRTHS, wp.float64(1.0))


# ----------------------------------------------------------------------------------------------- merge candidates


@wp.kernel
def positions3(
    patches: LFPatches,
    park: wp.vec3d,
    pos_out: wp.array[wp.vec3d],
):
    """Points for the hash grid; empty slots all at ``park``, in a cell no query visits (dim = P)."""
    i = wp.tid()
    if patches.alive[i] != 0:
        pos_out[i] = wp.vec3d(patches.x[i], patches.y[i], wp.float64(0.0))
    else:
        pos_out[i] = park


@wp.func
def candidate(i: int, j: int, alive: wp.array[wp.int32], pos: wp.array[wp.vec3d], radius: wp.float64) -> bool:
    """Whether patch j (a hash-grid hit) is a merge candidate of patch i: another alive patch within ``radius``."""
    return j != i and alive[j] != 0 and wp.length_sq(pos[j] - pos[i]) <= radius * radius


@wp.kernel
def candidates(
    grid: wp.uint64,
    radius: wp.float64,
    alive: wp.array[wp.int32],
    pos: wp.array[wp.vec3d],
    start: wp.array[wp.int32],
    fill: int,
    # Out:
    count_out: wp.array[wp.int32],
    index_out: wp.array[wp.int32],
):
    """The merge candidates of every alive patch (:func:`candidate`; dim = P): ``fill`` = 0, their number into
    ``count_out``; ``fill`` = 1, the CSR row from ``start[i]``, sorted by index (deterministic on every device).
    Both passes take the same hits, so a row holds exactly the entries counted for it."""
    i = wp.tid()
    if fill == 0:
        count_out[i] = 0
    if alive[i] == 0:
        return
    a = int(0)
    if fill != 0:
        a = start[i]
    k = a
    for j in wp.hash_grid_query(grid, pos[i], radius):
        if candidate(i, j, alive, pos, radius):
            if fill != 0:  # insertion sort keeps the row ordered whatever order the grid returns
                q = k
                while q > a and index_out[q - 1] > j:
                    index_out[q] = index_out[q - 1]
                    q -= 1
                index_out[q] = j
            k += 1
    if fill == 0:
        count_out[i] = k


@wp.kernel
def set_row_end(count: wp.array[wp.int32], start: wp.array[wp.int32], n: wp.int32):
    """start[n] = total number of entries (dim = 1)."""
    start[n] = start[n - 1] + count[n - 1]


# ----------------------------------------------------------------------------------------------- compaction


@wp.kernel
def compact_map(alive: wp.array[wp.int32], rank: wp.array[wp.int32], dst_out: wp.array[wp.int32]):
    """Destination slot of each patch for compaction: alive patches keep their order at the front (dim = P)."""
    i = wp.tid()
    if alive[i] != 0:
        dst_out[i] = rank[i]
    else:
        dst_out[i] = -1


@wp.kernel
def scatter(dst: wp.array[wp.int32], src: wp.array[Any], out: wp.array[Any]):
    """out[dst[i]] = src[i] where dst[i] ≥ 0 (compaction; dim = P)."""
    i = wp.tid()
    if dst[i] >= 0:
        out[dst[i]] = src[i]


for _t in (wp.float64, wp.int32):
    wp.overload(scatter, {"dst": wp.array[wp.int32], "src": wp.array[_t], "out": wp.array[_t]})
