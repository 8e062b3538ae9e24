"""An error-controlled composite integrator for one pad: the explicit DP5 pair while every patch slides, the forced
split scheme with the damped-midpoint sub-step once a patch touches the static branch; a NumPy prototype of the
default that docs/friction_step.md recommends.

Modes (per pad, decided at every sample time, where the state is synchronous):

* **E** — the package's ``adaptive``: Dormand–Prince 5(4) on y = (u, u̇) with its friction-weighted maximum norm
  relative to ``tol_e`` and its PI controller (exponents 0.7/5 and 0.4/5, factors 0.2–5, no growth right after a
  rejection), steps landing on the sample times (``dense=False``, as the kernels do) or free steps with the pair's
  4th-order continuous extension at the samples (``dense=True``).
* **I** — the forced split scheme (:mod:`aca_warp.studies.friction_schemes`, ``forced-<method>``): per merged step
  w ← Φ_{(h_prev + h)/2}[F_s(u)](w), u ← u + h w, F_s ← −K u, one spring evaluation. Error estimate per patch: the
  spring part, the local velocity error of the trapezoidal kick h³/12 |F̈_s|/m with F̈_s from the second divided
  difference of the last three spring forces (the step's own evaluations), and with ``friction_error`` the
  sub-step's own estimate (:func:`~aca_warp.studies.friction_schemes.substep_with_error`); each scaled by tol_i V_i
  (the DP5 norm's velocity scale), combined as √(e_s² + e_f²) and reduced over the pad by rms (``norm``) or maximum.
  The spring part alone decides acceptance (the merged sub-step also carries the closing half of the step before,
  which no shorter trial reduces); the combined error sizes the next step (PI, exponents 0.7/2 and 0.4/2 with the
  friction part, 0.7/3 and 0.4/3 without). The steps of a sample interval are equal (:func:`even_step`), at most the
  sample interval and 0.9 × the spring bound 2/ω_max.

Switch: a pad in E goes to I at the next sample once a patch of it was on the static branch of Eq. 4 (|v_d − u̇| <
STATIC_SLIP, where friction rises with the slip and its rate γ = F_N f′/m bounds the explicit step) at an accepted
step of the interval; a pad in I returns to E at a sample when no patch was on the static branch during the last
RELEASE intervals (in saturation some patch touches the static branch every few microseconds: without this
hysteresis a 150-patch hf1 sector switched ~5000 times in 30 ms).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aca_warp.studies.friction_schemes import (
    STATIC_SLIP,
    Pads,
    Record,
    friction,
    friction_pair,
    substep,
    substep_with_error,
)

DP5_A = (
    (),
    (1.0 / 5.0,),
    (3.0 / 40.0, 9.0 / 40.0),
    (44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0),
    (19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0),
    (9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0),
    (35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0),
)
DP5_E = (71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0)
# DOPRI5's continuous extension (Hairer, Nørsett & Wanner, the d_i of CONTD5), order 4
DP5_D = (
    -12715105075.0 / 11282082432.0, 0.0, 87487479700.0 / 32700410799.0, -10690763975.0 / 1880347072.0,
    701980252875.0 / 199316789632.0, -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0,
)  # fmt: skip
MIN_STEP = 1.0e-15  # s
SPRING_SAFETY = 0.9  # mode I's steps stay below this share of the spring bound 2/ω_max
RELEASE = 50  # sample intervals without a patch on the static branch before a pad in mode I returns to mode E


@dataclass
class Control:
    """A pad's step control (the kernels' ``ctl``/``mode`` columns): desired step ``want`` [s], previous scaled
    error ``err`` (PI), whether the last trial was rejected, and the counters of accepted and rejected trials.
    ``even``: the trials are the equal steps of :func:`even_step`, each taken as a full step (the next desired step
    is h × the PI factor); otherwise a step cut short to land says nothing against the desired one (the kernels'
    DP5 rule)."""

    want: float
    err: float = 1.0e-4
    rejected: bool = False
    accepted_n: int = 0
    rejected_n: int = 0
    even: bool = False

    def decide(self, err: float, h: float, order: int, h_max: float, accept: float | None = None) -> bool:
        """Accept or reject a trial of step h [s] with scaled error ``err``; set the next desired step (PI,
        Gustafsson, exponents 0.7/order and 0.4/order). ``accept``: the scaled error that decides acceptance
        (default ``err``); ``err`` then only sizes the next step. Returns True on acceptance."""
        if not math.isfinite(err):
            err = 1.0e10
        e = max(err, 1.0e-10)
        if (err if accept is None else accept) <= 1.0:
            fac = 0.9 * e ** (-0.7 / order) * self.err ** (0.4 / order)
            fac = min(max(fac, 0.2), 1.0 if self.rejected or err > 1.0 else 5.0)
            self.rejected = False
            self.err = max(e, 1.0e-4)
            self.want = h * fac if h >= self.want or self.even else max(self.want, h * fac)
            self.accepted_n += 1
            ok = True
        else:
            self.rejected = True
            self.want = h * min(max(0.9 * e ** (-1.0 / order), 0.2), 1.0)
            self.rejected_n += 1
            ok = False
        if self.want < MIN_STEP:
            raise RuntimeError(f"step fell below {MIN_STEP:g} s: the tolerance cannot be met")
        self.want = min(self.want, h_max)
        return ok


def trial_step(want: float, t: float, target: float) -> float:
    """The next trial: the desired step, cut to land on the target without a sliver (the kernels' rule)."""
    rest = target - t
    nxt = min(want, rest)
    return rest if rest - nxt < 0.01 * nxt else nxt


def even_step(want: float, t: float, target: float) -> float:
    """The next trial of mode I: the rest of the interval to the target in equal steps no longer than the desired
    one, rest / ceil(rest / want). Cutting one step short to land (``trial_step``) repeats a long-short pattern every
    sample interval, which pumped the pad's highest network mode (≈ 120 kHz) until it dominated (a 150-patch hf1
    sector at tol_i = 3e-3: Σ|u̇| ×9 after 11 ms); equal steps change only between intervals."""
    rest = target - t
    return rest / max(1, math.ceil(rest / want - 1e-9))


def scales(pads: Pads) -> tuple[np.ndarray, np.ndarray]:
    """The DP5 norm's U_i = F_N,i M/k_T,i [m] and V_i = max(|ω r_i|, F_N,i M/√(k_T,i m_i)) [m/s]."""
    force = pads.fn * pads.M
    return force / pads.kt, np.maximum(np.abs(pads.vd), force / np.sqrt(pads.kt * pads.m))


@dataclass
class Counts:
    """Work of a run: trials accepted and rejected per mode, spring evaluations, friction evaluations per patch,
    simulated time per mode [s], switches."""

    accepted: dict[str, int] = field(default_factory=lambda: {"E": 0, "I": 0})
    rejected: dict[str, int] = field(default_factory=lambda: {"E": 0, "I": 0})
    gathers: int = 0
    evals: float = 0.0
    time: dict[str, float] = field(default_factory=lambda: {"E": 0.0, "I": 0.0})
    switches: int = 0


class Composite:
    """The composite integrator on one pad (``pads`` with one pad): :meth:`run` fills a :class:`Record`."""

    def __init__(
        self,
        pads: Pads,
        *,
        tol_e: float,
        tol_i: float,
        method: str = "thmid",
        dense: bool = False,
        sample_dt: float = 1.0e-6,
        modes: str = "EI",
        h_spring: float | None = None,
        patch_window: float = 0.0,
        norm: str = "rms",
        friction_error: bool = True,
    ) -> None:
        if pads.pads != 1:
            raise ValueError("the composite prototype steps one pad")
        self.p, self.tol_e, self.tol_i, self.method, self.dense = pads, tol_e, tol_i, method, dense
        self.sample_dt, self.modes, self.patch_window = sample_dt, modes, patch_window
        self.norm, self.friction_error = norm, friction_error
        self.U, self.V = scales(pads)
        spring = 2.0 / pads.omega_max() if h_spring is None else h_spring
        self.h_max_i = min(sample_dt, SPRING_SAFETY * spring)
        self.n = pads.n
        self.counts = Counts()
        self.evals = np.zeros(pads.n)

    # ------------------------------------------------------------------------------------------ mode E

    def accel(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """a = (−K u − c v + F_N f(v_d − v))/m [m/s²] (one spring and one friction evaluation)."""
        self.counts.gathers += 1
        self.evals += 1
        p = self.p
        return (-(p.K @ u) - p.c * v + p.fn * friction(p, p.vd - v)) / p.m

    def dp5_error(self, h: float, u: np.ndarray, v: np.ndarray, un: np.ndarray, vn: np.ndarray, ku, kv) -> float:
        """The package's scaled DP5 error of a trial (maximum over the pad)."""
        eu = h * sum(e * k for e, k in zip(DP5_E, ku, strict=True))
        ev = h * sum(e * k for e, k in zip(DP5_E, kv, strict=True))
        _, fd = friction_pair(self.p, self.p.vd - vn)
        wv = self.V + np.maximum(np.abs(v), np.abs(vn))
        slope = np.abs(fd)
        wv = np.where(slope * wv > self.p.M, self.p.M / np.maximum(slope, 1e-300), wv)
        su = self.tol_e * (self.U + np.maximum(np.abs(u), np.abs(un)))
        return float(max(np.max(np.abs(eu) / su), np.max(np.abs(ev) / (self.tol_e * wv))))

    def run_e(self, u, v, t: float, target: float, end: float, ctl: Control, k0):
        """DP5 trials from (u, v) at t [s]: landing on ``target`` or (dense) free steps until the target is passed,
        never past ``end``. Returns (u, v, t, k0, any patch static, dense samples [(time, u, v)])."""
        static = False
        samples: list[tuple[float, np.ndarray, np.ndarray]] = []
        h_max = self.sample_dt if not self.dense else 10.0 * self.sample_dt
        next_sample = target
        while t < target * (1.0 - 1e-13):
            h = trial_step(ctl.want, t, end if self.dense else target)
            ku, kv = [v], [k0]
            for s in range(1, 7):
                us = u + h * sum(a * k for a, k in zip(DP5_A[s], ku, strict=False))
                vs = v + h * sum(a * k for a, k in zip(DP5_A[s], kv, strict=False))
                ku.append(vs)
                kv.append(self.accel(us, vs))
            if not ctl.decide(self.dp5_error(h, u, v, us, vs, ku, kv), h, 5, h_max):
                self.counts.rejected["E"] += 1
                continue
            if self.dense:
                while next_sample <= (t + h) * (1.0 + 1e-13) and next_sample <= end * (1.0 + 1e-13):
                    samples.append((next_sample, *self.dense_out((next_sample - t) / h, h, u, v, us, vs, ku, kv)))
                    next_sample += self.sample_dt
            t, u, v, k0 = t + h, us, vs, kv[6]
            self.counts.accepted["E"] += 1
            static = static or bool(np.any(np.abs(self.p.vd - v) < STATIC_SLIP))
        return u, v, t, k0, static, samples

    @staticmethod
    def dense_out(th: float, h: float, u, v, un, vn, ku, kv) -> tuple[np.ndarray, np.ndarray]:
        """DOPRI5's continuous extension at t + θh: (u, v)."""
        out = []
        for y0, y1, k in ((u, un, ku), (v, vn, kv)):
            r2 = y1 - y0
            r3 = h * k[0] - r2
            r4 = r2 - h * k[6] - r3
            r5 = h * sum(d * kk for d, kk in zip(DP5_D, k, strict=True))
            t1 = 1.0 - th
            out.append(y0 + th * (r2 + t1 * (r3 + th * (r4 + t1 * r5))))
        return out[0], out[1]

    # ------------------------------------------------------------------------------------------ mode I

    def run_i(self, st: dict[str, Any], t: float, target: float, ctl: Control) -> tuple[bool, float]:
        """Forced split steps from the staggered state ``st`` (u, w, F, F_prev, h_prev, t_prev) to the target;
        returns (any static, t)."""
        p = self.p
        static = False
        while t < target * (1.0 - 1e-13):
            h = even_step(ctl.want, t, target)
            span = 0.5 * h if st["h_prev"] is None else 0.5 * (st["h_prev"] + h)
            if self.friction_error:
                w, ef = substep_with_error(p, self.method, st["w"], span, st["F"], self.evals)
            else:
                w, ef = substep(p, self.method, st["w"], span, st["F"], self.evals), 0.0
            un = st["u"] + h * w
            fn = -(p.K @ un)
            self.counts.gathers += 1
            es = np.zeros(p.n)
            if st["F_prev"] is not None:  # the first step after opening has no spring history
                hp = st["h_prev"]
                dd = ((fn - st["F"]) / h - (st["F"] - st["F_prev"]) / hp) * (2.0 / (h + hp))
                es = h**3 / 12.0 * np.abs(dd) / p.m
            err_s, err = self.pad_norm(es), self.pad_norm(np.hypot(es, ef))
            # the merged sub-step's error includes the closing half of the accepted step before, which no shorter
            # trial reduces: it sizes the next step, the spring part alone decides acceptance
            if ctl.decide(err, h, 2 if self.friction_error else 3, self.h_max_i, accept=err_s):
                st.update(u=un, w=w, F_prev=st["F"], F=fn, h_prev=h)
                t += h
                self.counts.accepted["I"] += 1
                static = static or bool(np.any(np.abs(p.vd - w) < STATIC_SLIP))
            else:
                self.counts.rejected["I"] += 1
        return static, t

    def pad_norm(self, e: np.ndarray) -> float:
        """Errors e [m/s] (n,) scaled by tol_i V_i, as the pad's rms or maximum."""
        x = e / (self.tol_i * self.V)
        return float(np.sqrt(np.mean(x * x)) if self.norm == "rms" else np.max(x))

    def open_i(self, u: np.ndarray, v: np.ndarray) -> dict[str, Any]:
        """A staggered state from a synchronous one (the opening half sub-step comes with the first step)."""
        self.counts.gathers += 1
        return {"u": u.copy(), "w": v.copy(), "F": -(self.p.K @ u), "F_prev": None, "h_prev": None}

    def close_i(self, st: dict[str, Any]) -> np.ndarray:
        """The synchronous velocity of a staggered state (half sub-step, no spring evaluation)."""
        if st["h_prev"] is None:
            return st["w"].copy()
        return substep(self.p, self.method, st["w"], 0.5 * st["h_prev"], st["F"], self.evals)

    # ------------------------------------------------------------------------------------------ run

    def run(self, duration: float, first_step: float = 1.0e-9, progress: Any = None) -> Record:
        """Integrate from the pad's start state over ``duration`` [s]; samples every ``sample_dt``."""
        p = self.p
        samples = round(duration / self.sample_dt)
        end = samples * self.sample_dt
        rec = Record.empty(samples + 1, p, self.sample_dt, self.patch_window)
        u, v = p.u0.copy(), p.v0.copy()
        rec.put(0, p, v)
        mode = self.modes[0]
        ctl = {"E": Control(first_step), "I": Control(first_step, even=True)}
        k0 = self.accel(u, v) if mode == "E" else None
        st = self.open_i(u, v) if mode == "I" else {}
        t = 0.0
        calm = 0  # consecutive sample intervals without a patch on the static branch
        k = 1  # the next sample to record
        while k <= samples:
            target = k * self.sample_dt
            t0 = t
            if mode == "E":
                u, v, t, k0, static, dense = self.run_e(u, v, t, target, end, ctl["E"], k0)
                if self.dense:
                    for ts, _us, vs in dense:
                        rec.put(round(ts / self.sample_dt), p, vs)
                    k = round(dense[-1][0] / self.sample_dt) + 1
                else:
                    rec.put(k, p, v)
                    k += 1
            else:
                static, t = self.run_i(st, t, target, ctl["I"])
                u, v = st["u"], self.close_i(st)
                rec.put(k, p, v)
                k += 1
            self.counts.time[mode] += t - t0
            calm = 0 if static else calm + 1
            nxt = "I" if mode == "E" and static else "E" if mode == "I" and calm >= RELEASE else mode
            if nxt != mode and nxt in self.modes:
                self.counts.switches += 1
                if nxt == "I":
                    st = self.open_i(u, v)
                    ctl["I"].want = ctl["E"].want
                else:
                    k0 = self.accel(u, v)
                mode = nxt
            if progress is not None and k % 2000 == 0:
                progress(k, samples)
        self.counts.evals = float(self.evals.sum() / self.n)
        return rec
