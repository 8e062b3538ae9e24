"""What the studies share: Warp set-up, the measure-or-report command line, progress lines, the command that
reproduces a study, number formats, markdown tables, JSON files, the generated section of a docs page and figures
saved as PNG + PDF.

Figures are built on ``matplotlib.figure.Figure`` with the Agg canvas (as in :mod:`aca_warp.plots`): pyplot's
global state and an interactive backend of the caller (a notebook) are never touched.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from matplotlib.figure import Figure

NO_VALUE = "–"
"""What tables and captions show for a number that was not measured (None or not finite)."""


# ------------------------------------------------------------------------------------------------ set-up


def init_warp() -> ModuleType:
    """Import and initialise Warp with warnings only (no kernel-compile chatter, no note of a missing CUDA driver
    unless asked: :func:`aca_warp.common.devices.init_warp`); returns the module."""
    import warp as wp

    from aca_warp.common.devices import init_warp as init_quietly

    wp.config.quiet = True
    init_quietly()
    return wp


def add_device(parser: argparse.ArgumentParser, default: str = "cpu", help: str | None = None) -> None:
    """``--device``: the Warp device of a study's simulations."""
    parser.add_argument("--device", default=default, help=help or f"Warp device: cpu or cuda:N (default {default})")


def add_page_options(parser: argparse.ArgumentParser, page: str, figures: str) -> None:
    """``--page`` (docs page whose generated section a report rewrites) and ``--figures`` (its figure folder)."""
    parser.add_argument("--page", default=page, help=f"docs page whose generated section is rewritten ({page})")
    parser.add_argument("--figures", default=figures, help=f"figure folder ({figures})")


def measure_or_report(
    parser: argparse.ArgumentParser,
    argv: Sequence[str] | None,
    report: Callable[[argparse.Namespace], object],
    measure: Callable[[argparse.Namespace, list[str]], object],
) -> int:
    """The command line of a study that measures, or with ``--report`` only writes its page from result files:
    parses ``argv`` (``sys.argv[1:]`` when None) with ``parser``, then ``report(args)``; else Warp is initialised
    (:func:`init_warp`) and ``measure(args, argv)`` runs (``argv`` for the results' :func:`command_line`).
    Returns 0; before anything is written, one line on stderr and exit code 2 (4: an output that takes no file)
    for a --report file that is not there or (raised by ``report``) not this study's results, a page or figure
    folder that cannot be written, an absent ``--device`` or an ``--out`` folder that cannot be made."""
    from aca_warp.common.devices import get_device
    from aca_warp.common.errors import AcaError, SceneError
    from aca_warp.common.errors import command_line as command_line_flags
    from aca_warp.common.files import check_output_folder, check_output_path

    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    try:
        with command_line_flags():
            if args.report:
                for path in args.report:
                    if not Path(path).is_file():
                        raise SceneError(f"--report: no result file {path}")
                check_output_path(args.page, overwrite=True)
                check_output_folder(args.figures)
            else:
                get_device(args.device)
                check_output_folder(args.out)
    except AcaError as e:
        print(f"{parser.prog}: error: {e}", file=sys.stderr)
        return e.exit_code
    if args.report:
        try:
            report(args)
        except (ValueError, KeyError, TypeError, IndexError) as e:  # JSON that is not this study's results
            print(f"{parser.prog}: error: --report: not a result file of this study ({type(e).__name__}: {e})",
                  file=sys.stderr)  # fmt: skip
            return 2
        return 0
    init_warp()
    measure(args, argv)
    return 0


def command_line(script: str, argv: Sequence[str]) -> str:
    """The command that reproduces a study run with ``argv``: ``python3 scripts/<script> ARGS`` (shell-quoted)."""
    return " ".join(["python3", f"scripts/{script}", *(shlex.quote(a) for a in argv)])


class Log:
    """Progress lines on stdout, each with the wall time since the log was made."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()

    def elapsed(self) -> float:
        """Seconds since the log was made."""
        return time.perf_counter() - self.t0

    def __call__(self, message: str) -> None:
        print(f"[{self.elapsed():7.1f} s] {message}", flush=True)


# ------------------------------------------------------------------------------------------------ numbers


def num(v: Any) -> float:
    """``v`` as a float, NaN for None."""
    return float("nan") if v is None else float(v)


def fmt(v: Any, spec: str = ".3g") -> str:
    """``v`` formatted with ``spec`` (integers as they are), :data:`NO_VALUE` for None or a non-finite value."""
    if v is None:
        return NO_VALUE
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(int(v))
    v = float(v)
    return NO_VALUE if not math.isfinite(v) else format(v, spec)


def unsigned_zero(text: str) -> str:
    """``text`` (a formatted number) without the sign of a value that rounds to zero: "0", not "-0"."""
    mantissa = text.split("e")[0]
    return text[1:] if text.startswith("-") and not any(c in "123456789" for c in mantissa) else text


def fmt_hz(v: Any) -> str:
    """A frequency [Hz] in kHz with one decimal, :data:`NO_VALUE` for None or a non-finite value."""
    v = num(v)
    return NO_VALUE if not math.isfinite(v) else f"{v / 1e3:.1f} kHz"


def md_table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    """A markdown table: header line, separator, one line per row; a ``|`` inside a cell is escaped."""

    def cell(value: Any) -> str:
        text = str(value).replace("|", "\\|")
        return f" {text} " if text else " "

    def line(cells: Sequence[Any]) -> str:
        return "|" + "|".join(cell(c) for c in cells) + "|"

    return [line(header), "|" + "---|" * len(header), *(line(r) for r in rows)]


# ------------------------------------------------------------------------------------------------ files


def clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars and arrays to Python, non-finite floats to None, paths to str."""
    if isinstance(obj, dict):
        return {str(k): clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return clean(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _to_json(obj: Any) -> Any:
    """``json.dumps`` fallback: numpy scalars and arrays, paths."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def write_json(path: Path, obj: Any, indent: int = 1) -> Path:
    """Write ``obj`` (numpy scalars and arrays allowed; NaN stays NaN, see :func:`clean`) as UTF-8 JSON."""
    path.write_text(json.dumps(obj, indent=indent, ensure_ascii=False, default=_to_json) + "\n")
    return path


def generated_markers(command: str) -> tuple[str, str]:
    """The comment lines that enclose the part of a docs page ``command`` writes."""
    return f"<!-- BEGIN GENERATED ({command}) -->", "<!-- END GENERATED -->"


def replace_generated(page: Path, body: Sequence[str], markers: tuple[str, str], title: str) -> None:
    """Rewrite the part of ``page`` between ``markers`` with the lines ``body``; the rest of the page stays.

    A missing page is created as ``# title`` and the markers; a page without the begin marker gets them appended.
    """
    begin, end = markers
    text = page.read_text() if page.exists() else f"# {title}\n\n{begin}\n{end}\n"
    if begin not in text:
        text += f"\n{begin}\n{end}\n"
    head, rest = text.split(begin, 1)
    tail = rest.split(end, 1)[1] if end in rest else ""
    page.write_text(head + "\n".join([begin, *body, end]) + tail)


# ------------------------------------------------------------------------------------------------ figures


def figure(**kwargs: Any) -> Figure:
    """A Matplotlib figure on the Agg canvas (``kwargs`` as ``Figure``); nothing to close afterwards."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def save_figure(
    fig: Figure, folder: Path, stem: str, *, dpi: float = 110, formats: Sequence[str] = ("png", "pdf")
) -> list[Path]:
    """Write ``fig`` as ``folder/stem.<format>`` for each of ``formats`` (folder created); returns the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"{stem}.{ext}" for ext in formats]
    for p in paths:
        fig.savefig(p, dpi=dpi)
    return paths
