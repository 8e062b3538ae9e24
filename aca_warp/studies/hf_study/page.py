"""The paper's stand-alone HF study (§3.1, Figs. 8-9) and a patch-area sweep, with summaries beside the paper's.

Stages, each printed with the elapsed time:

1. **Presets** ``hf1``-``hf4`` (paper Table 1): each is simulated (default ``strang``, dt = 1e-8 s, fp64),
   recording the global outputs every ``--sample-dt`` and the per-patch velocities after ``--transient``;
   then ``analyze_run`` (spectra, Synchronization Index in ``--band``, peaks) and ``plot_run`` (figures
   ``<outdir>/<preset>_<figure>.png/.pdf/.gif``).
2. **Area sweep** (``--sweep-areas``, mean patch areas in mm², each a uniform range [0.4, 1.6] x mean;
   M, speed and the mean patch pressure fixed): the first velocity-spectrum peak of each point, a fit of the
   exponent b in f = c A^b (paper: -1/4) and the isolated-patch frequency sqrt(K_T sqrt(A) / (rho_A A)) / 2 pi
   as reference (``area_sweep.png/.pdf``).
3. **Summaries**: ``study.json`` (all numbers), ``results.md`` (our numbers beside the paper's, each claim as a
   measured yes/no, relative links to the figures). Both are rewritten after every run, so an interrupted
   study leaves what it had.

Run files go to ``<outdir>/runs/``. Examples::

    python3 scripts/hf_study.py --device cuda:0                       # full study (GPU, a few minutes)
    python3 scripts/hf_study.py --quick                               # short version on the CPU
    python3 scripts/hf_study.py --quick --presets hf1 --skip-sweep    # one preset only
    python3 scripts/hf_study.py --device cuda:0 --archive /tmp/hf_study.tar.gz   # plus one archive of the results

As a library: :func:`main` takes the command line as a list; :func:`fit_power_law`, :func:`isolated_frequency`,
:func:`preset_scene` / :func:`sweep_scene` (the scenes), :func:`analyse` (one run file's numbers) and
:func:`comparisons` (the paper's claims against a ``study.json``) work on their own.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import math
import sys
import tarfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.report import Log, clean, command_line, fmt, fmt_hz, md_table, num, write_json

PRESET_NAMES = ("hf1", "hf2", "hf3", "hf4")
NOMINAL_PATCHES = 1758
HF1_FORCE = 487.2  # N
HF1_MEAN_AREA = 5.0e-8  # m²
DEFAULT_PRESSURE = HF1_FORCE / (NOMINAL_PATCHES * HF1_MEAN_AREA)  # ≈ 5.54 MPa mean patch pressure of hf1
SPREAD = (0.4, 1.6)  # patch areas uniform in [0.4, 1.6] x mean (the paper's 0.02-0.08 and 0.5-2.0 mm²)
MM2 = 1.0e-6  # m² per mm²

FULL_DURATION, QUICK_DURATION = 4.0e-3, 2.0e-4  # s
FULL_TRANSIENT, QUICK_TRANSIENT = 2.0e-4, 5.0e-5  # s

PAPER = {
    "first_velocity_peak_hz": {"hf1": 73.0e3, "hf2": 32.8e3, "hf3": 73.0e3, "hf4": 32.8e3},
    "exponent": -0.25,
    "mean_area_m2": {"hf1": 5.0e-8, "hf2": 1.25e-6, "hf3": 5.0e-8, "hf4": 1.25e-6},
    "source": "Merlis & Ostermeyer 2019, §3.1, Figs. 8-9",
}
PEAK_TOLERANCE = 0.05  # relative, for "agrees with the paper's peak" (or two frequency bins, if larger)
EXPONENT_TOLERANCE = 0.025  # absolute (10 % of 1/4), for "agrees with -1/4" (or two standard errors, if larger)


# ------------------------------------------------------------------------------------------------ options


class _Help(argparse.ArgumentDefaultsHelpFormatter):
    """Shows defaults, except None (those helps say what None means)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        return action.help if action.default is None else super()._get_help_string(action)


def build_parser() -> argparse.ArgumentParser:
    """The command line of the study."""
    p = argparse.ArgumentParser(
        prog="hf_study.py",
        description=__doc__.split("\n\n")[0] + " Writes run files, figures, study.json and results.md into --outdir.",
        epilog="Full study on an H100: about 9 runs of 2e5 steps each plus analysis and figures (a few minutes). "
        "--quick on a 2-core CPU: a few minutes. See the module docstring for the stages.",
        formatter_class=_Help,
    )
    p.add_argument("--outdir", type=Path, default=Path("out/hf_study"), help="output folder (created)")
    p.add_argument("--device", default="auto", help="Warp device: cpu, cuda:0, or auto (cuda:0 when present)")
    p.add_argument("--precision", choices=("fp64", "fp32"), default="fp64", help="floating-point precision")
    p.add_argument("--integrator", default="strang", help="HF integrator (see aca-warp hf --help)")
    p.add_argument("--dt", type=float, default=1.0e-8, help="time step [s]")
    p.add_argument(
        "--quick",
        action="store_true",
        help=f"short CPU version: --duration {QUICK_DURATION:g}, --transient {QUICK_TRANSIENT:g} unless given",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help=f"simulated time per run [s] (default {FULL_DURATION:g}; {QUICK_DURATION:g} with --quick)",
    )
    p.add_argument(
        "--transient",
        type=float,
        default=None,
        help="start of the per-patch velocity record [s]; earlier samples are left out of the per-patch "
        f"spectra and S(f) (default {FULL_TRANSIENT:g}; {QUICK_TRANSIENT:g} with --quick)",
    )
    p.add_argument("--sample-dt", type=float, default=2.0e-7, help="sampling interval of the global outputs [s]")
    p.add_argument("--decimation", type=int, default=1, help="record per-patch velocities every N-th global sample")
    p.add_argument(
        "--band",
        type=float,
        nargs=2,
        default=(1.0e3, 5.0e5),
        metavar=("FMIN", "FMAX"),
        help="band of S(f), the CWT and the peak search [Hz]",
    )
    p.add_argument("--rule", choices=("relative", "snr"), default="relative", help="Phi rule of S(f)")
    p.add_argument(
        "--phi-min", type=int, default=10, help="prevalence level: S statistics use the bins with Phi >= this"
    )
    _add_run_selection(p)
    _add_sweep_options(p)
    _add_file_options(p)
    return p


def _add_run_selection(p: argparse.ArgumentParser) -> None:
    """Which presets run, with how many patches, and which figures they get."""
    p.add_argument(
        "--presets",
        nargs="*",
        choices=PRESET_NAMES,
        default=list(PRESET_NAMES),
        help="presets to run (none: only the sweep)",
    )
    p.add_argument(
        "--patches",
        type=int,
        default=None,
        help=f"patches per pad instead of {NOMINAL_PATCHES} (loads scaled to keep the pressure); for tests",
    )
    p.add_argument(
        "--figures",
        nargs="*",
        default=None,
        help="figures of plot_run per preset (default: all; none: no figures); e.g. spectra sync",
    )


def _add_sweep_options(p: argparse.ArgumentParser) -> None:
    """The area sweep: its points, friction factor, speed, pressure and patch seed."""
    p.add_argument("--skip-sweep", action="store_true", help="leave out the area sweep")
    p.add_argument(
        "--sweep-areas",
        type=float,
        nargs="+",
        default=[0.05, 0.125, 0.3, 0.6, 1.25],
        metavar="MM2",
        help="mean patch areas of the sweep [mm²], each range [0.4, 1.6] x mean",
    )
    p.add_argument("--sweep-M", type=float, default=0.8, help="friction factor M of the sweep")
    p.add_argument("--sweep-speed", type=float, default=10.0, help="sliding speed of the sweep at r = 0.13 m [m/s]")
    p.add_argument(
        "--sweep-pressure",
        type=float,
        default=DEFAULT_PRESSURE,
        help="mean patch pressure of the sweep F_N / (N mean area) [Pa] (hf1's)",
    )
    p.add_argument("--seed", type=int, default=1, help="patch generator seed of the sweep (presets: 1)")


def _add_file_options(p: argparse.ArgumentParser) -> None:
    """Run files kept, reused or deleted; the archive; progress bars."""
    p.add_argument(
        "--reuse",
        action="store_true",
        help="reuse complete run files found in <outdir>/runs (analysis and figures are redone)",
    )
    p.add_argument("--delete-runs", action="store_true", help="delete each run file once analysed and plotted")
    p.add_argument(
        "--archive",
        type=Path,
        default=None,
        help="also write a .tar.gz of the outdir without run files (figures, study.json, results.md); split into "
        "ARCHIVE-part1.tar.gz, -part2, ... when the files exceed --archive-max-mib",
    )
    p.add_argument("--archive-max-mib", type=float, default=15.0, help="largest archive part [MiB]")
    p.add_argument("--progress", action="store_true", help="show a progress bar per simulation")


def resolve(args: argparse.Namespace, wp: Any) -> argparse.Namespace:
    """Fill in the defaults that depend on --quick and on the machine; validate."""
    if args.duration is None:
        args.duration = QUICK_DURATION if args.quick else FULL_DURATION
    if args.transient is None:
        args.transient = QUICK_TRANSIENT if args.quick else FULL_TRANSIENT
    if args.device == "auto":
        args.device = "cuda:0" if wp.is_cuda_available() else "cpu"
    from aca_warp.plots import FIGURES

    problems = []
    if args.figures is None:
        args.figures = list(FIGURES)
    unknown = [f for f in args.figures if f not in FIGURES]
    if unknown:
        problems.append(f"unknown figure(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    if not args.duration > 0:
        problems.append("--duration must be > 0")
    if not 0 <= args.transient < args.duration:
        problems.append("--transient must lie in [0, duration)")
    if not args.band[1] > args.band[0] >= 0:
        problems.append("--band needs 0 <= FMIN < FMAX")
    if args.patches is not None and args.patches < 2:
        problems.append("--patches must be >= 2")
    if any(a <= 0 for a in args.sweep_areas):
        problems.append("--sweep-areas must be > 0")
    per_patch = (args.duration - args.transient) / (args.sample_dt * args.decimation)
    if per_patch < 16:
        problems.append(f"the per-patch record would hold {per_patch:.0f} samples; need >= 16")
    if problems:
        print("hf_study.py: " + "; ".join(problems), file=sys.stderr)
        raise SystemExit(2)
    return args


# ------------------------------------------------------------------------------------------------ physics


def isolated_frequency(area: np.ndarray | float, material: Any = None) -> np.ndarray | float:
    """Natural frequency of an isolated patch sqrt(k_T / m) / 2 pi, k_T = K_T sqrt(A), m = rho_A A (paper Eq. 2)
    [Hz] of patch areas ``area`` [m², any shape]; ``material``: a ``Material`` (None: the default one)."""
    if material is None:
        from aca_warp.scene import Material

        material = Material()
    area = np.asarray(area, dtype=np.float64)
    f = np.sqrt(material.K_T * np.sqrt(area) / (material.mass_per_area * area)) / (2.0 * np.pi)
    return float(f) if f.ndim == 0 else f


def fit_power_law(area: np.ndarray, freq: np.ndarray) -> dict[str, Any]:
    """Least-squares fit of log f = log c + b log A; b, its standard error and 95 % interval (n > 2)."""
    ok = np.isfinite(area) & np.isfinite(freq) & (area > 0) & (freq > 0)
    x, y = np.log(np.asarray(area)[ok]), np.log(np.asarray(freq)[ok])
    n = int(x.size)
    out: dict[str, Any] = {"n_points": n, "exponent": None, "stderr": None, "ci95": None, "prefactor": None}
    if n < 2 or np.ptp(x) == 0:
        return out
    xm, ym = x.mean(), y.mean()
    sxx = float(np.sum((x - xm) ** 2))
    b = float(np.sum((x - xm) * (y - ym)) / sxx)
    a = float(ym - b * xm)
    out.update(exponent=b, prefactor=math.exp(a), prefactor_unit="Hz m^(-2b)")
    if n > 2:
        from scipy.stats import t as student_t

        resid = y - (a + b * x)
        se = math.sqrt(float(np.sum(resid**2)) / (n - 2) / sxx)
        half = float(student_t.ppf(0.975, n - 2)) * se
        out.update(stderr=se, ci95=[b - half, b + half], rms_residual_log=float(np.sqrt(np.mean(resid**2))))
    return out


# ------------------------------------------------------------------------------------------------ scenes


def record_for(args: argparse.Namespace) -> Any:
    """The study's recording: global outputs every --sample-dt, per-patch velocities from --transient."""
    from aca_warp.scene import Record

    return Record(
        sample_dt=args.sample_dt,
        patches=("velocity",),
        window=(args.transient, args.duration),
        decimation=args.decimation,
    )


def _with_patches(scene: Any, gen: dict[str, Any], normal_force: float, **changes: Any) -> Any:
    """``scene`` with generated patches; the matrix is rebuilt (``matrix=None``) and ``origin`` updated so the
    run file's scene JSON names the new generator (``Scene.replace`` keeps both otherwise)."""
    from aca_warp.scene import PatchGenerator

    patches = PatchGenerator(**gen).generate(scene.pad)
    origin = dict(scene.origin or {})
    origin["patches"] = dict(gen)
    origin["load"] = {"normal_force": normal_force}
    return scene.replace(patches=patches, normal_force=normal_force, matrix=None, origin=origin, **changes)


def preset_scene(name: str, args: argparse.Namespace) -> Any:
    """Preset ``name`` with the study's recording (and ``--patches`` patches, load scaled to keep the pressure)."""
    from aca_warp.scene import preset

    scene = preset(name)
    if args.patches is not None and args.patches != scene.patches.count:
        gen = dict(scene.origin["patches"])
        force = scene.normal_force * args.patches / gen["count"]
        gen["count"] = args.patches
        scene = _with_patches(scene, gen, force)
    return scene.replace(record=record_for(args), duration=args.duration)


def sweep_scene(mean_mm2: float, args: argparse.Namespace) -> Any:
    """hf1 with patch areas uniform in SPREAD x mean, load = pressure x N x mean, M and speed of the sweep."""
    from aca_warp.scene import preset

    base = preset("hf1")
    n = args.patches or NOMINAL_PATCHES
    mean = mean_mm2 * MM2
    gen = {
        "count": n,
        "area_min": SPREAD[0] * mean,
        "area_max": SPREAD[1] * mean,
        "height": float(base.origin["patches"].get("height", 3.0e-6)),
        "seed": args.seed,
    }
    force = args.sweep_pressure * n * mean
    return _with_patches(
        base,
        gen,
        force,
        name=f"sweep_{mean_mm2:g}mm2",
        friction=dataclasses.replace(base.friction, M=args.sweep_M),
        angular_velocity=args.sweep_speed / base.pad.mean_radius,
        record=record_for(args),
        duration=args.duration,
    )


def scene_info(scene: Any) -> dict[str, Any]:
    """Patch count and areas, load, mean patch pressure, M, speed and isolated-patch frequency of ``scene``."""
    a = scene.patches.area
    return {
        "patches": int(scene.patches.count),
        "area_min_m2": float(a.min()),
        "area_max_m2": float(a.max()),
        "mean_area_m2": float(a.mean()),
        "normal_force_N": float(scene.normal_force),
        "mean_patch_pressure_Pa": float(scene.normal_force / a.sum()),
        "M": float(scene.friction.M),
        "sliding_speed_m_s": float(scene.sliding_speed),
        "isolated_patch_hz_at_mean_area": isolated_frequency(float(a.mean()), scene.material),
    }


# ------------------------------------------------------------------------------------------------ one run


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


# ------------------------------------------------------------------------------------------------ sweep figure


def _draw_frequency_vs_area(ax: Any, points: list[dict], fit: dict[str, Any], material: Any) -> None:
    """f against mean area (log-log): the sweep's peaks, the fit, the paper's -1/4 slope and its two peaks."""
    from matplotlib.ticker import FuncFormatter

    a = np.array([p["mean_area_m2"] for p in points]) / MM2
    f = np.array([num(p["first_velocity_peak_hz"]) for p in points]) / 1e3
    lo, hi = (a.min() / 1.5, a.max() * 1.5) if a.size else (0.02, 2.0)
    grid = np.geomspace(min(lo, 0.03), max(hi, 2.0), 100)
    ax.plot(
        grid,
        isolated_frequency(grid * MM2, material) / 1e3,
        color="0.45",
        lw=1.2,
        label=r"isolated patch $\sqrt{K_T\sqrt{A}/(\rho_A A)}/2\pi$ (slope $-1/4$)",
    )
    ok = np.isfinite(f)
    if fit.get("exponent") is not None:
        b, c = fit["exponent"], fit["prefactor"]
        se = fit.get("stderr")
        lab = f"fit $f \\propto A^{{{b:.3f}}}$" + (f" ± {se:.2g}" if se is not None else "")
        ax.plot(grid, c * (grid * MM2) ** b / 1e3, "C0-", lw=1.0, label=lab)
        # the paper's -1/4 through the data's centroid, for a direct slope comparison
        xm, ym = np.exp(np.mean(np.log(a[ok]))), np.exp(np.mean(np.log(f[ok])))
        ax.plot(grid, ym * (grid / xm) ** -0.25, "C3--", lw=0.9, label=r"slope $-1/4$ through the data (paper)")
    ax.plot(a[ok], f[ok], "o", color="C0", ms=6, label="first velocity-spectrum peak (sweep)")
    ax.plot([0.05, 1.25], [73.0, 32.8], "s", mfc="none", mec="C3", ms=8, label="paper HF1/HF3, HF2/HF4")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(plain)
    ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if f"{v:.1g}"[0] in "25" else ""))
    ax.yaxis.set_minor_formatter(plain)
    ax.tick_params(axis="y", which="minor", labelsize=7)
    ax.set_xlabel("mean patch area [mm²]")
    ax.set_ylabel("frequency [kHz]")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, loc="lower left")
    ax.set_title("first velocity-spectrum peak vs patch area", fontsize=9)


def _draw_sweep_spectra(ax: Any, points: list[dict], spectra: dict[str, dict], band: list[float]) -> None:
    """The mean per-patch velocity spectrum of each sweep point in ``band`` [Hz], normalised, peak dotted."""
    from matplotlib.ticker import FuncFormatter

    for i, p in enumerate(points):
        s = spectra.get(p["name"])
        if not s:
            continue
        fr, am = np.asarray(s["freq"]), np.asarray(s["amp"])
        keep = (fr >= band[0]) & (fr <= band[1]) & (fr > 0)
        if not keep.any() or not np.max(am[keep]) > 0:
            continue
        col = f"C{i % 10}"
        ax.plot(
            fr[keep] / 1e3, am[keep] / np.max(am[keep]), color=col, lw=0.8, label=f"{p['mean_area_m2'] / MM2:.3g} mm²"
        )
        if p["first_velocity_peak_hz"] is not None:
            ax.axvline(p["first_velocity_peak_hz"] / 1e3, color=col, lw=0.6, ls=":")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_ylim(1e-3, 1.5)
    ax.set_xlabel("frequency [kHz]")
    ax.set_ylabel("mean per-patch |X(f)| / its maximum")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, title="mean area", title_fontsize=7, loc="lower left")
    ax.set_title("mean per-patch velocity spectra (dotted: peak)", fontsize=9)


def plot_sweep(study: dict[str, Any], spectra: dict[str, dict], outdir: Path, material: Any) -> list[str]:
    """``area_sweep.png/.pdf``: f against mean area (log-log) with the fit and the isolated-patch -1/4 line;
    beside it the mean per-patch velocity spectra of the sweep points."""
    from aca_warp.studies.report import figure, save_figure

    s = study["settings"]
    fig = figure(figsize=(10.0, 4.6))
    ax, ax2 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.0, 1.15]})
    _draw_frequency_vs_area(ax, study["sweep"]["points"], study["sweep"]["fit"], material)
    _draw_sweep_spectra(ax2, study["sweep"]["points"], spectra, s["band_hz"])
    caption = (
        f"Area sweep: {s['sweep_patches']} patches, areas uniform in [{SPREAD[0]}, {SPREAD[1]}] × mean, M = "
        f"{s['sweep_M']:g}, {s['sweep_speed_m_s']:g} m/s, mean patch pressure {s['sweep_pressure_Pa'] / 1e6:.2f} MPa; "
        f"{s['integrator']} dt = {s['dt_s']:g} s, {s['precision']}, {s['duration_s']:g} s simulated, per-patch "
        f"velocities from {s['transient_s']:g} s; {study['machine']['device_name']}, "
        f"Warp {study['versions']['warp-lang']}."
    )
    fig.text(0.01, 0.01, caption, fontsize=6.5, wrap=True, va="bottom")
    fig.subplots_adjust(left=0.08, right=0.98, top=0.92, bottom=0.2, wspace=0.25)
    return [p.name for p in save_figure(fig, outdir, "area_sweep", dpi=150)]


# ------------------------------------------------------------------------------------------------ claims


def _peak_claims(pr: dict[str, Any]) -> list[dict[str, Any]]:
    """Each preset's first velocity-spectrum peak against the paper's, within PEAK_TOLERANCE or two bins."""
    out = []
    for name in PRESET_NAMES:
        if name not in pr:
            continue
        p = pr[name]
        f1, ref = p.get("first_velocity_peak_hz"), PAPER["first_velocity_peak_hz"][name]
        res = (p.get("patch_record") or {}).get("resolution_hz", 0.0)
        tol = max(PEAK_TOLERANCE * ref, 2.0 * res)
        measured = None if f1 is None else abs(f1 - ref) <= tol
        out.append(
            {
                "claim": f"{name}: first velocity-spectrum peak ≈ {ref / 1e3:g} kHz (paper)",
                "result": measured,
                "numbers": f"ours {fmt_hz(f1)} ({'–' if f1 is None else f'{100 * (f1 / ref - 1):+.1f} %'}); "
                f"criterion |Δ| ≤ max({100 * PEAK_TOLERANCE:g} %, 2 bins of {res / 1e3:.2f} kHz) = {tol / 1e3:.2f} kHz",
            }
        )
    return out


def _exponent_claim(fit: dict[str, Any]) -> list[dict[str, Any]]:
    """The sweep's fitted exponent against -1/4, within EXPONENT_TOLERANCE or two standard errors (none unfit)."""
    b, se = fit.get("exponent"), fit.get("stderr")
    if b is None:
        return []
    tol = max(2.0 * se, EXPONENT_TOLERANCE) if se is not None else EXPONENT_TOLERANCE
    interval = ""
    if fit.get("ci95"):
        lo, hi = fit["ci95"]
        interval = f"; the 95 % interval [{lo:.3f}, {hi:.3f}] " + ("contains" if lo <= -0.25 <= hi else "excludes")
        interval += " −1/4"
    return [
        {
            "claim": "f ∝ A^(−1/4) (paper, isolated-patch estimate)",
            "result": abs(b - PAPER["exponent"]) <= tol,
            "numbers": f"fitted exponent {b:.3f}"
            + (f" ± {se:.2g} (1 s.e.)" if se is not None else " (no s.e.: 2 points)")
            + f", {fit['n_points']} points; criterion |b + 0.25| ≤ "
            + (f"max(2 s.e., {EXPONENT_TOLERANCE:g})" if se is not None else f"{EXPONENT_TOLERANCE:g}")
            + f" = {tol:.3f}"
            + interval,
        }
    ]


def _sync_claim(pr: dict[str, Any], hi: str, lo: str, claim: str, phi: int) -> dict[str, Any]:
    """``claim`` that preset ``hi`` synchronises more than ``lo`` (lower M raises S), with every S measure."""
    if hi not in pr or lo not in pr:
        return {"claim": claim, "result": None, "numbers": f"not run ({hi} and {lo} needed)"}
    a, b = pr[hi], pr[lo]

    def higher(key: str) -> bool | None:
        va, vb = a.get(key), b.get(key)
        return None if va is None or vb is None else bool(va > vb)

    # Primary: the chance-corrected median S - S_null. Raw S is biased by Φ (S_null falls as Φ grows), so the
    # raw median compares bins of different Φ; it is reported beside it.
    checks = {
        "median S - S_null (primary)": higher("S_excess_median_phi_min"),
        "median S (raw)": higher("S_median_phi_min"),
        "fraction of bins with S > S_null": higher("S_above_null_fraction_phi_min"),
        "max S": higher("S_max_phi_min"),
    }

    def both(key: str, spec: str = ".3g") -> str:
        return f"{hi} {fmt(a.get(key), spec)} vs {lo} {fmt(b.get(key), spec)}"

    return {
        "claim": claim,
        "result": checks["median S - S_null (primary)"],
        "checks": checks,
        "numbers": f"over bins with Φ ≥ {phi}: median S − S_null {both('S_excess_median_phi_min')}; "
        f"raw median S {both('S_median_phi_min')} (median S_null {both('S_null_median_phi_min')}); "
        f"fraction with S > S_null {both('S_above_null_fraction_phi_min', '.2f')}; "
        f"max S {both('S_max_phi_min')}",
    }


def _spread_claim(pr: dict[str, Any], phi: int) -> dict[str, Any]:
    """Larger patches (hf2) spread S over more bins with a higher median Φ than small ones (hf1)."""
    claim = (
        f"larger patches spread S over more frequencies with higher prevalence Φ: hf2 vs hf1 (bins with S "
        f"defined and Φ ≥ {phi}, and their median Φ)"
    )
    if "hf1" not in pr or "hf2" not in pr:
        return {"claim": claim, "result": None, "numbers": "not run (hf1 and hf2 needed)"}
    a, b = pr["hf2"], pr["hf1"]
    na, nb = a.get("S_bins_phi_min"), b.get("S_bins_phi_min")
    pa, pb = a.get("Phi_median_phi_min"), b.get("Phi_median_phi_min")
    return {
        "claim": claim,
        "result": None if None in (na, nb, pa, pb) else bool(na > nb and pa > pb),
        "numbers": f"bins: hf2 {fmt(na)} vs hf1 {fmt(nb)}; "
        f"median Φ: hf2 {fmt(pa, '.0f')} vs hf1 {fmt(pb, '.0f')}; "
        f"mean Φ over defined bins: hf2 {fmt(a.get('Phi_mean_defined'), '.0f')} "
        f"vs hf1 {fmt(b.get('Phi_mean_defined'), '.0f')} "
        f"(same band and Δf for both)",
    }


def _order_claims(pr: dict[str, Any]) -> list[dict[str, Any]]:
    """Larger patches peak lower: hf2 below hf1, hf4 below hf3 (only pairs that ran)."""
    out = []
    for big, small in (("hf2", "hf1"), ("hf4", "hf3")):
        if big in pr and small in pr:
            fa, fb = pr[big].get("first_velocity_peak_hz"), pr[small].get("first_velocity_peak_hz")
            out.append(
                {
                    "claim": f"larger patches peak lower: {big} first velocity peak below {small}'s",
                    "result": None if None in (fa, fb) else fa < fb,
                    "numbers": f"{big} {fmt_hz(fa)} vs {small} {fmt_hz(fb)}",
                }
            )
    return out


def comparisons(study: dict[str, Any]) -> list[dict[str, Any]]:
    """The paper's §3.1 statements, each as a measured yes/no with the numbers (None where not run)."""
    pr = study["presets"]
    phi = study["settings"]["phi_min"]
    return [
        *_peak_claims(pr),
        *_exponent_claim((study.get("sweep") or {}).get("fit") or {}),
        _sync_claim(pr, "hf3", "hf1", "lower M raises S: hf3 (M = 0.4) above hf1 (M = 0.8), small patches", phi),
        _sync_claim(pr, "hf4", "hf2", "lower M raises S: hf4 (M = 0.4) above hf2 (M = 0.8), large patches", phi),
        _spread_claim(pr, phi),
        *_order_claims(pr),
    ]


# ------------------------------------------------------------------------------------------------ results.md


def yes_no(v: Any) -> str:
    """A claim's result in bold, or that it was not measured."""
    return "not measured" if v is None else ("**yes**" if v else "**no**")


def _reused_note(study: dict[str, Any]) -> str:
    runs = [p["run"] for p in study["presets"].values()] + [
        p["run"] for p in (study.get("sweep") or {}).get("points", [])
    ]
    reused = sum(bool(r.get("reused")) for r in runs)
    if not reused:
        return ""
    return f" ({reused} of {len(runs)} runs reused from earlier run files (--reuse), with those runs' simulation times)"


def _header_lines(study: dict[str, Any]) -> list[str]:
    """Title, the command, device, versions, run and analysis settings, wall time."""
    s, m, v = study["settings"], study["machine"], study["versions"]
    return [
        "# HF study: stand-alone HF simulations (paper §3.1) and patch-area sweep",
        "",
        "One run per preset from rest (4 ms by default): the record ends in the linear growth phase of the "
        "friction instability and each verdict below rests on one realisation. The "
        "verdicts on the paper's statements are those of [validation.md](../validation.md) (seed ensembles of "
        "saturated runs); this page is the single-run record they are compared with.",
        "",
        f"Produced by `{study['command']}` on {study['created']}"
        + ("" if study["complete"] else " — **incomplete: the study did not finish**")
        + ".",
        "",
        f"* Device: {m['device_name']} (`{m['device']}`); host {m['host']}.",
        f"* Versions: Warp {v['warp-lang']}, aca-warp {v.get('aca-warp', '?')}, Python {v['python']}.",
        f"* Runs: {s['integrator']}, dt = {s['dt_s']:g} s, {s['precision']}; {s['duration_s']:g} s simulated per run "
        f"({s['steps_per_run']:,} steps) from rest; global outputs every {s['sample_dt_s']:g} s; per-patch velocities "
        f"every {s['patch_sample_dt_s']:g} s from {s['transient_s']:g} s to the end "
        f"({s['patch_record_s']:g} s, Δf = {s['patch_resolution_hz'] / 1e3:.3g} kHz).",
        f"* Analysis: `analyze_run`, band {s['band_hz'][0] / 1e3:g}–{s['band_hz'][1] / 1e3:g} kHz, Φ rule "
        f"`{s['rule']}`; S statistics over the bins with Φ ≥ {s['phi_min']}. First velocity peak: largest peak of "
        "the mean per-patch velocity amplitude spectrum (docs/analysis.md).",
        f"* Wall time of the whole study: {study['total_wall_s']:.0f} s" + _reused_note(study) + ".",
    ]


def _preset_table(study: dict[str, Any]) -> list[str]:
    """Presets HF1-HF4 side by side: scene, peaks (ours and the paper's), μ, S and Φ statistics, wall time."""
    pr = study["presets"]
    transient, phi = study["settings"]["transient_s"], study["settings"]["phi_min"]

    def row(label: str, fn: Any) -> list[str]:
        return [label, *(fn(pr[n]) if n in pr else "not run" for n in PRESET_NAMES)]

    rows = [
        row("patches, mean area", lambda p: f"{p['scene']['patches']}, {p['scene']['mean_area_m2'] / MM2:.3g} mm²"),
        row("M, F_N", lambda p: f"{p['scene']['M']:g}, {p['scene']['normal_force_N']:.1f} N"),
        row("matrix load share", lambda p: fmt(p.get("matrix_load_share"), ".2%")),
        row("first velocity peak (ours)", lambda p: fmt_hz(p.get("first_velocity_peak_hz"))),
        ["first velocity peak (paper)", *(fmt_hz(PAPER["first_velocity_peak_hz"][n]) for n in PRESET_NAMES)],
        row("isolated patch at mean area", lambda p: fmt_hz(p["scene"]["isolated_patch_hz_at_mean_area"])),
        row("first peak amplitude [m/s]", lambda p: fmt(p.get("first_velocity_peak_amplitude"))),
        row("Σu̇ peak", lambda p: fmt_hz(p.get("sum_velocity_peak_hz"))),
        row(
            "largest μ peak (amplitude / mean μ)",
            lambda p: f"{fmt_hz(p.get('mu_peak_hz'))} ({fmt(p.get('mu_peak_amplitude'))})",
        ),
        row(f"mean μ (t ≥ {transient:g} s)", lambda p: fmt(p.get("mu_mean"), ".4f")),
        row(
            f"median / max S (Φ ≥ {phi})", lambda p: f"{fmt(p.get('S_median_phi_min'))} / {fmt(p.get('S_max_phi_min'))}"
        ),
        row(
            f"bins with Φ ≥ {phi} (of those with S defined)",
            lambda p: f"{fmt(p.get('S_bins_phi_min'))} ({fmt(p.get('S_bins_defined'))})",
        ),
        row(
            f"median Φ (Φ ≥ {phi}), max Φ",
            lambda p: f"{fmt(p.get('Phi_median_phi_min'), '.0f')}, {fmt(p.get('Phi_max'))}",
        ),
        row("bins with S > S_null (all, Φ ≥ 2)", lambda p: fmt(p.get("S_bins_above_null"))),
        row(
            f"median S − S_null, fraction S > S_null (Φ ≥ {phi})",
            lambda p: f"{fmt(p.get('S_excess_median_phi_min'))}, {fmt(p.get('S_above_null_fraction_phi_min'), '.2f')}",
        ),
        row(f"median R_w (Φ ≥ {phi})", lambda p: fmt(p.get("R_w_median_phi_min"))),
        row("S, Φ at the first peak", lambda p: f"{fmt(p.get('S_at_first_peak'))}, {fmt(p.get('Phi_at_first_peak'))}"),
        row("simulation wall time [s]", lambda p: fmt(p["run"].get("wall_s"), ".1f")),
    ]
    return ["## Presets HF1–HF4", "", *md_table(["", *PRESET_NAMES], rows)]


def _fit_sentence(study: dict[str, Any]) -> str:
    """The fitted exponent with its standard error and interval, beside the paper's."""
    fit = study["sweep"]["fit"]
    if fit.get("exponent") is None:
        return "No exponent: fewer than two sweep points with a peak."
    se, ci = fit.get("stderr"), fit.get("ci95")
    spread = (
        f" ± {se:.2g} (1 s.e.; 95 % interval {ci[0]:.3f} to {ci[1]:.3f})"
        if se is not None
        else " (two points: no standard error)"
    )
    return (
        f"Fitted exponent of f against mean patch area: **{fit['exponent']:.3f}**{spread}, {fit['n_points']} points. "
        "Paper: −1/4 (isolated-patch estimate); its two reported peaks (73 kHz at 0.05 mm², 32.8 kHz at 1.25 mm²) "
        f"imply {study['paper']['exponent_from_peaks']:.3f}."
    )


def _sweep_section(study: dict[str, Any]) -> list[str]:
    """The area sweep: one row per point, the fitted exponent and the figure."""
    s, sw = study["settings"], study.get("sweep")
    if not sw:
        return ["## Area sweep", "", "Not run (`--skip-sweep`)."]
    rows = []
    for p in sw["points"]:
        f1, fi = p.get("first_velocity_peak_hz"), p["isolated_patch_hz_at_mean_area"]
        rows.append(
            [
                f"{p['mean_area_m2'] / MM2:.3g} mm²",
                f"{p['area_min_m2'] / MM2:.3g}–{p['area_max_m2'] / MM2:.3g} mm²",
                f"{p['normal_force_N']:.1f} N",
                fmt(p.get("matrix_load_share"), ".2%"),
                fmt_hz(f1),
                fmt_hz(fi),
                "–" if f1 is None else f"{f1 / fi:.3f}",
            ]
        )
    header = ["mean area", "areas", "F_N", "matrix load share", "first velocity peak", "isolated patch", "ratio"]
    return [
        "## Area sweep",
        "",
        f"{s['sweep_patches']} patches, areas uniform in [{SPREAD[0]}, {SPREAD[1]}] × mean, M = {s['sweep_M']:g}, "
        f"{s['sweep_speed_m_s']:g} m/s, F_N = {s['sweep_pressure_Pa'] / 1e6:.3g} MPa × total nominal patch area "
        "(all patches loaded; the matrix share shows whether the matrix touches the disc).",
        "",
        *md_table(header, rows),
        "",
        _fit_sentence(study),
        "",
        "![area sweep](area_sweep.png)",
        "",
        "[area_sweep.png](area_sweep.png), [area_sweep.pdf](area_sweep.pdf)",
    ]


def _claims_section(study: dict[str, Any]) -> list[str]:
    """The paper's statements, each with the measured verdict (and the metrics that disagree with it)."""
    rows = []
    for c in study["comparisons"]:
        verdict = yes_no(c["result"])
        others = [f"{k}: {'yes' if v else 'no'}" for k, v in (c.get("checks") or {}).items() if v is not None]
        if others and any(v != c["result"] for v in c["checks"].values() if v is not None):
            verdict += " (metrics disagree — " + "; ".join(others) + ")"
        rows.append([c["claim"], verdict, c["numbers"]])
    return ["## The paper's statements, measured", "", *md_table(["statement", "measured", "numbers"], rows)]


def _figures_section(study: dict[str, Any]) -> list[str]:
    """Links to every figure of the presets and the sweep."""
    lines = ["## Figures", ""]
    for n in PRESET_NAMES:
        files = [f for f in study["presets"].get(n, {}).get("figures", []) if not f.endswith(".pdf")]
        if files:
            names = {
                f: Path(f).stem.removeprefix(n + "_") + (" animation" if f.endswith(".gif") else "") for f in files
            }
            links = ", ".join(f"[{label}]({f})" for f, label in names.items())
            lines.append(f"* {n}: {links} (PDFs beside the PNGs)")
    if study.get("sweep"):
        lines.append("* area sweep: [area_sweep.png](area_sweep.png), [area_sweep.pdf](area_sweep.pdf)")
    if len(lines) == 2:
        lines.append("None written.")
    return lines


def write_markdown(study: dict[str, Any], path: Path) -> None:
    """``results.md`` of a (cleaned) study: settings, the preset table, the sweep, the claims, figures, notes."""
    s = study["settings"]
    notes = [
        "## Notes",
        "",
        "* Every run starts from rest (u = u̇ = 0); the per-patch spectra and S(f) leave out t < "
        f"{s['transient_s']:g} s. The global-output spectra (μ peak) cover the whole record.",
        "* The paper's peaks are read off its Fig. 8; its run lengths are not stated. Frequencies here are resolved to "
        f"Δf = {s['patch_resolution_hz'] / 1e3:.3g} kHz (Gaussian interpolation of the peak bin).",
        "* S > S_null: S above the mean S of Φ uniformly random phases (Monte-Carlo null level, docs/analysis.md).",
    ]
    sections = [_header_lines, _preset_table, _sweep_section, _claims_section, _figures_section]
    lines: list[str] = []
    for section in sections:
        lines += [*section(study), ""]
    path.write_text("\n".join(lines + notes) + "\n")


def write_outputs(study: dict[str, Any], outdir: Path, log: Log) -> None:
    """``study.json`` and ``results.md`` as the study stands now (with its claims and wall time)."""
    study["total_wall_s"] = log.elapsed()
    study["comparisons"] = comparisons(study)
    write_json(outdir / "study.json", clean(study), indent=2)
    write_markdown(clean(study), outdir / "results.md")


def write_archive(outdir: Path, target: Path, max_mib: float, log: Log) -> list[Path]:
    """Everything in ``outdir`` but run files, as one .tar.gz or, above ``max_mib`` of input, several parts.

    Files are packed in order into parts of at most ``max_mib`` uncompressed (a larger single file gets a part of
    its own), so every part stays below the limit; study.json and results.md go into the first part.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    skip = {target.resolve()}
    files = [p for p in sorted(outdir.rglob("*")) if p.is_file() and p.suffix != ".h5" and p.resolve() not in skip]
    files = [p for p in files if p.name in ("study.json", "results.md")] + [
        p for p in files if p.name not in ("study.json", "results.md") and not p.name.endswith(".tar.gz")
    ]
    limit = max_mib * 2**20
    parts: list[list[Path]] = [[]]
    size = 0
    for p in files:
        n = p.stat().st_size
        if parts[-1] and size + n > limit:
            parts.append([])
            size = 0
        parts[-1].append(p)
        size += n
    name = target.name.removesuffix(".tar.gz").removesuffix(".tgz")
    paths = [target] if len(parts) == 1 else [target.with_name(f"{name}-part{i + 1}.tar.gz") for i in range(len(parts))]
    for path, group in zip(paths, parts, strict=True):
        with tarfile.open(path, "w:gz") as tar:
            for p in group:
                tar.add(p, arcname=str(Path(outdir.name) / p.relative_to(outdir)))
        log(f"archive {path} ({path.stat().st_size / 2**20:.1f} MiB, {len(group)} files)")
    return paths


# ------------------------------------------------------------------------------------------------ stages


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


def main(argv: list[str] | None = None) -> int:
    """Run the study; returns 0 when every run completed, 1 otherwise."""
    from aca_warp.studies.report import init_warp

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    wp = init_warp()
    args = resolve(args, wp)
    log = Log()
    outdir: Path = args.outdir
    (outdir / "runs").mkdir(parents=True, exist_ok=True)
    study = new_study(args, argv, wp.get_device(args.device))
    log(
        f"hf_study: {len(args.presets)} preset(s), {0 if args.skip_sweep else len(args.sweep_areas)} sweep point(s) "
        f"on {study['machine']['device_name']} ({args.device}), Warp {wp.__version__}, {args.precision}, "
        f"{args.integrator} "
        f"dt {args.dt:g} s, {args.duration:g} s per run, per-patch record {args.transient:g}–{args.duration:g} s "
        f"-> {outdir}"
    )
    all_ok = run_presets(study, args, log)
    if not args.skip_sweep:
        all_ok &= run_sweep(study, args, log)
    study["complete"] = all_ok
    write_outputs(study, outdir, log)
    log(f"wrote {outdir / 'study.json'} and {outdir / 'results.md'}")
    if args.archive is not None:
        write_archive(outdir, args.archive, args.archive_max_mib, log)
    for c in study["comparisons"]:
        verdict = "n/a" if c["result"] is None else ("yes" if c["result"] else "no")
        print(f"  {verdict:3}  {c['claim']}: {c['numbers']}")
    log("done" if all_ok else "done, but some runs stopped early (see study.json)")
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main())
