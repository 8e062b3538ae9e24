"""One run of the study: simulated into its run file (or a complete file reused), analysed with
``analyze_run`` and summarised (peaks, μ, contact, S(f) statistics), and drawn with ``plot_run``."""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.hf_study.base import MM2
from aca_warp.studies.hf_study.scenes import scene_info
from aca_warp.studies.report import Log, fmt, fmt_hz


def reused_run(path: Path, duration: float) -> dict[str, Any] | None:
    """The run facts of a complete run file of ``duration`` [s] at ``path``, None if there is none."""
    import h5py

    from aca_warp.analysis.report import run_attr

    try:
        with h5py.File(path, "r") as f:
            ok = bool(run_attr(f, "complete", False))
            dur = float(run_attr(f, "run_options", {}).get("duration", -1.0))
            if not (ok and math.isclose(dur, duration, rel_tol=1e-9)):
                return None
            return {
                "complete": True,
                "status": str(run_attr(f, "status", "")),
                "steps": int(run_attr(f, "steps", 0)),
                "wall_s": float(run_attr(f, "wall_time", float("nan"))),
                "compile_s": float(run_attr(f, "compile_time", float("nan"))),
                "reused": True,
            }
    except OSError:
        return None


def simulate(scene: Any, path: Path, args: argparse.Namespace, log: Log, label: str) -> dict[str, Any]:
    """Run ``scene`` into ``path`` (or reuse a complete file there with --reuse); returns run facts."""
    from aca_warp.studies.runs import run_to_file

    if args.reuse and path.is_file():
        reused = reused_run(path, args.duration)
        if reused is not None:
            log(f"{label}: reusing {path}")
            return reused
    info = scene_info(scene)
    log(
        f"{label}: simulating {args.duration:g} s ≈ {round(args.duration / args.dt):,} steps of {args.integrator} "
        f"dt={args.dt:g} s ({info['patches']} patches, mean area {info['mean_area_m2'] / MM2:.3g} mm², "
        f"F_N {info['normal_force_N']:.1f} N, M {info['M']:g}) on {args.device}, {args.precision}"
    )
    t0 = time.perf_counter()
    res = run_to_file(
        scene,
        path,
        duration=args.duration,
        device=args.device,
        integrator=args.integrator,
        dt=args.dt,
        precision=args.precision,
        overwrite=True,
        progress=args.progress,
    )
    total = time.perf_counter() - t0
    status = "complete" if res.complete else f"stopped: {res.fault}"
    rate = res.steps / max(res.wall_time, 1e-9)
    log(
        f"{label}: {status} in {total:.1f} s (stepping {res.wall_time:.1f} s, {rate:,.0f} steps/s, "
        f"compile/capture {res.compile_time:.1f} s)"
    )
    return {
        "complete": bool(res.complete),
        "status": status,
        "steps": int(res.steps),
        "wall_s": float(res.wall_time),
        "compile_s": float(res.compile_time),
        "total_s": total,
        "steps_per_s": rate,
        "reused": False,
    }


def _file_numbers(path: Path, transient: float) -> dict[str, Any]:
    """Mean μ after ``transient`` [s], patches in contact, the matrix's load share and the per-patch record."""
    import json

    import h5py

    out: dict[str, Any] = {}
    with h5py.File(path, "r") as f:
        t = f["global/time"][()]
        mu = f["global/mu"][()]
        out["mu_mean"] = float(np.mean(mu[t >= transient])) if np.any(t >= transient) else None
        out["mu_mean_whole_record"] = float(np.mean(mu))
        fn = f["patches/normal_force"][()]
        force = json.loads(f.attrs["scene"])["load"]["normal_force"]
        out["patches_in_contact"] = int(np.sum(fn > 0))
        out["matrix_load_share"] = float(max(0.0, 1.0 - fn.sum() / force)) if force > 0 else None
        if "patches/time" in f:
            pt = f["patches/time"][()]
            out["patch_record"] = {
                "start_s": float(pt[0]),
                "end_s": float(pt[-1]),
                "samples": int(pt.size),
                "resolution_hz": 1.0 / (pt.size * (pt[1] - pt[0])),
            }
    return out


def _sync_numbers(g: Any, phi_min: int, first_peak_hz: float | None) -> dict[str, Any]:
    """Statistics of S(f), S_null, Φ and R_w of the ``/analysis/sync`` group ``g`` over the bins with Φ ≥ phi_min,
    and S and Φ at the first velocity peak."""
    freq, S, phi, null = g["freq"], g["S"], g["Phi"], g["S_null"]
    defined = np.isfinite(S)
    prevalent = defined & (phi >= phi_min)
    above = defined & (S > null)
    sp = S[prevalent]
    some = bool(sp.size)
    out = {
        "S_bins": int(freq.size),
        "S_bins_defined": int(defined.sum()),
        "S_bins_phi_min": int(prevalent.sum()),
        "S_median_phi_min": float(np.median(sp)) if some else None,
        "S_max_phi_min": float(np.max(sp)) if some else None,
        "S_max_phi_min_hz": float(freq[prevalent][np.argmax(sp)]) if some else None,
        "S_bins_above_null": int(above.sum()),
        "S_bins_above_null_phi_min": int((above & prevalent).sum()),
        "S_above_null_fraction_phi_min": float(np.mean(sp > null[prevalent])) if some else None,
        "S_null_median_phi_min": float(np.median(null[prevalent])) if some else None,
        "S_excess_median_phi_min": float(np.median(sp - null[prevalent])) if some else None,
        "R_w_median_phi_min": float(np.median(g["R_w"][prevalent])) if some else None,
        "Phi_median_phi_min": float(np.median(phi[prevalent])) if some else None,
        "Phi_mean_defined": float(np.mean(phi[defined])) if defined.any() else None,
        "Phi_max": int(phi.max()) if phi.size else None,
        "S_band_hz": [float(freq[0]), float(freq[-1])] if freq.size else None,
    }
    if first_peak_hz is not None and freq.size:
        i = int(np.argmin(np.abs(freq - first_peak_hz)))
        out["S_at_first_peak"] = float(S[i])
        out["S_null_at_first_peak"] = float(null[i])
        out["Phi_at_first_peak"] = int(phi[i])
    return out


def summarize(path: Path, groups: dict[str, Any], args: argparse.Namespace) -> tuple[dict[str, Any], dict]:
    """Numbers of one analysed run; also the mean per-patch spectrum (for the sweep figure)."""
    pk = groups["peaks"].attrs
    out: dict[str, Any] = {
        "first_velocity_peak_hz": pk.get("first_velocity_peak_frequency"),
        "first_velocity_peak_amplitude": pk.get("first_velocity_peak_amplitude"),
        "first_velocity_peak_unit": pk.get("first_velocity_peak_amplitude_unit"),
        "first_velocity_peak_source": pk.get("first_velocity_peak_source"),
        "sum_velocity_peak_hz": pk.get("sum_velocity_peak_frequency"),
        "mu_peak_hz": pk.get("mu_peak_frequency"),
        "mu_peak_amplitude": pk.get("mu_peak_amplitude"),
        "mu_peak_note": "largest peak of the mean-normalised μ amplitude spectrum (whole record) in the peak band",
        "peak_band_hz": list(pk.get("band", [])),
    }
    out.update(_file_numbers(path, args.transient))
    spectrum = {}
    if "patch_spectrum" in groups:
        spectrum = {"freq": groups["patch_spectrum"]["freq"], "amp": groups["patch_spectrum"]["mean_amplitude"]}
    if "sync" in groups:
        out.update(_sync_numbers(groups["sync"], args.phi_min, out["first_velocity_peak_hz"]))
    return out, spectrum


def analyse(path: Path, args: argparse.Namespace, log: Log, label: str) -> tuple[dict[str, Any], dict]:
    """``analyze_run`` of the run file ``path`` and its :func:`summarize` numbers (with the analysis time)."""
    from aca_warp.analysis.report import analyze_run

    t0 = time.perf_counter()
    groups = analyze_run(path, freq_range=tuple(args.band), rule=args.rule)
    summary, spectrum = summarize(path, groups, args)
    summary["analysis_s"] = time.perf_counter() - t0
    log(
        f"{label}: analysed in {summary['analysis_s']:.1f} s: first velocity peak "
        f"{fmt_hz(summary['first_velocity_peak_hz'])}, μ peak {fmt_hz(summary['mu_peak_hz'])}, mean μ "
        f"{fmt(summary['mu_mean'], '.4f')}, median S (Φ≥{args.phi_min}) {fmt(summary.get('S_median_phi_min'))}, "
        f"bins S>S_null {fmt(summary.get('S_bins_above_null'))}"
    )
    return summary, spectrum


def plot(path: Path, args: argparse.Namespace, log: Log, label: str) -> tuple[list[str], float]:
    """The ``--figures`` of ``plot_run`` for the run file ``path``: file names relative to --outdir, seconds."""
    from aca_warp.plots import FIGURES, plot_run

    if not args.figures:
        return [], 0.0
    t0 = time.perf_counter()
    files = plot_run(
        path,
        args.outdir,
        which=None if set(args.figures) >= set(FIGURES) else args.figures,
        log=lambda m: log(f"{label}: {m}"),
    )
    dt = time.perf_counter() - t0
    log(f"{label}: {len(files)} figure files in {dt:.1f} s")
    return sorted(str(Path(p).relative_to(args.outdir)) for p in files), dt
