"""Figures of a run file after the paper's Figs. 4-11 (``aca-warp plot``; docs/analysis.md).

One public function per figure, each taking the run file and an output folder and returning the files
it wrote (a PNG and a PDF of the same figure, or a GIF for the animation):

===================  ==================================================================  =============
function             figure                                                              needs
===================  ==================================================================  =============
plot_patch_map       patch coverage state at chosen instants, coloured by u̇ (Figs. 4/6)   per-patch u̇
plot_global          μ, torque, friction radius, Σ|u̇| against time (Figs. 5/7)          -
plot_spectra         amplitude spectra of all global outputs (Fig. 8)                    -
plot_sync            Synchronization Index S(f) with Φ(f), null level, R_w (Fig. 9)     per-patch u̇
plot_stft            μ(t) and its STFT (Fig. 10)                                         -
plot_cwt             CWT of μ (Fig. 11)                                                   -
animate_patch_map    GIF of the patch coverage state over time (Pillow)                  per-patch u̇
===================  ==================================================================  =============

:func:`plot_run` makes every figure the file supports. Results stored under ``/analysis`` by
``aca-warp analyze`` are used when present; what is missing is computed on the fly (not written).
Figures are built on ``matplotlib.figure.Figure`` with the Agg canvas: pyplot's global state and the
interactive backend are never touched. Every figure carries a caption (what it shows, the normalisation)
and, in small print, the run's scene, integrator, precision and device.

Modules: :mod:`aca_warp.plots.hf` (the HF figures above), :mod:`aca_warp.plots.lf` (the figures of an LF run file,
which :func:`plot_run` makes for one), :mod:`aca_warp.plots.figure` (the scaffolding both share: Agg figure, caption
strip, PNG + PDF written whole, envelopes, pad outline).
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from aca_warp.analysis.groups import patch_rows
from aca_warp.analysis.report import MIN_SAMPLES, stored
from aca_warp.common.errors import SceneError, option
from aca_warp.common.files import all_or_nothing
from aca_warp.common.links import LinkError
from aca_warp.plots import lf as plots_lf
from aca_warp.plots.hf import (
    FIGURES,
    TRANSFORMS,
    _record_velocity,
    _Run,
    animate_patch_map,
    plot_cwt,
    plot_global,
    plot_patch_map,
    plot_spectra,
    plot_stft,
    plot_sync,
)

__all__ = [
    "FIGURES",
    "animate_patch_map",
    "plot_cwt",
    "plot_global",
    "plot_patch_map",
    "plot_run",
    "plot_spectra",
    "plot_stft",
    "plot_sync",
]


def _stderr(message: str) -> None:
    print(message, file=sys.stderr)


def _hf_figure_names(path: str | Path, which: Sequence[str] | None) -> list[str]:
    """The HF figures :func:`plot_run` makes, in order, without repeats; :class:`SceneError` for an LF figure name
    or an unknown one."""
    names = list(FIGURES if which is None else dict.fromkeys(which))
    lf_names = [n for n in names if n in plots_lf.LF_FIGURES]
    if lf_names:
        raise SceneError(
            f"{', '.join(lf_names)}: LF figures need an LF run file (aca-warp lf); {Path(path).name} is not one"
        )
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise SceneError(f"unknown figure(s) {', '.join(unknown)}; choose from {', '.join(FIGURES)}")
    return names


def _absent_figures(path: str | Path, names: list[str], which: Sequence[str] | None) -> dict[str, str]:
    """The figures of ``names`` the file cannot give, each with why: a record too short for the transforms, or
    per-patch velocities absent or too few for the per-patch figures (``sync`` also counts as present when
    ``/analysis/sync`` is stored); :class:`SceneError` when ``which`` named one of them."""
    with _Run(path, min_samples=2, needed_by="a figure") as run:
        rows = patch_rows(run.f)
        stored_sync = stored(run.f, "sync")
        samples = run.f["global/time"].shape[0]
    name = str(path)  # as given: a shard's pad in a temporary file is then named as the pad (analysis.commands)
    none = f"{name} holds no per-patch velocities"
    held = f"{rows} per-patch sample" + ("" if rows == 1 else "s")
    few = f"{name} holds {held}; the per-patch figures need at least {MIN_SAMPLES}"
    absent = {}
    for n in names:
        if n in TRANSFORMS and samples < MIN_SAMPLES:
            absent[n] = (
                f"{name} holds {samples} samples; spectra, time-frequency maps and S(f) need at least {MIN_SAMPLES}"
            )
        elif n in ("patch_map", "animation", "sync") and rows < MIN_SAMPLES and not (n == "sync" and stored_sync):
            absent[n] = none if rows == 0 else few
    if absent and which is not None:  # every reason, with the figures it keeps out
        reasons: dict[str, list[str]] = {}
        for n, why in absent.items():
            reasons.setdefault(why, []).append(n)
        said = "; ".join(f"{', '.join(ns)}: {why}" for why, ns in reasons.items())
        raise SceneError(f"{said}; {_record_velocity()}" if none in reasons else said)
    return absent


def plot_run(
    path: str | Path,
    outdir: str | Path,
    *,
    which: Sequence[str] | None = None,
    times: Sequence[float] | None = None,
    frames: int = 40,
    log: Callable[[str], None] | None = _stderr,
    quantity: str | None = None,
    snapshots: Sequence[str] | None = None,
) -> list[Path]:
    """Make every figure the run file supports (or those named in ``which``); returns the files written.

    An LF run file (root attribute ``kind = "lf"``) gets the LF figures instead (:func:`aca_warp.plots.lf.plot_lf_run`:
    ``which`` from :data:`aca_warp.plots.lf.LF_FIGURES`, ``quantity`` colours its patch map, ``snapshots`` selects
    its panels); ``times`` and ``frames`` apply to HF run files only, ``quantity`` and ``snapshots`` to LF ones.

    Figures whose data are absent (per-patch velocities for ``patch_map``, ``sync``, ``animation``; a
    record too short for a transform, a Synchronization Index of fewer than two bins) are skipped with a message to
    ``log`` when ``which`` is None; a figure named in ``which`` that cannot be made raises :class:`SceneError`, and
    the figures this call wrote before it are removed again and the earlier files they replaced put back (all or
    nothing, :func:`~aca_warp.common.files.all_or_nothing`; an interrupt likewise). A link planted where a figure's
    temporary file goes (:class:`~aca_warp.common.links.LinkError`) stops the call in either case.

    Args:
        path: Run file.
        outdir: Output folder (created if missing); files are named ``<run stem>_<figure>.png/.pdf``, the animation
            ``<run stem>_patch_map.gif``.
        which: Figure names from :data:`FIGURES` (default: all); one name may be given as a string.
        times: Instants of the patch map [s] (see :func:`plot_patch_map`).
        frames: Frames of the animation (see :func:`animate_patch_map`).
        log: Receives one line per skipped figure (None: silent).
    """
    if isinstance(which, str):  # one name, not its letters
        which = [which]
    if plots_lf.is_lf_file(path):
        if times is not None:
            raise SceneError(
                f"{Path(path).name} is an LF run file: choose its patch-map panels with "
                f"{option('snapshots=[…]', '--snapshots')}, not {option('times=[…]', '--times')}"
            )
        return plots_lf.plot_lf_run(
            path, outdir, which=which, quantity=quantity or "temperature", snapshots=snapshots, log=log
        )
    if quantity is not None or snapshots is not None:
        raise SceneError(f"{Path(path).name} is not an LF run file: quantity and snapshots apply to LF patch maps")
    names = _hf_figure_names(path, which)
    absent = _absent_figures(path, names, which)
    makers: dict[str, Callable[[], list[Path]]] = {
        "patch_map": lambda: plot_patch_map(path, outdir, times=times),
        "global": lambda: plot_global(path, outdir),
        "spectra": lambda: plot_spectra(path, outdir),
        "sync": lambda: plot_sync(path, outdir),
        "stft": lambda: plot_stft(path, outdir),
        "cwt": lambda: plot_cwt(path, outdir),
        "animation": lambda: animate_patch_map(path, outdir, frames=frames),
    }
    files: list[Path] = []
    with all_or_nothing() if which is not None else contextlib.nullcontext():  # figures asked for: all or nothing
        for name in names:
            if name in absent:
                if log:
                    log(f"skipped {name}: {absent[name]}")
                continue
            try:
                files += makers[name]()
            except SceneError as e:
                if isinstance(e, LinkError):  # a planted link stops the call, whatever was asked
                    raise
                if which is not None:
                    raise SceneError(f"{name}: {e}") from None
                if log:
                    log(f"skipped {name}: {e}")
    return files
