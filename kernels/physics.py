"""The HF model's physics as Warp functions, one home per term: every engine's kernels call them (the general and
adaptive kernels, both on-chip kernels), so a change of the model is made here only.

Equation of motion of patch i (paper §2.1.2, docs/model.md §2.2), u along the local disc direction:

    m_i ü_i + c_i u̇_i + k_T,i u_i + Σ_j k_ij (u_i − u_j) = F_N,i f(ω r_i − u̇_i),
    k_ij = K_C √A_i √A_j / D0_ij,   f(v) = (M/π) atan(a v) (1/(b|v| + 1) + 1)   (Eq. 4, signed).

* friction: the law f (:func:`friction_coefficient`, also the LF automaton's patch friction), the per-patch
  implicit solve (:func:`solve_velocity`), the θ-method step of a patch's forced friction equation
  (:func:`theta_substep`; backward Euler for ``implicit-friction``) and the damped-midpoint friction sub-step
  (:func:`friction_substep`, :func:`friction_substep_pair`), which every Strang path, general and on-chip, takes
  through :func:`strang_velocity`, :func:`strang_sample_velocity` (``strang``'s samples) and
  :func:`strang_close_velocity` (a run's end, and the error-controlled split step's samples); for strang's crossing
  treatment the law's integral (:func:`friction_integral`, :func:`friction_integral_at` where the arctangent is
  known) and its mean along a step's slip segment (:func:`segment_pair`);
* per-patch terms: the coupling gather F_s,i = Σ_j k_ij u_j − k_diag,i u_i (:func:`spring_force`; the on-chip
  shared-memory gather sums the links in the same order, :mod:`aca_warp.kernels.hf_onchip_gather`), the net force
  of the explicit schemes (:func:`patch_force`), growth (Eq. 10, :func:`grow_patch`) and the coupling stiffness it
  changes (Eq. 3, :func:`patch_coupling`);
* contact: one pad's normal forces on the flat matrix (:func:`contact_block`);
* samples: a patch's terms of a sample (:func:`patch_sample`; the crossing treatment's :func:`instant_velocity`), the
  block sums, the globals row (:func:`write_globals`), the watchdog and the per-patch histories (:func:`record_pad`
  puts them together).

Functions are generic in the state precision T (float32 or float64 arguments; sample sums in float64); those that read
the model's or the recorder's arrays take them as one struct, ``model`` (:data:`~aca_warp.kernels.hf_types.HFModel`)
or ``rec`` (:data:`~aca_warp.kernels.hf_types.HFRecorder`). SI units: velocities in m/s, forces in N, masses in kg,
times in s.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from aca_warp.kernels.tiles import cpu_build

wp.set_module_options({"enable_backward": False})

N_GLOBAL = 6  # mu, torque, friction radius, Σ u̇, Σ|u̇|, friction centroid
# the float64 sums of a sample: Σ F_i, Σ F_i r_i, Σ u̇_i, Σ |u̇_i|, Σ F_i x_i, Σ F_i y_i
SampleSums = wp.types.vector(length=6, dtype=wp.float64)


# ---------------------------------------------------------------------------------------------- friction


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


SEGMENT_TOL = wp.constant(1.0e3)  # a slip segment below this × the solve's tolerance [m/s]: f at its midpoint
INSTANT_SEED = wp.constant(20261130)  # seeds the instant reading, with the sample index (instant_velocity)


@wp.func
def friction_integral(s: Any, mu_scale: Any, slope: Any, decay: Any):
    """G(s) = ∫₀ˢ f(x) dx of Eq. 4 [m/s], even in s, in closed form up to O(decay²/slope³) (≈ 4e-9 m/s for the
    presets' law), in the precision of ``s`` (:func:`friction_integral_at` at |s|)."""
    x = wp.abs(s)
    return friction_integral_at(x, wp.atan(slope * x), mu_scale, slope, decay)


@wp.func
def friction_integral_at(x: Any, at: Any, mu_scale: Any, slope: Any, decay: Any):
    """G at slip magnitude ``x`` = |s| [m/s] given ``at`` = atan(slope x), which Eq. 4 at ±x shares
    (:func:`segment_pair`).

    With x = |s|, a = slope, b = decay and H(x) = ∫₀ˣ (1/(b x' + 1) + 1) dx' = x + ln(1 + b x)/b, by parts
    G = (M/π)[atan(a x) H(x) − ∫₀ˣ a H/(1 + a² x'²) dx']; the last integral is ln(1 + a² x²)/a for H's linear part
    2x, plus ∫ a (H − 2x')/(1 + a² x'²) dx', taken with a/(1 + a² x'²) → 1/(a x'²) (exactly
    (1 − ln(1 + b x)/(b x) − ln(1 + b x))/a) and the leading correction b atan(a x)/(2a²) from H − 2x' ≈ −b x'²/2
    where the two kernels differ (docs/friction_step.md §8)."""
    one = type(x)(1.0)
    half = type(x)(0.5)
    bx = decay * x
    r = one - bx * (half - bx * (one / type(x)(3.0) - bx / type(x)(4.0)))  # ln(1 + b x)/(b x), b x < 1e-3: series
    ln = bx * r
    q = one - r  # 1 − ln(1 + b x)/(b x)
    hx = x * (one + r)  # H(x)
    if bx >= type(x)(1.0e-3):
        ln = wp.log(one + bx)
        q = one - ln / bx
        hx = x + ln / decay
    ax = slope * x
    g = at * hx - (wp.log(one + ax * ax) + (q - ln) + decay * at / (type(x)(2.0) * slope)) / slope
    return mu_scale * g


@wp.func
def segment_pair(vp: Any, s0: Any, g0: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any):
    """The law of a step that crosses zero slip, at midpoint slip ``vp`` [m/s] of a step that starts at slip ``s0``
    (G(s0) = ``g0``, :func:`friction_integral`): the mean of f over the slips from s0 to s1 = 2 vp − s0 and its
    derivative in vp [1, s/m] (the averaged-vector-field form of the midpoint); :func:`friction_pair` at vp where
    the segment is shorter than :data:`SEGMENT_TOL` × ``tol`` m/s (1e-3 m/s in fp32, 1e-6 m/s in fp64), which
    misses the mean there by at most f″ Δs²/24 (5e-4, 5e-10); the rounding of G's difference, 2ε|G|/Δs, would
    overtake that only below a few 1e-4 m/s in fp32 (docs/friction_step.md §8.1). G(s1) and f(s1) share one
    arctangent: atan is odd, so f(s1) takes ±atan(slope |s1|), the same bits as :func:`friction_coefficient` (up to
    the sign of a zero)."""
    one = type(vp)(1.0)
    ds = type(vp)(2.0) * (vp - s0)
    if wp.abs(ds) <= type(vp)(SEGMENT_TOL) * tol:
        return friction_pair(vp, mu_scale, slope, decay)
    s1 = s0 + ds
    x1 = wp.abs(s1)
    at = wp.atan(slope * x1)
    inv = one / ds
    mean = (friction_integral_at(x1, at, mu_scale, slope, decay) - g0) * inv
    f1 = mu_scale * wp.where(s1 < vp - vp, -at, at) * (one / (decay * x1 + one) + one)
    return mean, type(vp)(2.0) * (f1 - mean) * inv


@wp.func
def law_pair(vp: Any, seg: int, s0: Any, g0: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any):
    """(f, df/dvp) of the implicit solve's law: Eq. 4 at ``vp`` (:func:`friction_pair`), or with ``seg`` ≠ 0 its
    mean along the step's slip segment from ``s0`` (:func:`segment_pair`)."""
    if seg != 0:
        return segment_pair(vp, s0, g0, mu_scale, slope, decay, tol)
    return friction_pair(vp, mu_scale, slope, decay)


@wp.func
def solve_velocity(
    a: Any, r: Any, hfn: Any, vd: Any, guess: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any, seg: int, s0: Any,
    g0: Any, known: int, f_guess: Any, df_guess: Any,
):  # fmt: skip
    """Solve a·v − hfn·f(vd − v) = b for v (a > 0, hfn ≥ 0), given r = b − a·guess: per-patch implicit friction.
    ``seg`` ≠ 0: with f the mean of Eq. 4 along a step's slip segment from ``s0`` [m/s] (G(s0) = ``g0``) instead
    (:func:`segment_pair`). ``known`` ≠ 0: (``f_guess``, ``df_guess``) is the law's pair at the guess itself
    (:func:`law_pair` at slip vd − guess), which the first iteration takes instead of evaluating it again where it
    starts at the guess (0 in the bracket). The code compiled for the CPU, which contracts no products into fused
    multiply-adds, gets the same values either way, so the same result (tests/test_friction_step.py); CUDA code must
    pass 0: there the compiler may contract the two evaluations differently.

    Works on the increment δ = v − guess, so the convergence test is relative to the size of the step's
    velocity change (meaningful in fp32 too). The caller forms r from its terms (θh (F − c·guess), plus
    m (v − guess) where the guess is not the step's start), never as b − a·guess: in fp32 the damping's θh c is
    below half an ulp of the mass m at the small steps (4.4e-14 kg against m ≈ 1.9e-6 kg, ulp 1.1e-13 kg, at 5e-8 s), so
    a = m + θh c rounds to m and b − a·guess would lose the damping force. |f| ≤ 2 mu_scale π/2 brackets δ in
    [(r − hfn f_max)/a, (r + hfn f_max)/a]. Safeguarded Newton, ``rtsafe`` of Numerical Recipes:
    it bisects when a Newton step would leave the bracket or when it is longer than half the step before the last
    one. Without the second rule Newton can settle, at hγ ≳ 10, into a 2-cycle across the steep part of Eq. 4 that
    stays inside the bracket and never shrinks it (docs/friction_step.md §2). It stops at an exact root, or when the
    step or the bracket is below ``tol`` times (|r| + hfn f_max)/a: a smooth patch costs two friction evaluations
    per solve.
    """
    fmax = mu_scale * type(a)(3.141592653589793)
    lo = (r - hfn * fmax) / a
    hi = (r + hfn * fmax) / a
    dtol = tol * (wp.abs(r) + hfn * fmax) / a
    vp0 = vd - guess
    zero = a - a
    half = type(a)(0.5)
    d = wp.clamp(zero, lo, hi)
    last = type(a)(2.0) * (hi - lo)  # the last two step lengths; twice the bracket lets any first steps pass
    before = last
    fresh = known
    for _it in range(60):
        f = f_guess
        df = df_guess
        if fresh == 0 or d != zero:
            f, df = law_pair(vp0 - d, seg, s0, g0, mu_scale, slope, decay, tol)
        fresh = 0
        g = a * d - hfn * f - r
        if g == zero:
            break
        if g > zero:
            hi = d
        else:
            lo = d
        dg = a + hfn * df
        dn = d - g / dg
        # Bisect only when Newton would leave the bracket or does not halve its steps every second iteration. A step
        # that rounds to d itself (the root found to the last bit, where d is also a bracket end) is accepted and
        # converges: treating dn == lo/hi as leaving made ~13 % of fp32 patches on an H100 bisect ~20 times per solve
        # (scripts/profile_onchip.py, docs/onchip.md).
        if dg <= zero or dn < lo or dn > hi or wp.abs(dn - d) > half * before:
            dn = half * (lo + hi)
        step = wp.abs(dn - d)
        converged = step <= dtol or hi - lo <= dtol
        before = last
        last = step
        d = dn
        if converged:
            break
    return guess + d


@wp.func
def theta_substep(
    v: Any, h: Any, theta: Any, m: Any, c: Any, fn: Any, force: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any,
    tol: Any,
):  # fmt: skip
    """The θ-method over h [s] of a patch's forced friction/damping equation m v̇ = F + F_N f(vd − v) − c v, with the
    force ``force`` = F [N] frozen: V = v + θh φ(V) (:func:`solve_velocity`), returns v + (V − v)/θ [m/s]. θ = 1 is
    backward Euler (V itself); θ = ½ the implicit midpoint. ``m`` mass [kg], ``c`` damping [N s/m], ``fn`` normal
    force [N], ``vd`` disc speed ω r [m/s]. Written as V + (V − v)(1/θ − 1), which is V itself at θ = 1."""
    th = theta * h
    zero = v - v
    vm = solve_velocity(
        m + th * c, th * (force - c * v), th * fn, vd, v, mu_scale, slope, decay, tol, 0, vd - v, zero, 0, zero, zero
    )
    return vm + (vm - v) * (type(v)(1.0) / theta - type(v)(1.0))


@wp.func
def friction_substep(
    v: Any, h: Any, m: Any, c: Any, fn: Any, force: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any,
    crossing: int,
):  # fmt: skip
    """The velocity [m/s] after the friction sub-step over h [s] from v (:func:`friction_substep_pair`, whose
    arguments it takes)."""
    _vm, out = friction_substep_pair(v, h, m, c, fn, force, vd, mu_scale, slope, decay, tol, crossing)
    return out


@wp.func
def friction_substep_pair(
    v: Any, h: Any, m: Any, c: Any, fn: Any, force: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any,
    crossing: int,
):  # fmt: skip
    """The friction sub-step of every Strang path: a damped implicit midpoint over h [s] of m v̇ = F + F_N f(vd − v)
    − c v from velocity v [m/s], with the spring force F = ``force`` [N] frozen inside the solve (docs/numerics.md,
    docs/friction_step.md §6.1).

    :func:`theta_substep` with θ = ½ (the implicit midpoint, second order) while h γ ≤ 6, γ = (c + F_N f′(vd − v))/m
    the patch's own friction rate at its slip; beyond, θ = (1 − 1.5/(hγ))/1.5, so that the stability function
    R(−hγ) stays ≥ −½: a held patch's chatter about its static slip halves every step instead of alternating without
    decay (R → −1 of the plain midpoint). With F inside, a patch held at h γ ≫ 1 lands on its sticking manifold
    F + F_N f(vd − v) − c v = 0, so its recorded friction force is its static friction.

    ``crossing`` ≠ 0 (``RunOptions.crossing`` "mean"): a midpoint step (θ = ½) whose slip changes sign is solved
    again, from its first solution, with the friction averaged along its slip segment (:func:`segment_pair`)
    instead of taken at the midpoint velocity (docs/friction_step.md §8). The two solves are two call sites, each
    with its law fixed: folded into one loop over the passes, the law became a variable of every Newton iteration,
    which made every patch's sub-step 30–40 % dearer on the CPU where no patch crossed (the same bits either way).

    Returns (V, v⁺) [m/s]: V the velocity the solve found, at which the sub-step takes its friction (the θ-point
    V = v + θh φ(V), so that v⁺ = v + h φ(V) whatever θ; with the crossing treatment the law is the segment's mean),
    and v⁺ the velocity after the sub-step.
    """
    one = type(v)(1.0)
    half = type(v)(0.5)
    f0, df0 = friction_pair(vd - v, mu_scale, slope, decay)
    x = h * (c + fn * df0) / m
    theta = half
    if x > type(v)(6.0):
        theta = wp.min((one - type(v)(1.5) / x) / type(v)(1.5), one)
    th = theta * h
    a = m + th * c
    s0 = vd - v
    zero = v - v
    # the solve starts at v, where f0, df0 are the law's pair: on the CPU it takes them (one friction evaluation
    # fewer, the same bits: 8-16 % of a CPU step); CUDA code evaluates again, which measured faster on an H200, and
    # compiles to the same machine code as without the choice (docs/friction_step.md §6.1). Its r, b − a·v, is written
    # by the terms of the second solve's (m (v − v) = 0): so written, the point treatment compiles for CUDA to the
    # machine code it had when both solves were one call site (scripts/compare_cuda_code.py)
    r = th * (force - c * v) + m * (v - v)
    vm = solve_velocity(a, r, th * fn, vd, v, mu_scale, slope, decay, tol, 0, s0, zero, cpu_build(), f0, df0)
    out = vm + (vm - v) * (one / theta - one)
    if crossing != 0 and theta == half and s0 * (vd - out) < zero:
        # from the first solution, r = b − a·vm by its terms (solve_velocity)
        r = th * (force - c * vm) + m * (v - vm)
        g0 = friction_integral(s0, mu_scale, slope, decay)
        vm = solve_velocity(a, r, th * fn, vd, vm, mu_scale, slope, decay, tol, 1, s0, g0, 0, f0, df0)
        out = vm + (vm - v) * (one / theta - one)
    return vm, out


# ---------------------------------------------------------------------------------------------- per-patch terms


@wp.func
def spring_force(i: int, u: wp.array[Any], model: Any):
    """Elastic force on patch i: Σ_j k_ij u_j − (k_T,i + Σ_j k_ij) u_i [N] (``model``: an
    :data:`~aca_warp.kernels.hf_types.HFModel`, its CSR and k_diag).

    Two partial sums break the dependency chain of the gather (about 30 % faster on the CPU): the even links of the
    row into the first, the odd ones into the second; the order of summation is fixed, so results stay
    bit-reproducible, and every gather of the engines sums in this order.
    """
    a0 = u[i] - u[i]
    a1 = a0
    e = model.nbr_start[i]
    end = model.nbr_start[i + 1]
    while e + 1 < end:
        a0 += model.nbr_stiffness[e] * u[model.nbr_index[e]]
        a1 += model.nbr_stiffness[e + 1] * u[model.nbr_index[e + 1]]
        e += 2
    if e < end:
        a0 += model.nbr_stiffness[e] * u[model.nbr_index[e]]
    return (a0 + a1) - model.k_diag[i] * u[i]


@wp.func
def patch_force(fs: Any, v: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any):
    """Net force on a patch [N]: elastic force ``fs`` + friction F_N f(vd − v) − damping c v, at velocity ``v``
    [m/s], disc speed ``vd`` = ω r [m/s], normal force ``fn`` [N] and damping ``c`` [N s/m]."""
    return fs + fn * friction_coefficient(vd - v, mu_scale, slope, decay) - c * v


@wp.func
def strang_velocity(
    first: int, w: Any, fs: Any, dt: Any, im: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any,
    tol: Any, crossing: int,
):  # fmt: skip
    """Strang's velocity update of one step of a patch, before its drift u ← u + dt v; ``fs`` the cached F_s(uₙ)
    [N], ``im`` = 1/m [1/kg]. The spring force is frozen inside the friction sub-step (:func:`friction_substep`, the
    "forced" splitting: kick and friction at fixed u against the drift). ``first`` ≠ 0, the opening half step from
    the synchronous velocity ``w``: the sub-step over dt/2. Otherwise a merged step on the staggered velocity ``w``:
    the sub-step over dt (the closing half of step n and the opening half of step n+1 are one sub-step); ``crossing``:
    the treatment of steps that cross zero slip (:func:`friction_substep`). Returns the staggered velocity (the drift
    velocity of the step)."""
    h = dt
    if first != 0:
        h = dt * type(dt)(0.5)
    return friction_substep(w, h, type(dt)(1.0) / im, c, fn, fs, vd, mu_scale, slope, decay, tol, crossing)


@wp.func
def strang_sample_velocity(
    w: Any, fs: Any, dt: Any, im: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any,
    crossing: int,
):  # fmt: skip
    """``strang``'s sample of a patch at the end of a step: the merged friction sub-step over ``dt`` [s] that the
    next step opens with, from the staggered ``w`` [m/s] and F_s(uₙ) ``fs`` [N] (:func:`friction_substep_pair`).
    Returns (V, w⁺) [m/s]: V, the velocity at which that sub-step takes its friction, is the sample's velocity (the
    sub-step spans the sample's instant, and w⁺ − w = dt φ(V) with the point law, whatever θ: the sample reads the
    friction that the step applies; a crossing step's segment mean: :func:`instant_velocity`), and w⁺ is the next
    step's drift velocity, so that the solve serves the sample and the step alike (docs/numerics.md, "Samples")."""
    return friction_substep_pair(w, dt, type(dt)(1.0) / im, c, fn, fs, vd, mu_scale, slope, decay, tol, crossing)


@wp.func
def strang_close_velocity(
    w: Any, fs: Any, dt: Any, im: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any,
    crossing: int,
):  # fmt: skip
    """The synchronous velocity of a patch from its staggered ``w`` and F_s(uₙ) ``fs``: the friction sub-step over
    dt/2 with F_s(uₙ) frozen inside (``crossing``: :func:`friction_substep`). The error-controlled split step's
    samples (its next step is not known when it samples); ``strang``'s: :func:`strang_sample_velocity`."""
    h = dt * type(dt)(0.5)
    return friction_substep(w, h, type(dt)(1.0) / im, c, fn, fs, vd, mu_scale, slope, decay, tol, crossing)


@wp.func
def grown_area(a: Any, increment: Any):
    """One growth event of an area (paper Eq. 10): (A + g √A [m²], its square root [m]) for A [m²] and the
    increment g [m]."""
    a = a + increment * wp.sqrt(a)
    return a, wp.sqrt(a)


@wp.func
def store_grown_patch(i: int, p: int, model: Any, a: Any, s: Any):
    """Patch i of pad p at area ``a`` [m²] (√A ``s`` [m]): A, √A, 1/m, k_T, k_N and c into ``model``'s arrays."""
    m = model.pad_mass_per_area[p] * a
    kt = model.pad_k_t[p] * s
    model.area[i] = a
    model.sqrt_area[i] = s
    model.inv_mass[i] = type(a)(1.0) / m
    model.k_t[i] = kt
    model.k_n[i] = model.pad_k_n[p] * s
    model.damping[i] = type(a)(2.0) * model.pad_zeta[p] * wp.sqrt(kt * m)


@wp.func
def grow_patch(i: int, p: int, model: Any):
    """One growth event of patch i of pad p (paper Eq. 10): A ← A + g √A (:func:`grown_area`), then m, k_T, k_N, c
    follow the area (written into ``model``'s arrays; g its ``pad_growth``)."""
    a, s = grown_area(model.area[i], model.pad_growth[p])
    store_grown_patch(i, p, model, a, s)


@wp.func
def link_stiffness(ki: Any, sqrt_area_j: Any, inv_dist: Any):
    """k_ij = K_C √A_i √A_j / D0_ij [N/m] (paper Eq. 3) from ``ki`` = K_C √A_i, √A_j and 1/D0_ij."""
    return ki * sqrt_area_j * inv_dist


@wp.func
def link_stiffness4(ki: Any, sqa: Any, off: int, j0: int, j1: int, j2: int, j3: int, e: int, model: Any):
    """k_ij (:func:`link_stiffness`) of the four links e … e + 3 of a row (neighbours j0 … j3, global indices, √A_j
    at ``sqa[j − off]``: the model's array with ``off`` 0, or a block's copy of its pad's), stored into ``model``'s
    ``nbr_stiffness`` and returned. The four links' loads are issued before their stores (a store may alias a later
    load, so the compiler would not move the loads ahead itself: on a GPU the neighbours' √A just grown come from
    L2, and four in flight wait once)."""
    s0 = sqa[j0 - off]
    s1 = sqa[j1 - off]
    s2 = sqa[j2 - off]
    s3 = sqa[j3 - off]
    k0 = link_stiffness(ki, s0, model.nbr_inv_dist[e])
    k1 = link_stiffness(ki, s1, model.nbr_inv_dist[e + 1])
    k2 = link_stiffness(ki, s2, model.nbr_inv_dist[e + 2])
    k3 = link_stiffness(ki, s3, model.nbr_inv_dist[e + 3])
    model.nbr_stiffness[e] = k0
    model.nbr_stiffness[e + 1] = k1
    model.nbr_stiffness[e + 2] = k2
    model.nbr_stiffness[e + 3] = k3
    return k0, k1, k2, k3


@wp.func
def patch_coupling(i: int, p: int, model: Any):
    """k_ij (:func:`link_stiffness`) for every link of patch i of pad p [N/m] and k_T,i + Σ_j k_ij, into ``model``'s
    ``nbr_stiffness`` and ``k_diag`` (the diagonal summed in link order), four links at a time
    (:func:`link_stiffness4`)."""
    ki = model.pad_kc[p] * model.sqrt_area[i]
    d = model.k_t[i]
    e = model.nbr_start[i]
    end = model.nbr_start[i + 1]
    while e + 3 < end:
        n = model.nbr_index
        k0, k1, k2, k3 = link_stiffness4(ki, model.sqrt_area, 0, n[e], n[e + 1], n[e + 2], n[e + 3], e, model)
        d += k0
        d += k1
        d += k2
        d += k3
        e += 4
    while e < end:
        k = link_stiffness(ki, model.sqrt_area[model.nbr_index[e]], model.nbr_inv_dist[e])
        model.nbr_stiffness[e] = k
        d += k
        e += 1
    model.k_diag[i] = d


# ---------------------------------------------------------------------------------------------- contact


ContactSums = wp.types.vector(length=5, dtype=wp.float64)  # covered area, first moment, Σ k_N, fp, kp


@wp.func
def _pad_terms(a: Any, r: Any, h: Any, kn: Any, g: wp.float64, acc: ContactSums, hmin: wp.float64):
    """``acc`` (:data:`ContactSums`) and the lowest height with one patch (area a [m²], radius r [m], height h [m],
    stiffness k_N [N/m]) added, its force and stiffness when compressed at gap g."""
    d = wp.float64(h) - g
    fp = acc[3]
    kp = acc[4]
    if d > wp.float64(0.0):
        fp += wp.float64(kn) * d
        kp += wp.float64(kn)
    return (
        ContactSums(acc[0] + wp.float64(a), acc[1] + wp.float64(a * r), acc[2] + wp.float64(kn), fp, kp),
        wp.min(hmin, wp.float64(h)),
    )


@wp.func
def _pad_sums(s: int, e: int, lane: int, threads: int, model: Any, area: Any, k_n: Any, off: int, g: wp.float64):
    """The pad's :data:`ContactSums` at gap g over the block (one reduction) and this thread's lowest height (the
    patches lane, lane + threads, … of s … e − 1 in index order, four patches' loads before their sums; areas and
    k_N of patch i at ``area[i − off]``, ``k_n[i − off]``, :func:`contact_block_from`)."""
    acc = ContactSums()
    hmin = wp.float64(0.0)
    i = s + lane
    while i + 3 * threads < e:
        a0 = area[i - off]
        r0 = model.radius[i]
        h0 = model.height[i]
        k0 = k_n[i - off]
        a1 = area[i + threads - off]
        r1 = model.radius[i + threads]
        h1 = model.height[i + threads]
        k1 = k_n[i + threads - off]
        a2 = area[i + 2 * threads - off]
        r2 = model.radius[i + 2 * threads]
        h2 = model.height[i + 2 * threads]
        k2 = k_n[i + 2 * threads - off]
        a3 = area[i + 3 * threads - off]
        r3 = model.radius[i + 3 * threads]
        h3 = model.height[i + 3 * threads]
        k3 = k_n[i + 3 * threads - off]
        acc, hmin = _pad_terms(a0, r0, h0, k0, g, acc, hmin)
        acc, hmin = _pad_terms(a1, r1, h1, k1, g, acc, hmin)
        acc, hmin = _pad_terms(a2, r2, h2, k2, g, acc, hmin)
        acc, hmin = _pad_terms(a3, r3, h3, k3, g, acc, hmin)
        i += 4 * threads
    while i < e:
        acc, hmin = _pad_terms(area[i - off], model.radius[i], model.height[i], k_n[i - off], g, acc, hmin)
        i += threads
    return block_sums(acc), hmin


@wp.func
def _compressed(h: Any, kn: Any, g: wp.float64, fp: wp.float64, kp: wp.float64):
    """(fp, kp) with patch (height h [m], stiffness k_N [N/m]) added when compressed at gap g: fp + k_N (h − g),
    kp + k_N."""
    d = wp.float64(h) - g
    if d > wp.float64(0.0):
        return fp + wp.float64(kn) * d, kp + wp.float64(kn)
    return fp, kp


@wp.func
def _compressed_sums(s: int, e: int, lane: int, threads: int, model: Any, k_n: Any, off: int, g: wp.float64):
    """This thread's partial (Σ k_N (h − g), Σ k_N) over the compressed patches lane, lane + threads, … of the
    range s … e − 1, in index order (k_N of patch i at ``k_n[i − off]``); four patches' loads issued before their
    sums (on a GPU the loads of stiffnesses just grown elsewhere come from L2, and four in flight wait once)."""
    fp = wp.float64(0.0)
    kp = wp.float64(0.0)
    i = s + lane
    while i + 3 * threads < e:
        h0 = model.height[i]
        k0 = k_n[i - off]
        h1 = model.height[i + threads]
        k1 = k_n[i + threads - off]
        h2 = model.height[i + 2 * threads]
        k2 = k_n[i + 2 * threads - off]
        h3 = model.height[i + 3 * threads]
        k3 = k_n[i + 3 * threads - off]
        fp, kp = _compressed(h0, k0, g, fp, kp)
        fp, kp = _compressed(h1, k1, g, fp, kp)
        fp, kp = _compressed(h2, k2, g, fp, kp)
        fp, kp = _compressed(h3, k3, g, fp, kp)
        i += 4 * threads
    while i < e:
        fp, kp = _compressed(model.height[i], k_n[i - off], g, fp, kp)
        i += threads
    return fp, kp


@wp.func
def _newton_from_left(f: wp.float64, kact: wp.float64, load: wp.float64, g: wp.float64):
    """One Newton step of the contact from the left of its root: (new gap [m], 1 when the solve stops here). It
    stops when the stiffness in contact is 0, when the step stops being positive (from the left of the root Newton
    only moves right: there f = F_N to rounding) or when it falls below 1e-15 of the gap."""
    if kact <= wp.float64(0.0):
        return g, 1
    dg = (f - load) / kact
    if dg <= wp.float64(0.0):
        return g, 1
    g = g + dg
    if dg <= wp.float64(1.0e-15) * (wp.abs(g) + wp.float64(1.0e-9)):
        return g, 1
    return g, 0


@wp.func
def contact_block_from(
    pad: int,
    lane: int,
    threads: int,
    model: Any,
    area: Any,
    k_n: Any,
    off: int,
    gap: wp.float64,
    out_start: int,
    out_end: int,
    writer: bool,
) -> wp.float64:
    """Re-solve the normal forces of one pad on a flat matrix at elevation 0 (one thread block per pad).

    Σ_i k_N,i max(h_i − g, 0) + k_m a_free max(−g, 0) = F_N by Newton from the left of the root (monotone
    and exact on a piecewise-linear convex function), warm-started from the previous gap; it stops when the step
    falls below 1e-15 of the gap or stops being positive (the rounding floor of the block sums; with the first
    test alone, the re-solve late in the varying-area study cost 7.3 µs per step on the H100 against 1.0 µs with
    the second, docs/onchip.md). The first pass also sums the pad's covered area, first moment and stiffness, in
    the same reduction as the compressed patches' force and stiffness at the warm start; the lowest height (the
    restart left of the root) is reduced only when the warm start lies right of the root. Launch with
    ``wp.launch_tiled(dim=[pads], block_dim=B)``; ``threads`` is the block size the device runs (B on CUDA, 1 on
    the CPU): thread ``lane`` sums patches lane, lane + B, … and the block reduces the sums, so every thread
    sees the same values and takes the same branches (the block-wide reductions stay outside per-thread code).
    Every thread of the block must call it (block-wide reductions inside).

    ``model``: the pad's :data:`~aca_warp.kernels.hf_types.HFModel` (its patch stiffnesses k_N, heights, areas and
    radii, the pad's area, first moment, matrix stiffness and load). ``gap``: the previous gap g [m] (the warm
    start); returns the new one (unchanged when the load is 0), which the caller stores. Writes the model's normal
    forces of the patches ``out_start`` … ``out_end − 1`` only (global indices; the pad's whole range on the
    general path, a block's own part in a cluster, where every block of the cluster solves the same contact
    redundantly) and, when ``writer``, the pad's matrix force and radius.

    ``area``, ``k_n``: where the patches' areas [m²] and normal stiffnesses [N/m] are read, patch i (a global index)
    at ``[i − off]``: the model's arrays (``off`` 0, :func:`contact_block`) or a block's shared copies of its pad's
    (``off`` its first patch; the on-chip kernel on a cluster, where every block grows the whole pad's copies).
    """
    s = model.pad_patch_start[pad]
    e = model.pad_patch_start[pad + 1]
    zero = wp.float64(0.0)
    load = wp.float64(model.pad_load[pad])
    g = gap
    sums, hmin = _pad_sums(s, e, lane, threads, model, area, k_n, off, g)  # one reduction
    free = wp.max(model.pad_area[pad] - sums[0], zero)
    km = model.pad_k_m[pad] * free
    ktot = sums[2] + km
    if free > zero and lane == 0 and writer:
        model.pad_matrix_radius[pad] = type(model.pad_load[pad])((model.pad_moment[pad] - sums[1]) / free)
    if load > zero:
        f = km * wp.max(-g, zero) + sums[3]
        kact = sums[4]
        if g < zero:
            kact += km
        stop = int(0)
        if f < load:  # the warm start lies right of the root: restart left of it, where every element is compressed
            hmin = wp.tile_min(wp.tile(hmin))[0]
            g = hmin - load / ktot
        else:
            g, stop = _newton_from_left(f, kact, load, g)
        it = int(1)
        while stop == 0 and it < 200:
            fp, kp = _compressed_sums(s, e, lane, threads, model, k_n, off, g)
            active = block_sums(wp.vec2d(fp, kp))  # the compressed patches' force and stiffness
            f = km * wp.max(-g, zero) + active[0]
            kact = active[1]
            if g < zero:
                kact += km
            g, stop = _newton_from_left(f, kact, load, g)
            it += 1
    i = out_start + lane
    while i < out_end:
        f_i = zero
        if load > zero:
            f_i = wp.float64(k_n[i - off]) * wp.max(wp.float64(model.height[i]) - g, zero)
        model.normal_force[i] = type(model.pad_load[pad])(f_i)
        i += threads
    if lane == 0 and writer:
        if load > zero:
            model.pad_matrix_force[pad] = type(model.pad_load[pad])(km * wp.max(-g, zero))
        else:
            model.pad_matrix_force[pad] = type(model.pad_load[pad])(0.0)
    return g


@wp.func
def contact_block(
    pad: int, lane: int, threads: int, model: Any, gap: wp.float64, out_start: int, out_end: int, writer: bool
) -> wp.float64:
    """:func:`contact_block_from` with the areas and stiffnesses from the model's arrays."""
    return contact_block_from(pad, lane, threads, model, model.area, model.k_n, 0, gap, out_start, out_end, writer)


# ---------------------------------------------------------------------------------------------- samples


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
def instant_velocity(v: Any, w: Any, w1: Any, vd: Any, crossing: int, k: int, i: int):
    """The velocity [m/s] at which sample k reads the friction of patch i (its index within its pad): the sample's
    velocity ``v`` (:func:`strang_sample_velocity`); with ``crossing`` ≠ 0 (``RunOptions.crossing`` "mean"), for a patch
    whose slip changes sign along the merged sub-step that the sample reads, from the staggered ``w`` to ``w1`` (w⁺), an
    instant of that sub-step's straight path, w + τ (w⁺ − w), τ uniform in [0, 1) from ``wp.rand_init(INSTANT_SEED + k,
    i)``: its mean over τ is the segment's mean of the law, which the step applies where it is a midpoint step (θ = ½; a
    held patch's damped step beyond h γ = 6 takes f at V); reproducible, and the same for a pad in any batch
    (docs/friction_step.md §8, the instant reading). ``vd`` the disc speed ω r [m/s]."""
    if crossing != 0 and (vd - w) * (vd - w1) < v - v:
        state = wp.rand_init(INSTANT_SEED + k, i)
        return w + type(v)(wp.randf(state)) * (w1 - w)
    return v


@wp.func
def patch_sample(
    v: Any, vf: Any, fn: Any, r: Any, x: Any, y: Any, omega: Any, mu_scale: Any, slope: Any, decay: Any
):  # fmt: skip
    """One patch's terms of the sample sums at velocity ``v`` [m/s], its friction read at ``vf`` [m/s] (v, or an instant
    of the sub-step the sample reads: :func:`instant_velocity`), normal force ``fn`` [N], radius ``r`` and position
    (``x``, ``y``) [m]: its friction force F = F_N f(ω r − vf) [N], F r [N m], v, |v| [m/s], F x, F y [N m]."""
    f = fn * friction_coefficient(omega * r - vf, mu_scale, slope, decay)
    return SampleSums(
        wp.float64(f), wp.float64(f * r), wp.float64(v), wp.float64(wp.abs(v)), wp.float64(f * x), wp.float64(f * y)
    )


@wp.func
def block_sums(s: Any):
    """The sums over the block of every thread's float64 vector ``s`` (a :data:`SampleSums`, a longer vector that
    begins with one, or the contact solve's sums) in one block-wide reduction (every thread must call it).

    A tile of vectors (``preserve_type``) is reduced with the scalar path's operations applied per component (Warp's
    ``tile_reduce_impl`` with the vector ``add`` and the per-component ``warp_shuffle_down``), so every component is
    the sum, in the same order, that its own scalar ``tile_sum`` gives, with one reduction's barriers for all."""
    return wp.tile_sum(wp.tile(s, preserve_type=True))[0]


@wp.func
def write_globals(
    rec: Any,
    row: int,
    pad: int,
    s: Any,
    omega: Any,
    mu_pad: Any,
    matrix_force: Any,
    matrix_radius: Any,
    load: Any,
):
    """Write one pad's sample row into ``rec.globals``: μ, torque [N m], friction radius [m], Σu̇, Σ|u̇| [m/s],
    friction centroid [m] from the pad's :data:`SampleSums` ``s`` (or a longer vector that begins with one) and the
    matrix's Coulomb friction μ_pad F_m sign(ω) at radius r_m.

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
    rec.globals[row, pad, 0] = mu
    rec.globals[row, pad, 1] = ttot
    rec.globals[row, pad, 2] = reff
    rec.globals[row, pad, 3] = s[2]
    rec.globals[row, pad, 4] = s[3]
    centroid = wp.float64(0.0)
    if fsum != wp.float64(0.0):
        centroid = wp.sqrt(s[4] * s[4] + s[5] * s[5]) / wp.abs(fsum)
    rec.globals[row, pad, 5] = centroid


@wp.func
def energy_speed2(v: Any, u: Any, k_t: Any, inv_mass: Any) -> wp.float64:
    """The watchdog's squared energy speed of a patch, s² = u̇² + (k_T/m) u² = 2E/m [m²/s²] (E: its kinetic and
    own-spring energy), in float64."""
    ui = wp.float64(u)
    return wp.float64(v) * wp.float64(v) + wp.float64(k_t * inv_mass) * ui * ui


@wp.func
def flag_fault(rec: Any, pad: int, k: int, broken: bool, bad: int, runaway: int, n: int, value: wp.float64):
    """The pad's first fault at sample k (rec.fault[pad] = [patch, sample, kind], kept once set): kind 0 when
    ``broken`` (a non-finite u or u̇; ``bad`` its first patch), else kind 1 when ``runaway`` < ``n`` (a patch whose
    energy speed √(:func:`energy_speed2`) = ``value`` [m/s] exceeds the pad's bound; rec.fault_value[pad] = value)."""
    if rec.fault[pad, 0] >= 0:
        return
    if broken:
        rec.fault[pad, 0] = bad
        rec.fault[pad, 1] = k
        rec.fault[pad, 2] = 0
    elif runaway < n:
        rec.fault[pad, 0] = runaway
        rec.fault[pad, 1] = k
        rec.fault[pad, 2] = 1
        rec.fault_value[pad] = value


@wp.func
def patch_sample_due(rec: Any, k: int) -> bool:
    """Whether global sample k also records per-patch histories (``rec``'s window [first, last], every n-th)."""
    return k >= rec.first and k <= rec.last and (k - rec.first) % rec.every == 0


@wp.func
def store_patch_sample(rec: Any, row: int, g: int, v: Any, u: Any):
    """Patch g's u̇ (and u, when its buffer has rows) into row ``row`` of ``rec``'s per-patch histories."""
    rec.velocity[row, g] = v
    if rec.displacement.shape[0] > 0:
        rec.displacement[row, g] = u


@wp.func
def record_pad(
    pad: int,
    lane: int,
    threads: int,
    row: int,
    k: int,
    model: Any,
    # State in:
    u_in: wp.array[Any],
    v_in: wp.array[Any],
    w_in: wp.array[Any],
    w1_in: wp.array[Any],
    crossing: int,
    rec: Any,
):
    """Sample k of pad ``pad`` (lane ``lane`` of its block of ``threads``) of the state (``u_in``, ``v_in``) of
    ``model`` (an :data:`~aca_warp.kernels.hf_types.HFModel`) into globals row ``row`` of ``rec`` (an
    :data:`~aca_warp.kernels.hf_types.HFRecorder`, :func:`write_globals`); flags the first faulty patch
    (:func:`flag_fault`). ``w_in``, ``w1_in``: the staggered velocities before and after the merged sub-step whose
    solve gave v (:func:`strang_sample_velocity`; ``v_in`` both where the state is
    synchronous), read with ``crossing`` ≠ 0 (:func:`instant_velocity`).

    Each of the block's ``threads`` lanes sums the patches lane, lane + threads, … in float64 (:func:`patch_sample`),
    and the block adds the lanes' sums; with one lane (a CPU block) that is the sum in patch order. Watchdog: a
    non-finite u or u̇, or a patch whose energy speed exceeds ``rec.watch_bound[pad]`` [m/s]; "first" is the lowest
    patch index.
    """
    a = model.pad_patch_start[pad]
    n = model.pad_patch_start[pad + 1] - a
    sums = SampleSums()
    omega = model.pad_omega[pad]
    bound2 = rec.watch_bound[pad] * rec.watch_bound[pad]
    runaway = n  # the lane's first patch beyond the bound (n: none)
    broken = n  # the lane's first patch with a non-finite u or u̇ (n: none)
    i = lane
    while i < n:
        g = a + i
        v = v_in[g]
        vf = instant_velocity(v, w_in[g], w1_in[g], omega * model.radius[g], crossing, k, i)
        sums += patch_sample(
            v, vf, model.normal_force[g], model.radius[g], model.x[g], model.y[g], omega, model.pad_mu_scale[pad],
            model.pad_slope[pad], model.pad_decay[pad],
        )  # fmt: skip
        if energy_speed2(v, u_in[g], model.k_t[g], model.inv_mass[g]) > bound2 and runaway == n:
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
        rec, row, pad, sums, omega, model.pad_mu_pad[pad], model.pad_matrix_force[pad],
        model.pad_matrix_radius[pad], model.pad_load[pad],
    )  # fmt: skip
    value = wp.float64(0.0)
    if runaway < n:
        g = a + runaway
        value = wp.sqrt(energy_speed2(v_in[g], u_in[g], model.k_t[g], model.inv_mass[g]))
    flag_fault(rec, pad, k, broken < n, broken, runaway, n, value)
