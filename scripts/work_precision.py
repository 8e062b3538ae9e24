#!/usr/bin/env python3
"""Work-precision study of the HF integrators: error against wall time, per scene, method, step and precision.

Scenes: ``hf1``, ``hf2`` and ``stickslip`` (hf1 with the disc at 0.5 m/s at the mean radius, where Eq. 4 is
steep enough that patches reach sticking). For every integrator of ``aca_warp.hf.options.INTEGRATORS`` × steps (or
tolerances for ``adaptive``) × fp32/fp64, and for SciPy's ``solve_ivp`` methods as baselines, it measures:

* ``state``: the final state after ``--t-state`` (0.1 ms): max(‖u − u_ref‖∞/‖u_ref‖∞, ‖u̇ − u̇_ref‖∞/‖u̇_ref‖∞)
  against an independent SciPy DOP853 solution at rtol 1e-10 (``aca_warp.hf.reference``);
* ``mu``: max |μ(t) − μ_ref(t)| over ``--t-long`` (1 ms, 0.2 ms with ``--quick``) against our own fp64 ``strang``
  run at ``--ref-dt``, checked by Richardson extrapolation (runs at 2 and 4 × ``--ref-dt``: estimated order and
  error of the reference);
* ``peak_f``, ``peak_a``: relative errors of the frequency and amplitude of the largest peak of the mean-normalised
  Hann spectrum of μ over the same record (``aca_warp.analysis.spectra``), band [``--fmin``, 200 kHz];
* ``sync``: mean |S(f) − S_ref(f)| of the Synchronization Index of the per-patch velocities (bins where both are
  defined, ``aca_warp.analysis.sync``, relative rule η = 0.1, no null trials).

Wall times are those of the stepping loop (kernel compilation and graph capture excluded, reported apart);
SciPy times are those of ``solve_ivp``. A SciPy method too slow for a window is timed on a tenth of it and its
time extrapolated ×10 (flagged ``extrapolated`` in the JSON and drawn hollow); its error is then the error at
the end of that shorter window. Results: ``OUT/wp_<device>_<scenes>.json``. Examples::

    python scripts/work_precision.py --quick --out /tmp/wp                # CPU, ~5 min
    python scripts/work_precision.py --device cuda:0 --out $OUT/wp        # GPU
    python scripts/work_precision.py --report a.json b.json               # figures + docs/work_precision.md
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.config.quiet = True

from aca_warp.analysis.spectra import amplitude_spectrum, peak  # noqa: E402
from aca_warp.analysis.sync import sync_index_from_signals  # noqa: E402
from aca_warp.common.files import machine  # noqa: E402
from aca_warp.hf.loop import run_hf  # noqa: E402
from aca_warp.hf.model import build_model  # noqa: E402
from aca_warp.hf.options import DEFAULT_DT, DEFAULT_INTEGRATOR, INTEGRATORS, RunOptions  # noqa: E402
from aca_warp.hf.reference import SCIPY_METHODS, ReferenceODE  # noqa: E402
from aca_warp.hf.state import initial_state  # noqa: E402
from aca_warp.scene import Record, Scene, preset  # noqa: E402

SCENES = ("hf1", "hf2", "stickslip")
STICK_SPEED = 0.5  # m/s at the mean radius 0.13 m
STICK_THRESHOLD = 1.0e-3  # m/s: a patch "sticks" while |ω r − u̇| is below this (1/5 of Eq. 4's 1/slope)
SAMPLE_DT = 1.0e-6  # s
BAND_TOP = 2.0e5  # Hz
MEASURES = ("state", "mu", "peak_f", "peak_a", "sync")
MEASURE_LABELS = {
    "state": "final state after {t_state} (rel. max error of u, u̇)",
    "mu": "μ(t) over {t_long} (max abs. error)",
    "peak_f": "largest spectral peak of μ: frequency (rel. error)",
    "peak_a": "largest spectral peak of μ: amplitude (rel. error)",
    "sync": "S(f) (mean abs. error)",
}
STEPS_FULL = [1e-6, 3e-7, 1e-7, 3e-8, 1e-8]
STEPS_QUICK = [1e-7, 3e-8, 1e-8]
EXPLICIT_FULL = [5e-8, 2e-8, 1e-8, 5e-9]
EXPLICIT_QUICK = [2e-8, 1e-8]
TOL_FULL = {"fp64": [1e-3, 1e-4, 1e-5, 1e-6], "fp32": [1e-3, 1e-4, 1e-5]}
TOL_QUICK = {"fp64": [1e-3, 1e-4, 1e-5], "fp32": [1e-3, 1e-4]}
SCIPY_RTOL = {"RK45": [1e-4, 1e-6, 1e-8], "DOP853": [1e-5, 1e-7, 1e-9]}
SCIPY_RTOL_IMPLICIT = [1e-4, 1e-6, 1e-8]


def make_scene(name: str) -> Scene:
    """The scene ``name``: a preset, or ``stickslip`` (hf1 at 0.5 m/s at the mean radius)."""
    if name == "stickslip":
        s = preset("hf1")
        return s.replace(name="stickslip", angular_velocity=STICK_SPEED / s.pad.mean_radius)
    return preset(name)


def richardson(a: np.ndarray, b: np.ndarray, c: np.ndarray, ratio: float = 2.0) -> dict[str, float]:
    """Richardson check of three solutions at steps r²h, rh, h (``a``, ``b``, ``c``; any common shape).

    Returns the observed order p = log(‖a − b‖∞/‖b − c‖∞)/log r and the estimated error of the finest one,
    ‖b − c‖∞/(r^p − 1) (NaN order when the differences vanish).
    """
    e1 = float(np.max(np.abs(np.asarray(a, float) - np.asarray(b, float))))
    e2 = float(np.max(np.abs(np.asarray(b, float) - np.asarray(c, float))))
    if e2 == 0.0 or e1 == 0.0:
        return {"order": math.nan, "diff_coarse": e1, "diff_fine": e2, "error_estimate": e2}
    p = math.log(e1 / e2) / math.log(ratio)
    est = e2 / (ratio**p - 1.0) if p > 0 else e2
    return {"order": p, "diff_coarse": e1, "diff_fine": e2, "error_estimate": est}


def spectral_peak(mu: np.ndarray, fmin: float) -> tuple[float, float]:
    """(frequency [Hz], amplitude [1]) of the largest peak of μ's mean-normalised spectrum in [fmin, 200 kHz]."""
    f, a = amplitude_spectrum(mu, SAMPLE_DT, normalise="mean")
    return peak(f, a, fmin=fmin, fmax=min(BAND_TOP, f[-1]))


def sync_curve(v: np.ndarray, fmin: float) -> np.ndarray:
    """S(f) of per-patch velocities of shape (N, n) in [fmin, 200 kHz] (NaN where Φ < 2)."""
    top = min(BAND_TOP, 0.5 / SAMPLE_DT)
    return sync_index_from_signals(np.asarray(v, np.float32), SAMPLE_DT, freq_range=(fmin, top), null_trials=0).S


def stick_stats(scene: Scene, radius: np.ndarray, t: np.ndarray, v: np.ndarray) -> dict[str, float]:
    """How much sticking a run shows: |ω r − u̇| < STICK_THRESHOLD per patch and sample."""
    s = np.abs(scene.angular_velocity * radius[None, :] - v) < STICK_THRESHOLD
    frac = s.mean(axis=1)
    first = np.flatnonzero(frac > 0)
    return {
        "threshold_m_s": STICK_THRESHOLD,
        "max_fraction": float(frac.max()),
        "mean_fraction": float(frac.mean()),
        "patches_ever_stuck": float(s.any(axis=0).mean()),
        "first_stick_s": float(t[first[0]]) if len(first) else math.nan,
    }


class Study:
    """One device's measurements of one scene."""

    def __init__(self, name: str, args: argparse.Namespace) -> None:
        self.name = name
        self.args = args
        self.scene = make_scene(name).replace(record=Record(sample_dt=SAMPLE_DT))
        self.dev = args.device
        self.n_state = round(args.t_state / SAMPLE_DT)
        self.n_long = round(args.t_long / SAMPLE_DT)
        self.fmin = max(args.fmin, 2.0 / args.t_long)
        self.rows: list[dict] = []
        self.info: dict = {"scene": name, "angular_velocity": self.scene.angular_velocity}

    def log(self, msg: str) -> None:
        print(f"[{self.name}] {msg}", flush=True)

    # ------------------------------------------------------------------------------------------- our runs
    def run(self, integrator: str, precision: str, duration: float, *, dt=None, tol=None, patches=True) -> dict:
        """One run from the initial state; returns μ, per-patch u/u̇ (if ``patches``) and timings."""
        model = build_model([self.scene], device=self.dev, precision=precision)
        state = initial_state(model)
        rec = Record(sample_dt=SAMPLE_DT, patches=("velocity", "displacement") if patches else ())
        # the study measures the error of every step, those that do not resolve sticking (strang) included
        kw = {"tolerance": tol} if integrator == "adaptive" else {"dt": dt, "force": integrator != "symplectic-euler"}
        res = run_hf(
            model, state, RunOptions(duration=duration, integrator=integrator, engine="general", **kw), record=rec
        )
        c = res.collect()
        out = {
            "complete": res.complete,
            "fault": "" if res.fault is None else str(res.fault),
            "wall_s": res.wall_time,
            "compile_s": res.compile_time,
            "steps": res.steps,
            "rejected": res.rejected,
            "dt": res.dt,
            "mu": c.globals[:, 0, 0].astype(np.float64),
            "radius": model.host("radius").astype(np.float64),
        }
        if patches:
            out["u"] = c.displacement.astype(np.float64)
            out["v"] = c.velocity.astype(np.float64)
        return out

    # ------------------------------------------------------------------------------------------- references
    def references(self) -> None:
        a = self.args
        model = build_model([self.scene], device=self.dev, precision="fp64")
        self.ode = ReferenceODE(model)
        self.u0, self.v0 = (x.astype(np.float64) for x in initial_state(model).numpy())
        times = np.arange(self.n_state + 1) * SAMPLE_DT
        self.log(f"SciPy DOP853 reference, rtol {a.ref_rtol:g}, {a.t_state:g} s")
        ref = self.ode.solve(times, method="DOP853", rtol=a.ref_rtol, u0=self.u0, v0=self.v0)
        self.ref_state = ref
        self.ref_state_mu = self.ode.globals(ref.u, ref.v)["mu"]
        self.info["scipy_reference"] = {
            "method": "DOP853",
            "rtol": a.ref_rtol,
            "atol": "rtol × per-patch scales F_N/k_T and (F_N/k_T)√(k_T/m)",
            "window_s": a.t_state,
            "wall_s": ref.wall_time,
            "nfev": ref.nfev,
        }
        # cross-check: DOP853 at 100× looser tolerance
        chk = self.ode.solve(times, method="DOP853", rtol=a.ref_rtol * 100, u0=self.u0, v0=self.v0)
        self.info["scipy_reference"]["self_check_rtol_x100"] = self.state_error(chk.u[-1], chk.v[-1])
        levels = [4 * a.ref_dt, 2 * a.ref_dt, a.ref_dt]
        runs = []
        for h in levels:
            self.log(f"fp64 strang reference at {h:.3g} s over {a.t_long:g} s")
            runs.append(self.run("strang", "fp64", a.t_long, dt=h))
        self.ref = runs[-1]
        rich_mu = richardson(*(r["mu"] for r in runs))
        rich_state = richardson(*(np.concatenate([r["u"][-1], r["v"][-1]]) for r in runs))
        rich_short = richardson(*(r["mu"][: self.n_state + 1] for r in runs))
        f_ref, a_ref = spectral_peak(self.ref["mu"], self.fmin)
        self.ref_peak = (f_ref, a_ref)
        self.ref_sync = sync_curve(self.ref["v"], self.fmin)
        stick = stick_stats(self.scene, self.ref["radius"], np.arange(self.n_long + 1) * SAMPLE_DT, self.ref["v"])
        self.info["long_reference"] = {
            "integrator": "strang",
            "precision": "fp64",
            "dt": [r["dt"] for r in runs],
            "window_s": a.t_long,
            "wall_s": [r["wall_s"] for r in runs],
            "richardson_mu": rich_mu,
            "richardson_mu_first_window": rich_short,
            "richardson_final_state": rich_state,
            "peak_hz": f_ref,
            "peak_amplitude": a_ref,
            "mu_mean": float(self.ref["mu"].mean()),
            "vs_scipy_mu_first_window": float(np.max(np.abs(self.ref["mu"][: self.n_state + 1] - self.ref_state_mu))),
            "vs_scipy_state": self.state_error(self.ref["u"][self.n_state], self.ref["v"][self.n_state]),
            "stick": stick,
        }
        self.log(
            f"Richardson order μ {rich_mu['order']:.2f} (est. error {rich_mu['error_estimate']:.2e}); "
            f"peak {f_ref:.5g} Hz; sticking max {stick['max_fraction']:.3f}, ever {stick['patches_ever_stuck']:.3f}"
        )

    def state_error(self, u: np.ndarray, v: np.ndarray) -> float:
        ru, rv = self.ref_state.u[-1], self.ref_state.v[-1]
        return float(max(np.max(np.abs(u - ru)) / np.max(np.abs(ru)), np.max(np.abs(v - rv)) / np.max(np.abs(rv))))

    def long_errors(self, mu: np.ndarray, v: np.ndarray | None) -> dict[str, float]:
        f, a = spectral_peak(mu, self.fmin)
        out = {
            "mu": float(np.max(np.abs(mu - self.ref["mu"]))),
            "peak_f": abs(f - self.ref_peak[0]) / self.ref_peak[0],
            "peak_a": abs(a - self.ref_peak[1]) / self.ref_peak[1],
        }
        if v is not None:
            s = sync_curve(v, self.fmin)
            both = np.isfinite(s) & np.isfinite(self.ref_sync)
            out["sync"] = float(np.mean(np.abs(s[both] - self.ref_sync[both]))) if both.any() else math.nan
        return out

    # ------------------------------------------------------------------------------------------- sweeps
    def ours(self) -> None:
        a = self.args
        for integ in a.integrators:
            for prec in a.precisions:
                if integ == "adaptive":
                    params = (TOL_QUICK if a.quick else TOL_FULL)[prec]
                elif integ == "symplectic-euler":
                    model = build_model([self.scene], device=self.dev, precision=prec)
                    from aca_warp.hf.solver import stable_step

                    lim = stable_step(model).explicit
                    base = a.explicit_steps or (EXPLICIT_QUICK if a.quick else EXPLICIT_FULL)
                    params = sorted({0.9 * lim, *[h for h in base if h < 0.9 * lim]}, reverse=True)
                else:
                    params = a.steps or (STEPS_QUICK if a.quick else STEPS_FULL)
                for p in params:
                    kw = {"tol": p} if integ == "adaptive" else {"dt": p}
                    row = {"kind": "aca_warp", "method": integ, "precision": prec, "device": self.dev}
                    row["tolerance" if integ == "adaptive" else "dt_requested"] = p
                    s = self.run(integ, prec, a.t_state, **kw)
                    row.update(
                        {
                            "state": {
                                "error": self.state_error(s["u"][-1], s["v"][-1]) if s["complete"] else math.nan,
                                "wall_s": s["wall_s"],
                                "steps": s["steps"],
                                "rejected": s["rejected"],
                            },
                            "dt": s["dt"],
                            "compile_s": s["compile_s"],
                        }
                    )
                    lg = self.run(integ, prec, a.t_long, **kw)
                    errs = self.long_errors(lg["mu"], lg["v"]) if lg["complete"] else {}
                    row["long"] = {
                        "wall_s": lg["wall_s"],
                        "steps": lg["steps"],
                        "rejected": lg["rejected"],
                        "complete": lg["complete"],
                        "fault": lg["fault"],
                        **errs,
                    }
                    self.rows.append(row)
                    self.log(
                        f"{integ:17s} {prec} {'tol' if integ == 'adaptive' else 'dt'} {p:.3g}: state "
                        f"{row['state']['error']:.2e} in {s['wall_s']:.3g} s; μ {errs.get('mu', math.nan):.2e}, "
                        f"peak f {errs.get('peak_f', math.nan):.1e} in {lg['wall_s']:.3g} s ({lg['steps']} steps)"
                    )

    def scipy(self) -> None:
        a = self.args
        cap = a.scipy_cap
        for method in a.scipy_methods:
            rtols = SCIPY_RTOL.get(method, SCIPY_RTOL_IMPLICIT)
            if a.quick:
                rtols = rtols[:2]
            for rtol in rtols:
                row = {"kind": "scipy", "method": f"scipy-{method}", "precision": "fp64", "rtol": rtol}
                row["device"] = "host CPU (NumPy/SciPy)"
                row["state"] = self._scipy_window(method, rtol, self.n_state, cap, long=False)
                row["long"] = self._scipy_window(method, rtol, self.n_long, cap, long=True)
                self.rows.append(row)
                self.log(
                    f"scipy {method:6s} rtol {rtol:.0e}: state {row['state']['error']:.2e} in "
                    f"{row['state']['wall_s']:.3g} s{' (extrapolated)' if row['state']['extrapolated'] else ''}; "
                    f"μ {row['long'].get('mu', math.nan):.2e} in {row['long']['wall_s']:.3g} s"
                    f"{' (extrapolated)' if row['long']['extrapolated'] else ''}"
                )

    def _scipy_window(self, method: str, rtol: float, n: int, cap: float, *, long: bool) -> dict:
        """Run on n samples if a tenth of it (timed first) extrapolates to ≤ cap seconds, else extrapolate."""
        short = max(1, n // 10)
        times = np.arange(short + 1) * SAMPLE_DT
        try:
            sol = self.ode.solve(times, method=method, rtol=rtol, u0=self.u0, v0=self.v0)
        except RuntimeError as e:
            return {"error": math.nan, "wall_s": math.nan, "extrapolated": False, "failed": str(e)}
        out: dict = {"extrapolated": True, "window_s": short * SAMPLE_DT, "nfev": sol.nfev, "njev": sol.njev}
        if sol.wall_time * n / short <= cap:
            sol = self.ode.solve(np.arange(n + 1) * SAMPLE_DT, method=method, rtol=rtol, u0=self.u0, v0=self.v0)
            out.update({"extrapolated": False, "window_s": n * SAMPLE_DT, "nfev": sol.nfev, "njev": sol.njev})
            out["wall_s"] = sol.wall_time
        else:
            out["wall_s"] = sol.wall_time * n / short
            out["measured_wall_s"] = sol.wall_time
        mu = self.ode.globals(sol.u, sol.v)["mu"]
        if long and not out["extrapolated"]:
            out.update(self.long_errors(mu, sol.v))
        elif long:  # error over the shorter window only
            out["mu"] = float(np.max(np.abs(mu - self.ref["mu"][: len(mu)])))
        else:
            ref_u, ref_v = self.ref_state.u[len(mu) - 1], self.ref_state.v[len(mu) - 1]
            err = max(
                np.max(np.abs(sol.u[-1] - ref_u)) / np.max(np.abs(ref_u)),
                np.max(np.abs(sol.v[-1] - ref_v)) / np.max(np.abs(ref_v)),
            )
            out["error"] = float(err)
        out.setdefault("error", out.get("mu", math.nan) if long else math.nan)
        return out


def measure(args: argparse.Namespace) -> Path:
    dev = wp.get_device(args.device)
    t0 = time.perf_counter()
    results = []
    for name in args.scenes:
        st = Study(name, args)
        st.references()
        if "ours" in args.parts:
            st.ours()
        if "scipy" in args.parts:
            st.scipy()
        results.append({**st.info, "rows": st.rows, "patches": st.scene.patches.count})
    import scipy

    doc = {
        "machine": machine(dev),
        "versions": {
            "warp": wp.__version__,
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "python": sys.version.split()[0],
        },
        "quick": args.quick,
        "t_state_s": args.t_state,
        "t_long_s": args.t_long,
        "sample_dt_s": SAMPLE_DT,
        "fmin_hz": args.fmin,
        "scenes": results,
        "total_wall_s": time.perf_counter() - t0,
        "command": " ".join(sys.argv),
    }
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tag = re.sub(r"[^A-Za-z0-9]+", "", args.device) + ("_quick" if args.quick else "")
    path = out / f"wp_{tag}_{'-'.join(args.scenes)}.json"
    path.write_text(json.dumps(doc, indent=1, default=float))
    print(f"wrote {path} ({doc['total_wall_s']:.0f} s)")
    return path


# ----------------------------------------------------------------------------------------------- report


def _fmt_s(x: float) -> str:
    return f"{x * 1e3:g} ms" if x >= 1e-3 else f"{x * 1e6:g} µs"


def _device_tag(doc: dict) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "", doc["machine"]["device"]) + ("_quick" if doc.get("quick") else "")


def load_results(paths: list[str]) -> list[tuple[dict, dict]]:
    """(document, scene block) pairs of several result JSONs; for a repeated (device, scene) the last file wins."""
    out: dict[tuple[str, str], tuple[dict, dict]] = {}
    for p in paths:
        doc = json.loads(Path(p).read_text())
        for sc in doc["scenes"]:
            out[(_device_tag(doc), sc["scene"])] = (doc, sc)  # a later file replaces the same device and scene
    return list(out.values())


def plot(doc: dict, sc: dict, figdir: Path) -> str:
    """One figure per (device, scene): a panel per error measure; returns the file stem."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stem = f"wp_{sc['scene']}_{_device_tag(doc)}"
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    colours = {m: f"C{i}" for i, m in enumerate([*INTEGRATORS, *(f"scipy-{s}" for s in SCIPY_METHODS)])}
    lab = {
        k: v.format(t_state=_fmt_s(doc["t_state_s"]), t_long=_fmt_s(doc["t_long_s"])) for k, v in MEASURE_LABELS.items()
    }
    for ax, meas in zip(axes.flat, MEASURES, strict=False):
        block = "state" if meas == "state" else "long"
        groups: dict[tuple[str, str], list] = {}
        for r in sc["rows"]:
            b = r[block]
            err = b.get("error") if meas == "state" else b.get(meas)
            if err is None or not np.isfinite(err) or not np.isfinite(b.get("wall_s", np.nan)):
                continue
            groups.setdefault((r["method"], r["precision"]), []).append(
                (b["wall_s"], max(err, 1e-16), b.get("extrapolated", False))
            )
        for (m, prec), pts in sorted(groups.items()):
            pts.sort()
            w, e, x = (np.array(z) for z in zip(*pts, strict=True))
            ls = "-" if prec == "fp64" else "--"
            ax.plot(
                w,
                e,
                ls,
                color=colours.get(m, "k"),
                marker="o" if m.startswith("scipy") else "s",
                ms=4,
                mfc="none" if x.any() else colours.get(m, "k"),
                label=f"{m} {prec}" if not m.startswith("scipy") else f"{m}",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("error")
        ax.set_title(lab[meas], fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    h, labels = axes.flat[0].get_legend_handles_labels()
    axes.flat[5].axis("off")
    axes.flat[5].legend(h, labels, loc="center", fontsize=8, ncol=1)
    lr = sc["long_reference"]
    v = doc["versions"]
    fig.suptitle(
        f"Work-precision, {sc['scene']} ({sc['patches']} patches, ω = {sc['angular_velocity']:.4g} rad/s) on "
        f"{doc['machine']['device_name']}\nWarp {v['warp']}, NumPy {v['numpy']}, SciPy {v['scipy']}. References: "
        f"state — SciPy DOP853 rtol {sc['scipy_reference']['rtol']:g}; μ, spectra — fp64 strang dt "
        f"{lr['dt'][-1]:.3g} s (Richardson order {lr['richardson_mu']['order']:.2f}, est. error "
        f"{lr['richardson_mu']['error_estimate']:.1e}). Solid fp64, dashed fp32; hollow: SciPy time extrapolated.",
        fontsize=9,
    )
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    figdir.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "pdf"):
        fig.savefig(figdir / f"{stem}.{ext}", dpi=110)
    plt.close(fig)
    return stem


def table(doc: dict, sc: dict) -> list[str]:
    lines = [
        "| method | precision | dt [s] / rtol, tol | state err | wall [s] | μ err | peak f err | peak A err | S err "
        "| wall [s] | steps |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in sc["rows"]:
        s, lg = r["state"], r["long"]
        par = (
            f"tol {r['tolerance']:.0e}"
            if "tolerance" in r
            else (f"rtol {r['rtol']:.0e}" if "rtol" in r else f"{r['dt']:.3g}")
        )
        xs = " (extrap.)" if s.get("extrapolated") else ""
        xl = " (extrap.)" if lg.get("extrapolated") else ""
        g = lambda d, k: f"{d[k]:.1e}" if k in d and d[k] is not None and np.isfinite(d[k]) else "–"  # noqa: E731
        steps = lg.get("steps", lg.get("nfev", ""))
        if r["kind"] == "scipy":
            steps = f"{lg.get('nfev', '')} f-evals"
        elif lg.get("rejected"):
            steps = f"{steps} (+{lg['rejected']} rej.)"
        lines.append(
            f"| {r['method']} | {r['precision']} | {par} | {g(s, 'error')} | {s['wall_s']:.3g}{xs} | {g(lg, 'mu')} "
            f"| {g(lg, 'peak_f')} | {g(lg, 'peak_a')} | {g(lg, 'sync')} | {lg['wall_s']:.3g}{xl} | {steps} |"
        )
    return lines


BEGIN, END = "<!-- BEGIN GENERATED (scripts/work_precision.py --report) -->", "<!-- END GENERATED -->"


def report(paths: list[str], page: Path, figdir: Path) -> None:
    """Figures for every (device, scene) of the result JSONs and the generated part of ``page``."""
    lines = [BEGIN, ""]
    for doc, sc in load_results(paths):
        stem = plot(doc, sc, figdir)
        lr, sr = sc["long_reference"], sc["scipy_reference"]
        rm, rs = lr["richardson_mu"], lr["richardson_final_state"]
        st = lr["stick"]
        rel = Path("figures") / figdir.name / f"{stem}.png"
        v = doc["versions"]
        lines += [
            f"### {sc['scene']} on {doc['machine']['device_name']}{' (--quick)' if doc.get('quick') else ''}",
            "",
            f"![work-precision {sc['scene']}]({rel.as_posix()})",
            "",
            f"*{sc['scene']}, {sc['patches']} patches, ω = {sc['angular_velocity']:.4g} rad/s; "
            f"{doc['machine']['device_name']}; Warp {v['warp']}, SciPy {v['scipy']}; "
            f"windows {_fmt_s(doc['t_state_s'])} "
            f"(state) and {_fmt_s(doc['t_long_s'])} (μ, spectra), samples every {_fmt_s(doc['sample_dt_s'])}. "
            f"PDF: `{(Path('figures') / figdir.name / f'{stem}.pdf').as_posix()}`.*",
            "",
            f"References: SciPy DOP853 at rtol {sr['rtol']:g} ({sr['wall_s']:.3g} s; rtol ×100 differs by "
            f"{sr['self_check_rtol_x100']:.1e}); fp64 strang at dt = {', '.join(f'{h:.3g}' for h in lr['dt'])} s: "
            f"Richardson order of μ(t) {rm['order']:.2f} (over the first {_fmt_s(doc['t_state_s'])}: "
            f"{lr['richardson_mu_first_window']['order']:.2f}), "
            f"estimated μ error of the reference {rm['error_estimate']:.1e}; "
            f"final state order {rs['order']:.2f}. "
            f"The finest strang run against DOP853 over {_fmt_s(doc['t_state_s'])}: "
            f"μ {lr['vs_scipy_mu_first_window']:.1e}, state {lr['vs_scipy_state']:.1e}. Reference spectral peak "
            f"{lr['peak_hz'] / 1e3:.2f} kHz, amplitude {lr['peak_amplitude']:.3g} (of mean μ {lr['mu_mean']:.4f}). "
            f"Sticking (|ωr − u̇| < {st['threshold_m_s']:g} m/s): at most {100 * st['max_fraction']:.2f} % of the "
            f"patches at once, {100 * st['patches_ever_stuck']:.1f} % at some time, first at "
            + (f"{st['first_stick_s'] * 1e6:.0f} µs." if np.isfinite(st["first_stick_s"]) else "never."),
            "",
            *table(doc, sc),
            "",
        ]
    lines.append(END)
    text = page.read_text() if page.exists() else f"# Work-precision\n\n{BEGIN}\n{END}\n"
    if BEGIN not in text:
        text += f"\n{BEGIN}\n{END}\n"
    head, rest = text.split(BEGIN, 1)
    tail = rest.split(END, 1)[1] if END in rest else ""
    page.write_text(head + "\n".join(lines) + tail)
    print(f"wrote {page} and figures in {figdir}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    ap.add_argument("--quick", action="store_true", help="short windows, fewer steps (CPU: a few minutes)")
    ap.add_argument("--out", default="wp_results", help="folder of the result JSON")
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES)
    ap.add_argument("--integrators", nargs="+", default=list(INTEGRATORS), choices=INTEGRATORS)
    ap.add_argument("--precisions", nargs="+", default=["fp64", "fp32"], choices=["fp64", "fp32"])
    ap.add_argument("--parts", nargs="+", default=["ours", "scipy"], choices=["ours", "scipy"])
    ap.add_argument("--scipy-methods", nargs="+", default=list(SCIPY_METHODS), choices=SCIPY_METHODS)
    ap.add_argument("--steps", nargs="+", type=float, help="fixed steps of strang/implicit-friction [s]")
    ap.add_argument("--explicit-steps", nargs="+", type=float, help="steps of symplectic-euler [s] (+0.9×limit)")
    ap.add_argument("--t-state", type=float, default=1e-4, help="window of the final-state error [s]")
    ap.add_argument("--t-long", type=float, help="window of μ(t) and the spectra [s] (1e-3; --quick 2e-4)")
    ap.add_argument("--ref-dt", type=float, help="finest step of the strang reference [s] (2.5e-9; cuda 1.25e-9)")
    ap.add_argument("--ref-rtol", type=float, default=1e-10, help="rtol of the SciPy DOP853 reference")
    ap.add_argument("--fmin", type=float, default=5e3, help="lower edge of the spectral band [Hz]")
    ap.add_argument("--scipy-cap", type=float, help="SciPy runs longer than this are extrapolated [s] (20; quick 5)")
    ap.add_argument("--report", nargs="+", metavar="JSON", help="make figures and the docs page from result JSONs")
    ap.add_argument("--page", default="docs/work_precision.md", help="docs page whose generated part is rewritten")
    ap.add_argument("--figures", default="docs/figures/work_precision", help="figure folder")
    args = ap.parse_args(argv)
    if args.report:
        report(args.report, Path(args.page), Path(args.figures))
        return 0
    args.t_long = args.t_long or (2e-4 if args.quick else 1e-3)
    args.ref_dt = args.ref_dt or (1.25e-9 if args.device.startswith("cuda") else 2.5e-9)
    args.scipy_cap = args.scipy_cap or (5.0 if args.quick else 20.0)
    print(f"default integrator {DEFAULT_INTEGRATOR}, dt {DEFAULT_DT:g} s", flush=True)
    measure(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
