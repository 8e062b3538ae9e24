"""The per-pad sample of the HF engines: patch sums, block reductions, the globals row and the watchdog.

One home for what a sample is, shared by the general recorder (:func:`record_pad`, also called by the on-chip
adaptive kernel) and the on-chip strang kernel, which sums the same terms from its shared-memory state:

* :func:`patch_sample`: one patch's contributions (friction force, torque, u̇, |u̇|, force-weighted position) as a
  :data:`SampleSums` vector, summed in float64 whatever the state precision;
* :func:`block_sums`: the block-wide sums (every thread of the block must call it);
* :func:`write_globals`: the pad's row of μ, torque, friction radius, Σu̇, Σ|u̇| and friction centroid;
* :func:`energy_speed2` and :func:`flag_fault`: the watchdog;
* :func:`patch_sample_due` and :func:`store_patch_sample`: the per-patch histories.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels.friction import friction_coefficient

wp.set_module_options({"enable_backward": False})

N_GLOBAL = 6  # mu, torque, friction radius, Σ u̇, Σ|u̇|, friction centroid
# the float64 sums of a sample: Σ F_i, Σ F_i r_i, Σ u̇_i, Σ |u̇_i|, Σ F_i x_i, Σ F_i y_i
SampleSums = wp.types.vector(length=6, dtype=wp.float64)


@wp.func
def sign_or_zero(x: Any):
    """−1, 0 or 1 (``wp.sign`` returns 1 at 0: a disc at rest must give no matrix friction)."""
    zero = x - x
    if x > zero:
        return type(x)(1.0)
    if x < zero:
        return type(x)(-1.0)
    return zero


@wp.func
def patch_sample(v: Any, fn: Any, r: Any, x: Any, y: Any, omega: Any, mu_scale: Any, slope: Any, decay: Any):
    """One patch's terms of the sample sums at velocity ``v`` [m/s], normal force ``fn`` [N], radius ``r`` and
    position (``x``, ``y``) [m]: its friction force F = F_N f(ω r − v) [N], F r [N m], v, |v| [m/s], F x, F y [N m]."""
    f = fn * friction_coefficient(omega * r - v, mu_scale, slope, decay)
    return SampleSums(
        wp.float64(f), wp.float64(f * r), wp.float64(v), wp.float64(wp.abs(v)), wp.float64(f * x), wp.float64(f * y)
    )


@wp.func
def block_sums(s: SampleSums):
    """The sums of every thread's ``s`` over the block (block-wide reductions: every thread must call it)."""
    return SampleSums(
        wp.tile_sum(wp.tile(s[0]))[0],
        wp.tile_sum(wp.tile(s[1]))[0],
        wp.tile_sum(wp.tile(s[2]))[0],
        wp.tile_sum(wp.tile(s[3]))[0],
        wp.tile_sum(wp.tile(s[4]))[0],
        wp.tile_sum(wp.tile(s[5]))[0],
    )


@wp.func
def write_globals(
    globals_out: wp.array3d[wp.float64],
    row: int,
    pad: int,
    s: SampleSums,
    omega: Any,
    mu_pad: Any,
    matrix_force: Any,
    matrix_radius: Any,
    load: Any,
):
    """Write one pad's sample row: μ, torque [N m], friction radius [m], Σu̇, Σ|u̇| [m/s], friction centroid [m]
    from the pad's :data:`SampleSums` ``s`` and the matrix's Coulomb friction μ_pad F_m sign(ω) at radius r_m.

    μ = (Σ F_i + μ_pad F_m sign ω)/F_N (0 without load); friction radius r_eff = T / total friction force (matrix
    included); friction centroid = |Σ F_i r⃗_i| / |Σ F_i|, the distance from the disc axis of the centroid of the
    patches' friction forces (the matrix, whose friction does not vibrate and whose cells carry no angular
    position, is left out; 0 when the patch forces sum to 0)."""
    fsum = s[0]
    fm = wp.float64(mu_pad * matrix_force * sign_or_zero(omega))
    ftot = fsum + fm
    ttot = s[1] + fm * wp.float64(matrix_radius)
    mu = wp.float64(0.0)
    reff = wp.float64(0.0)
    if wp.float64(load) > wp.float64(0.0):
        mu = ftot / wp.float64(load)
    if ftot != wp.float64(0.0):
        reff = ttot / ftot
    globals_out[row, pad, 0] = mu
    globals_out[row, pad, 1] = ttot
    globals_out[row, pad, 2] = reff
    globals_out[row, pad, 3] = s[2]
    globals_out[row, pad, 4] = s[3]
    centroid = wp.float64(0.0)
    if fsum != wp.float64(0.0):
        centroid = wp.sqrt(s[4] * s[4] + s[5] * s[5]) / wp.abs(fsum)
    globals_out[row, pad, 5] = centroid


@wp.func
def energy_speed2(v: Any, u: Any, k_t: Any, inv_mass: Any) -> wp.float64:
    """The watchdog's squared energy speed of a patch, s² = u̇² + (k_T/m) u² = 2E/m [m²/s²] (E: its kinetic and
    own-spring energy), in float64."""
    ui = wp.float64(u)
    return wp.float64(v) * wp.float64(v) + wp.float64(k_t * inv_mass) * ui * ui


@wp.func
def flag_fault(
    fault_out: wp.array2d[wp.int32],
    fault_value_out: wp.array[wp.float64],
    pad: int,
    k: int,
    broken: bool,
    bad: int,
    runaway: int,
    n: int,
    value: wp.float64,
):
    """The pad's first fault at sample k (fault_out[pad] = [patch, sample, kind], kept once set): kind 0 when
    ``broken`` (a non-finite u or u̇; ``bad`` its first patch), else kind 1 when ``runaway`` < ``n`` (a patch whose
    energy speed √(:func:`energy_speed2`) = ``value`` [m/s] exceeds the pad's bound; fault_value_out[pad] = value)."""
    if fault_out[pad, 0] >= 0:
        return
    if broken:
        fault_out[pad, 0] = bad
        fault_out[pad, 1] = k
        fault_out[pad, 2] = 0
    elif runaway < n:
        fault_out[pad, 0] = runaway
        fault_out[pad, 1] = k
        fault_out[pad, 2] = 1
        fault_value_out[pad] = value


@wp.func
def patch_sample_due(k: int, first: int, last: int, every: int) -> bool:
    """Whether global sample k also records per-patch histories (window [first, last], every n-th)."""
    return k >= first and k <= last and (k - first) % every == 0


@wp.func
def store_patch_sample(
    velocity_out: wp.array2d[Any], displacement_out: wp.array2d[Any], row: int, g: int, v: Any, u: Any
):
    """Patch g's u̇ (and u, when its buffer has rows) into row ``row`` of the per-patch histories."""
    velocity_out[row, g] = v
    if displacement_out.shape[0] > 0:
        displacement_out[row, g] = u


@wp.func
def record_pad(
    pad: int,
    lane: int,
    threads: int,
    row: int,
    k: int,
    # Model:
    pad_patch_start: wp.array[wp.int32],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    pad_mu_pad: wp.array[Any],
    pad_load: wp.array[Any],
    pad_matrix_force: wp.array[Any],
    pad_matrix_radius: wp.array[Any],
    inv_mass: wp.array[Any],
    k_t: wp.array[Any],
    x: wp.array[Any],
    y: wp.array[Any],
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    # Recorder:
    globals_out: wp.array3d[wp.float64],
    watch_bound: wp.array[wp.float64],
    fault_out: wp.array2d[wp.int32],
    fault_value_out: wp.array[wp.float64],
):
    """Sample k of pad ``pad`` (lane ``lane`` of its block of ``threads``) into globals row ``row``
    (:func:`write_globals`); flags the first faulty patch (:func:`flag_fault`).

    Each of the block's ``threads`` lanes sums the patches lane, lane + threads, … in float64 (:func:`patch_sample`),
    and the block adds the lanes' sums; with one lane (a CPU block) that is the sum in patch order. Watchdog: a
    non-finite u or u̇, or a patch whose energy speed exceeds ``watch_bound[pad]`` [m/s]; "first" is the lowest
    patch index.
    """
    a = pad_patch_start[pad]
    n = pad_patch_start[pad + 1] - a
    sums = SampleSums()
    omega = pad_omega[pad]
    bound2 = watch_bound[pad] * watch_bound[pad]
    runaway = n  # the lane's first patch beyond the bound (n: none)
    broken = n  # the lane's first patch with a non-finite u or u̇ (n: none)
    i = lane
    while i < n:
        g = a + i
        v = v_in[g]
        sums += patch_sample(
            v, normal_force[g], radius[g], x[g], y[g], omega, pad_mu_scale[pad], pad_slope[pad], pad_decay[pad]
        )
        if energy_speed2(v, u_in[g], k_t[g], inv_mass[g]) > bound2 and runaway == n:
            runaway = i
        if broken == n and not (wp.isfinite(v) and wp.isfinite(wp.float64(u_in[g]))):
            broken = i
        i += threads
    sums = block_sums(sums)
    runaway = wp.tile_min(wp.tile(runaway))[0]
    broken = wp.tile_min(wp.tile(broken))[0]
    if lane != 0:
        return
    write_globals(
        globals_out, row, pad, sums, omega, pad_mu_pad[pad], pad_matrix_force[pad], pad_matrix_radius[pad],
        pad_load[pad],
    )  # fmt: skip
    value = wp.float64(0.0)
    if runaway < n:
        g = a + runaway
        value = wp.sqrt(energy_speed2(v_in[g], u_in[g], k_t[g], inv_mass[g]))
    flag_fault(fault_out, fault_value_out, pad, k, broken < n, broken, runaway, n, value)
