"""Work-precision study of the HF integrators: error against wall time in sliding, stick-slip and saturation.

Scenes (:data:`SPECS`): ``hf1`` and ``hf2`` from rest (sliding), ``stickslip`` (hf1 with the disc at 0.5 m/s at the
mean radius: patches stick within 0.1 ms), ``va_start`` (the varying_area preset at its start, growth off: HF1
patches under the HF2 load, from rest, near sticking), ``va_late`` (varying_area with its growth ×100 run for 2 ms
from rest, then frozen: the grown areas, stiffnesses and normal forces, the saturated state), ``hf1_sat`` and
``hf3_sat`` (hf1 and hf3 from equilibrium + 0.01 m/s velocity perturbation run to saturation, 20 and 40 ms of
strang at 5e-8 s). The start states that need a run are made once and cached in the output folder
(``state_<scene>.npz``, with how they were made and the saturation detector's verdict).

Measures:

* **pointwise window** (every scene): max |μ(t) − μ_ref(t)| and the final state error
  max(‖u − u_ref‖∞/‖u_ref‖∞, ‖u̇ − u̇_ref‖∞/‖u̇_ref‖∞) against SciPy DOP853 at ``--ref-rtol`` (1e-11) on
  :class:`~aca_warp.hf.reference.ReferenceODE`, checked by DOP853 at 10× that rtol and by our own finest
  ``adaptive`` run (an independent code); on the non-chaotic scenes also the relative errors of the frequency and
  amplitude of the largest peak of μ's spectrum and the mean |S(f) − S_ref(f)| of the Synchronization Index;
* **statistics window** (saturated scenes: chaotic, pointwise μ errors there say nothing after a short time):
  mean and standard deviation of μ, its spectrum in bands (mean |ln A/A_ref| over 5 kHz bands), the largest
  peak, S(f) and the fraction of sticking patches, against a long fp64 ``strang`` reference at ``--long-ref-dt``;
  the **floor** is the same reference run from a state perturbed by 1e-9 m/s (an equally exact trajectory):
  statistics errors at the floor are as good as exact for that window length.

Our methods: ``adaptive`` over tolerances 1e-2 … 1e-7 and ``strang`` over steps (fp64; the other integrators and
fp32 on request: earlier full runs found them dominated by strang and fp64); baselines SciPy DOP853 and Radau at
several rtols. Wall times are those of the stepping loop (kernel compilation and graph capture excluded); SciPy
times those of ``solve_ivp``; a SciPy run whose first tenth extrapolates beyond ``--scipy-cap`` is timed on that
tenth and extrapolated ×10 (flagged; its error is the error at the end of the tenth). Results:
``OUT/wp_<device>_<scenes>.json``. Examples::

    python scripts/work_precision.py --quick --out /tmp/wp                 # CPU, 300-patch sectors, ~4 min
    python scripts/work_precision.py --scenes hf1 hf2 stickslip va_start --out wp_cpu   # CPU, full pads, ~16 min
    python scripts/work_precision.py --report wp_cpu/*.json                # figures + docs/work_precision.md

As a library: :mod:`aca_warp.studies.work_precision_states` makes (or reads) the scenes' start states,
:class:`Study` measures one scene (:meth:`Study.reference`, :meth:`Study.long_reference`, :meth:`Study.ours`,
:meth:`Study.scipy`), :func:`measure` writes a result JSON; :mod:`aca_warp.studies.work_precision_report` turns
result JSONs into figures and the docs section.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.analysis.spectra import amplitude_spectrum, peak
from aca_warp.analysis.sync import sync_index_from_signals
from aca_warp.common.argtypes import int_at_least, nonneg, positive
from aca_warp.hf.options import DEFAULT_INTEGRATOR, DEFAULT_TOLERANCE, INTEGRATORS, default_step
from aca_warp.hf.reference import SCIPY_METHODS, ReferenceODE
from aca_warp.scene import Record
from aca_warp.studies.report import add_device, add_page_options, command_line, measure_or_report, write_json
from aca_warp.studies.runs import model_from_state, run_general
from aca_warp.studies.work_precision_states import SAMPLE_DT, SAT_SEED, VA_GROW, VA_SPEEDUP, Start, start_state

BAND_TOP = 2.0e5  # Hz
BAND_WIDTH = 5.0e3  # Hz, bands of the spectrum statistic
STICK_THRESHOLD = 1.0e-3  # m/s: a patch "sticks" while |ω r − u̇| is below this (1/5 of Eq. 4's 1/slope)
TWIN_DV = 1.0e-9  # m/s, perturbation of the floor run
QUICK_PATCHES = 300
TOLS = {False: (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7), True: (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)}
LONG_TOLS = {False: (1e-3, 1e-4, 1e-5), True: (1e-3, 1e-4, 1e-5)}
LONG_STEPS = {False: (3e-8, 1e-8, 3e-9), True: (3e-8, 1e-8, 3e-9)}
SCIPY_RTOL = {"DOP853": (1e-5, 1e-7, 1e-9), "Radau": (1e-4, 1e-6, 1e-8)}
SCIPY_RTOL_QUICK = {"DOP853": (1e-5, 1e-7, 1e-9), "Radau": (1e-6,)}
LONG_SCIPY = ("DOP853", 1e-8)
EXPLICIT_STEPS = (5e-8, 2e-8, 1e-8)


@dataclass(frozen=True)
class Spec:
    """How one scene of the study is measured.

    Attributes:
        what: One line for the docs.
        regime: ``sliding``, ``stick-slip`` or ``saturated``.
        window: Pointwise window [s]: (full, --quick).
        steps: strang steps [s] of the pointwise window: (full, --quick).
        long: Statistics window [s]: (full, --quick); (0, 0) for none.
        spectra: Spectral errors over the pointwise window (not on chaotic states).
    """

    what: str
    regime: str
    window: tuple[float, float]
    steps: tuple[tuple[float, ...], tuple[float, ...]]
    long: tuple[float, float] = (0.0, 0.0)
    spectra: bool = True


SLIDING_STEPS = ((1e-7, 3e-8, 1e-8, 3e-9), (3e-8, 1e-8, 3e-9))
STICK_STEPS = ((3e-8, 1e-8, 3e-9, 1e-9), (1e-8, 3e-9, 1e-9))
FINE_STEPS = ((1e-8, 3e-9, 1e-9), (1e-8, 3e-9, 1e-9))


def _from_rest(preset: str) -> Spec:
    """``preset`` from rest, sliding at 10 m/s with linear growth."""
    return Spec(f"{preset} from rest (sliding at 10 m/s, linear growth)", "sliding", (1e-3, 2e-4), SLIDING_STEPS)


def _saturated(preset: str) -> Spec:
    """``preset`` saturated: from equilibrium plus a perturbation; no spectral errors (a chaotic state)."""
    what = f"{preset} saturated (from equilibrium + perturbation)"
    return Spec(what, "saturated", (1e-4, 1e-4), FINE_STEPS, (1e-3, 2e-4), spectra=False)


SPECS = {
    "hf1": _from_rest("hf1"),
    "hf2": _from_rest("hf2"),
    "stickslip": Spec(
        "hf1 at 0.5 m/s from rest: patches reach sticking within 0.1 ms", "stick-slip", (5e-4, 1e-4), STICK_STEPS
    ),
    "va_start": Spec(
        "varying_area at its start, growth off (HF1 patches under the HF2 load) from rest",
        "stick-slip",
        (2e-4, 1e-4),
        FINE_STEPS,
    ),  # fmt: skip
    "va_late": Spec(
        f"varying_area, growth ×{VA_SPEEDUP:g} for {VA_GROW * 1e3:g} ms from rest, then frozen (saturated)",
        "saturated",
        (5e-5, 5e-5),
        FINE_STEPS,
        (5e-4, 1e-4),
        spectra=False,
    ),  # fmt: skip
    "hf1_sat": _saturated("hf1"),
    "hf3_sat": _saturated("hf3"),
}
SCENES = tuple(SPECS)


# ----------------------------------------------------------------------------------------------- measures


def spectral_peak(mu: np.ndarray, fmin: float) -> tuple[float, float]:
    """(frequency [Hz], amplitude [1]) of the largest peak of μ's mean-normalised spectrum in [fmin, 200 kHz]."""
    f, a = amplitude_spectrum(mu, SAMPLE_DT, normalise="mean")
    return peak(f, a, fmin=fmin, fmax=min(BAND_TOP, f[-1]))


def sync_curve(v: np.ndarray, fmin: float) -> np.ndarray:
    """S(f) of per-patch velocities of shape (N, n) in [fmin, 200 kHz] (NaN where Φ < 2)."""
    top = min(BAND_TOP, 0.5 / SAMPLE_DT)
    return sync_index_from_signals(np.asarray(v, np.float32), SAMPLE_DT, freq_range=(fmin, top), null_trials=0).S


def sticking(slip_speed: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Fraction of sticking patches (|ω r − u̇| < STICK_THRESHOLD) per sample; ``slip_speed`` ω r [m/s] (n,),
    ``v`` [m/s] (N, n)."""
    return (np.abs(slip_speed[None, :] - v) < STICK_THRESHOLD).mean(axis=1)


def statistics(mu: np.ndarray, v: np.ndarray, slip_speed: np.ndarray, fmin: float) -> dict[str, Any]:
    """Statistics of a saturated window: μ (N,), per-patch velocities v (N, n) [m/s], disc speeds ω r (n,) [m/s].

    Returns mean and std of μ, the mean-normalised amplitude spectrum of μ averaged over bands of
    max(5 kHz, 5/T) from ``fmin`` to 200 kHz, the largest peak, S(f) and the mean fraction of sticking patches.
    """
    f, a = amplitude_spectrum(mu, SAMPLE_DT, normalise="mean")
    top = min(BAND_TOP, f[-1])
    width = max(BAND_WIDTH, 5.0 / (len(mu) * SAMPLE_DT))
    edges = np.arange(fmin, top + 0.5 * width, width)
    bands = np.array([a[(f >= lo) & (f < hi)].mean() for lo, hi in zip(edges[:-1], edges[1:], strict=True)])
    pf, pa = peak(f, a, fmin=fmin, fmax=top)
    return {
        "mean": float(mu.mean()),
        "std": float(mu.std()),
        "bands": bands,
        "peak_f": pf,
        "peak_a": pa,
        "sync": sync_curve(v, fmin),
        "stick": float(sticking(slip_speed, v).mean()),
    }


def stat_errors(s: dict[str, Any], ref: dict[str, Any]) -> dict[str, float]:
    """Errors of the statistics ``s`` against ``ref`` (:func:`statistics`): |Δ mean μ|, |Δ std μ|/std, mean
    |ln A/A_ref| over the bands, relative peak-frequency error, mean |ΔS| (bins defined in both) and the relative
    error of the sticking fraction."""
    both = np.isfinite(s["sync"]) & np.isfinite(ref["sync"])
    pos = (s["bands"] > 0) & (ref["bands"] > 0)
    return {
        "mean": abs(s["mean"] - ref["mean"]),
        "std": abs(s["std"] - ref["std"]) / ref["std"],
        "spectrum": float(np.mean(np.abs(np.log(s["bands"][pos] / ref["bands"][pos])))) if pos.any() else math.nan,
        "peak_f": abs(s["peak_f"] - ref["peak_f"]) / ref["peak_f"],
        "sync": float(np.mean(np.abs(s["sync"][both] - ref["sync"][both]))) if both.any() else math.nan,
        "stick": abs(s["stick"] - ref["stick"]) / ref["stick"] if ref["stick"] > 0 else math.nan,
    }


def state_error(u: np.ndarray, v: np.ndarray, ru: np.ndarray, rv: np.ndarray) -> float:
    """max(‖u − u_ref‖∞/‖u_ref‖∞, ‖u̇ − u̇_ref‖∞/‖u̇_ref‖∞) of one state."""
    return float(max(np.max(np.abs(u - ru)) / np.max(np.abs(ru)), np.max(np.abs(v - rv)) / np.max(np.abs(rv))))


class Overrun(Exception):
    """A SciPy solve ran past its time limit."""


@contextlib.contextmanager
def deadline(ode: ReferenceODE, seconds: float) -> Iterator[None]:
    """Within the block, ``ode``'s right-hand side raises :class:`Overrun` once ``seconds`` [s] have passed (a
    SciPy method that would take far longer than the cap is stopped instead of waited for)."""
    rhs, end = ode.rhs, time.perf_counter() + seconds

    def capped(t: float, y: np.ndarray) -> np.ndarray:
        if time.perf_counter() > end:
            raise Overrun(f"first tenth not done within {seconds:g} s")
        return rhs(t, y)

    ode.rhs = capped  # type: ignore[method-assign]
    try:
        yield
    finally:
        del ode.rhs


# ----------------------------------------------------------------------------------------------- one scene


class Study:
    """One device's measurements of one scene from its start state."""

    def __init__(self, name: str, start: Start, args: argparse.Namespace) -> None:
        self.name, self.start, self.args = name, start, args
        self.spec = SPECS[name]
        q = int(bool(args.quick))
        self.window = args.window or self.spec.window[q]
        self.long = 0.0 if args.no_long else (args.long_window or self.spec.long[q]) if self.spec.long[q] else 0.0
        self.n = round(self.window / SAMPLE_DT)
        self.n_long = round(self.long / SAMPLE_DT)
        self.fmin = max(args.fmin, 2.0 / self.window)
        self.fmin_long = max(args.fmin, 2.0 / self.long) if self.long else math.nan
        self.rows: list[dict[str, Any]] = []
        self.info: dict[str, Any] = {
            "scene": name,
            "what": self.spec.what,
            "regime": self.spec.regime,
            "patches": start.scene.patches.count,
            "angular_velocity": start.scene.angular_velocity,
            "start": start.info,
            "window_s": self.window,
            "long_window_s": self.long,
        }

    def log(self, msg: str) -> None:
        print(f"[{self.name}] {msg}", flush=True)

    def run(self, integrator: str, precision: str, n: int, *, dt=None, tol=None, v=None) -> dict[str, Any]:
        """One run of n samples from the start state (velocities ``v`` instead of the start's if given)."""
        s = self.start
        model, state = model_from_state(s.scene, self.args.device, precision, s.u, s.v if v is None else v, s.arrays)
        rec = Record(sample_dt=SAMPLE_DT, patches=("velocity", "displacement"))
        res = run_general(model, state, duration=n * SAMPLE_DT, integrator=integrator, record=rec, dt=dt, tolerance=tol)
        c = res.collect()
        return {
            "complete": res.complete,
            "fault": "" if res.fault is None else str(res.fault),
            "wall_s": res.wall_time,
            "compile_s": res.compile_time,
            "steps": res.steps,
            "rejected": res.rejected,
            "dt": res.dt,
            "mu": c.globals[:, 0, 0].astype(np.float64),
            "u": c.displacement.astype(np.float64),
            "v": c.velocity.astype(np.float64),
        }

    # ------------------------------------------------------------------------------------------- references
    def reference(self) -> None:
        """DOP853 at --ref-rtol over the pointwise window, checked at 10× that rtol; sticking and spectra of it."""
        a, s = self.args, self.start
        model, _ = model_from_state(s.scene, a.device, "fp64", s.u, s.v, s.arrays)
        self.ode = ReferenceODE(model)
        self.slip = self.ode.vd
        times = np.arange(self.n + 1) * SAMPLE_DT
        self.log(f"SciPy DOP853 reference, rtol {a.ref_rtol:g}, {self.window:g} s")
        ref = self.ode.solve(times, method="DOP853", rtol=a.ref_rtol, u0=s.u, v0=s.v)
        chk = self.ode.solve(times, method="DOP853", rtol=10 * a.ref_rtol, u0=s.u, v0=s.v)
        self.ref, self.ref_mu = ref, self.ode.globals(ref.u, ref.v)["mu"]
        stick = sticking(self.slip, ref.v)
        first = np.flatnonzero(stick > 0)
        self.info["reference"] = {
            "method": "DOP853",
            "rtol": a.ref_rtol,
            "atol": "rtol × per-patch scales F_N/k_T and (F_N/k_T)√(k_T/m)",
            "wall_s": ref.wall_time,
            "nfev": ref.nfev,
            "check_rtol": 10 * a.ref_rtol,
            "check_mu": float(np.max(np.abs(self.ode.globals(chk.u, chk.v)["mu"] - self.ref_mu))),
            "check_state": state_error(chk.u[-1], chk.v[-1], ref.u[-1], ref.v[-1]),
            "mu_mean": float(self.ref_mu.mean()),
            "stick": {
                "threshold_m_s": STICK_THRESHOLD,
                "max_fraction": float(stick.max()),
                "mean_fraction": float(stick.mean()),
                "patches_ever_stuck": float((np.abs(self.slip - ref.v) < STICK_THRESHOLD).any(axis=0).mean()),
                "first_stick_s": float(times[first[0]]) if len(first) else math.nan,
            },
        }
        if self.spec.spectra:
            self.ref_peak = spectral_peak(self.ref_mu, self.fmin)
            self.ref_sync = sync_curve(ref.v, self.fmin)
            self.info["reference"].update(peak_hz=self.ref_peak[0], peak_amplitude=self.ref_peak[1])
        r = self.info["reference"]
        self.log(
            f"reference {ref.wall_time:.3g} s, check rtol ×10: μ {r['check_mu']:.2e}; sticking max {stick.max():.4f}"
        )

    def long_reference(self) -> None:
        """fp64 strang at --long-ref-dt over the statistics window, and its twin from a perturbed state (floor)."""
        if not self.long:
            return
        a = self.args
        dv = TWIN_DV * np.random.default_rng(SAT_SEED).standard_normal(len(self.start.v))
        self.log(f"long reference: fp64 strang at {a.long_ref_dt:g} s over {self.long:g} s, and its twin")
        ref = self.run("strang", "fp64", self.n_long, dt=a.long_ref_dt)
        twin = self.run("strang", "fp64", self.n_long, dt=a.long_ref_dt, v=self.start.v + dv)
        for r in (ref, twin):
            if not r["complete"]:
                raise RuntimeError(f"long reference of {self.name} stopped: {r['fault']}")
        self.long_ref = statistics(ref["mu"], ref["v"], self.slip, self.fmin_long)
        floor = stat_errors(statistics(twin["mu"], twin["v"], self.slip, self.fmin_long), self.long_ref)
        self.info["long_reference"] = {
            "integrator": "strang",
            "precision": "fp64",
            "dt": a.long_ref_dt,
            "wall_s": [ref["wall_s"], twin["wall_s"]],
            "twin_dv_m_s": TWIN_DV,
            "floor": floor,
            "vs_reference_mu": float(np.max(np.abs(ref["mu"][: self.n + 1] - self.ref_mu))),
            "mean": self.long_ref["mean"],
            "std": self.long_ref["std"],
            "stick": self.long_ref["stick"],
            "peak_hz": self.long_ref["peak_f"],
        }
        self.log(f"floor: {', '.join(f'{k} {v:.2e}' for k, v in floor.items())}")

    # ------------------------------------------------------------------------------------------- errors
    def window_errors(self, mu: np.ndarray, u: np.ndarray, v: np.ndarray) -> dict[str, float]:
        """Errors of a pointwise-window run (μ (N,), u and v (N, n), N ≤ window samples + 1) against DOP853."""
        k = len(mu)
        out = {
            "mu": float(np.max(np.abs(mu - self.ref_mu[:k]))),
            "state": state_error(u[-1], v[-1], self.ref.u[k - 1], self.ref.v[k - 1]),
        }
        if self.spec.spectra and k == self.n + 1:
            f, amp = spectral_peak(mu, self.fmin)
            s = sync_curve(v, self.fmin)
            both = np.isfinite(s) & np.isfinite(self.ref_sync)
            out.update(
                peak_f=abs(f - self.ref_peak[0]) / self.ref_peak[0],
                peak_a=abs(amp - self.ref_peak[1]) / self.ref_peak[1],
                sync=float(np.mean(np.abs(s[both] - self.ref_sync[both]))) if both.any() else math.nan,
            )
        return out

    def long_errors(self, mu: np.ndarray, v: np.ndarray) -> dict[str, float]:
        """Statistics errors of a statistics-window run against the long reference."""
        return stat_errors(statistics(mu, v, self.slip, self.fmin_long), self.long_ref)

    # ------------------------------------------------------------------------------------------- our runs
    def params(self, integrator: str, precision: str) -> tuple[list[float], list[float]]:
        """(pointwise, statistics-window) tolerances (``adaptive``) or steps [s] of ``integrator``."""
        from aca_warp.hf.solver import stable_step

        a, q = self.args, bool(self.args.quick)
        long = {"adaptive": LONG_TOLS[q], "strang": LONG_STEPS[q]}.get(integrator, ()) if self.long else ()
        if integrator == "adaptive":
            return list(a.tolerances or TOLS[q]), list(long)
        if integrator == "symplectic-euler":
            s = self.start
            lim = stable_step(model_from_state(s.scene, self.args.device, precision, s.u, s.v, s.arrays)[0]).explicit
            return sorted({0.9 * lim, *[h for h in EXPLICIT_STEPS if h < 0.9 * lim]}, reverse=True), []
        return list(a.steps or self.spec.steps[q]), list(long)

    def ours(self) -> None:
        """Every --integrators × --precisions × its steps or tolerances (pointwise and statistics windows)."""
        for integ in self.args.integrators:
            for prec in self.args.precisions:
                point, long = self.params(integ, prec)
                order = sorted(set(point) | set(long), reverse=True)
                for p in order:
                    self.rows.append(self.measure_one(integ, prec, p, window=p in point, long=p in long))

    def measure_one(self, integ: str, prec: str, p: float, *, window: bool, long: bool) -> dict[str, Any]:
        """One row: ``integ`` in ``prec`` at step (tolerance for ``adaptive``) ``p`` over the windows asked for."""
        kw = {"tol": p} if integ == "adaptive" else {"dt": p}
        row: dict[str, Any] = {"kind": "aca_warp", "method": integ, "precision": prec, "device": self.args.device}
        row["tolerance" if integ == "adaptive" else "dt_requested"] = p
        msg = []
        for block, n, on in (("window", self.n, window), ("long", self.n_long, long)):
            if not on:
                continue
            r = self.run(integ, prec, n, **kw)
            row.update(dt=r["dt"], compile_s=r["compile_s"])
            b = {k: r[k] for k in ("wall_s", "steps", "rejected", "complete", "fault")}
            if r["complete"]:
                b.update(
                    self.window_errors(r["mu"], r["u"], r["v"])
                    if block == "window"
                    else self.long_errors(r["mu"], r["v"])
                )
            row[block] = b
            err = (
                f"μ {b.get('mu', math.nan):.2e}" if block == "window" else f"spectrum {b.get('spectrum', math.nan):.2e}"
            )
            msg.append(f"{block} {err} in {b['wall_s']:.3g} s ({b['steps']} steps)")
        self.log(f"{integ} {prec} {'tol' if integ == 'adaptive' else 'dt'} {p:.3g}: " + "; ".join(msg))
        return row

    # ------------------------------------------------------------------------------------------- SciPy
    def scipy(self) -> None:
        """Every --scipy-methods at its rtols over the pointwise window; DOP853 at 1e-8 over the statistics one."""
        a = self.args
        table = SCIPY_RTOL_QUICK if a.quick else SCIPY_RTOL
        for method in a.scipy_methods:
            point = list(a.scipy_rtols or table.get(method, (1e-6,)))
            long = [LONG_SCIPY[1]] if self.long and method == LONG_SCIPY[0] else []
            for rtol in sorted(set(point) | set(long), reverse=True):
                row = {"kind": "scipy", "method": f"scipy-{method}", "precision": "fp64", "rtol": rtol}
                row["device"] = "host CPU (NumPy/SciPy)"
                if rtol in point:
                    row["window"] = self._scipy(method, rtol, self.n, a.scipy_cap, long=False)
                if rtol in long:
                    row["long"] = self._scipy(method, rtol, self.n_long, a.scipy_cap_long, long=True)
                self.rows.append(row)
                self.log(f"scipy {method} rtol {rtol:.0e}: " + "; ".join(
                    f"{b} {row[b].get('mu', row[b].get('spectrum', math.nan)):.2e} in {row[b]['wall_s']:.3g} s"
                    f"{' (extrapolated)' if row[b].get('extrapolated') else ''}" for b in ("window", "long") if b in row
                ))  # fmt: skip

    def _scipy(self, method: str, rtol: float, n: int, cap: float, *, long: bool) -> dict[str, Any]:
        """Run n samples if its first tenth (timed first) extrapolates to ≤ ``cap`` s; else, or when the whole
        window outlasts 2 × ``cap``, report that tenth, extrapolated (statistics windows: no errors then)."""
        s = self.start
        short = max(1, n // 10)
        out: dict[str, Any] = {"extrapolated": True}
        try:
            with deadline(self.ode, cap):  # a tenth that alone takes longer than the cap is given up
                sol = self.ode.solve(np.arange(short + 1) * SAMPLE_DT, method=method, rtol=rtol, u0=s.u, v0=s.v)
            if sol.wall_time * n / short <= cap:
                try:  # the rest of a window can be far dearer than its first tenth (sticking comes later)
                    with deadline(self.ode, 2 * cap):
                        sol = self.ode.solve(np.arange(n + 1) * SAMPLE_DT, method=method, rtol=rtol, u0=s.u, v0=s.v)
                    out["extrapolated"] = False
                except Overrun:
                    out["note"] = f"whole window not done within {2 * cap:g} s"
        except (RuntimeError, Overrun) as e:
            return {"wall_s": math.nan, "extrapolated": False, "complete": False, "fault": str(e)}
        k = len(sol.t) - 1
        out.update(window_s=k * SAMPLE_DT, nfev=sol.nfev, njev=sol.njev, complete=True)
        out["wall_s"] = sol.wall_time * (n / k if out["extrapolated"] else 1.0)
        mu = self.ode.globals(sol.u, sol.v)["mu"]
        if not long:
            out.update(self.window_errors(mu, sol.u, sol.v))
        elif not out["extrapolated"]:
            out.update(self.long_errors(mu, sol.v))
        return out


# ----------------------------------------------------------------------------------------------- the study


def measure(args: argparse.Namespace, argv: list[str]) -> Path:
    """Measure every --scenes on --device (the defaults of the options that depend on --quick filled in); writes
    and returns ``OUT/wp_<device>_<scenes>.json``."""
    import scipy
    import warp as wp

    from aca_warp.common.files import machine

    if args.quick and args.patches is None:
        args.patches = QUICK_PATCHES
    args.long_ref_dt = args.long_ref_dt or 2.5e-9
    args.scipy_cap = args.scipy_cap or (5.0 if args.quick else 30.0)
    args.scipy_cap_long = args.scipy_cap_long or (10.0 if args.quick else 60.0)
    dt = default_step(DEFAULT_INTEGRATOR)  # the default for a scene of no preset (the full presets': regime_step)
    print(f"default integrator {DEFAULT_INTEGRATOR}, dt {dt:g} s, tolerance {DEFAULT_TOLERANCE:g}", flush=True)
    dev = wp.get_device(args.device)
    t0 = time.perf_counter()
    results = []
    for name in args.scenes:
        start = start_state(name, args, lambda m: print(m, flush=True))
        st = Study(name, start, args)
        st.reference()
        st.long_reference()
        if "ours" in args.parts:
            st.ours()
        if "scipy" in args.parts:
            st.scipy()
        results.append({**st.info, "rows": st.rows, "wall_s": time.perf_counter() - t0})
    doc = {
        "machine": machine(dev),
        "versions": {"warp": wp.__version__, "numpy": np.__version__, "scipy": scipy.__version__},
        "python": sys.version.split()[0],
        "quick": bool(args.quick),
        "sample_dt_s": SAMPLE_DT,
        "fmin_hz": args.fmin,
        "defaults": {"integrator": DEFAULT_INTEGRATOR, "dt": dt, "tolerance": DEFAULT_TOLERANCE},
        "scenes": results,
        "total_wall_s": time.perf_counter() - t0,
        "command": command_line("work_precision.py", argv),
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tag = re.sub(r"[^A-Za-z0-9]+", "", args.device) + ("_quick" if args.quick else "")
    path = write_json(out / f"wp_{tag}_{'-'.join(args.scenes)}.json", doc)
    print(f"wrote {path} ({doc['total_wall_s']:.0f} s)")
    return path


# ----------------------------------------------------------------------------------------------- command line


def build_parser() -> argparse.ArgumentParser:
    """The command line of the study."""
    ap = argparse.ArgumentParser(
        description=__doc__.split("As a library:")[0].rstrip(), formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_device(ap)
    ap.add_argument("--quick", action="store_true", help=f"{QUICK_PATCHES}-patch sectors, short windows, fewer points")
    ap.add_argument("--out", default="wp_results", help="folder of the result JSON and the cached start states")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES)
    ap.add_argument(
        "--patches", type=int_at_least(1), help=f"patches per pad (a sector; default all, --quick {QUICK_PATCHES})"
    )
    ap.add_argument("--integrators", nargs="+", default=["adaptive", "strang"], choices=INTEGRATORS)
    ap.add_argument("--precisions", nargs="+", default=["fp64"], choices=["fp64", "fp32"])
    ap.add_argument("--parts", nargs="+", default=["ours", "scipy"], choices=["ours", "scipy"])
    ap.add_argument("--scipy-methods", nargs="+", default=["DOP853", "Radau"], choices=SCIPY_METHODS)
    ap.add_argument("--scipy-rtols", nargs="+", type=positive, help="rtols of every SciPy method (default per method)")
    ap.add_argument("--tolerances", nargs="+", type=positive, help="tolerances of adaptive (default 1e-2 … 1e-7)")
    ap.add_argument(
        "--steps", nargs="+", type=positive, help="steps of strang/implicit-friction [s] (default per scene)"
    )
    ap.add_argument("--window", type=positive, help="pointwise window [s] (default per scene)")
    ap.add_argument("--long-window", type=positive, help="statistics window of the saturated scenes [s]")
    ap.add_argument("--no-long", action="store_true", help="no statistics windows")
    ap.add_argument("--ref-rtol", type=positive, default=1e-11, help="rtol of the SciPy DOP853 reference")
    ap.add_argument("--long-ref-dt", type=positive, help="step of the strang statistics reference [s] (2.5e-9)")
    ap.add_argument("--fmin", type=nonneg, default=5e3, help="lower edge of the spectral band [Hz]")
    ap.add_argument("--scipy-cap", type=positive, help="SciPy runs longer than this are extrapolated [s] (30; quick 5)")
    ap.add_argument("--scipy-cap-long", type=positive, help="the same for the statistics window [s] (60; quick 10)")
    ap.add_argument("--report", nargs="+", metavar="JSON", help="make figures and the docs page from result JSONs")
    add_page_options(ap, "docs/work_precision.md", "docs/figures/work_precision")
    return ap


def report(args: argparse.Namespace) -> None:
    """Figures and the docs page from the result JSONs of --report."""
    from aca_warp.studies.work_precision_report import report as write_report

    write_report(args.report, Path(args.page), Path(args.figures))


def main(argv: list[str] | None = None) -> int:
    """Measure (or, with --report, only report); returns 0."""
    return measure_or_report(build_parser(), argv, report, measure)


if __name__ == "__main__":
    sys.exit(main())
