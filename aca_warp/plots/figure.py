"""Figure scaffolding shared by the HF figures (:mod:`aca_warp.plots.hf`) and the LF figures (:mod:`aca_warp.plots.lf`).

A constrained-layout ``matplotlib.figure.Figure`` on the Agg canvas (pyplot's global state and the interactive
backend are never touched), a caption strip with a small-print footer below it, PNG (150 dpi) and PDF output side
by side, min/max envelopes of long series and the annular-sector pad outline from a run file's scene.
"""

from __future__ import annotations

import math
import textwrap
import warnings
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aca_warp.common.files import whole

WIDTH = 9.0  # in
DPI = 150
CAPTION_PT = 8.0
FOOTER_PT = 6.5


def device_text(f: Any) -> str:
    """The device that made a run file, for a footer, the same for HF and LF files: ``cpu (Intel(R) Xeon(R)
    Processor, 2 cores)`` (the host's processor, attribute ``host``) or ``cuda:0 (NVIDIA H100 80GB HBM3)``
    (``device_name``); the bare alias where the file names nothing more (files of earlier versions)."""
    from aca_warp.analysis.report import run_attr

    device, name, host = (str(run_attr(f, k, "?")) for k in ("device", "device_name", "host"))
    if device.startswith("cpu") and host != "?":
        return f"{device} ({host})"
    return device if name in ("?", device, "CPU") or device.startswith("cpu") else f"{device} ({name})"


def new_figure(height: float, width: float = WIDTH) -> Figure:
    """A constrained-layout figure [in] on the Agg canvas (:func:`finish` adds the caption strip below it)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def finish(fig: Figure, caption: str, footer: str) -> None:
    """Grow ``fig`` by a bottom strip holding the wrapped ``caption`` and the small-print ``footer``."""
    lines = textwrap.wrap(caption, width=int(0.97 * fig.get_figwidth() * 72 / (CAPTION_PT * 0.52)))
    strip = (len(lines) * CAPTION_PT * 1.3 + FOOTER_PT * 1.5 + 12.0) / 72.0  # in
    h = fig.get_figheight()
    fig.set_figheight(h + strip)
    fig.get_layout_engine().set(rect=(0.0, strip / (h + strip), 1.0, h / (h + strip)))
    fig.text(0.012, (strip - 4.0 / 72.0) / (h + strip), "\n".join(lines), va="top", ha="left", fontsize=CAPTION_PT)
    fig.text(0.012, 3.0 / 72.0 / (h + strip), footer, va="bottom", ha="left", fontsize=FOOTER_PT, color="0.35")


def run_stem(path: str | Path) -> str:
    """The name a run file's figures start with: its name without ``.h5`` (and without ``.partial``, an unfinished
    run's)."""
    return Path(Path(path).name.removesuffix(".partial")).stem


def save(fig: Figure, outdir: Path, stem: str) -> list[Path]:
    """Write ``outdir/stem.png`` (150 dpi) and ``outdir/stem.pdf`` (folder created if missing), each whole
    (:func:`whole`) and the two together: both are drawn under temporary names before either takes its own (one
    rename after the other), so an interrupt while either is drawn leaves neither. Returns both paths. The PDF
    takes the layout the PNG's drawing settled (the constrained layout runs once per figure, not again at the PDF's
    72 dpi, where text metrics move the axes by up to ~0.4 % of the figure): the two files show the same layout,
    and the PDF costs ~15 % less time."""
    outdir.mkdir(parents=True, exist_ok=True)
    files = [outdir / f"{stem}.png", outdir / f"{stem}.pdf"]
    with whole(files[0], "temporary figure") as png, whole(files[1], "temporary figure") as pdf:
        fig.savefig(png, format="png", dpi=DPI)
        engine = fig.get_layout_engine()
        fig.set_layout_engine("none")
        try:
            fig.savefig(pdf, format="pdf")
        finally:
            fig.set_layout_engine(engine)
    return files


class GifInto(PillowWriter):
    """Matplotlib's Pillow GIF writer, writing into an open file (:func:`whole`) instead of reopening a name."""

    def __init__(self, fh: BinaryIO, fps: int) -> None:
        super().__init__(fps=fps)
        self.fh = fh

    def finish(self) -> None:
        self.outfile = self.fh  # Pillow takes the format from the file's name (.gif)
        super().finish()


def envelope(t: np.ndarray, y: np.ndarray, points: int = 4000) -> tuple[np.ndarray, np.ndarray, int]:
    """Min/max envelope of blocks so that at most ~``points`` are drawn; returns (t, y, block length).

    NaN samples are ignored within a block (a block of NaN stays NaN, so gaps stay gaps)."""
    n = y.size
    block = max(1, math.ceil(n / (points // 2)))
    if block <= 2:
        return t, y, 1
    m = n // block * block
    yb = y[:m].reshape(-1, block)
    tb = t[:m].reshape(-1, block)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN block: NaN, as wanted
        lo, hi = np.nanmin(yb, axis=1), np.nanmax(yb, axis=1)
    tt = np.repeat(tb.mean(axis=1), 2)
    yy = np.column_stack([lo, hi]).ravel()
    return tt, yy, block


def pad_outline(scene: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """Outline of the annular-sector pad [mm] from the run's scene attribute (dict), or None."""
    try:
        pad = scene["pad"]
        r0, r1, span = float(pad["r_inner"]), float(pad["r_outer"]), math.radians(float(pad["span_deg"]))
    except (KeyError, TypeError, ValueError):
        return None
    th = np.pi / 2 + np.linspace(-span / 2, span / 2, 200)
    th_all = np.concatenate([th, th[::-1], th[:1]])
    r = np.concatenate([np.full(200, r1), np.full(200, r0), [r1]])
    return 1e3 * r * np.cos(th_all), 1e3 * r * np.sin(th_all)
