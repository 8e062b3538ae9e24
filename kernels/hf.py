"""HF kernels: patch forces, integrator stages, recording, growth and the device contact solve.

Equation of motion of patch i (paper §2.1.2, docs/model.md §2.2), u along the local disc direction:

    m_i ü_i + c_i u̇_i + k_T,i u_i + Σ_j k_ij (u_i − u_j) = F_N,i f(ω r_i − u̇_i),
    k_ij = K_C √A_i √A_j / D0_ij,   f(v) = (M/π) atan(a v) (1/(b|v| + 1) + 1)   (Eq. 4, signed).

All kernels are generic in the state precision T (float32 or float64; overloads generated at the bottom). Batched
pads are flat arrays: ``patch_pad`` gives each patch's pad, ``pad_patch_start`` (pads+1) the offsets, and
``pad_*`` arrays hold per-pad parameters. Recorded sums are accumulated in float64 whatever T is.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels import precision_overloads

wp.set_module_options({"enable_backward": False})

# counters[] slots shared by the recording kernels (int32 array of length 4)
SAMPLE_INDEX = 0  # absolute index of the next global sample
GLOBAL_ROWS = 1  # rows written to the global buffer since the last flush
PATCH_ROWS = 2  # rows written to the per-patch buffer since the last flush
RECORD_FLAG = 3  # adaptive stepping: 1 when every pad has landed on the sample time (kernels.hf_adaptive.landing)

N_GLOBAL = 6  # mu, torque, friction radius, Σ u̇, Σ|u̇|, friction centroid


# ---------------------------------------------------------------------------------------------- physics


@wp.func
def friction_coefficient(vp: Any, mu_scale: Any, slope: Any, decay: Any):
    """Signed Eq. 4: f(vp) = mu_scale atan(slope vp)(1/(decay|vp| + 1) + 1), mu_scale = M/π."""
    one = type(vp)(1.0)
    return mu_scale * wp.atan(slope * vp) * (one / (decay * wp.abs(vp) + one) + one)


@wp.func
def friction_pair(vp: Any, mu_scale: Any, slope: Any, decay: Any):
    """(f(vp), df/dvp) of :func:`friction_coefficient`, sharing one atan [1, s/m]."""
    one = type(vp)(1.0)
    at = wp.atan(slope * vp)
    rq = one / (decay * wp.abs(vp) + one)
    da = slope / (one + slope * slope * vp * vp)
    return mu_scale * at * (rq + one), mu_scale * (da * (rq + one) - at * decay * wp.sign(vp) * rq * rq)


@wp.func
def spring_force(
    i: int,
    u: wp.array[Any],
    k_diag: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
):
    """Elastic force on patch i: Σ_j k_ij u_j − (k_T,i + Σ_j k_ij) u_i [N].

    Two partial sums break the dependency chain of the gather (about 30 % faster on the CPU); the order of
    summation is fixed, so results stay bit-reproducible.
    """
    a0 = u[i] - u[i]
    a1 = a0
    e = nbr_start[i]
    end = nbr_start[i + 1]
    while e + 1 < end:
        a0 += nbr_stiffness[e] * u[nbr_index[e]]
        a1 += nbr_stiffness[e + 1] * u[nbr_index[e + 1]]
        e += 2
    if e < end:
        a0 += nbr_stiffness[e] * u[nbr_index[e]]
    return (a0 + a1) - k_diag[i] * u[i]


@wp.func
def solve_velocity(a: Any, b: Any, hfn: Any, vd: Any, guess: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any):
    """Solve a·v − hfn·f(vd − v) = b for v (a > 0, hfn ≥ 0): per-patch implicit friction.

    Works on the increment δ = v − guess, so the convergence test is relative to the size of the step's
    velocity change (meaningful in fp32 too). |f| ≤ 2 mu_scale π/2 brackets δ in
    [(r − hfn f_max)/a, (r + hfn f_max)/a], r = b − a·guess; safeguarded Newton (bisection whenever a Newton
    step would leave the bracket) converges for any step size. It stops at an exact root, or when the
    Newton step or the bracket is below ``tol`` times (|r| + hfn f_max)/a: a smooth patch costs two
    friction evaluations per solve.
    """
    fmax = mu_scale * type(a)(3.141592653589793)
    r = b - a * guess
    lo = (r - hfn * fmax) / a
    hi = (r + hfn * fmax) / a
    dtol = tol * (wp.abs(r) + hfn * fmax) / a
    vp0 = vd - guess
    zero = a - a
    d = wp.clamp(zero, lo, hi)
    for _it in range(60):
        f, df = friction_pair(vp0 - d, mu_scale, slope, decay)
        g = a * d - hfn * f - r
        if g == zero:
            break
        if g > zero:
            hi = d
        else:
            lo = d
        dg = a + hfn * df
        dn = d - g / dg
        # Bisect only when Newton would leave the bracket. A step that rounds to d itself (the root found to the
        # last bit, where d is also a bracket end) is accepted and converges: treating dn == lo/hi as leaving made
        # ~13 % of fp32 patches on an H100 bisect ~20 times per solve (scripts/profile_onchip.py, docs/onchip.md).
        if dg <= zero or dn < lo or dn > hi:
            dn = type(a)(0.5) * (lo + hi)
        converged = wp.abs(dn - d) <= dtol or hi - lo <= dtol
        d = dn
        if converged:
            break
    return guess + d


@wp.func
def midpoint_friction(
    v: Any, dt: Any, m: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any
):
    """Implicit-midpoint step of m v̇ = F_N f(vd − v) − c v over dt (second order, A-stable).

    Solves m (v_m − v) = dt/2 (F_N f(vd − v_m) − c v_m) for the midpoint velocity, returns 2 v_m − v.
    """
    half = type(v)(0.5) * dt
    vm = solve_velocity(m + half * c, m * v, half * fn, vd, v, mu_scale, slope, decay, tol)
    return type(v)(2.0) * vm - v


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
def growth_due(step: wp.array[wp.int64], every: int) -> bool:
    """Whether a growth event is due. ``every`` > 0 (fixed step): whether the step just taken (``step[0]`` counts
    completed steps before it) ends a growth interval; ``every`` = 0 (adaptive): whether ``step[0]``, the event
    flag that the adaptive landing sets when every pad stands on an event time, is set."""
    if every == 0:
        return step[0] != wp.int64(0)
    return (step[0] + wp.int64(1)) % wp.int64(every) == wp.int64(0)


# ---------------------------------------------------------------------------------------------- stepping


@wp.kernel
def euler_velocity(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    k_diag: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    dt: Any,
    # State in:
    u_in: wp.array[Any],
    # State in/out:
    v_io: wp.array[Any],
):
    """Symplectic Euler, velocity half: v ← v + dt/m (F_s(u) + F_N f(ωr − v) − c v) (explicit friction)."""
    i = wp.tid()
    p = patch_pad[i]
    v = v_io[i]
    fs = spring_force(i, u_in, k_diag, nbr_start, nbr_index, nbr_stiffness)
    vp = pad_omega[p] * radius[i] - v
    ff = normal_force[i] * friction_coefficient(vp, pad_mu_scale[p], pad_slope[p], pad_decay[p])
    v_io[i] = v + dt * inv_mass[i] * (fs + ff - damping[i] * v)


@wp.kernel
def implicit_velocity(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    k_diag: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    dt: Any,
    tol: Any,
    # State in:
    u_in: wp.array[Any],
    # State in/out:
    v_io: wp.array[Any],
):
    """IMEX Euler, velocity half: m(v⁺ − v) = dt (F_s(u) + F_N f(ωr − v⁺) − c v⁺), Newton per patch."""
    i = wp.tid()
    p = patch_pad[i]
    v = v_io[i]
    m = type(v)(1.0) / inv_mass[i]
    fs = spring_force(i, u_in, k_diag, nbr_start, nbr_index, nbr_stiffness)
    a = m + dt * damping[i]
    b = m * v + dt * fs
    vd = pad_omega[p] * radius[i]
    v_io[i] = solve_velocity(a, b, dt * normal_force[i], vd, v, pad_mu_scale[p], pad_slope[p], pad_decay[p], tol)


@wp.kernel
def drift(
    dt: Any,
    # State in:
    v_in: wp.array[Any],
    # State in/out:
    u_io: wp.array[Any],
):
    """Position update u ← u + dt v (second half of both Euler schemes)."""
    i = wp.tid()
    u_io[i] = u_io[i] + dt * v_in[i]


@wp.kernel
def spring_forces(
    # Model:
    k_diag: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_stiffness: wp.array[Any],
    # State in:
    u_in: wp.array[Any],
    # State out:
    force_out: wp.array[Any],
):
    """Elastic force F_s(u) on every patch [N] (first-same-as-last cache of the Strang scheme)."""
    i = wp.tid()
    force_out[i] = spring_force(i, u_in, k_diag, nbr_start, nbr_index, nbr_stiffness)


@wp.kernel
def strang_open(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    dt: Any,
    tol: Any,
    # State in:
    force_in: wp.array[Any],
    # State in/out:
    u_io: wp.array[Any],
    v_io: wp.array[Any],
):
    """Strang, first half step from a synchronous state: friction over dt/2, half kick, drift.

    Afterwards ``v_io`` holds the staggered velocity w (the velocity just before the next half kick).
    """
    i = wp.tid()
    p = patch_pad[i]
    half = dt * type(dt)(0.5)
    im = inv_mass[i]
    vd = pad_omega[p] * radius[i]
    v = midpoint_friction(
        v_io[i],
        half,
        type(dt)(1.0) / im,
        damping[i],
        normal_force[i],
        vd,
        pad_mu_scale[p],
        pad_slope[p],
        pad_decay[p],
        tol,
    )
    v = v + half * im * force_in[i]
    v_io[i] = v
    u_io[i] = u_io[i] + dt * v


@wp.kernel
def strang_step(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    dt: Any,
    tol: Any,
    # State in:
    force_in: wp.array[Any],
    # State in/out:
    u_io: wp.array[Any],
    v_io: wp.array[Any],
):
    """One merged Strang step on the staggered velocity w: kick dt/2, friction dt, kick dt/2, drift.

    The closing friction half of step n and the opening half of step n+1 are one implicit-midpoint solve
    over dt; both kicks use the cached F_s(uₙ). Follow with :func:`spring_forces` at the new u.
    """
    i = wp.tid()
    p = patch_pad[i]
    half = dt * type(dt)(0.5)
    im = inv_mass[i]
    kick = half * im * force_in[i]
    vd = pad_omega[p] * radius[i]
    v = (
        midpoint_friction(
            v_io[i] + kick,
            dt,
            type(dt)(1.0) / im,
            damping[i],
            normal_force[i],
            vd,
            pad_mu_scale[p],
            pad_slope[p],
            pad_decay[p],
            tol,
        )
        + kick
    )
    v_io[i] = v
    u_io[i] = u_io[i] + dt * v


@wp.kernel
def strang_close(
    # Model:
    patch_pad: wp.array[wp.int32],
    inv_mass: wp.array[Any],
    damping: wp.array[Any],
    normal_force: wp.array[Any],
    radius: wp.array[Any],
    pad_omega: wp.array[Any],
    pad_mu_scale: wp.array[Any],
    pad_slope: wp.array[Any],
    pad_decay: wp.array[Any],
    dt: Any,
    tol: Any,
    # State in:
    force_in: wp.array[Any],
    v_in: wp.array[Any],
    # Out:
    v_out: wp.array[Any],
):
    """Synchronous velocity from the staggered w and F_s(uₙ): half kick, friction over dt/2 (may be in place)."""
    i = wp.tid()
    p = patch_pad[i]
    half = dt * type(dt)(0.5)
    im = inv_mass[i]
    vd = pad_omega[p] * radius[i]
    v_out[i] = midpoint_friction(
        v_in[i] + half * im * force_in[i],
        half,
        type(dt)(1.0) / im,
        damping[i],
        normal_force[i],
        vd,
        pad_mu_scale[p],
        pad_slope[p],
        pad_decay[p],
        tol,
    )


# ---------------------------------------------------------------------------------------------- recording


@wp.func
def patch_sample_due(k: int, first: int, last: int, every: int) -> bool:
    """Whether global sample k also records per-patch histories (window [first, last], every n-th)."""
    return k >= first and k <= last and (k - first) % every == 0


@wp.func
def write_globals(
    globals_out: wp.array3d[wp.float64],
    row: int,
    pad: int,
    fsum: wp.float64,
    tsum: wp.float64,
    vsum: wp.float64,
    vabs: wp.float64,
    fxsum: wp.float64,
    fysum: wp.float64,
    omega: Any,
    mu_pad: Any,
    matrix_force: Any,
    matrix_radius: Any,
    load: Any,
):
    """Write one pad's sample row: μ, torque [N m], friction radius [m], Σu̇, Σ|u̇| [m/s], friction centroid [m]
    from the float64 patch sums of friction force, torque and force-weighted position (Σ F_i x_i, Σ F_i y_i) and the
    matrix's Coulomb friction μ_pad F_m sign(ω) at radius r_m.

    Friction radius r_eff = T / total friction force (matrix included); friction centroid = |Σ F_i r⃗_i| / |Σ F_i|,
    the distance from the disc axis of the centroid of the patches' friction forces (the matrix, whose friction
    does not vibrate and whose cells carry no angular position, is left out; 0 when the patch forces sum to 0)."""
    fm = wp.float64(mu_pad * matrix_force * sign_or_zero(omega))
    ftot = fsum + fm
    ttot = tsum + fm * wp.float64(matrix_radius)
    mu = wp.float64(0.0)
    reff = wp.float64(0.0)
    if wp.float64(load) > wp.float64(0.0):
        mu = ftot / wp.float64(load)
    if ftot != wp.float64(0.0):
        reff = ttot / ftot
    globals_out[row, pad, 0] = mu
    globals_out[row, pad, 1] = ttot
    globals_out[row, pad, 2] = reff
    globals_out[row, pad, 3] = vsum
    globals_out[row, pad, 4] = vabs
    centroid = wp.float64(0.0)
    if fsum != wp.float64(0.0):
        centroid = wp.sqrt(fxsum * fxsum + fysum * fysum) / wp.abs(fsum)
    globals_out[row, pad, 5] = centroid


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
    """Sample k of pad ``pad`` (lane ``lane`` of its block of ``threads``) into globals row ``row``: μ, torque [N m],
    friction radius [m], Σu̇ [m/s], Σ|u̇| [m/s], friction centroid [m]; flags the first faulty patch.

    μ = (Σ F_N,i f(ωr_i − u̇_i) + μ_pad F_matrix sign ω)/F_N (0 without load); T = Σ r_i F_i + r_m μ_pad F_m;
    r_eff = T / total friction force; centroid = |Σ F_i (x_i, y_i)| / |Σ F_i| over the patches (:func:`write_globals`).
    Each of the block's ``threads`` lanes sums the patches lane, lane + threads, … in float64, and the block adds
    the lanes' sums; with one lane (a CPU block) that is the sum in patch order.

    Watchdog (fault_out[pad] = [patch, sample, kind], first fault only): kind 0 a non-finite u or u̇; kind 1 a
    patch whose energy speed s_i = √(u̇_i² + (k_T,i/m_i) u_i²) = √(2E_i/m_i) exceeds ``watch_bound[pad]`` [m/s]
    (E_i: the patch's kinetic and own-spring energy); fault_value_out[pad] = s_i; "first" is the lowest patch index.
    """
    a = pad_patch_start[pad]
    n = pad_patch_start[pad + 1] - a
    fsum = wp.float64(0.0)
    tsum = wp.float64(0.0)
    vsum = wp.float64(0.0)
    vabs = wp.float64(0.0)
    fxsum = wp.float64(0.0)
    fysum = wp.float64(0.0)
    omega = pad_omega[pad]
    bound2 = watch_bound[pad] * watch_bound[pad]
    runaway = n  # the lane's first patch beyond the bound (n: none)
    broken = n  # the lane's first patch with a non-finite u or u̇ (n: none)
    i = lane
    while i < n:
        g = a + i
        v = v_in[g]
        f = normal_force[g] * friction_coefficient(
            omega * radius[g] - v, pad_mu_scale[pad], pad_slope[pad], pad_decay[pad]
        )
        fsum += wp.float64(f)
        tsum += wp.float64(f * radius[g])
        vsum += wp.float64(v)
        vabs += wp.float64(wp.abs(v))
        fxsum += wp.float64(f * x[g])
        fysum += wp.float64(f * y[g])
        ui = wp.float64(u_in[g])
        s2 = wp.float64(v) * wp.float64(v) + wp.float64(k_t[g] * inv_mass[g]) * ui * ui
        if s2 > bound2 and runaway == n:
            runaway = i
        if broken == n and not (wp.isfinite(v) and wp.isfinite(ui)):
            broken = i
        i += threads
    fsum = wp.tile_sum(wp.tile(fsum))[0]
    tsum = wp.tile_sum(wp.tile(tsum))[0]
    vsum = wp.tile_sum(wp.tile(vsum))[0]
    vabs = wp.tile_sum(wp.tile(vabs))[0]
    fxsum = wp.tile_sum(wp.tile(fxsum))[0]
    fysum = wp.tile_sum(wp.tile(fysum))[0]
    runaway = wp.tile_min(wp.tile(runaway))[0]
    broken = wp.tile_min(wp.tile(broken))[0]
    if lane != 0:
        return
    write_globals(
        globals_out, row, pad, fsum, tsum, vsum, vabs, fxsum, fysum, omega, pad_mu_pad[pad],
        pad_matrix_force[pad], pad_matrix_radius[pad], pad_load[pad],
    )  # fmt: skip
    if fault_out[pad, 0] >= 0:
        return
    if broken < n:
        fault_out[pad, 0] = broken
        fault_out[pad, 1] = k
        fault_out[pad, 2] = 0
    elif runaway < n:
        g = a + runaway
        ui = wp.float64(u_in[g])
        vi = wp.float64(v_in[g])
        fault_out[pad, 0] = runaway
        fault_out[pad, 1] = k
        fault_out[pad, 2] = 1
        fault_value_out[pad] = wp.sqrt(vi * vi + wp.float64(k_t[g] * inv_mass[g]) * ui * ui)


@wp.kernel
def record_globals(
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
    conditional: int,
    threads: int,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    # Recorder:
    counters: wp.array[wp.int32],
    globals_out: wp.array3d[wp.float64],
    watch_bound: wp.array[wp.float64],
    fault_out: wp.array2d[wp.int32],
    fault_value_out: wp.array[wp.float64],
):
    """Per pad (one block, ``launch_tiled``): the sample ``counters[0]`` into globals row ``counters[1]``
    (:func:`record_pad`); with ``conditional``, only when ``counters[3]`` flags a sample."""
    pad, lane = wp.tid()
    if conditional != 0 and counters[3] == 0:
        return
    record_pad(
        pad, lane, threads, counters[1], counters[0], pad_patch_start, normal_force, radius, pad_omega, pad_mu_scale,
        pad_slope, pad_decay, pad_mu_pad, pad_load, pad_matrix_force, pad_matrix_radius, inv_mass, k_t, x, y, u_in,
        v_in, globals_out, watch_bound, fault_out, fault_value_out,
    )  # fmt: skip


@wp.kernel
def record_patches(
    first: int,
    last: int,
    every: int,
    conditional: int,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    # Recorder:
    counters: wp.array[wp.int32],
    velocity_out: wp.array2d[Any],
    displacement_out: wp.array2d[Any],
):
    """Copy u̇ (and u, when its buffer has rows) of every patch into the per-patch buffers when due."""
    i = wp.tid()
    if conditional != 0 and counters[3] == 0:
        return
    if not patch_sample_due(counters[0], first, last, every):
        return
    row = counters[2]
    velocity_out[row, i] = v_in[i]
    if displacement_out.shape[0] > 0:
        displacement_out[row, i] = u_in[i]


@wp.kernel
def advance_counters(first: int, last: int, every: int, conditional: int, counters: wp.array[wp.int32]):
    """After a sample: next sample index and buffer rows (one thread)."""
    if conditional != 0 and counters[3] == 0:
        return
    k = counters[0]
    if patch_sample_due(k, first, last, every):
        counters[2] = counters[2] + 1
    counters[0] = k + 1
    counters[1] = counters[1] + 1


# ---------------------------------------------------------------------------------------------- growth


@wp.kernel
def tick(step: wp.array[wp.int64]):
    """Count a completed step (one thread); growth kernels read the count to fire every n-th step."""
    step[0] = step[0] + wp.int64(1)


@wp.func
def grow_patch(
    i: int,
    p: int,
    pad_growth: wp.array[Any],
    pad_k_t: wp.array[Any],
    pad_k_n: wp.array[Any],
    pad_mass_per_area: wp.array[Any],
    pad_zeta: wp.array[Any],
    area_io: wp.array[Any],
    sqrt_area_out: wp.array[Any],
    inv_mass_out: wp.array[Any],
    k_t_out: wp.array[Any],
    k_n_out: wp.array[Any],
    damping_out: wp.array[Any],
):
    """One growth event of patch i of pad p (paper Eq. 10): A ← A + g √A, then m, k_T, k_N, c follow the area."""
    a = area_io[i]
    a = a + pad_growth[p] * wp.sqrt(a)
    s = wp.sqrt(a)
    m = pad_mass_per_area[p] * a
    kt = pad_k_t[p] * s
    area_io[i] = a
    sqrt_area_out[i] = s
    inv_mass_out[i] = type(a)(1.0) / m
    k_t_out[i] = kt
    k_n_out[i] = pad_k_n[p] * s
    damping_out[i] = type(a)(2.0) * pad_zeta[p] * wp.sqrt(kt * m)


@wp.kernel
def grow_patches(
    # Model:
    patch_pad: wp.array[wp.int32],
    pad_growth: wp.array[Any],
    pad_k_t: wp.array[Any],
    pad_k_n: wp.array[Any],
    pad_mass_per_area: wp.array[Any],
    pad_zeta: wp.array[Any],
    # Control:
    step: wp.array[wp.int64],
    every: int,
    # Model in/out:
    area_io: wp.array[Any],
    sqrt_area_out: wp.array[Any],
    inv_mass_out: wp.array[Any],
    k_t_out: wp.array[Any],
    k_n_out: wp.array[Any],
    damping_out: wp.array[Any],
):
    """One growth event for every patch (:func:`grow_patch`) when an event is due (:func:`growth_due`)."""
    i = wp.tid()
    if not growth_due(step, every):
        return
    grow_patch(
        i, patch_pad[i], pad_growth, pad_k_t, pad_k_n, pad_mass_per_area, pad_zeta, area_io, sqrt_area_out,
        inv_mass_out, k_t_out, k_n_out, damping_out,
    )  # fmt: skip


@wp.func
def patch_coupling(
    i: int,
    p: int,
    sqrt_area: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_inv_dist: wp.array[Any],
    pad_kc: wp.array[Any],
    k_t: wp.array[Any],
    nbr_stiffness_out: wp.array[Any],
    k_diag_out: wp.array[Any],
):
    """k_ij = K_C √A_i √A_j / D0_ij for every link of patch i of pad p [N/m] (paper Eq. 3) and k_T,i + Σ_j k_ij."""
    ki = pad_kc[p] * sqrt_area[i]
    d = k_t[i]
    for e in range(nbr_start[i], nbr_start[i + 1]):
        k = ki * sqrt_area[nbr_index[e]] * nbr_inv_dist[e]
        nbr_stiffness_out[e] = k
        d += k
    k_diag_out[i] = d


@wp.kernel
def coupling_stiffness(
    # Model:
    patch_pad: wp.array[wp.int32],
    sqrt_area: wp.array[Any],
    nbr_start: wp.array[wp.int32],
    nbr_index: wp.array[wp.int32],
    nbr_inv_dist: wp.array[Any],
    pad_kc: wp.array[Any],
    k_t: wp.array[Any],
    # Control:
    step: wp.array[wp.int64],
    every: int,
    # Model out:
    nbr_stiffness_out: wp.array[Any],
    k_diag_out: wp.array[Any],
):
    """Coupling stiffnesses of every patch (:func:`patch_coupling`) when an event is due (:func:`growth_due`)."""
    i = wp.tid()
    if not growth_due(step, every):
        return
    patch_coupling(
        i, patch_pad[i], sqrt_area, nbr_start, nbr_index, nbr_inv_dist, pad_kc, k_t, nbr_stiffness_out, k_diag_out
    )


@wp.func
def contact_block(
    pad: int,
    lane: int,
    threads: int,
    pad_patch_start: wp.array[wp.int32],
    k_n: wp.array[Any],
    height: wp.array[Any],
    area: wp.array[Any],
    radius: wp.array[Any],
    pad_area: wp.array[wp.float64],
    pad_moment: wp.array[wp.float64],
    pad_k_m: wp.array[wp.float64],
    pad_load: wp.array[Any],
    gap: wp.float64,
    out_start: int,
    out_end: int,
    writer: bool,
    normal_force_out: wp.array[Any],
    pad_matrix_force_out: wp.array[Any],
    pad_matrix_radius_out: wp.array[Any],
) -> wp.float64:
    """Re-solve the normal forces of one pad on a flat matrix at elevation 0 (one thread block per pad).

    Σ_i k_N,i max(h_i − g, 0) + k_m a_free max(−g, 0) = F_N by Newton from the left of the root (monotone
    and exact on a piecewise-linear convex function), warm-started from the previous gap; it stops when the step
    falls below 1e-15 of the gap or stops being positive (the rounding floor of the block sums; with the first
    test alone, the re-solve late in the varying-area study cost 7.3 µs per step on the H100 against 1.0 µs after
    this stop, docs/onchip.md). Launch with
    ``wp.launch_tiled(dim=[pads], block_dim=B)``; ``threads`` is the block size the device runs (B on CUDA, 1 on
    the CPU): thread ``lane`` sums patches lane, lane + B, … and the block reduces the sums, so every thread
    sees the same values and takes the same branches (the block-wide reductions stay outside per-thread code).
    Every thread of the block must call it (block-wide reductions inside).

    ``gap``: the previous gap g [m] (the warm start); returns the new one (unchanged when the load is 0), which the
    caller stores. Writes the normal forces of the patches ``out_start`` … ``out_end − 1`` only (global indices;
    the pad's whole range on the general path, a block's own part in a cluster, where every block of the cluster
    solves the same contact redundantly) and, when ``writer``, the pad's matrix force and radius.
    """
    s = pad_patch_start[pad]
    e = pad_patch_start[pad + 1]
    zero = wp.float64(0.0)
    load = wp.float64(pad_load[pad])
    covered = zero
    moment = zero
    hmin = zero
    ktot = zero
    i = s + lane
    while i < e:
        covered += wp.float64(area[i])
        moment += wp.float64(area[i] * radius[i])
        hmin = wp.min(hmin, wp.float64(height[i]))
        ktot += wp.float64(k_n[i])
        i += threads
    covered = wp.tile_sum(wp.tile(covered))[0]
    moment = wp.tile_sum(wp.tile(moment))[0]
    hmin = wp.tile_min(wp.tile(hmin))[0]
    ktot = wp.tile_sum(wp.tile(ktot))[0]
    free = wp.max(pad_area[pad] - covered, zero)
    km = pad_k_m[pad] * free
    ktot += km
    if free > zero and lane == 0 and writer:
        pad_matrix_radius_out[pad] = type(pad_load[pad])((pad_moment[pad] - moment) / free)
    g = gap
    if load > zero:
        for it in range(200):
            fp = zero
            kp = zero
            i = s + lane
            while i < e:
                d = wp.float64(height[i]) - g
                if d > zero:
                    fp += wp.float64(k_n[i]) * d
                    kp += wp.float64(k_n[i])
                i += threads
            f = km * wp.max(-g, zero) + wp.tile_sum(wp.tile(fp))[0]
            kact = wp.tile_sum(wp.tile(kp))[0]
            if g < zero:
                kact += km
            if it == 0 and f < load:
                g = hmin - load / ktot  # restart left of the root, where every element is compressed
                continue
            if kact <= zero:
                break
            dg = (f - load) / kact
            if dg <= zero:  # from the left of the root Newton only moves right: here f = F_N to rounding
                break
            g = g + dg
            if dg <= wp.float64(1.0e-15) * (wp.abs(g) + wp.float64(1.0e-9)):
                break
    i = out_start + lane
    while i < out_end:
        f_i = zero
        if load > zero:
            f_i = wp.float64(k_n[i]) * wp.max(wp.float64(height[i]) - g, zero)
        normal_force_out[i] = type(pad_load[pad])(f_i)
        i += threads
    if lane == 0 and writer:
        if load > zero:
            pad_matrix_force_out[pad] = type(pad_load[pad])(km * wp.max(-g, zero))
        else:
            pad_matrix_force_out[pad] = type(pad_load[pad])(0.0)
    return g


@wp.kernel
def contact_flat(
    # Model:
    pad_patch_start: wp.array[wp.int32],
    k_n: wp.array[Any],
    height: wp.array[Any],
    area: wp.array[Any],
    radius: wp.array[Any],
    pad_area: wp.array[wp.float64],
    pad_moment: wp.array[wp.float64],
    pad_k_m: wp.array[wp.float64],
    pad_load: wp.array[Any],
    # Control:
    step: wp.array[wp.int64],
    every: int,
    threads: int,
    # Contact in/out:
    pad_gap: wp.array[wp.float64],
    normal_force_out: wp.array[Any],
    pad_matrix_force_out: wp.array[Any],
    pad_matrix_radius_out: wp.array[Any],
):
    """:func:`contact_block` for every pad (one thread block each) when an event is due (:func:`growth_due`)."""
    pad, lane = wp.tid()
    if not growth_due(step, every):
        return
    g = contact_block(
        pad, lane, threads, pad_patch_start, k_n, height, area, radius, pad_area, pad_moment, pad_k_m, pad_load,
        pad_gap[pad], pad_patch_start[pad], pad_patch_start[pad + 1], True, normal_force_out, pad_matrix_force_out,
        pad_matrix_radius_out,
    )  # fmt: skip
    if lane == 0:
        pad_gap[pad] = g  # every thread read the old gap: the reductions in contact_block are block barriers


# ---------------------------------------------------------------------------------------------- overloads

precision_overloads(
    euler_velocity, implicit_velocity, drift, spring_forces, strang_open, strang_step, strang_close,
    record_globals, record_patches, grow_patches, coupling_stiffness, contact_flat,
)  # fmt: skip
