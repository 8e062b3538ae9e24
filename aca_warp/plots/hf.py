"""The HF figures of a run file after the paper's Figs. 4-11, one public function per figure (the table of them
and :func:`~aca_warp.plots.plot_run`, which makes them all, are in :mod:`aca_warp.plots`)."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import FuncFormatter

from aca_warp.analysis import report
from aca_warp.analysis.report import MIN_SAMPLES, Group, analysis_group, has_patch_velocity, open_run_file, run_attr
from aca_warp.analysis.spectra import DEFAULT_FLOOR_HZ
from aca_warp.common.errors import SceneError, option
from aca_warp.common.files import whole
from aca_warp.plots.figure import GifInto, device_text, run_stem
from aca_warp.plots.figure import envelope as _envelope
from aca_warp.plots.figure import finish as _finish
from aca_warp.plots.figure import new_figure as _figure
from aca_warp.plots.figure import pad_outline as _pad_outline
from aca_warp.plots.figure import save as _save

FIGURES = ("patch_map", "global", "spectra", "sync", "stft", "cwt", "animation")
# the figures of the analysis's transforms (at least MIN_SAMPLES samples)
TRANSFORMS = ("spectra", "sync", "stft", "cwt")
GIF_DPI = 80  # the animation's resolution: 6.4 x 3.6 in frames are 512 x 288 px
GIF_FOOTER_PT = 7.0  # the animation's footer [pt]: 7.8 px letters in its 512 x 288 px frames (80 dpi)
GIF_FOOTER_CHARS = 100  # ... wrapped to lines this long, which fit the frame's width
"""Figure names accepted by :func:`~aca_warp.plots.plot_run` (``which``) and ``aca-warp plot --only``."""

WITH_DISC = "#d62728"
AGAINST_DISC = "#1f77b4"
AT_REST = "#9a9a9a"


# ------------------------------------------------------------------------------------------- helpers


class _Run:
    """An open run file with what every figure needs (path, stem, footer text, scene)."""

    def __init__(self, path: str | Path, *, min_samples: int = MIN_SAMPLES, needed_by: str = "the analysis") -> None:
        """``min_samples``: the fewest samples ``needed_by`` needs (the analysis': 8; the global series: 2)."""
        self.path = Path(path)
        self.f = open_run_file(self.path, "r", min_samples=min_samples, needed_by=needed_by)
        self.scene = run_attr(self.f, "scene", {}) or {}
        if not isinstance(self.scene, dict):
            self.scene = {}
        self.name = str(run_attr(self.f, "scene_name", "") or self.scene.get("scene", {}).get("name", "?"))

    def __enter__(self) -> _Run:
        return self

    def __exit__(self, *exc: object) -> None:
        self.f.close()

    @property
    def footer(self) -> str:
        a = {k: run_attr(self.f, k, "?") for k in ("integrator", "precision", "status")}
        return (
            f"{self.path.name} · scene {self.name} · integrator {a['integrator']} · precision {a['precision']} · "
            f"device {device_text(self.f)} · run {a['status']}"
        )

    def save(self, fig: Figure, caption: str, outdir: str | Path, name: str) -> list[Path]:
        """Finish ``fig`` with ``caption`` above the run's footer and write it as ``outdir/STEM_name.png`` and
        ``.pdf`` (STEM: the run file's stem); returns both paths."""
        _finish(fig, caption, self.footer)
        return _save(fig, Path(outdir), f"{run_stem(self.path)}_{name}")

    def group(self, name: str, compute: Callable[[], Group | None]) -> Group | None:
        return analysis_group(self.f, name, compute)

    def spectra(self) -> Group:
        g = self.group("spectra", lambda: report.compute_spectra(self.f))
        assert g is not None
        return g

    def peaks(self) -> Group:
        """Stored peaks, else peaks from the global spectra (no per-patch pass)."""
        g = self.group("peaks", lambda: report.compute_peaks(self.spectra()))
        assert g is not None
        return g

    def first_peak(self) -> float | None:
        fp = self.peaks().attrs.get("first_velocity_peak_frequency")
        return float(fp) if fp is not None and np.isfinite(fp) and fp > 0 else None

    def band_top(self) -> float:
        """Top of the analysis band [Hz]: /analysis/sync's band, else min(200 kHz, Nyquist)."""
        if report.stored(self.f, "sync"):
            return float(np.asarray(self.f["analysis/sync"].attrs["band"])[1])
        dt = report.sample_interval(self.f["global/time"][()])
        return min(report.DEFAULT_BAND_TOP, 0.5 / dt)


def _log_max(f: np.ndarray, a: np.ndarray, points: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """Largest value per logarithmic frequency bin (peaks survive), for f > 0 sorted ascending."""
    if f.size <= points:
        return f, a
    edges = np.geomspace(f[0], f[-1] * (1 + 1e-12), points + 1)
    idx = np.searchsorted(f, edges)
    starts = np.unique(idx[:-1][idx[:-1] < f.size])
    best = np.array([s + np.argmax(a[s:e]) for s, e in zip(starts, np.append(starts[1:], f.size), strict=True)])
    return f[best], a[best]


_PLAIN = FuncFormatter(lambda v, _: f"{v:g}")
_UNITS = {"m s-1": "m/s", "N m": "N m", "m": "m", "1": "1", "Hz": "Hz"}


def _hz(f: float) -> str:
    """A frequency [Hz] with its unit, in Hz, kHz or MHz by size (10 Hz, 200 kHz, 2.5 MHz)."""
    f = float(f)
    for scale, unit in ((1e6, "MHz"), (1e3, "kHz")):
        if abs(f) >= scale:
            return f"{f / scale:.4g} {unit}"
    return f"{f:.4g} Hz"


def _unit(unit: str) -> str:
    """Plot-friendly spelling of a run-file unit string ("m s-1" -> "m/s")."""
    return _UNITS.get(unit, unit)


def _plain_log(axis: Any) -> None:
    """Plain numbers (20, 50, 100) instead of powers of ten on a logarithmic frequency axis."""
    axis.set_major_formatter(_PLAIN)
    axis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if f"{v:.1g}"[0] in "25" else ""))


def _record_velocity() -> str:
    """How to record what the patch figures need, for the reader of the message."""
    return option(
        "run it again with Record(patches=('velocity',)) in the scene",
        "rerun aca-warp hf with --record-patches velocity",
    )


def _require_patch_velocity(run: _Run, figure: str) -> None:
    if not has_patch_velocity(run.f):
        raise SceneError(f"{run.path.name}: the {figure} figure needs per-patch velocities; {_record_velocity()}")


# ----------------------------------------------------------------------------------------- patch map


def check_instants(times: Sequence[float], lo: float, hi: float, name: str, what: str = "instant") -> None:
    """Refuse an instant of ``times`` [s] outside the per-patch record ``lo``–``hi`` [s] of the run ``name``."""
    for t in times:
        if not lo - 1e-12 <= t <= hi + 1e-12:
            raise SceneError(f"{what} {t:g} s lies outside the per-patch record {lo:g}-{hi:g} s of {name}")


def _patch_rows(run: _Run, times: Sequence[float] | None, count: int = 4) -> tuple[np.ndarray, str]:
    """Rows of /patches/velocity to draw and a sentence on how they were chosen."""
    pt = run.f["patches/time"][()]
    if times is not None and len(times):
        times = np.asarray(times, dtype=np.float64)
        check_instants(times, float(pt[0]), float(pt[-1]), run.path.name)
        rows = np.unique(np.abs(pt[None, :] - times[:, None]).argmin(axis=1))
        return rows, "Instants as requested (nearest recorded sample)."
    fp = run.first_peak()
    if fp is not None and pt.size > 1 and 0.75 / fp < pt[-1] - pt[0]:
        dt = (pt[-1] - pt[0]) / (pt.size - 1)  # the per-patch record's spacing (every decimation-th sample)
        step = max(1, round(0.25 / fp / dt))  # rows per quarter period: evenly spaced instants whatever dt is
        rows = pt.size - 1 - step * np.arange(count)[::-1]
        if rows[0] >= 0:
            quarter = f"a quarter period of the first velocity-spectrum peak ({fp / 1e3:.4g} kHz"
            spacing = step * dt
            if abs(spacing - 0.25 / fp) <= 0.02 * 0.25 / fp:
                return rows, f"Default instants: {quarter}) apart, at the end of the per-patch record."
            return rows, (
                f"Default instants: {spacing * 1e6:.4g} µs apart at the end of the per-patch record, the whole number "
                f"of its sample intervals ({dt * 1e6:.4g} µs) nearest to {quarter}: {0.25e6 / fp:.4g} µs)."
            )
    rows = np.unique(np.linspace(0, pt.size - 1, count).round().astype(int))
    return rows, "Default instants: evenly spaced over the per-patch record."


def _marker_scale(ax: Any, fig: Figure, x: np.ndarray, y: np.ndarray, area: np.ndarray) -> float:
    """Marker area [pt²] of the largest patch: ~85 % of the mean patch spacing on screen, in diameter."""
    fig.canvas.draw()
    bbox = ax.get_window_extent()
    x0, x1 = ax.get_xlim()
    pt_per_mm = bbox.width / fig.dpi * 72.0 / (x1 - x0)
    hull = (x.max() - x.min()) * (y.max() - y.min()) if x.size > 1 else 1.0
    spacing_mm = math.sqrt(max(hull, 1e-9) * 0.6 / x.size) if x.size > 1 else 5.0
    return float(np.clip((0.85 * spacing_mm * pt_per_mm) ** 2, 2.0, 400.0))


def _colours(v: np.ndarray) -> np.ndarray:
    out = np.empty(v.shape, dtype=object)
    out[:] = AT_REST
    out[v > 0] = WITH_DISC
    out[v < 0] = AGAINST_DISC
    return out


def _map_axes(ax: Any, outline: tuple[np.ndarray, np.ndarray] | None, x: np.ndarray, y: np.ndarray) -> None:
    if outline is not None:
        ax.plot(*outline, color="0.6", lw=0.6)
    ax.set_aspect("equal")
    margin = 2.0
    xs = x if outline is None else np.concatenate([x, outline[0]])
    ys = y if outline is None else np.concatenate([y, outline[1]])
    ax.set_xlim(xs.min() - margin, xs.max() + margin)
    ax.set_ylim(ys.min() - margin, ys.max() + margin)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.tick_params(labelsize=7)


def _legend_handles() -> list[Line2D]:
    return [
        Line2D([], [], ls="", marker="o", color=WITH_DISC, label="u̇ > 0: with the disc"),
        Line2D([], [], ls="", marker="o", color=AGAINST_DISC, label="u̇ < 0: against the disc"),
    ]


def plot_patch_map(path: str | Path, outdir: str | Path, *, times: Sequence[float] | None = None) -> list[Path]:
    """Patch coverage state coloured by direction of motion at chosen instants (paper Figs. 4, 6).

    One marker per patch at (x, y) [mm], marker area ∝ patch area; red where u̇ > 0 (moving with the disc),
    blue where u̇ < 0, in the pad frame. Below, μ(t) over the per-patch record with the instants marked.

    Args:
        path: Run file with per-patch velocities.
        outdir: Output folder (created if missing).
        times: Instants [s] (nearest recorded sample); default four quarter periods of the first
            velocity-spectrum peak at the end of the record, else four evenly spaced instants.
    """
    with _Run(path) as run:
        _require_patch_velocity(run, "patch map")
        rows, how = _patch_rows(run, times)
        pt = run.f["patches/time"][()]
        vel = run.f["patches/velocity"][np.sort(rows), :].astype(np.float64)
        x, y = 1e3 * run.f["patches/x"][()], 1e3 * run.f["patches/y"][()]
        area = run.f["patches/area"][()]
        gt, mu = run.f["global/time"][()], run.f["global/mu"][()]
        outline = _pad_outline(run.scene)
        n = rows.size
        ncols = 1 if n == 1 else 2
        nrows = math.ceil(n / ncols)
        caption = (
            f"Patch coverage state at {n} instant{'s' if n > 1 else ''} (after paper Figs. 4/6): one marker per "
            f"patch at its position (x, y) [mm], marker area proportional to the patch area (largest "
            f"{area.max() * 1e6:.3g} mm², enlarged for visibility, not to scale); red: the patch moves with the "
            "disc (u̇ > 0, pad frame), blue: against it (u̇ < 0); grey: at rest. Grey outline: the pad. "
            f"{how} Bottom: global friction coefficient μ(t), raw, with the instants marked."
        )
        fig = _figure(2.35 * nrows + 1.9)
        gs = fig.add_gridspec(nrows + 1, ncols, height_ratios=[2.35] * nrows + [1.5])
        axes = []
        for k in range(n):
            ax = fig.add_subplot(gs[k // ncols, k % ncols])
            _map_axes(ax, outline, x, y)
            v = vel[k]
            ax.set_title(
                f"t = {pt[rows[k]] * 1e6:.4g} µs: {np.count_nonzero(v > 0)} with, {np.count_nonzero(v < 0)} "
                "against the disc",
                fontsize=8,
            )
            axes.append((ax, ax.scatter(x, y, s=1.0, c=list(_colours(v)), linewidths=0, rasterized=x.size > 3000)))
        fig.legend(handles=_legend_handles(), fontsize=8, loc="outside upper center", ncols=2, frameon=False)
        axm = fig.add_subplot(gs[nrows, :])
        sel = (gt >= pt[0]) & (gt <= pt[-1])
        if np.count_nonzero(sel) < 2:
            sel = slice(None)
        tt, mm, _ = _envelope(gt[sel], mu[sel])
        axm.plot(tt * 1e3, mm, lw=0.7, color="k")
        for r in rows:
            axm.axvline(pt[r] * 1e3, color="tab:orange", lw=0.8, ls="--")
        axm.set_xlabel("time t [ms]")
        axm.set_ylabel("μ [1]")
        axm.tick_params(labelsize=7)
        _finish(fig, caption, run.footer)
        smax = _marker_scale(axes[0][0], fig, x, y, area)
        for _, sc in axes:
            sc.set_sizes(smax * area / area.max())
        return _save(fig, Path(outdir), f"{run_stem(run.path)}_patch_map")


def animate_patch_map(
    path: str | Path,
    outdir: str | Path,
    *,
    t0: float | None = None,
    t1: float | None = None,
    frames: int = 40,
    fps: int = 10,
) -> list[Path]:
    """GIF of the patch coverage state (colours as in :func:`plot_patch_map`) over [t0, t1], 512 × 288 px.

    Default window: the last two periods of the first velocity-spectrum peak, else the whole per-patch
    record; ``frames`` evenly spaced recorded samples (``frames`` ≥ 2; fewer when the window holds fewer recorded
    samples: each frame is a different sample), shown at ``fps`` ≥ 1 frames per second. Needs Pillow (matplotlib's
    ``PillowWriter``).
    """
    from matplotlib import animation

    for name, value, least in (("frames", frames, 2), ("fps", fps, 1)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < least:
            raise SceneError(f"{name} must be an integer >= {least}, got {value!r}")
    frames, fps = int(frames), int(fps)

    if not animation.writers.is_available("pillow"):
        raise SceneError("the animation needs Pillow (pip install pillow); it is not installed")
    with _Run(path) as run:
        fig, update, count = animation_figure(run, t0, t1, frames)
        anim = animation.FuncAnimation(fig, update, frames=count, blit=False, repeat=False)
        out = Path(outdir)
        out.mkdir(parents=True, exist_ok=True)
        gif = out / f"{run_stem(run.path)}_patch_map.gif"
        with whole(gif, "temporary figure") as fh:
            anim.save(fh.name, writer=GifInto(fh, fps), dpi=GIF_DPI)
        return [gif]


def animation_figure(
    run: _Run, t0: float | None, t1: float | None, frames: int
) -> tuple[Figure, Callable[[int], tuple[Any, ...]], int]:
    """The animation's figure (6.4 × 3.6 in at :data:`GIF_DPI`: 512 × 288 px, its layout frozen), the function that
    draws frame k into it, and the number of frames (:func:`animate_patch_map`)."""
    _require_patch_velocity(run, "animation")
    pt = run.f["patches/time"][()]
    fp = run.first_peak()
    if t0 is None and t1 is None and fp is not None and 2.0 / fp < pt[-1] - pt[0]:
        t0, t1 = pt[-1] - 2.0 / fp, pt[-1]
    t0 = pt[0] if t0 is None else t0
    t1 = pt[-1] if t1 is None else t1
    if not (pt[0] - 1e-12 <= t0 < t1 <= pt[-1] + 1e-12):
        raise SceneError(f"animation window {t0:g}-{t1:g} s is not inside the record {pt[0]:g}-{pt[-1]:g} s")
    i0, i1 = int(np.searchsorted(pt, t0 - 1e-12)), int(np.searchsorted(pt, t1 + 1e-12)) - 1
    rows = np.unique(np.linspace(i0, i1, max(2, frames)).round().astype(int))
    vel = run.f["patches/velocity"][rows[0] : rows[-1] + 1, :][rows - rows[0]]
    x, y = 1e3 * run.f["patches/x"][()], 1e3 * run.f["patches/y"][()]
    area = run.f["patches/area"][()]
    fig = Figure(figsize=(6.4, 3.6), dpi=GIF_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    _map_axes(ax, _pad_outline(run.scene), x, y)
    sc = ax.scatter(x, y, s=1.0, c=list(_colours(vel[0])), linewidths=0)

    def caption(k: int) -> str:
        return f"{run.name}: t = {pt[rows[k]] * 1e6:.5g} µs (red: u̇ > 0 with the disc, blue: u̇ < 0 against it)"

    title = ax.set_title(caption(0), fontsize=8)  # before the layout is frozen: room for the title
    footer = textwrap.wrap(f"marker area ∝ patch area · {run.footer}", GIF_FOOTER_CHARS, break_on_hyphens=False)
    fig.supxlabel("\n".join(footer), x=0.01, ha="left", fontsize=GIF_FOOTER_PT, color="0.35")  # in the layout
    sc.set_sizes(_marker_scale(ax, fig, x, y, area) * area / area.max())
    fig.set_layout_engine("none")  # freeze the layout drawn by _marker_scale: frames only recolour
    # Animation.save() redraws the canvas for display and again for the writer; this figure is never
    # displayed, so its (private) canvas skips the first draw.
    fig.canvas.draw_idle = lambda *args, **kwargs: None

    def update(k: int) -> tuple[Any, ...]:
        sc.set_color(list(_colours(vel[k])))
        title.set_text(caption(k))
        return sc, title

    return fig, update, len(rows)


# ------------------------------------------------------------------------------------------- globals


def plot_global(path: str | Path, outdir: str | Path) -> list[Path]:
    """μ, friction torque, effective friction radius and Σ|u̇| against time [ms], stacked (Figs. 5, 7)."""
    with _Run(path, min_samples=2, needed_by="the global series") as run:
        t = run.f["global/time"][()]
        panels = [
            ("mu", "μ [1]", 1.0),
            ("torque", "torque T [N m]", 1.0),
            ("friction_radius", "friction radius r_eff [mm]", 1e3),
            ("sum_abs_velocity", "Σ|u̇| [m/s]", 1.0),
        ]
        block = 1
        fig = _figure(7.0)
        axes = fig.subplots(len(panels), 1, sharex=True)
        for ax, (name, label, scale) in zip(axes, panels, strict=True):
            tt, yy, block = _envelope(t, run.f[f"global/{name}"][()] * scale)
            ax.plot(tt * 1e3, yy, lw=0.6, color="k", rasterized=yy.size > 5000)
            ax.set_ylabel(label, fontsize=8)
            ax.tick_params(labelsize=7)
            ax.ticklabel_format(axis="y", useOffset=False)
        axes[-1].set_xlabel("time t [ms]")
        drawn = "sample by sample" if block == 1 else f"as the min/max envelope of blocks of {block} samples"
        caption = (
            "Global tribological data against time (after paper Figs. 5/7): friction coefficient μ = total "
            "friction force / F_N, friction torque T, effective friction radius r_eff = T / total friction force "
            "and Σ|u̇|, the sum of the absolute patch velocities in the pad frame. Raw values, not normalised; "
            f"{t.size} samples at {report.sample_interval(t):.4g} s, drawn {drawn}."
        )
        return run.save(fig, caption, outdir, "global")


# ------------------------------------------------------------------------------------------- spectra


_SPECTRA_COLOURS = dict(
    zip(report.GLOBAL_OUTPUTS, ("k", "tab:orange", "tab:green", "tab:purple", "tab:blue", "tab:brown"), strict=True)
)
"""Colour of each global output's spectrum in :func:`plot_spectra`."""


def _physical_spectra(ax: Any, spec: Group, phys: list[str], keep: np.ndarray, patch: Group | None) -> None:
    """The lower panel of :func:`plot_spectra`: the spectra ``phys`` kept in physical units (bins ``keep``) and,
    when given, the mean per-patch velocity spectrum of ``patch``."""
    freq = spec["freq"]
    for name in phys:
        f, a = _log_max(freq[keep], spec[name][keep])
        unit = _unit(spec.meta(name).get("unit", "?"))
        ax.loglog(f / 1e3, a, lw=0.7, color=_SPECTRA_COLOURS[name], label=f"{report.LABELS[name]} [{unit}]")
    if patch is not None:
        pf = patch["freq"]
        pk = report.shown_bins(pf)
        f, a = _log_max(pf[pk], patch["mean_amplitude"][pk])
        ax.loglog(f / 1e3, a, lw=0.7, color="tab:red", label="mean per-patch |X_i(f)| of u̇_i [m/s]")
    ax.set_ylabel("amplitude [m/s]" if all(spec.meta(k).get("unit") == "m s-1" for k in phys) else "amplitude")
    ax.legend(fontsize=7)


def _mark_velocity_peak(axes: Any, peaks: Group) -> str:
    """A dotted line at the first velocity-spectrum peak on every panel, its frequency on the top one; the
    caption's sentence about it ("" without a peak)."""
    fp = peaks.attrs.get("first_velocity_peak_frequency")
    if fp is None:
        return ""
    for ax in axes:
        ax.axvline(fp / 1e3, color="tab:red", lw=0.8, ls=":")
    axes[0].annotate(
        f"{fp / 1e3:.4g} kHz",
        (fp / 1e3, 1.0),
        xycoords=("data", "axes fraction"),
        fontsize=7,
        color="tab:red",
        ha="left",
        va="top",
        xytext=(3, -3),
        textcoords="offset points",
    )
    source = peaks.attrs.get("first_velocity_peak_source", "?").split(" (")[0]
    edge = peaks.attrs.get("first_velocity_peak_at_band_edge", "no")
    if edge in ("lower", "upper"):
        return (
            f" Dotted red: the largest value of the {source} in the band searched "
            f"({_hz(peaks.attrs['band'][0])} – {_hz(peaks.attrs['band'][1])}), {fp / 1e3:.4g} kHz, at the band's "
            f"{edge} edge: no peak inside the band."
        )
    return (
        f" Dotted red: first velocity-spectrum peak, {fp / 1e3:.4g} kHz "
        f"(largest peak of the {source} in {_hz(peaks.attrs['band'][0])} – {_hz(peaks.attrs['band'][1])})."
    )


def plot_spectra(path: str | Path, outdir: str | Path) -> list[Path]:
    """Amplitude spectra of every global output on a log frequency axis [kHz], f < 10 Hz dropped (Fig. 8).

    Mean-normalised spectra share the top panel; spectra kept in physical units (signals that change sign,
    such as Σu̇) and, when ``/analysis`` holds it, the mean per-patch velocity spectrum go below.
    """
    with _Run(path) as run:
        spec = run.spectra()
        peaks = run.peaks()
        patch = analysis_group(run.f, "patch_spectrum", lambda: None)
        freq = spec["freq"]
        floor = report.leakage_floor(freq)
        keep = report.shown_bins(freq)
        norm = [k for k in report.GLOBAL_OUTPUTS if k in spec and spec.meta(k).get("unit") == "1"]
        phys = [k for k in report.GLOBAL_OUTPUTS if k in spec and k not in norm]
        lower = bool(phys) or patch is not None
        fig = _figure(6.4 if lower else 4.2)
        axes = fig.subplots(2 if lower else 1, 1, sharex=True, squeeze=False)[:, 0]
        styles = {"mu": "-", "torque": "--"}
        for name in norm:
            f, a = _log_max(freq[keep], spec[name][keep])
            axes[0].loglog(
                f / 1e3, a, lw=0.7, color=_SPECTRA_COLOURS[name], ls=styles.get(name, "-"), label=report.LABELS[name]
            )
        axes[0].set_ylabel("amplitude / |mean| [1]")
        axes[0].legend(fontsize=7, ncols=2)
        if lower:
            _physical_spectra(axes[1], spec, phys, keep, patch)
        peak_text = _mark_velocity_peak(axes, peaks)
        for ax in axes:
            ax.grid(True, which="major", lw=0.3, alpha=0.5)
            ax.tick_params(labelsize=7, which="both")
        _plain_log(axes[-1].xaxis)
        axes[-1].set_xlabel("frequency f [kHz]")
        n = spec.attrs.get("samples", freq.size * 2 - 2)
        caption = (
            "One-sided amplitude spectra of the global outputs (after paper Fig. 8): periodic Hann window over "
            f"the whole record ({n} samples, Δf = {freq[1] - freq[0]:.4g} Hz), coherent-gain corrected (a "
            "sinusoid of amplitude a shows a). Top: each spectrum divided by the mean of its raw signal "
            "(dimensionless)."
            + (" Bottom, in physical units: " if lower else "")
            + ("signals that change sign" if phys else "")
            + (" and " if phys and patch else "")
            + ("the mean over patches of the per-patch velocity amplitude spectra" if patch else "")
            + ("." if lower else "")
            + f" Dropped: f < max(10 Hz, 2 Δf) = {floor:.4g} Hz (bin 1 holds the window's leakage of the mean). "
            "Log axes; the largest value per logarithmic frequency bin is drawn." + peak_text
        )
        return run.save(fig, caption, outdir, "spectra")


# ---------------------------------------------------------------------------------------------- sync


def _rule_text(a: dict[str, Any]) -> str:
    if a.get("rule") == "snr":
        return f"SNR rule |X_i(f)| ≥ κ·median_f |X_i| with κ = {a.get('snr')}"
    return f"relative rule |X_i(f)| ≥ η·max_j |X_j(f)| with η = {a.get('eta')}"


def plot_sync(path: str | Path, outdir: str | Path, **options: Any) -> list[Path]:
    """Synchronization Index: (f, Φ) coloured by S, and S(f), S_null(f), R_w(f) against f (after Fig. 9).

    Uses ``/analysis/sync``; without it the index is computed from the per-patch velocities with
    ``options`` (keywords of :func:`aca_warp.analysis.report.compute_patch_velocity`).
    """
    with _Run(path) as run:
        if not report.stored(run.f, "sync"):
            _require_patch_velocity(run, "Synchronization Index")
        g = run.group("sync", lambda: report.compute_sync(run.f, **options))
        assert g is not None
        a = g.attrs
        f, S, phi, s0, rw = (g[k] for k in ("freq", "S", "Phi", "S_null", "R_w"))
        df, floor, shown = report.bin_width(f, a), report.leakage_floor(f, a), report.shown_bins(f, a)
        if np.count_nonzero(shown) < 2:
            raise SceneError(
                f"the Synchronization Index holds {np.count_nonzero(shown)} frequency bin(s) at or above "
                f"{floor:.4g} Hz (Δf = {df:.4g} Hz): too few to draw; record longer (Δf = 1 / record length) or "
                "widen the band (analyze --freq-min/--freq-max)"
            )
        f, S, phi, s0, rw = (x[shown] for x in (f, S, phi, s0, rw))
        valid = np.isfinite(S)
        above = valid & (S > s0)
        below = valid & ~above
        fig = _figure(6.4)
        ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[1.5, 1.0])
        fk = f / 1e3
        size = float(np.clip(4000.0 / max(1, np.count_nonzero(valid)), 2.0, 14.0))
        ax1.scatter(
            fk[below], phi[below], s=0.6 * size, color="0.75", linewidths=0, rasterized=True, label="S ≤ S_null"
        )
        order = np.flatnonzero(above)[np.argsort(S[above])]
        sc = ax1.scatter(
            fk[order],
            phi[order],
            c=S[order],
            s=size,
            cmap="viridis",
            norm=Normalize(0.0, 1.0),
            linewidths=0,
            rasterized=True,
        )
        fig.colorbar(sc, ax=ax1, label="Synchronization Index S [1]", pad=0.01)
        ax1.set_ylabel("Φ: oscillating patches")
        ax1.legend(fontsize=7, loc="upper right", markerscale=2)
        ax2.scatter(fk[valid], S[valid], s=0.5 * size, color="tab:blue", linewidths=0, rasterized=True, label="S(f)")
        ax2.scatter(
            fk[valid], s0[valid], s=0.5 * size, color="tab:red", linewidths=0, rasterized=True, label="S_null(f)"
        )
        finite = np.isfinite(rw)
        tt, rr = _log_max(fk[finite], rw[finite]) if finite.any() else (fk[:0], rw[:0])
        ax2.plot(tt, rr, lw=0.6, color="k", label="R_w(f) (max per log bin)", rasterized=True)
        ax2.set_ylim(0.0, 1.02)
        ax2.set_ylabel("S, S_null, R_w [1]")
        ax2.set_xlabel("frequency f [kHz]")
        ax2.legend(fontsize=7, ncols=3, loc="upper right", markerscale=3)
        for ax in (ax1, ax2):
            ax.set_xscale("log")
            ax.grid(True, lw=0.3, alpha=0.5)
            ax.tick_params(labelsize=7, which="both")
        _plain_log(ax2.xaxis)
        band = np.asarray(a.get("band", [f[0], f[-1]]), dtype=float)
        caption = (
            "Synchronization Index of the per-patch velocities (paper §2.2, Fig. 9). Top: every frequency bin "
            "with Φ ≥ 2 at (f, Φ), coloured by S ∈ [0, 1]; grey where S does not exceed its null level S_null. "
            "Bottom: S(f), S_null(f) = mean S of Φ uniformly random phases "
            f"({a.get('null_trials')} trials), and the amplitude-weighted order parameter R_w = |Σ X_i| / Σ |X_i| "
            f"over all patches. Φ: {_rule_text(a)}; {a.get('n_bins')} phase bins on [−π, π)"
            + (", circular 3-bin Gaussian filter (σ = 1 bin)" if a.get("smooth", True) else ", no filter")
            + f"; τ_AB = {a.get('tau_ab')}, τ_BC = {a.get('tau_bc')}, w = {a.get('w')}. Band "
            f"{_hz(band[0])} – {_hz(band[1])}, Δf = {df:.4g} Hz; {a.get('patches')} patches × "
            f"{a.get('samples')} samples, Hann window; bins below max(10 Hz, 2 Δf) = {floor:.4g} Hz left out (the "
            f"window's leakage of the mean). {np.count_nonzero(valid)} of {f.size} bins shown have Φ ≥ 2, "
            f"{np.count_nonzero(above)} with S > S_null."
        )
        return run.save(fig, caption, outdir, "sync")


# -------------------------------------------------------------------------------------- STFT and CWT


def _normalised_map(amp: np.ndarray, freq: np.ndarray, top: float) -> tuple[np.ndarray, np.ndarray, float, tuple]:
    """Rows of ``amp`` up to ``top`` [Hz] divided by their maximum; returns (map, rows, max, (i_f, i_t))."""
    rows = np.flatnonzero(freq <= top)
    if rows.size == 0:
        rows = np.arange(freq.size)
    sub = np.asarray(amp[rows], dtype=np.float64)
    peak = float(np.nanmax(sub)) if sub.size else 0.0
    where = np.unravel_index(np.nanargmax(sub), sub.shape) if peak > 0 else (0, 0)
    return (sub / peak if peak > 0 else sub), rows, peak, where


def plot_stft(path: str | Path, outdir: str | Path) -> list[Path]:
    """μ(t) above its STFT amplitude, normalised to the maximum of the map shown (after Fig. 10)."""
    with _Run(path) as run:
        g = run.group("stft", lambda: report.compute_stft(run.f))
        assert g is not None
        top = run.band_top()
        amp, rows, peak, (i_f, i_t) = _normalised_map(g["amplitude"], g["freq"], top)
        freq, times = g["freq"][rows], g["time"]
        fig = _figure(5.6)
        ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[1.0, 2.0])
        t, mu = run.f["global/time"][()], run.f["global/mu"][()]
        tt, mm, _ = _envelope(t, mu)
        ax1.plot(tt * 1e3, mm, lw=0.6, color="k", rasterized=mm.size > 5000)
        ax1.set_ylabel("μ [1]")
        ax1.ticklabel_format(axis="y", useOffset=False)
        mesh = ax2.pcolormesh(
            times * 1e3, freq / 1e3, amp, shading="nearest", cmap="magma", vmin=0, vmax=1, rasterized=True
        )
        fig.colorbar(mesh, ax=[ax1, ax2], label="|S| / max |S| [1]", pad=0.01)
        ax2.set_ylabel("frequency f [kHz]")
        ax2.set_xlabel("time t [ms]")
        for ax in (ax1, ax2):
            ax.tick_params(labelsize=7)
        a = g.attrs
        caption = (
            "Friction coefficient μ(t), raw (top), and the amplitude of its short-time Fourier transform (bottom; "
            "after paper Fig. 10): " + str(a.get("window", "")) + f"; {a.get('resolution', '')}; "
            f"{a.get('detrend', '')}; one-sided, amplitude-true. Normalised to the maximum of the "
            f"map shown, |S| = {peak:.4g} at {freq[i_f] / 1e3:.4g} kHz, t = {times[i_t] * 1e3:.4g} ms; "
            f"f < {DEFAULT_FLOOR_HZ:g} Hz omitted, shown up to {freq[-1] / 1e3:.4g} kHz."
        )
        return run.save(fig, caption, outdir, "stft")


def plot_cwt(path: str | Path, outdir: str | Path) -> list[Path]:
    """CWT amplitude of μ(t) on a log frequency axis, normalised to its maximum (after Fig. 11)."""
    with _Run(path) as run:
        g = run.group("cwt", lambda: report.compute_cwt(run.f))
        assert g is not None
        amp, rows, peak, (i_f, i_t) = _normalised_map(g["amplitude"], g["freq"], np.inf)
        freq, times = g["freq"][rows], g["time"]
        fig = _figure(4.2)
        ax = fig.subplots()
        mesh = ax.pcolormesh(
            times * 1e3, freq / 1e3, amp, shading="nearest", cmap="magma", vmin=0, vmax=1, rasterized=True
        )
        ax.set_yscale("log")
        _plain_log(ax.yaxis)
        fig.colorbar(mesh, ax=ax, label="|W| / max |W| [1]", pad=0.01)
        ax.set_ylabel("frequency f [kHz]")
        ax.set_xlabel("time t [ms]")
        ax.tick_params(labelsize=7, which="both")
        a = g.attrs
        caption = (
            "Continuous wavelet transform of the friction coefficient μ(t) (after paper Fig. 11): "
            f"{a.get('wavelet', '')}; {a.get('normalisation', '')}; {a.get('mean_removed', '')}; "
            f"{a.get('resolution', '')}; {a.get('edges', '')}. {a.get('decimation', '')}. "
            f"Normalised to the global maximum |W| = {peak:.4g} at {freq[i_f] / 1e3:.4g} kHz, "
            f"t = {times[i_t] * 1e3:.4g} ms; {freq.size} log-spaced frequencies "
            f"{freq[0] / 1e3:.3g}–{freq[-1] / 1e3:.4g} kHz."
        )
        return run.save(fig, caption, outdir, "cwt")
