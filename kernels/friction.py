"""The friction law (paper Eq. 4) and the friction/damping sub-step of one HF patch: the one home of both.

Every engine calls these functions: the HF kernels (general, adaptive and both on-chip kernels) and the LF
automaton's patch friction (:func:`aca_warp.kernels.lf.eq4`). Functions are generic in the precision (float32 or
float64 arguments); velocities in m/s, forces in N, masses in kg, times in s.

    f(v) = (M/π) atan(a v) (1/(b|v| + 1) + 1)   (signed Eq. 4; ``mu_scale`` = M/π, ``slope`` = a, ``decay`` = b)

The friction/damping sub-step of a patch, m v̇ = F_N f(v_d − v) − c v over a step dt, is :func:`friction_substep`:
every Strang path (general and on-chip) takes it through the sub-steps of :mod:`aca_warp.kernels.patch`, so a
different scheme for it is a change here only.
"""

from __future__ import annotations

from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})


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
def friction_substep(
    v: Any, dt: Any, m: Any, c: Any, fn: Any, vd: Any, mu_scale: Any, slope: Any, decay: Any, tol: Any
):
    """The friction/damping sub-step of a patch: m v̇ = F_N f(vd − v) − c v over dt from velocity v, by the
    implicit midpoint rule (second order, A-stable); returns the velocity after it [m/s].

    Solves m (v_m − v) = dt/2 (F_N f(vd − v_m) − c v_m) for the midpoint velocity (:func:`solve_velocity`),
    returns 2 v_m − v. ``m`` mass [kg], ``c`` damping [N s/m], ``fn`` normal force [N], ``vd`` disc speed ω r [m/s].
    """
    half = type(v)(0.5) * dt
    vm = solve_velocity(m + half * c, m * v, half * fn, vd, v, mu_scale, slope, decay, tol)
    return type(v)(2.0) * vm - v
