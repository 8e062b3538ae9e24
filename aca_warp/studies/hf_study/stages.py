"""The stages of the study: its record before any run, the presets (simulated, analysed, plotted) and the area
sweep (simulated, analysed, fitted, drawn); ``study.json`` and ``results.md`` are rewritten after every run."""

from __future__ import annotations

import argparse
import datetime as _dt
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.hf_study.base import NOMINAL_PATCHES, PAPER, SPREAD, fit_power_law
from aca_warp.studies.hf_study.one_run import analyse, plot, simulate
from aca_warp.studies.hf_study.page import write_outputs
from aca_warp.studies.hf_study.scenes import preset_scene, scene_info, sweep_scene
from aca_warp.studies.hf_study.sweep_figure import plot_sweep
from aca_warp.studies.report import Log, clean, command_line, fmt, num


def new_study(args: argparse.Namespace, argv: list[str], device: Any) -> dict[str, Any]:
    """The study record before any run: command, machine, versions, settings, the paper's numbers."""
    from aca_warp.common.files import machine, versions

    patch_dt = args.sample_dt * args.decimation
    patch_n = int(math.floor((args.duration - args.transient) / patch_dt + 1e-9)) + 1
    return {
        "study": "hf_study",
        "complete": False,
        "command": command_line("hf_study.py", argv),
        "created": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(device),
        "versions": versions(),
        "settings": {
            "quick": args.quick,
            "duration_s": args.duration,
            "transient_s": args.transient,
            "dt_s": args.dt,
            "steps_per_run": round(args.duration / args.dt),
            "integrator": args.integrator,
            "precision": args.precision,
            "sample_dt_s": args.sample_dt,
            "decimation": args.decimation,
            "patch_sample_dt_s": patch_dt,
            "patch_record_s": args.duration - args.transient,
            "patch_samples": patch_n,
            "patch_resolution_hz": 1.0 / (patch_n * patch_dt),
            "band_hz": list(args.band),
            "rule": args.rule,
            "phi_min": args.phi_min,
            "patches": args.patches or NOMINAL_PATCHES,
            "sweep_areas_mm2": list(args.sweep_areas),
            "sweep_patches": args.patches or NOMINAL_PATCHES,
            "sweep_M": args.sweep_M,
            "sweep_speed_m_s": args.sweep_speed,
            "sweep_pressure_Pa": args.sweep_pressure,
            "sweep_spread": list(SPREAD),
            "figures": list(args.figures),
        },
        "paper": {
            **PAPER,
            "exponent_from_peaks": math.log(32.8 / 73.0) / math.log(1.25 / 0.05),
        },
        "presets": {},
        "sweep": None,
        "timings_s": {},
    }


def run_presets(study: dict[str, Any], args: argparse.Namespace, log: Log) -> bool:
    """Stage 1: simulate, analyse and plot each of --presets; True when every run completed."""
    outdir: Path = args.outdir
    all_ok = True
    for name in args.presets:
        t0 = time.perf_counter()
        scene = preset_scene(name, args)
        path = outdir / "runs" / f"{name}.h5"
        run = simulate(scene, path, args, log, name)
        all_ok &= run["complete"]
        summary, _ = analyse(path, args, log, name)
        figures, plot_s = plot(path, args, log, name)
        summary.update(
            scene=scene_info(scene),
            run=run,
            figures=figures,
            plot_s=plot_s,
            run_file=str(path.relative_to(outdir)),
            paper_first_velocity_peak_hz=PAPER["first_velocity_peak_hz"][name],
        )
        study["presets"][name] = summary
        study["timings_s"][name] = time.perf_counter() - t0
        if args.delete_runs:
            path.unlink()
        write_outputs(study, outdir, log)
    return all_ok


def _sweep_point(mean_mm2: float, scene: Any, summary: dict[str, Any], run: dict[str, Any], run_file: str) -> dict:
    """One sweep point's entry of ``study.json``."""
    return {
        "name": scene.name,
        "mean_area_nominal_mm2": mean_mm2,
        **scene_info(scene),
        "first_velocity_peak_hz": summary["first_velocity_peak_hz"],
        "first_velocity_peak_amplitude": summary["first_velocity_peak_amplitude"],
        "mu_peak_hz": summary["mu_peak_hz"],
        "mu_mean": summary["mu_mean"],
        "S_median_phi_min": summary.get("S_median_phi_min"),
        "S_bins_above_null": summary.get("S_bins_above_null"),
        "matrix_load_share": summary["matrix_load_share"],
        "patches_in_contact": summary["patches_in_contact"],
        "run": run,
        "analysis_s": summary["analysis_s"],
        "run_file": run_file,
    }


def run_sweep(study: dict[str, Any], args: argparse.Namespace, log: Log) -> bool:
    """Stage 2: simulate and analyse each of --sweep-areas, fit the exponent, draw the sweep figure; True when
    every run completed."""
    from aca_warp.scene import Material

    outdir: Path = args.outdir
    points: list[dict[str, Any]] = []
    spectra: dict[str, dict] = {}
    material = Material()
    study["sweep"] = {"points": points, "fit": {}}
    all_ok = True
    for mean_mm2 in args.sweep_areas:
        t0 = time.perf_counter()
        scene = sweep_scene(mean_mm2, args)
        material = scene.material
        path = outdir / "runs" / f"{scene.name}.h5"
        run = simulate(scene, path, args, log, scene.name)
        all_ok &= run["complete"]
        summary, spectra[scene.name] = analyse(path, args, log, scene.name)
        points.append(_sweep_point(mean_mm2, scene, summary, run, str(path.relative_to(outdir))))
        study["timings_s"][scene.name] = time.perf_counter() - t0
        if args.delete_runs:
            path.unlink()
        study["sweep"]["fit"] = fit_power_law(
            np.array([p["mean_area_m2"] for p in points]),
            np.array([num(p["first_velocity_peak_hz"]) for p in points]),
        )
        write_outputs(study, outdir, log)
    fit = study["sweep"]["fit"]
    study["sweep"]["fit_note"] = (
        "least squares of ln f against ln(mean patch area) over the sweep points; "
        "stderr from the residuals (n − 2 degrees of freedom)"
    )
    study["sweep"]["reference"] = {
        "isolated_patch_hz": "sqrt(K_T sqrt(A) / (rho_A A)) / (2 pi), exponent -1/4",
        "K_T": material.K_T,
        "rho_A": material.mass_per_area,
    }
    t0 = time.perf_counter()
    study["sweep"]["figures"] = plot_sweep(clean(study), spectra, outdir, material)
    study["timings_s"]["sweep_figure"] = time.perf_counter() - t0
    log(
        f"sweep: fitted exponent {fmt(fit.get('exponent'), '.3f')} ± {fmt(fit.get('stderr'), '.2g')} (paper −0.25); "
        "area_sweep.png/.pdf written"
    )
    return all_ok
