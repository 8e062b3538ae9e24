"""The area sweep's figure ``area_sweep.png/.pdf``: the first velocity-spectrum peak against the mean patch area
with the fit and the isolated-patch -1/4 line, beside the mean per-patch velocity spectra of the sweep points."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.hf_study.base import MM2, SPREAD, isolated_frequency
from aca_warp.studies.report import num


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
