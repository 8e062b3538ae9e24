"""Figures of an LF run file (``aca-warp plot LF.h5``; docs/analysis.md "LF figures"; layout in docs/lf_model.md).

===============  ===========================================================================================
name             figure
===============  ===========================================================================================
lf_global        clamp force, μ, friction torque, friction radius and temperatures against time, pauses shaded
lf_population    patch count, coverage and patch load share, cumulative births / deaths / merges; at the
                 snapshots the debris stored on the matrix, the mass bound in patches and the patch thickness
lf_patch_map     one panel per snapshot: every patch a disc of area ∝ its area at its position on the pad
                 outline, coloured by a chosen quantity (:data:`QUANTITIES`), one colour bar with its unit
===============  ===========================================================================================

:func:`plot_lf_run` makes them all (or those named); :func:`aca_warp.plots.plot_run` calls it for a file with the
root attribute ``kind = "lf"``; :func:`lf_figure` returns one as an unsaved Matplotlib figure. Files are
``<run stem>_<name>.png`` and ``.pdf``, drawn with the scaffolding of :mod:`aca_warp.plots.figure` (captions,
small-print footer, Agg canvas).
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.collections import EllipseCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from aca_warp.analysis.report import run_attr
from aca_warp.common.errors import SceneError
from aca_warp.common.files import all_or_nothing, open_h5, reading
from aca_warp.common.links import LinkError
from aca_warp.plots.figure import WIDTH, device_text, envelope, finish, new_figure, pad_outline, run_stem, save

LF_FIGURES = ("lf_global", "lf_population", "lf_patch_map")
"""LF figure names accepted by :func:`plot_lf_run` (``which``) and ``aca-warp plot --only``."""


@dataclass(frozen=True)
class Quantity:
    """A per-patch snapshot quantity the patch map can be coloured by.

    Attributes:
        label: Name on the colour bar.
        unit: Unit shown (after ``scale``).
        scale: Factor from the SI value in the file to the unit shown.
        cmap: Matplotlib colour map.
    """

    label: str
    unit: str
    scale: float
    cmap: str


QUANTITIES = {
    "temperature": Quantity("patch temperature T", "K", 1.0, "inferno"),
    "thickness": Quantity("patch thickness t", "µm", 1e6, "viridis"),
    "normal_force": Quantity("patch normal force F_N,i", "N", 1.0, "viridis"),
    "pressure": Quantity("patch contact pressure F_N,i / A_i", "MPa", 1e-6, "viridis"),
    "age": Quantity("patch age", "s", 1.0, "viridis"),
    "power": Quantity("patch friction power", "W", 1.0, "viridis"),
    "height": Quantity("patch top elevation (lowest element at 0)", "µm", 1e6, "viridis"),
    "area": Quantity("patch area A", "mm²", 1e6, "viridis"),
}
"""Quantities of ``--quantity`` (``/snapshots/NAME/patches/<name>``; ``pressure`` is normal_force / area)."""


class _LFRun:
    """An open LF run file with what every LF figure needs (path, scene, footer, snapshots)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.f = open_lf_file(self.path)
        scene = run_attr(self.f, "scene", {})
        self.scene = scene if isinstance(scene, dict) else {}
        self.name = str(run_attr(self.f, "scene_name", "") or self.scene.get("scene", {}).get("name", "?"))
        self.time = self.f["global/time"][()]

    def __enter__(self) -> _LFRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.f.close()

    def series(self, name: str) -> np.ndarray:
        return self.f[f"global/{name}"][()].astype(np.float64)

    @property
    def footer(self) -> str:
        a = {k: run_attr(self.f, k, "?") for k in ("precision", "status")}
        dt = self.scene.get("lf", {}).get("dt", "?")
        return (
            f"{self.path.name} · scene {self.name} · LF automaton, Δt = {dt} s · precision {a['precision']} · "
            f"device {device_text(self.f)} · run {a['status']}"
        )

    def snapshots(self) -> list[str]:
        """Snapshot names in time order."""
        g = self.f["snapshots"]
        return sorted(g, key=lambda n: float(g[n].attrs["time"]))

    def pad_area(self) -> float:
        """Pad area [m²] from the scene (NaN when the scene lacks the pad)."""
        try:
            pad = self.scene["pad"]
            return math.radians(float(pad["span_deg"])) / 2 * (float(pad["r_outer"]) ** 2 - float(pad["r_inner"]) ** 2)
        except (KeyError, TypeError, ValueError):
            return math.nan


def is_lf_file(path: str | Path) -> bool:
    """True when ``path`` is an HDF5 file with the root attribute ``kind = "lf"`` (False for anything else)."""
    p = Path(path)
    if not p.is_file() or not h5py.is_hdf5(p):
        return False
    try:
        with h5py.File(p, "r") as f:
            kind = f.attrs.get("kind")
    except OSError:
        return False
    return (kind.decode() if isinstance(kind, bytes) else kind) == "lf"


def open_lf_file(path: str | Path) -> h5py.File:
    """Open an LF run file read-only; :class:`SceneError` (one line) when it is missing or not an LF run file."""
    f = open_h5(path, "LF run file")
    lacks = [f"/global/{k}" for k in ("time", "mu", "normal_force") if f"global/{k}" not in f]
    lacks += ["/snapshots"] if "snapshots" not in f else []
    if run_attr(f, "kind") != "lf" or lacks:
        f.close()
        what = ", ".join(lacks) if lacks else "the root attribute kind = 'lf'"
        raise SceneError(f"{path} is not an LF run file (lacks {what})")
    return f


def _pauses(time: np.ndarray, load: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) [s] of the runs of steps without load (row k covers (t_k − Δt, t_k])."""
    if time.size == 0:
        return []
    dt = float(time[1] - time[0]) if time.size > 1 else float(time[0])
    idle = np.concatenate([[False], load == 0.0, [False]])
    edges = np.flatnonzero(np.diff(idle.astype(np.int8)))
    return [(float(time[a] - dt), float(time[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _stack(run: _LFRun, panels: int, height: float = 1.45) -> tuple[Any, np.ndarray, list[tuple[float, float]]]:
    """A figure of ``panels`` axes sharing the time axis [s], pauses shaded; returns (fig, axes, pauses)."""
    fig = new_figure(height * panels + 0.5)
    axes = np.atleast_1d(fig.subplots(panels, 1, sharex=True))
    pauses = _pauses(run.time, run.series("normal_force"))
    for ax in axes:
        for a, b in pauses:
            ax.axvspan(a, b, color="0.92", lw=0)
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3, alpha=0.5)
    axes[-1].set_xlabel("time t [s]")
    if run.time.size:
        axes[-1].set_xlim(min(0.0, float(run.time[0])), float(run.time[-1]))
    return fig, axes, pauses


def _line(ax: Any, t: np.ndarray, y: np.ndarray, **kw: Any) -> int:
    tt, yy, block = envelope(t, y)
    ax.plot(tt, yy, lw=0.8, **kw)
    return block


def _drawn(block: int) -> str:
    return "step by step" if block == 1 else f"as min/max envelopes of blocks of {block} steps"


def _draw_global(run: _LFRun) -> Figure:
    """Clamp force [N or kN], μ [1], friction torque [N m], friction radius [mm] and temperatures [K] against time [s].

    μ, torque and friction radius are 0 by convention while the pad is lifted (paper §2.1.2); they are not drawn
    there. The area-weighted patch temperature is not drawn while no patch is alive.
    """
    t, load = run.time, run.series("normal_force")
    lifted = load == 0.0
    fig, axes, pauses = _stack(run, 5)
    kilo = load.size > 0 and float(np.max(load)) >= 1e3
    block = _line(axes[0], t, load * (1e-3 if kilo else 1.0), color="k")
    axes[0].set_ylabel(f"clamp force F_N [{'kN' if kilo else 'N'}]", fontsize=8)
    for ax, (name, label, scale) in zip(
        axes[1:4],
        (("mu", "μ [1]", 1.0), ("torque", "friction torque T [N m]", 1.0), ("friction_radius", "r_eff [mm]", 1e3)),
        strict=True,
    ):
        _line(ax, t, np.where(lifted, np.nan, run.series(name) * scale), color="k")
        ax.set_ylabel(label, fontsize=8)
        ax.ticklabel_format(axis="y", useOffset=False)
    no_patch = run.series("patch_count") == 0 if "global/patch_count" in run.f else np.zeros(t.size, bool)
    for name, label, colour, hide in (
        ("disc_temperature_max", "disc, hottest ring", "tab:red", None),
        ("disc_temperature_mean", "disc, ring mean", "tab:orange", None),
        ("patch_temperature", "patches, area-weighted", "tab:blue", no_patch),
    ):
        if f"global/{name}" in run.f:
            y = run.series(name)
            _line(axes[4], t, y if hide is None else np.where(hide, np.nan, y), color=colour, label=label)
    axes[4].set_ylabel("temperature [K]", fontsize=8)
    axes[4].legend(fontsize=7, ncols=3, loc="best")
    caption = (
        "LF time series: clamp force F_N from the load schedule; global friction coefficient μ = total friction "
        "force / F_N; friction torque T about the disc axis; effective friction radius r_eff = T / total "
        "friction force; disc ring temperatures (mean and hottest of the radial rings) and the area-weighted "
        f"temperature of the alive patches. Grey bands: {len(pauses)} pause{'s' if len(pauses) != 1 else ''} "
        "(F_N = 0), where μ, T and r_eff are 0 by convention and not drawn. Raw values, one row per LF step "
        f"({t.size} steps), drawn {_drawn(block)}."
    )
    finish(fig, caption, run.footer)
    return fig


def _snapshot_masses(run: _LFRun) -> dict[str, np.ndarray]:
    """Per snapshot, in time order: time [s], stored debris Σ store [kg], patch mass Σ ρ_patch t A [kg], mean
    patch thickness (area-weighted) [m]."""
    rho = run.scene.get("lf", {}).get("rho_patch")
    out: dict[str, list[float]] = {"time": [], "store": [], "patch_mass": [], "thickness": []}
    for name in run.snapshots():
        g = run.f["snapshots"][name]
        area, thick = g["patches/area"][()], g["patches/thickness"][()]
        out["time"].append(float(g.attrs["time"]))
        out["store"].append(float(g["matrix/store"][()].sum()))
        out["patch_mass"].append(float(rho) * float(np.sum(area * thick)) if rho is not None else math.nan)
        out["thickness"].append(float(np.sum(area * thick) / area.sum()) if area.size else math.nan)
    return {k: np.asarray(v, dtype=np.float64) for k, v in out.items()}


def _draw_population(run: _LFRun) -> Figure:
    """Patch count, coverage and load share [%], cumulative births/deaths/merges against time [s]; with snapshots,
    the debris stored on the matrix and the mass bound in patches [µg] and the mean patch thickness [µm] there."""
    t = run.time
    snaps = _snapshot_masses(run)
    panels = 3 + (2 if snaps["time"].size else 0)
    fig, axes, _ = _stack(run, panels)
    block = _line(axes[0], t, run.series("patch_count"), color="k")
    axes[0].set_ylabel("alive patches [1]", fontsize=8)
    _line(axes[1], t, 100.0 * run.series("coverage"), color="k", label="coverage Σ A_i / pad area")
    _line(axes[1], t, 100.0 * run.series("patch_share"), color="tab:blue", label="patch share of F_N")
    axes[1].set_ylabel("[%]", fontsize=8)
    axes[1].legend(fontsize=7, ncols=2, loc="upper left")
    for name, colour in (("births", "tab:green"), ("deaths", "tab:red"), ("merges", "tab:purple")):
        axes[2].plot(t, np.cumsum(run.series(name)), lw=0.9, color=colour, label=name)
    axes[2].set_ylabel("cumulative count [1]", fontsize=8)
    axes[2].legend(fontsize=7, ncols=3, loc="upper left")
    more = ""
    if snaps["time"].size:
        st = snaps["time"]
        axes[3].plot(st, 1e9 * snaps["store"], "o-", ms=3, lw=0.8, color="tab:brown", label="stored on the matrix")
        axes[3].plot(st, 1e9 * snaps["patch_mass"], "s-", ms=3, lw=0.8, color="tab:blue", label="bound in patches")
        axes[3].set_ylabel("mass [µg]", fontsize=8)
        axes[3].margins(y=0.3)  # room for the legend beside a few markers (one snapshot: a single point)
        axes[3].legend(fontsize=7, ncols=2, loc="best")
        axes[4].plot(st, 1e6 * snaps["thickness"], "o-", ms=3, lw=0.8, color="k")
        axes[4].set_ylabel("mean patch\nthickness [µm]", fontsize=8)
        at = "the snapshot" if st.size == 1 else f"the {st.size} snapshots"
        more = (
            f" At {at} (markers): the debris stored on the matrix cells (Σ store), the mass "
            "bound in patches (Σ ρ_patch t_i A_i) and the area-weighted mean patch thickness, which patch wear "
            "lowers; the run file holds these at the snapshots only."
        )
    caption = (
        "LF patch population: alive patches; coverage (Σ patch area / pad area) and the patches' share of the "
        "clamp force; births, deaths (lower area or thickness limits, thermal destruction) and merges summed "
        f"from the start. Grey bands: pauses (F_N = 0). One row per LF step ({t.size} steps), drawn "
        f"{_drawn(block)}." + more
    )
    finish(fig, caption, run.footer)
    return fig


def _choose_snapshots(run: _LFRun, snapshots: Sequence[str] | None) -> list[str]:
    names = run.snapshots()
    if not names:
        raise SceneError(
            f"{run.path.name} holds no snapshots (the run ended before its first snapshot was due, or the LF scene's "
            "[snapshots] table asked for none)"
        )
    if snapshots is None:
        return names
    unknown = [s for s in snapshots if s not in names]
    if unknown:
        raise SceneError(f"no snapshot {', '.join(unknown)} in {run.path.name}; it has: {', '.join(names)}")
    return list(dict.fromkeys(snapshots))


def _patch_values(g: h5py.Group, quantity: str) -> np.ndarray:
    """The per-patch values of ``quantity`` in snapshot group ``g`` [SI]."""
    if quantity == "pressure":
        area = g["patches/area"][()]
        return g["patches/normal_force"][()] / np.where(area > 0, area, np.nan)
    return g[f"patches/{quantity}"][()]


_EDGE_PT = 0.4
"""Edge width [pt] of the patch discs: a patch far smaller than a pixel still shows as a dot."""


def _panel_grid(n: int, outline: tuple[np.ndarray, np.ndarray] | None) -> tuple[int, int, float]:
    """(rows, columns, panel height [in]) for ``n`` map panels of the pad's aspect ratio."""
    ncols = 1 if n == 1 else (2 if n <= 8 else 3)
    aspect = 0.5 if outline is None else float(np.ptp(outline[1]) + 4.0) / float(np.ptp(outline[0]) + 4.0)
    width = (WIDTH - 1.0) / ncols
    return math.ceil(n / ncols), ncols, float(np.clip(width * aspect, 1.2, 4.5)) + 0.6


def _disc_scale(run: _LFRun, diameters: list[np.ndarray]) -> float:
    """Magnification of the disc diameters: 1 (true size) unless the largest disc would be under ~85 % of the mean
    patch spacing; then so much that it is (all discs alike, so that disc area stays ∝ patch area)."""
    d = np.concatenate(diameters) if diameters else np.zeros(0)
    if d.size == 0 or not np.nanmax(d) > 0:
        return 1.0
    count = max(len(x) for x in diameters)
    spacing = math.sqrt(run.pad_area() / count) if math.isfinite(run.pad_area()) else float(np.nanmax(d))
    return max(1.0, 0.85 * spacing / float(np.nanmax(d)))


def _map_panel(
    ax: Any, g: h5py.Group, name: str, values: np.ndarray, grow: float, q: Quantity, norm: Normalize, run: _LFRun
) -> None:
    """One snapshot panel: the pad outline and every patch a disc of diameter ``grow``·2√(A/π) [mm] at (x, y)."""
    x, y = 1e3 * g["patches/x"][()], 1e3 * g["patches/y"][()]
    area = g["patches/area"][()]
    d = grow * 2e3 * np.sqrt(area / np.pi)
    outline = pad_outline(run.scene)
    if outline is not None:
        ax.plot(*outline, color="0.5", lw=0.6)
    ax.add_collection(
        EllipseCollection(
            d, d, np.zeros(d.size), units="xy", offsets=np.column_stack([x, y]), offset_transform=ax.transData,
            array=values, cmap=q.cmap, norm=norm, edgecolors="face", linewidths=_EDGE_PT,
        )
    )  # fmt: skip
    xs = np.concatenate([x, outline[0]]) if outline is not None else x
    ys = np.concatenate([y, outline[1]]) if outline is not None else y
    if xs.size:
        ax.set_xlim(xs.min() - 2.0, xs.max() + 2.0)
        ax.set_ylim(ys.min() - 2.0, ys.max() + 2.0)
    ax.set_aspect("equal")
    load = float(g.attrs["normal_force"])
    load_text = f"{load / 1e3:.4g} kN" if load >= 1e3 else f"{load:.4g} N"
    ax.set_title(
        f"{name}\nt = {float(g.attrs['time']):.4g} s, F_N = {load_text}, {x.size} patches "
        f"({100.0 * float(area.sum()) / run.pad_area():.3g} %)",
        fontsize=7.5,
    )
    ax.set_xlabel("x [mm]", fontsize=7)
    ax.set_ylabel("y [mm]", fontsize=7)
    ax.tick_params(labelsize=6.5)


def _draw_patch_map(run: _LFRun, quantity: str, snapshots: Sequence[str] | None) -> Figure:
    """Patch maps of the snapshots (``snapshots``, default all in time order): one panel each, one colour scale."""
    if quantity not in QUANTITIES:
        raise SceneError(f"unknown quantity {quantity!r}; choose from {', '.join(QUANTITIES)}")
    q = QUANTITIES[quantity]
    names = _choose_snapshots(run, snapshots)
    groups = [run.f["snapshots"][n] for n in names]
    values = [q.scale * _patch_values(g, quantity) for g in groups]
    finite = np.concatenate([v[np.isfinite(v)] for v in values])
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    norm = Normalize(lo, hi if hi > lo else lo + max(abs(lo), 1.0) * 1e-6)
    grow = _disc_scale(run, [2e3 * np.sqrt(g["patches/area"][()] / np.pi) for g in groups])
    rows, ncols, h = _panel_grid(len(names), pad_outline(run.scene))
    fig = new_figure(rows * h + 0.3)
    axes = np.atleast_1d(fig.subplots(rows, ncols, squeeze=False)).ravel()
    for ax, name, g, v in zip(axes, names, groups, values, strict=False):
        _map_panel(ax, g, name, v, grow, q, norm, run)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    fig.colorbar(
        ScalarMappable(norm=norm, cmap=q.cmap), ax=list(axes), label=f"{q.label} [{q.unit}]", location="bottom",
        shrink=0.6, aspect=40, pad=0.02,
    )  # fmt: skip
    size = (
        "at their true size" if grow == 1.0 else f"enlarged {grow:.3g}× in diameter for visibility (not to scale)"
    ) + f", outlined by a {_EDGE_PT:g} pt edge so that the smallest stay visible"
    caption = (
        f"LF snapshots ({len(names)}): every alive patch a disc at its centre (x, y) [mm] on the pad outline "
        f"(grey), disc area proportional to the patch area, {size}; coloured by the {q.label} [{q.unit}] on one "
        f"scale for all panels ({lo:.4g}–{hi:.4g} {q.unit}). Titles: snapshot time, clamp force, patch count and "
        "(in brackets) the fraction of the pad area the patches cover. The snapshots are the states HF runs "
        "start from (aca-warp hf LF.h5 --snapshot NAME)."
    )
    finish(fig, caption, run.footer)
    return fig


def lf_figure(
    path: str | Path, name: str, *, quantity: str = "temperature", snapshots: Sequence[str] | None = None
) -> Figure:
    """The LF figure ``name`` (one of :data:`LF_FIGURES`) of an LF run file as a Matplotlib Figure, not saved.

    Args:
        path: LF run file.
        name: ``lf_global``, ``lf_population`` or ``lf_patch_map``.
        quantity: Colour of the patch map, a key of :data:`QUANTITIES`.
        snapshots: Panels of the patch map: snapshot names (default every snapshot, in time order).
    """
    if name not in LF_FIGURES:
        raise SceneError(f"unknown LF figure {name!r}; choose from {', '.join(LF_FIGURES)}")
    with _LFRun(path) as run:
        if name == "lf_global":
            return _draw_global(run)
        if name == "lf_population":
            return _draw_population(run)
        return _draw_patch_map(run, quantity, snapshots)


def plot_lf_global(path: str | Path, outdir: str | Path) -> list[Path]:
    """Clamp force, μ, friction torque, friction radius and temperatures against time (PNG + PDF in ``outdir``)."""
    return save(lf_figure(path, "lf_global"), Path(outdir), f"{run_stem(path)}_lf_global")


def plot_lf_population(path: str | Path, outdir: str | Path) -> list[Path]:
    """Patch count, coverage, load share, life-cycle counts; debris, patch mass and thickness at the snapshots."""
    return save(lf_figure(path, "lf_population"), Path(outdir), f"{run_stem(path)}_lf_population")


def plot_lf_patch_map(
    path: str | Path, outdir: str | Path, *, quantity: str = "temperature", snapshots: Sequence[str] | None = None
) -> list[Path]:
    """Patch maps of the snapshots coloured by ``quantity`` (:func:`lf_figure`), PNG + PDF in ``outdir``."""
    fig = lf_figure(path, "lf_patch_map", quantity=quantity, snapshots=snapshots)
    return save(fig, Path(outdir), f"{run_stem(path)}_lf_patch_map")


def _stderr(message: str) -> None:
    print(message, file=sys.stderr)


def plot_lf_run(
    path: str | Path,
    outdir: str | Path,
    *,
    which: Sequence[str] | None = None,
    quantity: str = "temperature",
    snapshots: Sequence[str] | None = None,
    log: Callable[[str], None] | None = _stderr,
) -> list[Path]:
    """Make every LF figure (or those named in ``which``, from :data:`LF_FIGURES`); returns the files written.

    Without ``which``, the patch map of a file without snapshots is skipped with a message to ``log``; a figure
    named in ``which`` that cannot be made, an unknown name, quantity or snapshot raise :class:`SceneError`
    before anything is written. A figure that fails while it is drawn (a damaged group of the file) is skipped with
    a message to ``log`` when ``which`` is None; when ``which`` names figures, its error is raised and the figures
    this call wrote before it are removed again and the earlier files they replaced put back (all or nothing), as for
    HF run files
    (:func:`~aca_warp.plots.plot_run`).
    """
    names = list(LF_FIGURES if which is None else dict.fromkeys(which))
    unknown = [n for n in names if n not in LF_FIGURES]
    if unknown:
        raise SceneError(
            f"{Path(path).name} is an LF run file; its figures are {', '.join(LF_FIGURES)} (not {', '.join(unknown)})"
        )
    if quantity not in QUANTITIES:
        raise SceneError(f"unknown quantity {quantity!r}; choose from {', '.join(QUANTITIES)}")
    maps, reason = True, ""
    with _LFRun(path) as run:
        try:
            _choose_snapshots(run, snapshots)
        except SceneError as e:
            if (which is not None and "lf_patch_map" in names) or snapshots is not None:
                raise
            maps, reason = False, str(e)
    makers: dict[str, Callable[[], list[Path]]] = {
        "lf_global": lambda: plot_lf_global(path, outdir),
        "lf_population": lambda: plot_lf_population(path, outdir),
        "lf_patch_map": lambda: plot_lf_patch_map(path, outdir, quantity=quantity, snapshots=snapshots),
    }
    files: list[Path] = []
    with all_or_nothing() if which is not None else contextlib.nullcontext():  # figures asked for: all or nothing
        for name in names:
            if name == "lf_patch_map" and not maps:
                if log:
                    log(f"skipped lf_patch_map: {reason}")
                continue
            try:
                with reading(path, "run file"):  # a damaged group: one SceneError line naming the file
                    files += makers[name]()
            except SceneError as e:
                if isinstance(e, LinkError) or which is not None:  # a planted link stops the call, whatever was asked
                    raise
                if log:
                    log(f"skipped {name}: {e}")
    return files
