#!/usr/bin/env python3
"""The data-flow figure of docs/architecture.md: scene → model and state → engine → recorder → run file →
analysis → figures, with the LF automaton and the sweeps beside it.

The boxes name the modules of each stage; redraw after a module moves::

    python3 scripts/architecture_figure.py                  # writes docs/figures/architecture/data_flow.png
    python3 scripts/architecture_figure.py --out flow.png
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path as FilePath

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch
from matplotlib.path import Path

from aca_warp.common.argtypes import int_at_least

XLIM, YLIM = (0.0, 112.0), (-12.5, 95.5)  # drawing units (the axes' data coordinates), 10 to the inch
HF, LF, SWEEP, STUDY = "#dbe9f6", "#fde8cf", "#dff0d8", "#eeeeee"  # box colours of the three lanes and the studies

LANES = ((15, "LF automaton (lf/)", LF), (55, "HF run (hf/, kernels/)", HF), (95, "sweeps (sweep/)", SWEEP))
OUT = FilePath(__file__).resolve().parent.parent / "docs" / "figures" / "architecture" / "data_flow.png"

# name: (x centre, y centre, width, height, colour, title, body)
BOXES = {
    "scene": (55, 86, 38, 8, HF, "scene", "aca_warp.scene: a preset or TOML file → Scene (SI, validated)"),
    "model": (
        55,
        73,
        38,
        9,
        HF,
        "model + state",
        "hf.model.build_model: contact solve, neighbour CSR,\nper-pad parameters as flat Warp arrays;\n"
        "hf.state.initial_state",
    ),
    "engine": (
        55,
        59,
        38,
        10,
        HF,
        "engine, advanced by the one run loop",
        "hf.loop.run_hf over hf.general | hf.onchip |\nhf.onchip_adaptive, as hf.options.RunOptions say;\n"
        "the Warp kernels in kernels/",
    ),
    "recorder": (
        55,
        45,
        38,
        9,
        HF,
        "recorder",
        "hf.recorder.Recorder: global outputs per sample and pad,\nper-patch histories, watchdog; flushed in chunks",
    ),
    "runfile": (
        55,
        32,
        38,
        9,
        HF,
        "run file",
        "hf.runfile.RunWriter: HDF5, .partial until it ends;\ncheckpoints in common.checkpoint; hf.runner.run_scene",
    ),
    "analysis": (
        55,
        19,
        38,
        9,
        HF,
        "analysis",
        "analysis: analyze_run (aca-warp analyze): spectra,\nSTFT, CWT, Synchronization Index, saturation → /analysis",
    ),
    "figures": (
        55,
        6.5,
        38,
        7,
        HF,
        "figures",
        "plots.plot_run (aca-warp plot): the paper's Figs. 4-11",
    ),
    "lf_scene": (15, 86, 26, 8, LF, "LF scene", "lf.scene: pad, constants of\nthe rules, load schedule"),
    "lf_solver": (
        15,
        73,
        26,
        9,
        LF,
        "LF automaton",
        "lf.solver.LFSimulation\n(0.01 s steps), kernels/lf_*.py",
    ),
    "lf_file": (
        15,
        59,
        26,
        10,
        LF,
        "LF run file + snapshots",
        "lf.io.LFRunWriter; drawn by\nplots.plot_run, read by\ndataset.open_run",
    ),
    "spec": (95, 86, 30, 8, SWEEP, "sweep spec", "sweep.spec: TOML grid of scene\nparameters → pads in shards"),
    "shard": (
        95,
        66,
        30,
        12,
        SWEEP,
        "shards",
        "sweep.shard: batched pads\nthrough build_model and run_hf;\nsweep.run, sweep.overlap,\nsweep.cluster (Dask)",
    ),
    "shard_file": (
        95,
        45,
        30,
        9,
        SWEEP,
        "shard files + manifest",
        "shard-NNNNN.h5 (HF run-file\nlayout), sweep.manifest",
    ),
    "dataset": (
        95,
        25,
        30,
        9,
        SWEEP,
        "xarray Dataset",
        "dataset.open_run: HF, LF and\nshard files, units, long names",
    ),
    "studies": (
        55,
        -7,
        106,
        8,
        STUDY,
        "studies/: the paper's experiments",
        "hf_study, varying_area, multiscale, validation, work_precision, time_to_solution:\n"
        "scenes, runs (studies.runs), analysis and figures composed; results.md pages and JSON",
    ),
}

# (from, to, from side, to side, label, dashed, x of the vertical leg of a side-to-side arrow or None)
ARROWS = [
    ("scene", "model", "bottom", "top", "", False, None),
    ("model", "engine", "bottom", "top", "", False, None),
    ("engine", "recorder", "bottom", "top", "", False, None),
    ("recorder", "runfile", "bottom", "top", "chunks, to a sink", False, None),
    ("runfile", "analysis", "bottom", "top", "", False, None),
    ("analysis", "figures", "bottom", "top", "", False, None),
    ("lf_scene", "lf_solver", "bottom", "top", "", False, None),
    ("lf_solver", "lf_file", "bottom", "top", "", False, None),
    ("lf_file", "scene", "right", "left", "lf.io.scene_from_snapshot", False, 32.0),
    ("spec", "shard", "bottom", "top", "", False, None),
    ("shard", "model", "left", "right", "", True, 77.0),
    ("shard", "shard_file", "bottom", "top", "", False, None),
    ("shard_file", "dataset", "bottom", "top", "", False, None),
    ("runfile", "dataset", "right", "left", "", True, 77.0),
]


def _anchor(name: str, side: str) -> tuple[float, float]:
    """The middle of one side (top, bottom, left, right) of box ``name`` in drawing units."""
    x, y, w, h = BOXES[name][:4]
    return {"top": (x, y + h / 2), "bottom": (x, y - h / 2), "left": (x - w / 2, y), "right": (x + w / 2, y)}[side]


def draw() -> Figure:
    """The figure, on the Agg canvas."""
    fig = Figure(figsize=((XLIM[1] - XLIM[0]) / 10, (YLIM[1] - YLIM[0]) / 10))
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(*XLIM)
    ax.set_ylim(*YLIM)
    ax.axis("off")
    for x, y, w, h, colour, title, body in BOXES.values():
        ax.add_patch(
            FancyBboxPatch(
                (x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.4,rounding_size=1.2", fc=colour, ec="0.35", lw=0.8
            )
        )
        lines = body.count("\n") + 1
        ax.text(x, y + h / 2 - 1.6, title, ha="center", va="top", fontsize=9.5, weight="bold")
        ax.text(x, y - h / 2 + 1.0 + 0.2 * (3 - lines), body, ha="center", va="bottom", fontsize=7.2, linespacing=1.25)
    for a, b, sa, sb, label, dashed, via in ARROWS:
        p, q = _anchor(a, sa), _anchor(b, sb)
        points = [p, q] if via is None else [p, (via, p[1]), (via, q[1]), q]
        ax.add_patch(
            FancyArrowPatch(
                path=Path(points),
                arrowstyle="-|>",
                mutation_scale=11,
                lw=0.9,
                color="0.25",
                ls="--" if dashed else "-",
                shrinkA=3,
                shrinkB=3,
            )
        )
        if label:  # beside a straight arrow, or along the vertical leg of a routed one
            x, turn = (p[0] + 1.0, 0) if via is None else (via + 1.1, 90)
            ha = "left" if via is None else "center"
            ax.text(x, (p[1] + q[1]) / 2, label, fontsize=7, ha=ha, va="center", rotation=turn, style="italic")
    for x, text, colour in LANES:
        lane = {"fc": colour, "ec": "none", "boxstyle": "round,pad=0.3"}
        ax.text(x, 93, text, ha="center", va="center", fontsize=10, color="0.15", bbox=lane)
    return fig


def main(argv: list[str] | None = None) -> int:
    """Write the figure (PNG) to ``--out``."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=FilePath, default=OUT, help="PNG to write")
    p.add_argument("--dpi", type=int_at_least(1), default=110, help="resolution [dots per inch]")
    args = p.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    draw().savefig(args.out, dpi=args.dpi, metadata={"Software": None})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
