"""The paper's multi-timescale study (§3.3, Figs. 12-13): LF over the load procedure, HF on its saved states.

Stages (each printed with the elapsed time):

1. **LF** over the scene's schedule (default the preset ``multiscale``: 10 s applications at 10/30/5/15 bar,
   5 s pauses, 10 m/s, M = 0.8) into ``<outdir>/lf.h5`` with snapshots at the start and end of each application.
2. **HF** (``aca_warp.hf.runner.run_scene``) on each snapshot, areas frozen, recording per-patch velocities;
   ``analyze_run`` gives the μ spectrum and the Synchronization Index S(f).
3. **Figures**: ``fig13_panel.png`` (per state: patch map, μ spectrum, S(f); paper Fig. 13),
   ``lf_timeseries.png`` (μ, torque, friction radius, patch count, coverage, temperatures) and, with ``--tei``,
   ``tei.png`` (Coulomb friction everywhere: ring temperatures over time and the effective friction radius).
4. **Summaries**: ``study.json`` and, with ``--docs FILE`` (``--figures DIR``: figures copied there and shown), the
   calibration page (patch lifetimes, areas, counts, coverage per state, the carry-over of coverage from the
   high-load to the low-load application) and, after the HF stage, a table of the HF states (μ, peaks, S(f)).

Examples::

    python3 scripts/multiscale_study.py --quick                          # CPU, shortened schedule, minutes
    python3 scripts/multiscale_study.py --device cuda:0 --tei --docs docs/results_multiscale.md \
        --figures docs/figures/multiscale

As a library: :func:`main` takes the command line as a list; :func:`calibration` (an LF run file),
:func:`hf_summary` (an HF run file), :func:`lf_figure` and :func:`fig13` work on files of earlier runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.common.argtypes import positive
from aca_warp.common.errors import AcaError
from aca_warp.common.errors import command_line as command_line_flags
from aca_warp.studies.report import Log, add_device, command_line, figure, fmt, md_table, save_figure, write_json

MM2 = 1.0e-6
HF_DT = 1.0e-8  # s: the HF runs' strang step (docs/results_multiscale_hf.md); the dense states need it


def build_parser() -> argparse.ArgumentParser:
    """The command line of the study."""
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--scene", default="multiscale", help="LF preset or TOML file (default multiscale)")
    p.add_argument("--outdir", default="multiscale_study", help="output folder (default multiscale_study)")
    add_device(p, help="Warp device for LF and HF (default cpu)")
    p.add_argument("--quick", action="store_true", help="CPU-sized: 2 s applications, 1 s pauses, short HF records")
    p.add_argument("--hf-duration", type=positive, help="HF simulated time per state [s] (default 2e-3; quick 1e-4)")
    p.add_argument("--hf-sample-dt", type=positive, default=1.0e-7, help="HF sample interval [s] (default 1e-7)")
    p.add_argument("--skip-hf", action="store_true", help="LF, figures of LF and calibration only")
    p.add_argument("--runs-dir", help="folder of the HF run files (default: the output folder; they are large)")
    p.add_argument("--tei", action="store_true", help="also run the Coulomb-friction TEI check (tei.png)")
    p.add_argument("--tei-duration", type=positive, default=20.0, help="TEI application length [s] (quick: 5)")
    p.add_argument("--docs", help="write the calibration page (markdown) to this file")
    p.add_argument("--figures", help="with --docs: copy the figures into this folder and show them on the page")
    p.add_argument("--overwrite", action="store_true", help="replace existing run files")
    p.add_argument("--reuse-lf", action="store_true", help="use <outdir>/lf.h5 from an earlier run (skip the LF stage)")
    return p


def check_arguments(args: argparse.Namespace) -> None:
    """Refuse what would fail later, before anything is written (AcaError): an absent device, an unknown scene, an
    output folder or page that cannot be written, an LF run file there already (without --overwrite or
    --reuse-lf)."""
    from aca_warp.common.devices import get_device
    from aca_warp.common.files import check_output_folder, check_output_path
    from aca_warp.lf.scene import load_lf_scene

    get_device(args.device)
    load_lf_scene(args.scene)
    for folder in (args.outdir, args.runs_dir, args.figures):
        if folder:
            check_output_folder(folder)
    lf_path = Path(args.outdir) / "lf.h5"
    if not (args.reuse_lf and lf_path.is_file()) and Path(args.outdir).is_dir():
        check_output_path(lf_path, overwrite=args.overwrite)
    if args.docs:
        check_output_path(args.docs, overwrite=True)


# ------------------------------------------------------------------------------------------------ stages


def quick_overrides(scene: Any) -> Any:
    """The same load levels with 2 s applications (0.2 s ramp) and 1 s pauses."""
    from aca_warp.lf.scene import Segment

    segs = tuple(
        Segment(s.kind, 2.0 if s.kind == "application" else 1.0, s.normal_force, s.sliding_speed, min(s.ramp, 0.2))
        for s in scene.schedule
    )
    return scene.replace(schedule=segs)


def run_lf_stage(args: argparse.Namespace, log: Log) -> Path:
    """Stage 1: the LF automaton over the schedule into ``<outdir>/lf.h5``."""
    from aca_warp.lf.commands import run_lf
    from aca_warp.lf.scene import load_lf_scene

    scene = load_lf_scene(args.scene)
    if args.quick:
        scene = quick_overrides(scene)
    out = Path(args.outdir) / "lf.h5"
    sim = run_lf(scene, out, device=args.device, overwrite=args.overwrite, progress=False)
    log(f"LF: {sim.step_index} steps in {sim.wall_time:.1f} s ({sim.step_index / sim.wall_time:.0f} steps/s) -> {out}")
    return out


def hf_duration(args: argparse.Namespace) -> float:
    """HF simulated time per state [s]: ``--hf-duration``, else 1e-4 (quick) or 2e-3."""
    return args.hf_duration or (1.0e-4 if args.quick else 2.0e-3)


def run_hf_stage(lf_path: Path, args: argparse.Namespace, log: Log) -> dict[str, Path]:
    """Stage 2: HF on every application snapshot of ``lf_path``, analysed; returns the run files by state."""
    from aca_warp.analysis.report import analyze_run
    from aca_warp.lf.io import scene_from_snapshot, snapshot_names
    from aca_warp.scene import Record
    from aca_warp.studies.runs import run_to_file

    duration = hf_duration(args)
    transient = duration / 4
    out: dict[str, Path] = {}
    for name in snapshot_names(lf_path):
        if not name.startswith("app"):
            continue
        scene = scene_from_snapshot(lf_path, name, duration=duration)
        scene = scene.replace(
            record=Record(sample_dt=args.hf_sample_dt, patches=("velocity",), window=(transient, duration)),
            matrix=scene.matrix,
            origin=None,
        )
        path = Path(args.runs_dir or args.outdir) / f"hf_{name}.h5"
        path.parent.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        run_to_file(scene, path, device=args.device, overwrite=args.overwrite, dt=HF_DT)
        analyze_run(path, freq_range=(1.0e3, None))
        log(
            f"HF {name}: {scene.patches.count} patches, F_N {scene.normal_force:.0f} N, "
            f"{time.perf_counter() - t0:.1f} s"
        )
        out[name] = path
    return out


def hf_summary(path: Path) -> dict[str, Any]:
    """One HF state's numbers for the docs table: μ after the transient (mean, standard deviation), the largest
    peaks of |μ(f)| / mean μ and of the mean patch-velocity spectrum (``/analysis/peaks``: above 1 kHz and 3 bins,
    up to 200 kHz), and the Synchronization Index (largest S, share of frequencies with S above its null level)."""
    import h5py

    with h5py.File(path, "r") as f:
        t, mu = f["global/time"][()], f["global/mu"][()]
        keep = t >= t[-1] / 4
        pk = f["analysis/peaks"].attrs
        out = {
            "patches": int(f["patches/x"].shape[0]),
            "normal_force_N": float(json.loads(f.attrs["scene"])["load"]["normal_force"]),
            "mu_mean": float(mu[keep].mean()),
            "mu_std": float(mu[keep].std()),
            "mu_peak_hz": float(pk["mu_peak_frequency"]),
            "mu_peak_amplitude": float(pk["mu_peak_amplitude"]),
            "velocity_peak_hz": float(pk["first_velocity_peak_frequency"]),
            "peak_band_hz": [float(x) for x in pk["band"]],
        }
        if "analysis/sync" in f:
            sy = f["analysis/sync"]
            S, S0 = sy["S"][()], sy["S_null"][()]
            ok = np.isfinite(S)
            out["S_max"] = float(S[ok].max()) if ok.any() else None
            out["S_above_null_share"] = float(np.mean(S[ok] > S0[ok])) if ok.any() else None
    return out


# ------------------------------------------------------------------------------------------------ figures


def _fig13_row(axes: Any, name: str, path: Path) -> None:
    """One state of the Fig. 13 panel: patch map coloured by the direction of u̇, μ spectrum, S(f)."""
    import h5py

    with h5py.File(path, "r") as f:
        x, y, a = f["patches/x"][()], f["patches/y"][()], f["patches/area"][()]
        v = f["patches/velocity"][-1] if "patches/velocity" in f else np.zeros_like(x)
        sp = f["analysis/spectra"]
        freq, amp = sp["freq"][()], sp["mu"][()]
        sync = f["analysis/sync"] if "analysis/sync" in f else None
        fs, S = (sync["freq"][()], sync["S"][()]) if sync is not None else (None, None)
        fn = float(json.loads(f.attrs["scene"])["load"]["normal_force"])
    ax = axes[0]
    ax.scatter(x * 1e3, y * 1e3, s=np.maximum(a / MM2 * 4, 0.2), c=np.where(v > 0, "tab:red", "tab:blue"), lw=0)
    ax.set_aspect("equal")
    ax.set_title(f"{name}: {len(x)} patches, {a.sum() / MM2:.0f} mm², F_N {fn / 1e3:.2f} kN", fontsize=8)
    ax.set_xlabel("x [mm]", fontsize=7)
    ax.set_ylabel("y [mm]", fontsize=7)
    keep = (freq >= 1.0e3) & (freq <= 200.0e3)
    axes[1].semilogy(freq[keep] / 1e3, amp[keep], lw=0.6)
    axes[1].set_xlabel("f [kHz]", fontsize=7)
    axes[1].set_ylabel("|μ(f)| / mean μ", fontsize=7)
    if S is not None:
        axes[2].plot(fs / 1e3, S, lw=0.6)
    axes[2].set_ylim(0, 1)
    axes[2].set_xlabel("f [kHz]", fontsize=7)
    axes[2].set_ylabel("S(f)", fontsize=7)


def fig13(hf: dict[str, Path], outdir: Path) -> Path:
    """``fig13_panel.png``: a row per HF state (paper Fig. 13)."""
    fig = figure(figsize=(12, 2.6 * len(hf)))
    axes = fig.subplots(len(hf), 3, squeeze=False)
    for row, (name, path) in enumerate(hf.items()):
        _fig13_row(axes[row], name, path)
    fig.suptitle("Multi-timescale study (paper Fig. 13): HF on LF states; red = moving with the disc, blue = against")
    fig.tight_layout()
    return save_figure(fig, outdir, "fig13_panel", formats=("png",))[0]


def lf_figure(lf_path: Path, outdir: Path, stem: str = "lf_timeseries") -> Path:
    """``<stem>.png``: μ, torque, friction radius, patch count, coverage and temperatures of an LF run."""
    import h5py

    with h5py.File(lf_path, "r") as f:
        g = {k: f["global"][k][()] for k in f["global"]}
    t = g["time"]
    rows = [
        ("mu", "μ (0 in pauses)", 1),
        ("torque", "torque [N m]", 1),
        ("friction_radius", "r_eff [mm]", 1e3),
        ("patch_count", "patches", 1),
        ("coverage", "coverage [%]", 100),
        ("disc_temperature_max", "T [°C]: disc max / mean, patches", 1),
    ]
    fig = figure(figsize=(9, 11))
    axes = fig.subplots(len(rows), 1, sharex=True)
    for ax, (k, label, scale) in zip(axes, rows, strict=True):
        if k == "disc_temperature_max":
            for kk, lab in (
                ("disc_temperature_max", "disc max"),
                ("disc_temperature_mean", "disc mean"),
                ("patch_temperature", "patches (area mean)"),
            ):
                y = g[kk] - 273.15
                if kk == "patch_temperature":
                    y = np.where(g["patch_count"] > 0, y, np.nan)
                ax.plot(t, y, lw=0.7, label=lab)
            ax.legend(fontsize=7)
        else:
            y = g[k] * scale
            if k == "friction_radius":
                y = np.where(g["normal_force"] > 0, y, np.nan)
            ax.plot(t, y, lw=0.7)
        ax.set_ylabel(label, fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"LF time series ({lf_path.name})")
    fig.tight_layout()
    return save_figure(fig, outdir, stem, formats=("png",))[0]


# ------------------------------------------------------------------------------------------------ TEI check


def _tei_run(args: argparse.Namespace, log: Log) -> tuple[Any, np.ndarray, np.ndarray, float]:
    """One application at 15 bar with Coulomb friction everywhere; returns the LF simulation, the sample times [s],
    the ring temperatures [K] of shape (samples, rings) and the application length [s]."""
    from aca_warp.lf.scene import Segment, load_lf_scene
    from aca_warp.lf.solver import LFSimulation

    base = load_lf_scene(args.scene)
    dur = 5.0 if args.quick else args.tei_duration
    lf = dataclasses.replace(base.lf, coulomb=1)
    scene = base.replace(lf=lf, schedule=(Segment("application", dur, 15 * lf.newton_per_bar, 10.0, 0.2),))
    sim = LFSimulation(scene, device=args.device)
    every = 10
    temps, times = [], []
    t0 = time.perf_counter()
    while sim.step_index < sim.table.steps:
        sim.run(every)
        temps.append(sim.ring_T.numpy().copy())
        times.append(sim.step_index * lf.dt)
    log(f"TEI: {sim.step_index} steps in {time.perf_counter() - t0:.1f} s")
    return sim, np.array(times), np.array(temps), dur


def tei_check(args: argparse.Namespace, log: Log) -> dict[str, Any]:
    """Coulomb friction everywhere (patches μ = lf.mu_coulomb, matrix μ_pad), one long application: ring map."""
    sim, times, temps, dur = _tei_run(args, log)
    h = sim.history()
    T = temps - 273.15
    r = sim.ring_r.numpy() * 1e3
    fig = figure(figsize=(8, 7))
    a1, a2 = fig.subplots(2, 1, sharex=True)
    im = a1.pcolormesh(times, r, (T - T.mean(axis=1, keepdims=True)).T, shading="nearest", cmap="inferno")
    fig.colorbar(im, ax=a1, label="T − ring mean [K]")
    a1.set_ylabel("disc radius [mm]")
    a1.set_title("Coulomb friction everywhere: disc ring temperature (hot bands) and effective friction radius")
    a2.plot(h["time"], h["friction_radius"] * 1e3, lw=0.8)
    a2.set_ylabel("r_eff [mm]")
    a2.set_xlabel("time [s]")
    fig.tight_layout()
    path = save_figure(fig, Path(args.outdir), "tei", formats=("png",))[0]
    loaded = h["normal_force"] > 0
    excess = T.max(axis=1) - T.mean(axis=1)
    return {
        "figure": path.name,
        "duration_s": dur,
        "r_eff_mm_range": [
            float(h["friction_radius"][loaded].min() * 1e3),
            float(h["friction_radius"][loaded].max() * 1e3),
        ],
        "hot_band_excess_K_final": float(excess[-1]),
        "hot_band_radius_mm_final": float(r[np.argmax(T[-1])]),
        "hot_band_radius_mm_path": [float(r[np.argmax(x)]) for x in T[:: max(len(T) // 10, 1)]],
    }


# ------------------------------------------------------------------------------------------------ calibration


def _pad_area(pad: dict) -> float:
    """Nominal area of the annular-sector pad of a scene's ``pad`` table [m²]."""
    return math.radians(pad["span_deg"]) / 2 * (pad["r_outer"] ** 2 - pad["r_inner"] ** 2)


def _states(f: Any) -> dict[str, dict[str, Any]]:
    """Time, load, patch count, coverage (of the pad area), load share and area percentiles of every snapshot of
    the open LF file ``f``, in time order."""
    states = {}
    pad_area = _pad_area(json.loads(f.attrs["scene"])["pad"])
    for name in sorted(f["snapshots"], key=lambda n: float(f["snapshots"][n].attrs["time"])):
        s = f["snapshots"][name]
        a = s["patches/area"][()]
        fn = s["patches/normal_force"][()]
        states[name] = {
            "time_s": float(s.attrs["time"]),
            "normal_force_N": float(s.attrs["normal_force"]),
            "patches": int(len(a)),
            "coverage": float(a.sum()) / pad_area,
            "area_mm2_percentiles_10_50_90_max": [float(x) for x in np.percentile(a / MM2, [10, 50, 90, 100])]
            if len(a)
            else [],
            "patch_load_share": float(fn.sum() / max(float(s.attrs["normal_force"]), 1e-300)),
        }
    return states


def _carry_over(st: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    """Coverage of the high-load application 2 carried into the low-load application 3 (None without them)."""
    if not all(k in st for k in ("app1_end", "app2_end", "app3_start", "app3_end")):
        return None
    c1, c2, c3s, c3e = (st[k]["coverage"] for k in ("app1_end", "app2_end", "app3_start", "app3_end"))
    return {
        "app1_end_coverage": c1,
        "app2_end_coverage": c2,
        "app3_start_coverage": c3s,
        "app3_end_coverage": c3e,
        "kept_over_pause": c3s / c2 if c2 > 0 else None,
        "app3_start_over_app1_end": c3s / c1 if c1 > 0 else None,
        # the low-load application starts with (at least 90 % of) the coverage built under high load, more
        # than the first application (no such history) ever reached
        "carries_high_load_coverage": bool(c3s >= 0.9 * c2 and c3s > c1),
    }


def calibration(lf_path: Path) -> dict[str, Any]:
    """The LF run's calibration numbers: states, patch lifetimes, μ while loaded, counts, coverage, temperature,
    the carry-over of coverage."""
    import h5py

    out: dict[str, Any] = {}
    with h5py.File(lf_path, "r") as f:
        age = f["calibration/death_age"][()]
        darea = f["calibration/death_area"][()]
        g = {k: f["global"][k][()] for k in f["global"]}
        out["machine"] = f.attrs.get("device_name", "")
        out["steps_per_second"] = float(f.attrs.get("steps_per_second", np.nan))
        out["states"] = _states(f)
    out["lifetimes_s"] = {
        "deaths": int(len(age)),
        "percentiles_10_50_90": [float(x) for x in np.percentile(age, [10, 50, 90])] if len(age) else [],
        "mean": float(age.mean()) if len(age) else None,
        "area_at_death_mm2_median": float(np.median(darea) / MM2) if len(darea) else None,
    }
    loaded = g["normal_force"] > 0
    out["mu_loaded"] = {
        "mean": float(g["mu"][loaded].mean()),
        "min": float(g["mu"][loaded].min()),
        "max": float(g["mu"][loaded].max()),
    }
    out["patch_count"] = {"min": int(g["patch_count"].min()), "max": int(g["patch_count"].max())}
    out["coverage_max"] = float(g["coverage"].max())
    out["disc_temperature_max_K"] = float(g["disc_temperature_max"].max())
    out["pause_mu_all_zero"] = bool(np.all(g["mu"][~loaded] == 0))
    carry = _carry_over(out["states"])
    if carry is not None:
        out["carry_over"] = carry
    return out


# ------------------------------------------------------------------------------------------------ docs page


def _states_section(study: dict[str, Any]) -> list[str]:
    """One table row per snapshot."""
    rows = [
        [
            name,
            f"{s['time_s']:.2f}",
            f"{s['normal_force_N']:.0f}",
            s["patches"],
            f"{s['coverage']:.4f}",
            f"{s['patch_load_share']:.3f}",
            " / ".join(f"{x:.3g}" for x in s["area_mm2_percentiles_10_50_90_max"]),
        ]
        for name, s in study["calibration"]["states"].items()
    ]
    header = ["state", "t [s]", "F_N [N]", "patches", "coverage", "patch load share"]
    header.append("area p10 / p50 / p90 / max [mm²]")
    return ["## States (snapshots)", "", *md_table(header, rows)]


def _life_section(study: dict[str, Any]) -> list[str]:
    """Patch deaths and lifetimes, counts, coverage, μ, the hottest ring, the LF speed."""
    c = study["calibration"]
    lt = c["lifetimes_s"]
    deaths = f"* Deaths (not merges) over the run: {lt['deaths']}"
    if lt["deaths"]:
        deaths += (
            "; lifetime p10 / p50 / p90 = "
            + " / ".join(f"{x:.3g}" for x in lt["percentiles_10_50_90"])
            + f" s, mean {lt['mean']:.3g} s; median area at death {lt['area_at_death_mm2_median']:.3g} mm²."
        )
    else:
        deaths += "."
    return [
        "## Patch life",
        "",
        deaths,
        f"* Patch count range {c['patch_count']['min']}–{c['patch_count']['max']}; "
        f"peak coverage {c['coverage_max']:.4f}.",
        f"* μ while loaded: mean {c['mu_loaded']['mean']:.3f} "
        f"(range {c['mu_loaded']['min']:.3f}–{c['mu_loaded']['max']:.3f});"
        f" μ = 0 in every pause step: {c['pause_mu_all_zero']}.",
        f"* Hottest disc ring: {c['disc_temperature_max_K'] - 273.15:.0f} °C.",
        f"* LF speed: {c['steps_per_second']:.0f} steps/s on this machine (device {study['device']}).",
    ]


def _carry_over_section(study: dict[str, Any]) -> list[str]:
    """The coverage carried from the high-load into the low-load application (nothing without those states)."""
    co = study["calibration"].get("carry_over")
    if not co:
        return []
    return [
        "",
        "## Carry-over of the high-load coverage",
        "",
        f"Coverage at the end of the high-load application 2: {co['app2_end_coverage']:.4f}; at the start of the "
        f"low-load application 3: {co['app3_start_coverage']:.4f} ({co['kept_over_pause']:.3f} of it kept over the "
        f"pause); at its end: {co['app3_end_coverage']:.4f}. Application 1 (low load, no high-load history) ended "
        f"at {co['app1_end_coverage']:.4f}, so application 3 starts with "
        f"{co['app3_start_over_app1_end']:.2f}× that.",
        "The low-load application starts with the high-load coverage (≥ 90 % of app2_end and more than app1_end): "
        f"**{co['carries_high_load_coverage']}**. Its patches then carry the low load at a low mean pressure, the "
        "state in which the paper finds the largest μ oscillation amplitudes (§3.3).",
    ]


def _tei_section(study: dict[str, Any]) -> list[str]:
    """The TEI check's friction radius and hot band (nothing without --tei)."""
    if "tei" not in study:
        return []
    t = study["tei"]
    return [
        "",
        "## TEI check (Coulomb friction everywhere)",
        "",
        f"One {t['duration_s']:g} s application at 15 bar with constant patch μ: the effective friction radius "
        f"moves over {t['r_eff_mm_range'][0]:.1f}–{t['r_eff_mm_range'][1]:.1f} mm; the hottest ring ends "
        f"{t['hot_band_excess_K_final']:.0f} K above the ring mean at r = {t['hot_band_radius_mm_final']:.1f} mm "
        f"(hot-band radius over time: {', '.join(f'{x:.1f}' for x in t['hot_band_radius_mm_path'])} mm). "
        f"Figure: `{t['figure']}` in the study folder.",
    ]


def _hf_section(study: dict[str, Any]) -> list[str]:
    """The table of the HF states, or where to find it when the HF stage did not run."""
    lines: list[str] = []
    if study.get("hf_summary"):
        rows = [
            [
                name,
                h["patches"],
                f"{h['normal_force_N'] / 1e3:.2f}",
                f"{h['mu_mean']:.4f}",
                f"{h['mu_std']:.2e}",
                f"{h['mu_peak_amplitude']:.2e}",
                f"{h['mu_peak_hz'] / 1e3:.1f}",
                f"{h['velocity_peak_hz'] / 1e3:.1f}",
                fmt(h.get("S_max"), ".2f"),
                fmt(h.get("S_above_null_share"), ".2f"),
            ]
            for name, h in study["hf_summary"].items()
        ]
        header = ["state", "patches", "F_N [kN]", "mean μ", "std μ", "μ peak: |μ(f)|/μ̄", "at [kHz]"]
        header += ["patch-velocity peak [kHz]", "max S(f)", "share of f with S > S_null"]
        lines += [
            "",
            "## HF on the states (paper Fig. 13)",
            "",
            f"Each state run for {study['hf_duration_s']:g} s of HF (areas frozen, the first quarter dropped as "
            "transient, μ and every patch velocity sampled every "
            f"{study['hf_sample_dt_s']:g} s); spectra and S(f) from `aca_warp.analysis.report.analyze_run`.",
            "",
            *md_table(header, rows),
        ]
    if not study.get("hf"):
        lines += [
            "",
            "The HF half (Fig. 13 panel: patch map, μ spectrum and S(f) on each state) was not run for this page; "
            "[results_multiscale_hf.md](results_multiscale_hf.md) has it from a GPU run of the whole study "
            "(`python3 scripts/multiscale_study.py --device cuda:0 --outdir DIR`).",
        ]
    return lines


def _figures_section(study: dict[str, Any], path: Path, figures: Path | None) -> list[str]:
    """The study's figures: named (``figures`` None) or copied into ``figures`` and shown relative to ``path``."""
    import os
    import shutil

    figs = ["lf_timeseries.png"] + (["fig13_panel.png"] if study.get("hf") else [])
    figs += ["tei.png"] if "tei" in study else []
    if figures is None:
        return ["", "Figures (in the study folder): " + ", ".join(f"`{x}`" for x in figs) + "."]
    figures.mkdir(parents=True, exist_ok=True)
    lines = ["", "## Figures", ""]
    for x in figs:
        shutil.copyfile(Path(study["outdir"]) / x, figures / x)
        rel = Path(os.path.relpath(figures / x, path.parent)).as_posix()
        lines += [f"![{x}]({rel})", ""]
    return lines


VERDICTS = (
    "**For verdicts see [validation.md](validation.md)** (the §3.3 and §4 rows: LF seed ensembles, every state run "
    "to saturation), summarised with what the cause experiments show on "
    "[results_multiscale_hf.md](results_multiscale_hf.md). This page is the calibration record of one LF run and, "
    "where the HF stage ran, of short HF runs from rest on its states (one realisation), which stop in the linear "
    "growth of the slowly growing ones: its HF table is not the saturated state that the verdicts judge."
)


def write_docs(study: dict[str, Any], path: Path, argv: list[str], figures: Path | None = None) -> None:
    """The calibration page; with ``figures`` (a folder), the study's figures are copied there and shown."""
    c = study["calibration"]
    lines = [
        "# Multi-timescale study: LF calibration results",
        "",
        f"Generated by `{command_line('multiscale_study.py', argv)}` on {c['machine']}"
        f" ({study['date']}). Numbers are measured, not tuned by hand afterwards; the constants are the defaults",
        "of `aca_warp/lf/scene.py` (docs/lf_model.md). "
        + ("**Quick mode**: 2 s applications, 1 s pauses." if study["quick"] else "Full schedule of the preset."),
        "",
        VERDICTS,
        "",
        *_states_section(study),
        "",
        *_life_section(study),
        *_carry_over_section(study),
        *_tei_section(study),
        *_hf_section(study),
        *_figures_section(study, path, figures),
    ]
    path.write_text("\n".join(lines) + "\n")


# ------------------------------------------------------------------------------------------------ main


def main(argv: list[str] | None = None) -> int:
    """Run the study; returns 0."""
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        with command_line_flags():  # messages name --overwrite, not overwrite=True
            check_arguments(args)
    except AcaError as e:
        print(f"{ap.prog}: error: {e}", file=sys.stderr)
        return e.exit_code
    log = Log()
    outdir = Path(args.outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    lf_path = outdir / "lf.h5"
    if not (args.reuse_lf and lf_path.is_file()):
        lf_path = run_lf_stage(args, log)
    study: dict[str, Any] = {"device": args.device, "quick": args.quick, "date": datetime.date.today().isoformat()}
    study["outdir"] = str(outdir)
    study["hf_duration_s"] = hf_duration(args)
    study["hf_sample_dt_s"] = args.hf_sample_dt
    study["lf_figure"] = lf_figure(lf_path, outdir).name
    study["calibration"] = calibration(lf_path)
    if not args.skip_hf:
        hf = run_hf_stage(lf_path, args, log)
        study["hf"] = {k: v.name for k, v in hf.items()}
        study["hf_summary"] = {k: hf_summary(v) for k, v in hf.items()}
        study["fig13"] = fig13(hf, outdir).name
    if args.tei:
        study["tei"] = tei_check(args, log)
    write_json(outdir / "study.json", study)
    if args.docs:
        write_docs(study, Path(args.docs), argv, Path(args.figures) if args.figures else None)
    log(f"done: {outdir}/study.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
