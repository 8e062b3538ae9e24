"""Per-patch friction sub-steps for large steps: a NumPy prototype on the package's own HF equations.

Each patch obeys m ü + c u̇ + k_T u + Σ k_ij (u − u_j) = F_N f(ω r − u̇) (docs/model.md §2.2). The split
integrators here advance y = (u, u̇) of a batch of pads with one spring evaluation F_s(u) = −K u per step and a
per-patch scalar sub-step Φ_h of the friction/damping velocity equation, vectorised over the patches:

* ``kicks="outside"`` is the package's ``strang``: Φ_h solves m v̇ = F_N f(v_d − v) − c v; the spring force enters
  as two half kicks around it (velocity Verlet).
* ``kicks="inside"`` (forced friction): Φ_h solves m v̇ = F_s(u) + F_N f(v_d − v) − c v with F_s(u) frozen over the
  sub-step (Strang splitting of "kick + friction" at fixed u against the drift u̇ = v). The merged step is
  w ← Φ_h[F_s(u)](w), u ← u + h w: the cost of ``strang`` (one spring evaluation, one sub-step), and the spring
  force is inside the implicit solve, so at h γ ≫ 1 an L-stable sub-step puts a sticking patch on its sticking
  manifold F_s + F_N f(v_d − v) − c v = 0 with the right static friction force.

Sub-steps (:data:`METHODS`; each stage one call of :func:`solve`, the kernels' bracketed Newton ``solve_velocity``):

* ``mid``: implicit midpoint (today's ``midpoint_friction``), order 2, A-stable, R(−∞) = −1;
* ``thmid``: the θ-method with θ = 1/2 (midpoint) while the patch's own friction rate γ = (c + F_N f′)/m at its
  slip keeps hγ ≤ 6, larger beyond so that |R| ≤ 1/2 at any step (:func:`theta_of`): order 2 where hγ ≤ 6;
* ``be``: backward Euler, order 1, L-stable;
* ``sdirk2``: Alexander's 2-stage SDIRK, d = 1 − 1/√2, order 2, L-stable, stiffly accurate; the second stage reuses
  the first stage's slope (Y1 − v)/(d h) instead of evaluating f again;
* ``trbdf2``: TR-BDF2 with γ = 2 − √2 (trapezoid to t + γh, then BDF2), order 2, L-stable, stiffly accurate; one
  explicit friction evaluation plus two solves;
* ``sub4``: four ``sdirk2`` sub-steps of h/4 (an accurate sub-flow, to separate the splitting error from the
  sub-step's);
* ``thmean``: ``thmid``, except where a midpoint step (θ = 1/2) crosses zero slip: there the friction is its mean
  along the step's slip segment, (G(s₁) − G(s₀))/(s₁ − s₀) with G = ∫ f (:func:`friction_integral`), instead of
  f at the midpoint (the averaged-vector-field form of the midpoint; the same for a linear law). It integrates
  the sign change of Eq. 4 inside a step exactly along a straight velocity path, where the midpoint takes one
  sample of it (docs/friction_step.md §8).

Scenes, models and neighbour lists come from the package (:func:`load_pads`: ``build_model`` and the SciPy
reference :class:`~aca_warp.hf.reference.ReferenceODE`), so the equations and parameters are exactly the package's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from aca_warp.hf.options import NEWTON_TOL as SOLVER_TOL

METHODS = ("mid", "thmid", "be", "sdirk2", "trbdf2", "sub4", "thmean")
KICKS = ("outside", "inside")
SDIRK_D = 1.0 - 1.0 / math.sqrt(2.0)  # diagonal of sdirk2 and of both TR-BDF2 stages
TRBDF2_G = 2.0 - math.sqrt(2.0)  # TR-BDF2's intermediate time fraction
TRBDF2_C1 = 1.0 / (TRBDF2_G * (2.0 - TRBDF2_G))  # BDF2 weights: y⁺ = c1 Y1 − c0 y + d h φ(y⁺)
TRBDF2_C0 = (1.0 - TRBDF2_G) ** 2 / (TRBDF2_G * (2.0 - TRBDF2_G))
NEWTON_TOL = SOLVER_TOL["fp64"]  # of the step's velocity change: the kernels' fp64 tolerance
SUBSTEPS = 4  # sdirk2 sub-steps of ``sub4``
THETA_RHO = 0.5  # ``thmid`` keeps |R(−hγ)| ≤ this at the patch's own friction rate: θ = 1/2 up to hγ = 6
STATIC_SLIP = 0.17  # m/s: Eq. 4 rises with the slip below this (its maximum); a patch there holds to the disc
CHATTER_FLOOR = 1.0e-4 * STATIC_SLIP  # m/s: slip increments below this do not count as chatter
INSTANT_SEED = 20261130  # seeds the random instants of ``Record.mu_instant`` (with the sample's index)
SEGMENT_MIN = 1.0e-9  # m/s: ``thmean`` takes f at the midpoint where the slip segment is shorter than this


# ---------------------------------------------------------------------------------------------------- pads


@dataclass
class Pads:
    """A batch of pads as flat patch arrays (pads contiguous), float64.

    Attributes:
        m, c, fn, vd, kt: Mass [kg], damping [N s/m], normal force [N], disc speed ω r [m/s], k_T [N/m]; (n,).
        K: Stiffness matrix, F_s(u) = −K u [N/m], CSR (n, n), block-diagonal over the pads.
        start: Patch offsets of the pads, (P + 1,).
        M, slope, decay: Eq. 4's factor [1], regularisation slope and decay [s/m] (shared by the batch).
        load: Clamp force of each pad [N], (P,).
        coulomb: Matrix friction μ_pad F_m sign ω of each pad [N], (P,).
        u0, v0: Start state [m], [m/s], (n,).
        names: Scene names, (P,).
    """

    m: np.ndarray
    c: np.ndarray
    fn: np.ndarray
    vd: np.ndarray
    kt: np.ndarray
    K: sp.csr_matrix
    start: np.ndarray
    M: float
    slope: float
    decay: float
    load: np.ndarray
    coulomb: np.ndarray
    u0: np.ndarray
    v0: np.ndarray
    names: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.m)

    @property
    def pads(self) -> int:
        return len(self.start) - 1

    @property
    def pad_of(self) -> np.ndarray:
        return np.repeat(np.arange(self.pads), np.diff(self.start))

    def gamma_max(self) -> np.ndarray:
        """γ_i = (c_i + F_N,i f′(0))/m_i [1/s], the friction rate of a sticking patch, (n,)."""
        return (self.c + self.fn * 2.0 * self.slope * self.M / math.pi) / self.m

    def omega_max(self) -> float:
        """The largest angular frequency of the undamped spring network [rad/s] (sparse eigenvalue of M⁻¹ᐟ² K M⁻¹ᐟ²)."""
        from scipy.sparse.linalg import eigsh

        s = sp.diags(1.0 / np.sqrt(self.m))
        a = (s @ self.K @ s).tocsc()
        if self.n <= 400:
            return float(math.sqrt(np.linalg.eigvalsh(a.toarray()).max()))
        return float(math.sqrt(eigsh(a, k=1, which="LA", return_eigenvectors=False)[0]))

    def dispersion_corrected(self, h: float) -> Pads:
        """This batch with K replaced by K_c = K − (h²/12) K M⁻¹ K: the step-h leapfrog's frequency of each spring
        mode, (2/h) arcsin(ω_c h/2), then equals ω to O((ωh)⁴) (ω_c² = ω² (1 − ω²h²/12)), so the first peak f1
        does not move with h. K_c couples neighbours of neighbours; h [s]."""
        corrected = self.K - (h * h / 12.0) * (self.K @ sp.diags(1.0 / self.m) @ self.K)
        return dataclasses.replace(self, K=corrected.tocsr())

    def subset(self, pads: list[int]) -> Pads:
        """The pads ``pads`` of this batch as a batch of their own."""
        idx = np.concatenate([np.arange(self.start[p], self.start[p + 1]) for p in pads])
        counts = np.diff(self.start)[pads]
        return Pads(
            self.m[idx], self.c[idx], self.fn[idx], self.vd[idx], self.kt[idx], self.K[idx][:, idx].tocsr(),
            np.concatenate([[0], np.cumsum(counts)]), self.M, self.slope, self.decay, self.load[pads],
            self.coulomb[pads], self.u0[idx], self.v0[idx], [self.names[p] for p in pads],
        )  # fmt: skip


def load_pads(scenes: list[Any], device: str = "cpu") -> Pads:
    """The pads of ``scenes`` (one pad each) with their start states, built by the package (``build_model``,
    ``initial_state``) and read through :class:`~aca_warp.hf.reference.ReferenceODE`."""
    from aca_warp.hf.reference import ReferenceODE
    from aca_warp.studies.runs import batch_at_start

    parts = []
    for scene in scenes:
        model, state = batch_at_start([scene], device, "fp64")
        ode = ReferenceODE(model)
        u, v = (x.astype(np.float64) for x in state.numpy())
        parts.append((ode, u, v, scene.name, model.host("k_t").astype(np.float64)))
    o0 = parts[0][0]
    if any((o.M, o.slope, o.decay) != (o0.M, o0.slope, o0.decay) for o, *_ in parts):
        raise ValueError("the pads of a batch need one friction law")
    cat = lambda f: np.concatenate([f(p) for p in parts])  # noqa: E731
    return Pads(
        m=cat(lambda p: p[0].m),
        c=cat(lambda p: p[0].c),
        fn=cat(lambda p: p[0].fn),
        vd=cat(lambda p: p[0].vd),
        kt=cat(lambda p: p[4]),
        K=sp.block_diag([p[0].K for p in parts], format="csr"),
        start=np.concatenate([[0], np.cumsum([p[0].n for p in parts])]),
        M=o0.M,
        slope=o0.slope,
        decay=o0.decay,
        load=np.array([p[0].load for p in parts], dtype=np.float64),
        coulomb=np.array([p[0].mu_pad * p[0].f_matrix * np.sign(p[0].omega) for p in parts]),
        u0=cat(lambda p: p[1]),
        v0=cat(lambda p: p[2]),
        names=[p[3] for p in parts],
    )


# ------------------------------------------------------------------------------------------------ friction


def friction(pads: Pads, s: np.ndarray) -> np.ndarray:
    """Signed Eq. 4, f(s), for sliding speeds s [m/s]."""
    return pads.M / math.pi * np.arctan(pads.slope * s) * (1.0 / (pads.decay * np.abs(s) + 1.0) + 1.0)


def friction_pair(pads: Pads, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(f(s), df/ds [s/m]) sharing one atan (the kernels' ``friction_pair``)."""
    at = np.arctan(pads.slope * s)
    rq = 1.0 / (pads.decay * np.abs(s) + 1.0)
    da = pads.slope / (1.0 + (pads.slope * s) ** 2)
    k = pads.M / math.pi
    return k * at * (rq + 1.0), k * (da * (rq + 1.0) - at * pads.decay * np.sign(s) * rq * rq)


def friction_integral(pads: Pads, s: np.ndarray) -> np.ndarray:
    """G(s) = ∫₀ˢ f(x) dx of Eq. 4 [m/s], even in s, in closed form up to O(decay²/slope³) (≈ 4e-9 m/s for the
    presets' law).

    With x = |s|, a = slope, b = decay and H(x) = ∫₀ˣ (1/(b x' + 1) + 1) dx' = x + ln(1 + b x)/b, integration by
    parts gives (M/π)[atan(a x) H(x) − ∫₀ˣ a H/(1 + a² x'²) dx']. The last integral is ln(1 + a² x²)/a for H's
    linear part 2x, plus ∫ a (H − 2x')/(1 + a² x'²) dx', taken with a/(1 + a² x'²) → 1/(a x'²) (exactly
    (1 − ln(1 + b x)/(b x) − ln(1 + b x))/a) and the leading correction b atan(a x)/(2a²) from H − 2x' ≈ −b x'²/2
    where the two kernels differ (x' ≲ 1/a)."""
    x = np.abs(s)
    a, b = pads.slope, pads.decay
    bx = b * x
    small = bx < 1e-6
    with np.errstate(divide="ignore", invalid="ignore"):
        ln = np.log1p(bx)
        q = np.where(small, 0.5 * bx, 1.0 - ln / bx)  # 1 − ln(1 + b x)/(b x)
        hx = x + np.where(small, x * (1.0 - 0.5 * bx), ln / b)  # H(x)
    at = np.arctan(a * x)
    g = at * hx - np.log1p((a * x) ** 2) / a - (q - ln) / a - b * at / (2.0 * a * a)
    return pads.M / math.pi * g


def segment_pair(pads: Pads, s: np.ndarray, s0: np.ndarray, g0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``thmean``'s law at midpoint slip s [m/s] of a step that starts at slip s0 (G(s0) = ``g0``): the mean of f
    over the slips from s0 to s1 = 2 s − s0 and its derivative in s; :func:`friction_pair` at s where the segment is
    shorter than SEGMENT_MIN."""
    f, df = friction_pair(pads, s)
    ds = 2.0 * (s - s0)
    use = np.abs(ds) > SEGMENT_MIN
    if not use.any():
        return f, df
    s1 = s0[use] + ds[use]
    mean = (friction_integral(pads, s1) - g0[use]) / ds[use]
    f[use] = mean
    df[use] = 2.0 * (friction(pads, s1) - mean) / ds[use]
    return f, df


def solve(
    pads: Pads,
    a: np.ndarray,
    b: np.ndarray,
    hfn: np.ndarray,
    guess: np.ndarray,
    evals: np.ndarray,
    *,
    halving: bool = True,
    vd: np.ndarray | None = None,
    start: np.ndarray | None = None,
) -> np.ndarray:
    """Solve a v − hfn f(v_d − v) = b per patch (a > 0, hfn ≥ 0): the kernels' ``solve_velocity``, vectorised, with
    one more safeguard.

    Newton on δ = v − guess inside the bracket [(r − hfn M)/a, (r + hfn M)/a], r = b − a·guess, bisecting where a
    Newton step would leave it; stops per patch when the step or the bracket is below NEWTON_TOL (|r| + hfn M)/a.
    The added safeguard (``rtsafe`` of Numerical Recipes): from the third iteration on, a Newton step longer than
    half the step before the last one bisects instead. Without it, at hγ ≳ 10 Newton can settle into a 2-cycle
    across the steep part of Eq. 4 that stays inside the bracket and never shrinks it (:data:`CYCLE_CASE`); the
    kernels' version then returns after 60 iterations with an error of up to the bracket width (``halving=False``
    is the kernels' algorithm). ``vd``: the patches' disc speeds [m/s] where the arrays are a subset of the
    batch's patches (default ``pads.vd``). With ``start`` (the sub-step's start velocity [m/s]) the law is the mean
    of f along the step (:func:`segment_pair`; ``thmean``). Adds the friction evaluations of every patch to
    ``evals``; patches that have converged drop out of the arrays.
    """
    r = b - a * guess
    hm = hfn * pads.M
    lo = (r - hm) / a
    hi = (r + hm) / a
    tol = NEWTON_TOL * (np.abs(r) + hm) / a
    disc = pads.vd if vd is None else vd
    s0 = disc - guess
    seg = start is not None
    if seg:
        st = disc - start
        g0 = friction_integral(pads, st)
    d = np.clip(0.0, lo, hi)
    out = d.copy()
    last = np.full_like(d, np.inf)  # the last step and the one before [m/s]
    before = last.copy()
    act: np.ndarray | None = None  # indices of the patches still iterating (None: all)
    for _ in range(60):
        vd = s0 - d
        f, df = segment_pair(pads, vd, st, g0) if seg else friction_pair(pads, vd)
        g = a * d - hfn * f - r
        if act is None:
            evals += 1
        else:
            evals[act] += 1
        pos = g > 0.0
        hi = np.where(pos, d, hi)
        lo = np.where(pos, lo, d)
        dg = a + hfn * df
        with np.errstate(divide="ignore", invalid="ignore"):
            dn = d - g / dg
        ok = (dg > 0.0) & (dn >= lo) & (dn <= hi)
        if halving:
            ok &= np.abs(dn - d) <= 0.5 * before
        dn = np.where(ok, dn, 0.5 * (lo + hi))
        dn = np.where(g == 0.0, d, dn)
        done = (g == 0.0) | (np.abs(dn - d) <= tol) | (hi - lo <= tol)
        before, last = last, np.abs(dn - d)
        if act is None:
            out = dn.copy()
        else:
            out[act] = dn
        if done.all():
            break
        keep = np.flatnonzero(~done)
        act = keep if act is None else act[keep]
        a, r, hfn, s0, lo, hi, tol, d = a[keep], r[keep], hfn[keep], s0[keep], lo[keep], hi[keep], tol[keep], dn[keep]
        last, before = last[keep], before[keep]
        if seg:
            st, g0 = st[keep], g0[keep]
    return guess + out


# A solve on which the kernels' Newton (without the step-halving safeguard) 2-cycles: hf1 sector seed 1, patch 30,
# forced-sdirk2 at 1e-6 s, second stage of step 3214 (a [kg], b [kg m/s], hfn [N s], guess [m/s], v_d [m/s]).
CYCLE_CASE = {
    "a": 7.631056032890043e-07,
    "b": 6.656976158055828e-06,
    "hfn": 8.540002729610647e-08,
    "guess": 7.839064377625342,
    "vd": 8.69403734446907,
}


def stage(pads: Pads, x: np.ndarray, theta_h: np.ndarray, force: np.ndarray, evals: np.ndarray) -> np.ndarray:
    """One implicit stage: V with m (V − x) = θh (F + F_N f(v_d − V) − c V) [m/s]; ``theta_h`` θh [s]."""
    return solve(pads, pads.m + theta_h * pads.c, pads.m * x + theta_h * force, theta_h * pads.fn, x, evals)


def rate(pads: Pads, v: np.ndarray, force: np.ndarray) -> np.ndarray:
    """φ(v) = (F + F_N f(v_d − v) − c v)/m [m/s²]."""
    return (force + pads.fn * friction(pads, pads.vd - v) - pads.c * v) / pads.m


def substep(
    pads: Pads, method: str, v: np.ndarray, h: np.ndarray | float, force: np.ndarray, evals: np.ndarray
) -> np.ndarray:
    """Φ_h: the velocity after h [s] of m v̇ = F + F_N f(v_d − v) − c v by ``method`` (:data:`METHODS`), F [N]
    frozen; adds friction evaluations to ``evals``."""
    h = np.broadcast_to(np.asarray(h, dtype=np.float64), v.shape)
    if method == "mid":
        return 2.0 * stage(pads, v, 0.5 * h, force, evals) - v
    if method == "thmid":
        theta = theta_of(pads, v, h, evals)
        return v + (stage(pads, v, theta * h, force, evals) - v) / theta
    if method == "thmean":
        return thmean(pads, v, h, force, evals)
    if method == "be":
        return stage(pads, v, h, force, evals)
    if method == "sdirk2":
        return sdirk2(pads, v, h, force, evals)[0]
    if method == "trbdf2":
        evals += 1
        y1 = stage(pads, v + SDIRK_D * h * rate(pads, v, force), SDIRK_D * h, force, evals)
        return stage(pads, TRBDF2_C1 * y1 - TRBDF2_C0 * v, SDIRK_D * h, force, evals)
    if method == "sub4":
        for _ in range(SUBSTEPS):
            v = substep(pads, "sdirk2", v, h / SUBSTEPS, force, evals)
        return v
    raise ValueError(f"unknown friction sub-step {method!r}; choose from {', '.join(METHODS)}")


def theta_of(pads: Pads, v: np.ndarray, h: np.ndarray, evals: np.ndarray) -> np.ndarray:
    """``thmid``'s θ per patch: 1/2 while h γ ≤ x0 = (1 + ρ)/(1/2 − ρ/2), with γ = (c + F_N f′(v_d − v))/m the
    friction rate at the patch's slip; beyond, θ = (1 − (1 + ρ)/(hγ))/(1 + ρ), so that R = (1 − (1 − θ)hγ)/(1 + θhγ)
    stays ≥ −ρ (ρ = THETA_RHO): the damped midpoint. One friction evaluation."""
    evals += 1
    x = h * (pads.c + pads.fn * friction_pair(pads, pads.vd - v)[1]) / pads.m
    rho = THETA_RHO
    with np.errstate(divide="ignore"):
        theta = (1.0 - (1.0 + rho) / np.maximum(x, 1e-300)) / (1.0 + rho)
    return np.clip(theta, 0.5, 1.0)


def thmean(pads: Pads, v: np.ndarray, h: np.ndarray, force: np.ndarray, evals: np.ndarray) -> np.ndarray:
    """``thmean``: ``thmid``, then, for the patches whose midpoint step (θ = 1/2) crosses zero slip, the midpoint
    solved again with the friction averaged along the step's slip segment (:func:`segment_pair`), from the first
    solution."""
    theta = theta_of(pads, v, h, evals)
    vm = stage(pads, v, theta * h, force, evals)
    out = v + (vm - v) / theta
    cross = (theta == 0.5) & ((pads.vd - v) * (pads.vd - out) < 0.0)
    if not cross.any():
        return out
    i = np.flatnonzero(cross)
    th = 0.5 * h[i]
    e = np.zeros(i.size)
    vm = solve(pads, pads.m[i] + th * pads.c[i], pads.m[i] * v[i] + th * force[i], th * pads.fn[i], vm[i], e,
               vd=pads.vd[i], start=v[i])  # fmt: skip
    evals[i] += e
    out[i] = 2.0 * vm - v[i]
    return out


def sdirk2(
    pads: Pads, v: np.ndarray, h: np.ndarray, force: np.ndarray, evals: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The ``sdirk2`` sub-step and its embedded error [m/s]: Y1 = v + d h φ(Y1), x = v + (1 − d)/d (Y1 − v),
    Y2 = x + d h φ(Y2); the error of the first-order solution v + h φ(Y1) against Y2, d h (φ(Y2) − φ(Y1)) =
    (Y2 − x) − (Y1 − v) (no further friction evaluation)."""
    y1 = stage(pads, v, SDIRK_D * h, force, evals)
    x = v + (1.0 - SDIRK_D) / SDIRK_D * (y1 - v)
    y2 = stage(pads, x, SDIRK_D * h, force, evals)
    return y2, (y2 - x) - (y1 - v)


def substep_with_error(
    pads: Pads, method: str, v: np.ndarray, h: np.ndarray, force: np.ndarray, evals: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Φ_h and an estimate of its local error [m/s]: ``sdirk2``'s embedded one; for ``mid`` and ``thmid`` the
    trapezoidal rule against the step, h (φ(v) + φ(v⁺))/2 − (v⁺ − v), O(h³) where smooth (two friction evaluations,
    of which the kernels can share φ(v⁺) with the next step)."""
    h = np.broadcast_to(np.asarray(h, dtype=np.float64), v.shape)
    if method == "sdirk2":
        return sdirk2(pads, v, h, force, evals)
    if method in ("mid", "thmid"):
        vn = substep(pads, method, v, h, force, evals)
        evals += 2
        return vn, 0.5 * h * (rate(pads, v, force) + rate(pads, vn, force)) - (vn - v)
    raise ValueError(f"no error estimate for the sub-step {method!r} (sdirk2, mid, thmid)")


def stability_function(method: str, z: complex) -> complex:
    """R(z) of a sub-step on v̇ = λ v, z = hλ (closed forms; ``sub4`` is R_sdirk2(z/4)⁴; ``thmean`` is ``thmid``'s)."""
    d = SDIRK_D
    if method == "mid":
        return (1.0 + z / 2.0) / (1.0 - z / 2.0)
    if method == "be":
        return 1.0 / (1.0 - z)
    if method == "sdirk2":
        return (1.0 + (1.0 - 2.0 * d) * z) / (1.0 - d * z) ** 2
    if method == "trbdf2":
        y1 = (1.0 + d * z) / (1.0 - d * z)
        return (TRBDF2_C1 * y1 - TRBDF2_C0) / (1.0 - d * z)
    if method == "sub4":
        return stability_function("sdirk2", z / SUBSTEPS) ** SUBSTEPS
    if method in ("thmid", "thmean"):  # thmean is thmid on a linear law
        x = max(-z.real, 1e-300)
        th = min(max((1.0 - (1.0 + THETA_RHO) / x) / (1.0 + THETA_RHO), 0.5), 1.0)
        return (1.0 + (1.0 - th) * z) / (1.0 - th * z)
    raise ValueError(f"unknown friction sub-step {method!r}")


# --------------------------------------------------------------------------------------------- integrator


@dataclass(frozen=True)
class Scheme:
    """A split integrator: friction sub-step ``method`` (:data:`METHODS`), spring kicks ``outside`` the sub-step
    (today's ``strang`` with ``mid``) or ``inside`` it (:data:`KICKS`)."""

    method: str
    kicks: str

    @property
    def name(self) -> str:
        return f"{'strang' if self.kicks == 'outside' else 'forced'}-{self.method}"

    @classmethod
    def parse(cls, name: str) -> Scheme:
        """``strang-<method>`` or ``forced-<method>``."""
        head, _, method = name.partition("-")
        kicks = {"strang": "outside", "forced": "inside"}.get(head)
        if kicks is None or method not in METHODS:
            raise ValueError(f"unknown scheme {name!r}: strang-<m> or forced-<m>, m in {', '.join(METHODS)}")
        return cls(method, kicks)


class SplitStepper:
    """Fixed or per-pad steps of a :class:`Scheme` on a batch of pads (staggered velocity between steps).

    State: u [m], the staggered velocity w [m/s] (the drift velocity of the last step), the spring force
    F = F_s(u) [N], and ``evals`` (friction evaluations per patch) and ``gathers`` (spring evaluations). Chatter
    counters: ``held`` counts patch-steps whose drift slip v_d − w stays below STATIC_SLIP in size over three
    consecutive steps, ``flips`` those among them whose slip zig-zags (its two increments of opposite sign, each
    above CHATTER_FLOOR): the period-2 oscillation of a sub-step with R(−∞) = −1 (a smooth slip changes the sign of
    its increment only at its extrema).
    """

    def __init__(self, pads: Pads, scheme: Scheme) -> None:
        self.pads, self.scheme = pads, scheme
        self.u = pads.u0.copy()
        self.w = pads.v0.copy()
        self.force = -(pads.K @ self.u)
        self.evals = np.zeros(pads.n)
        self.gathers = 1
        self.open_h: np.ndarray | None = None  # the step of the last drift, per patch (None: synchronous)
        self.held = 0
        self.flips = 0
        self._slip: np.ndarray | None = None  # the drift slip one step back

    def _phi(self, v: np.ndarray, h: np.ndarray, force: np.ndarray) -> np.ndarray:
        """Φ_h with the scheme's kicks: inside (F frozen in the solve) or outside (kick h/2, Φ, kick h/2)."""
        if self.scheme.kicks == "inside":
            return substep(self.pads, self.scheme.method, v, h, force, self.evals)
        kick = 0.5 * h * force / self.pads.m
        return substep(self.pads, self.scheme.method, v + kick, h, np.zeros_like(v), self.evals) + kick

    def step(self, h: np.ndarray) -> None:
        """Advance every patch by its step h [s] (n,): the closing half of the last step and the opening half of
        this one merged into one sub-step over (h_last + h)/2, then the drift and one spring evaluation."""
        span = 0.5 * h if self.open_h is None else 0.5 * (self.open_h + h)
        w_old = self.w
        if self.scheme.kicks == "outside" and self.open_h is not None:
            # kick by the last step's closing half and this step's opening half around the friction sub-step
            k1 = 0.5 * self.open_h * self.force / self.pads.m
            k2 = 0.5 * h * self.force / self.pads.m
            zero = np.zeros_like(self.w)
            self.w = substep(self.pads, self.scheme.method, self.w + k1, span, zero, self.evals) + k2
        elif self.scheme.kicks == "outside":  # opening from a synchronous state: friction h/2, then kick h/2
            zero = np.zeros_like(self.w)
            self.w = substep(self.pads, self.scheme.method, self.w, span, zero, self.evals)
            self.w = self.w + 0.5 * h * self.force / self.pads.m
        else:
            self.w = substep(self.pads, self.scheme.method, self.w, span, self.force, self.evals)
        if self.open_h is not None:
            s0, s1 = self.pads.vd - w_old, self.pads.vd - self.w
            if self._slip is not None:
                sm = self._slip
                held = (np.abs(sm) < STATIC_SLIP) & (np.abs(s0) < STATIC_SLIP) & (np.abs(s1) < STATIC_SLIP)
                d0, d1 = s0 - sm, s1 - s0
                zig = (d0 * d1 < 0.0) & (np.minimum(np.abs(d0), np.abs(d1)) > CHATTER_FLOOR)
                self.held += int(held.sum())
                self.flips += int((held & zig).sum())
            self._slip = s0
        self.u = self.u + h * self.w
        self.force = -(self.pads.K @ self.u)
        self.gathers += 1
        self.open_h = h

    def velocity(self) -> np.ndarray:
        """The synchronous velocity [m/s] (closing half sub-step from the staggered state; costs evaluations)."""
        if self.open_h is None:
            return self.w.copy()
        h = self.open_h
        if self.scheme.kicks == "inside":
            return substep(self.pads, self.scheme.method, self.w, 0.5 * h, self.force, self.evals)
        kick = 0.5 * h * self.force / self.pads.m
        return substep(self.pads, self.scheme.method, self.w + kick, 0.5 * h, np.zeros_like(self.w), self.evals)

    def sample_velocity(self) -> tuple[np.ndarray, np.ndarray]:
        """The package's ``strang`` sample (:func:`~aca_warp.kernels.physics.strang_sample_velocity`): (V, w⁺)
        [m/s] of the merged sub-step over the last step that the next step of the same length opens with, V = w +
        θ (w⁺ − w) the velocity at which it takes its friction; the state is left as it is. The θ-method sub-steps
        with the spring force inside (``forced-thmid``, ``forced-thmean``) only; from a synchronous state (w, w)."""
        if self.scheme.kicks != "inside" or self.scheme.method not in ("thmid", "thmean"):
            raise ValueError(f"a step's sample is the θ-point of forced-thmid/-thmean, not of {self.scheme.name}")
        if self.open_h is None:
            return self.w.copy(), self.w.copy()
        h = np.broadcast_to(np.asarray(self.open_h, dtype=np.float64), self.w.shape)
        w1 = substep(self.pads, self.scheme.method, self.w, h, self.force, self.evals)
        theta = theta_of(self.pads, self.w, h, np.zeros_like(self.evals))  # the sub-step's θ again, not counted
        return self.w + theta * (w1 - self.w), w1

    def synchronise(self) -> None:
        """Close the staggered state (w becomes the synchronous velocity); the next step opens afresh."""
        self.w = self.velocity()
        self.open_h = None


def pad_globals(
    pads: Pads, v: np.ndarray, w: np.ndarray | None = None, tau: np.ndarray | None = None, w1: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """μ, Σu̇ [m/s] and Σ|u̇| [m/s] of every pad at patch velocities v (n,) (docs/model.md §2.8), each (P,). Given
    the staggered velocities w (n,) [m/s] that v was closed from, also two readings that differ from μ only at the
    patches whose slip changes sign between w and v: ``mu_segment``, each such patch taking the mean of f along its
    slip segment instead of f at v, and ``mu_instant``, each taking f at the fraction ``tau`` (n,) in [0, 1) of its
    segment (random fractions: an instant of the straight path, whose mean over τ is the segment's mean). With
    ``w1`` (n,) [m/s] the segment runs from w to w1 instead of from w to v (the package's ``strang`` sample, whose v
    is the θ-point of the merged sub-step from w to w1)."""
    s = pads.vd - v
    f = pads.fn * friction(pads, s)
    seg = pads.start[:-1]
    mu = lambda forces: (np.add.reduceat(forces, seg) + pads.coulomb) / pads.load  # noqa: E731  (N per patch → μ)
    out = {
        "mu": mu(f),
        "sum_velocity": np.add.reduceat(v, seg),
        "sum_abs_velocity": np.add.reduceat(np.abs(v), seg),
    }
    if w is not None:
        s0 = pads.vd - w
        s1 = s if w1 is None else pads.vd - w1
        cross = np.flatnonzero((s0 * s1 < 0.0) & (np.abs(s1 - s0) > SEGMENT_MIN))
        seg_f = f.copy()
        g = friction_integral(pads, s1[cross]) - friction_integral(pads, s0[cross])
        seg_f[cross] = pads.fn[cross] * g / (s1[cross] - s0[cross])
        out["mu_segment"] = mu(seg_f)
        if tau is not None:
            inst_f = f.copy()
            inst_f[cross] = pads.fn[cross] * friction(pads, s0[cross] + tau[cross] * (s1 - s0)[cross])
            out["mu_instant"] = mu(inst_f)
    return out


@dataclass
class Record:
    """Sampled pad globals: ``time`` (N,) [s], ``mu``, ``sum_velocity``, ``sum_abs_velocity`` (N, P) [1, m/s, m/s];
    per-patch velocities ``velocity`` (N − patch_first, n) [m/s] from sample ``patch_first`` on (None: not kept).

    Three other readings of μ (N, P) [1] (None unless :meth:`empty` was asked for them; NaN where not taken):
    ``mu_segment`` and ``mu_instant`` (:func:`pad_globals`: f averaged along the slip segment of the patches that
    cross zero slip in the closing half step, or taken at a random instant of it) and ``mu_applied``, the friction
    and damping force the steps applied over the sample interval ending at the sample, from the momentum balance
    m (w⁺ − w) = span (F_s + F_N f − c v) of each sub-step (its time mean equals the mean friction the pad passes
    to its springs; the damping's mean, c Σu̇, is zero in a bounded steady state)."""

    time: np.ndarray
    mu: np.ndarray
    sum_velocity: np.ndarray
    sum_abs_velocity: np.ndarray
    velocity: np.ndarray | None = None
    patch_first: int = 0
    mu_segment: np.ndarray | None = None
    mu_instant: np.ndarray | None = None
    mu_applied: np.ndarray | None = None

    @classmethod
    def empty(
        cls, samples: int, pads: Pads, sample_dt: float, patch_window: float = 0.0, *, readings: bool = False
    ) -> Record:
        """A record of ``samples`` samples of ``pads``, per-patch velocities over the last ``patch_window`` [s];
        with ``readings``, room for the other readings of μ."""
        z = lambda: np.full((samples, pads.pads), np.nan)  # noqa: E731
        rows = min(samples, round(patch_window / sample_dt) + 1) if patch_window > 0 else 0
        vel = np.full((rows, pads.n), np.nan) if rows else None
        more = (z(), z(), z()) if readings else (None, None, None)
        return cls(np.arange(samples) * sample_dt, z(), z(), z(), vel, samples - rows, *more)

    def put(self, k: int, pads: Pads, v: np.ndarray, w: np.ndarray | None = None, w1: np.ndarray | None = None) -> None:
        """Sample k from the synchronous patch velocities v (n,) [m/s]; ``mu_segment`` and ``mu_instant`` too where
        the record has room for them and the staggered velocities w (n,) [m/s] that v was closed from are given (the
        instants drawn from a generator seeded by k: reproducible); with ``w1`` (n,) [m/s] the readings are along the
        sub-step from w to w1 instead (the package's ``strang`` sample, :meth:`SplitStepper.sample_velocity`)."""
        if w is None or self.mu_segment is None or self.mu_instant is None:
            g = pad_globals(pads, v)
        else:
            # τ depends on k only: a batch's patches draw their own, records of other pads at the same place repeat them
            g = pad_globals(pads, v, w, np.random.default_rng((INSTANT_SEED, k)).random(pads.n), w1)
            self.mu_segment[k], self.mu_instant[k] = g["mu_segment"], g["mu_instant"]
        self.mu[k], self.sum_velocity[k], self.sum_abs_velocity[k] = g["mu"], g["sum_velocity"], g["sum_abs_velocity"]
        if self.velocity is not None and k >= self.patch_first:
            self.velocity[k - self.patch_first] = v


def fixed_step(dt: float, sample_dt: float) -> tuple[int, float]:
    """The steps per sample interval and the step [s] that :func:`run_fixed` takes for a step of at most dt [s]
    (the interval ``sample_dt`` [s] divided evenly)."""
    per = max(1, math.ceil(sample_dt / dt - 1e-9))
    return per, sample_dt / per


def run_fixed(
    pads: Pads,
    scheme: Scheme,
    dt: float,
    duration: float,
    sample_dt: float,
    *,
    patch_window: float = 0.0,
    progress: Any = None,
    readings: bool = False,
    sample: str = "close",
) -> dict[str, Any]:
    """Run ``scheme`` at the fixed step dt [s] (shortened to fit the sample interval) for ``duration`` [s];
    samples every ``sample_dt`` [s] (``sample`` "close": the synchronous velocities of the closing sub-step;
    "step": the package's ``strang`` sample, :meth:`SplitStepper.sample_velocity`, its readings along the merged
    sub-step), per-patch velocities over the last ``patch_window``
    [s]; with ``readings`` also the record's other readings of μ (segment, instant, applied). Returns the
    :class:`Record`, the step, the steps, and
    friction evaluations per patch per step (recording closes excluded) and per simulated ms."""
    if sample not in ("close", "step"):
        raise ValueError(f"sample must be 'close' or 'step', got {sample!r}")
    per, h = fixed_step(dt, sample_dt)
    samples = round(duration / sample_dt)
    rec = Record.empty(samples + 1, pads, sample_dt, patch_window, readings=readings)
    applied = rec.mu_applied
    st = SplitStepper(pads, scheme)
    rec.put(0, pads, st.w)
    hh = np.full(pads.n, h)
    seg = pads.start[:-1]
    close_evals = 0.0
    for k in range(1, samples + 1):
        if applied is None:
            for _ in range(per):
                st.step(hh)
        else:
            impulse, span = np.zeros(pads.n), 0.0
            for _ in range(per):
                w0, force, sub = st.w, st.force, (0.5 * h if st.open_h is None else h)
                st.step(hh)
                impulse += pads.m * (st.w - w0) - sub * force
                span += sub
            applied[k] = (np.add.reduceat(impulse, seg) / span + pads.coulomb) / pads.load
        before = st.evals.sum()
        if sample == "step":
            v, w1 = st.sample_velocity()
            rec.put(k, pads, v, st.w, w1)
        else:
            v = st.velocity()
            rec.put(k, pads, v, st.w)
        close_evals += st.evals.sum() - before
        if not np.all(np.isfinite(v)):
            break
        if progress is not None and k % 2000 == 0:
            progress(k, samples)
    steps = samples * per
    run_evals = (st.evals.sum() - close_evals) / pads.n
    return {
        "record": rec,
        "dt": h,
        "steps": steps,
        "evals_per_step": run_evals / steps,
        "gathers": st.gathers,
        "chatter": st.flips / max(st.held, 1),
        "finite": bool(np.all(np.isfinite(rec.mu))),
    }
