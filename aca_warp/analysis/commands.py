"""The ``aca-warp analyze`` and ``aca-warp plot`` subcommands (registered by the ``aca-warp`` parser).

``add_parsers(sub)`` adds both to the ``add_subparsers`` object of the main parser; each sets
``handler`` (``set_defaults``), a function of the parsed arguments that returns the exit code and
raises :class:`aca_warp.common.errors.AcaError` subclasses for bad input (the main CLI prints one line and
exits 2). Heavy imports (SciPy, Matplotlib) happen inside the handlers, so ``--help`` stays fast. Both read and
write files only: they set ``uses_warp=False``, and the command line starts no Warp for them.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from aca_warp.common.argtypes import fraction, int_at_least, nonneg, positive
from aca_warp.common.errors import SceneError

FIGURE_NAMES = ("patch_map", "global", "spectra", "sync", "stft", "cwt", "animation")
"""HF figure names of ``plot --only`` (same as ``aca_warp.plots.FIGURES``, kept here to avoid importing Matplotlib)."""

LF_FIGURE_NAMES = ("lf_global", "lf_population", "lf_patch_map")
"""LF figure names of ``plot --only`` (same as ``aca_warp.plots.lf.LF_FIGURES``)."""

LF_QUANTITIES = ("temperature", "thickness", "normal_force", "pressure", "age", "power", "height", "area")
"""Colour quantities of the LF patch map (``plot --quantity``; keys of ``aca_warp.plots.lf.QUANTITIES``)."""

SYNC_OPTIONS = ("rule", "eta", "snr", "n_bins")
"""``analyze``'s options of the Synchronization Index (argparse destinations; None: not given)."""

ANALYZE_EPILOG = """\
Writes the group /analysis into RUN.h5, replacing an earlier one (computed first, swapped in at the end: a
failure leaves the file as it was):
  /analysis/spectra         Hann amplitude spectra of mu, torque, friction radius, sum u', sum |u'| and the
                            friction centroid (mean-normalised where the signal keeps one sign)
  /analysis/patch_spectrum  mean per-patch velocity amplitude spectrum          (with per-patch velocities)
  /analysis/stft, /cwt      time-frequency maps of mu
  /analysis/sync            Synchronization Index S(f), Phi(f), S_null(f), R_w(f) (with per-patch velocities)
  /analysis/peaks           attributes: first velocity-spectrum peak, largest mu peak (flagged when only a
                            band edge: no peak inside the band)
  /analysis/saturation      growth and saturation of sum |u'| and mu, beside the predicted growth rate
Units are SI: frequencies in Hz. See docs/analysis.md.
Example:  aca-warp analyze run.h5 --freq-max 150e3 --rule snr --snr 8
"""

PLOT_EPILOG = """\
Figures (PNG and PDF side by side), named <RUN stem>_<figure>.<ext>; the animation as <RUN stem>_patch_map.gif.
HF run files (aca-warp hf):
  patch_map  patch coverage state coloured by direction of motion (paper Figs. 4/6)  needs per-patch velocities
  global     mu, torque, friction radius, sum |u'| against time (Figs. 5/7)
  spectra    amplitude spectra of all global outputs (Fig. 8)
  sync       Synchronization Index against frequency (Fig. 9)                      needs per-patch velocities
  stft, cwt  time-frequency maps of mu (Figs. 10/11)
  animation  GIF of the patch coverage state                                       needs per-patch velocities
LF run files (aca-warp lf; recognised by their root attribute kind = "lf"):
  lf_global      clamp force, mu, torque, friction radius, disc and patch temperatures against time
  lf_population  patch count, coverage, load share, births/deaths/merges; debris and patch mass at snapshots
  lf_patch_map   one panel per snapshot: patches as discs (area ~ patch area) coloured by --quantity
Results of 'aca-warp analyze' are used when the file holds them; anything missing is computed on the fly
(not written). Without --only, figures the file cannot support are skipped with a note.
Examples: aca-warp plot run.h5 -o figures --only patch_map spectra --times 9.5e-4 9.6e-4
          aca-warp plot lf.h5 -o figures --only lf_patch_map --quantity thickness --snapshots app2_start app2_end
"""


def add_parsers(subparsers: Any) -> None:
    """Add ``analyze`` and ``plot`` to the ``add_subparsers()`` object of the ``aca-warp`` parser."""
    _add_analyze(subparsers)
    _add_plot(subparsers)


def _add_analyze(subparsers: Any) -> None:
    """Register ``aca-warp analyze``."""
    a = subparsers.add_parser(
        "analyze",
        aliases=["analyse"],
        help="spectra, time-frequency maps and Synchronization Index of a run file, into its /analysis group",
        description="Analyse a run file (paper §2.2, §3): amplitude spectra of the global outputs, STFT and CWT "
        "of mu, the first velocity-spectrum peak and, when the run recorded per-patch velocities, the "
        "Synchronization Index S(f) with the number of oscillating patches Phi(f), its random-phase null "
        "level and the order parameter R_w(f).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=ANALYZE_EPILOG,
    )
    a.add_argument("run", metavar="RUN.h5", help="HF run file written by 'aca-warp hf', or a sweep shard with --pad")
    a.add_argument(
        "--pad",
        type=int_at_least(0),
        metavar="K",
        help="RUN.h5 is a sweep shard: analyse its pad K (the pad's index in the sweep), written with its /analysis "
        "as the run file SHARD_padK.h5 beside the shard",
    )
    a.add_argument(
        "--freq-min",
        type=nonneg,
        metavar="HZ",
        help="lower band edge [Hz] of the Synchronization Index, the CWT and the peak search (default 10 Hz)",
    )
    a.add_argument(
        "--freq-max",
        type=positive,
        metavar="HZ",
        help="upper band edge [Hz] (default min(200 kHz, Nyquist frequency); with neither edge given the "
        "peak search covers 1 kHz to the Nyquist frequency)",
    )
    a.add_argument(
        "--rule",
        choices=("relative", "snr"),
        help="how Phi(f) counts a patch as oscillating at f: 'relative' |X_i(f)| >= eta * max_j |X_j(f)| "
        "(default), or 'snr' |X_i(f)| >= snr * median over f of |X_i|",
    )
    a.add_argument("--eta", type=fraction, metavar="X", help="eta of the relative rule (default 0.1)")
    a.add_argument("--snr", type=positive, metavar="X", help="factor of the snr rule (default 5)")
    a.add_argument("--n-bins", type=int_at_least(2), metavar="N", help="phase bins on [-pi, pi) (default 180)")
    a.add_argument(
        "--stft-window",
        type=positive,
        metavar="S",
        help="STFT window length [s], at least 4 samples and leaving at least 2 windows in the record (default, for "
        "N samples at dt: 2^round(log2(N/64)) samples, at least 16; if that gives df > 25 kHz, the next power of two "
        "up with df = 1/(samples dt) <= 25 kHz (df <= Nyquist/8 when the Nyquist frequency is below 200 kHz); at "
        "most the largest power of two <= N/2)",
    )
    a.add_argument(
        "--no-sync",
        action="store_true",
        help="do not read the per-patch velocities: no Synchronization Index and no mean per-patch spectrum "
        "(the slow part); the velocity peak then comes from the sum-of-velocities spectrum",
    )
    a.set_defaults(handler=cmd_analyze, uses_warp=False, command="analyze")  # the alias runs as analyze


def _add_plot(subparsers: Any) -> None:
    """Register ``aca-warp plot``."""
    p = subparsers.add_parser(
        "plot",
        help="figures of a run file (HF: patch map, global data, spectra, sync index, STFT, CWT, animation; LF: "
        "time series, patch population, snapshot patch maps)",
        description="Draw the paper-style figures of an HF run file (Merlis & Ostermeyer 2019, Figs. 4-11), or the "
        "time series and snapshot patch maps of an LF run file, as PNG and PDF, each captioned with what it shows, "
        "its normalisation and the run's device, integrator and precision.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=PLOT_EPILOG,
    )
    p.add_argument(
        "run", metavar="RUN.h5", help="run file written by 'aca-warp hf' or 'aca-warp lf', or a sweep shard with --pad"
    )
    p.add_argument(
        "--pad",
        type=int_at_least(0),
        metavar="K",
        help="RUN.h5 is a sweep shard: the figures of its pad K (the pad's index in the sweep; its /analysis from "
        "'analyze SHARD --pad K' where that ran), named SHARD_padK_<figure>",
    )
    p.add_argument(
        "-o", "--output-dir", required=True, metavar="DIR", help="folder for the figures (created if missing)"
    )
    p.add_argument(
        "--only",
        nargs="+",
        choices=FIGURE_NAMES + LF_FIGURE_NAMES,
        metavar="NAME",
        help=f"make only these figures: HF {', '.join(FIGURE_NAMES)}; LF {', '.join(LF_FIGURE_NAMES)}",
    )
    p.add_argument(
        "--times",
        nargs="+",
        type=nonneg,
        metavar="T",
        help="instants of the patch map [s] (nearest recorded sample; default: four quarter periods of the "
        "first velocity-spectrum peak at the end of the per-patch record)",
    )
    p.add_argument(
        "--quantity",
        choices=LF_QUANTITIES,
        metavar="NAME",
        help=f"LF patch map colour: {', '.join(LF_QUANTITIES)} (default temperature)",
    )
    p.add_argument(
        "--snapshots", nargs="+", metavar="NAME", help="LF patch map panels (default: every snapshot, in time order)"
    )
    p.set_defaults(handler=cmd_plot, uses_warp=False)


def cmd_analyze(args: argparse.Namespace) -> int:
    """``aca-warp analyze``: write /analysis and print a summary (the groups written, then a finding per line); 0 on
    success."""

    if args.freq_min is not None and args.freq_max is not None and args.freq_min >= args.freq_max:
        raise SceneError(f"--freq-min ({args.freq_min:g} Hz) must be below --freq-max ({args.freq_max:g} Hz)")
    _check_sync_options(args)
    band = None if args.freq_min is None and args.freq_max is None else (args.freq_min, args.freq_max)

    with run_or_pad(args, "analyze", keep=True) as run:
        return _analyze(args, run, band)


def _check_sync_options(args: argparse.Namespace) -> None:
    """Refuse options of the Synchronization Index that would not act: any of them with --no-sync, --snr with the
    relative rule, --eta with the snr rule."""
    given = [f"--{k.replace('_', '-')}" for k in SYNC_OPTIONS if getattr(args, k) is not None]
    if args.no_sync and given:
        them = "it" if len(given) == 1 else "them"
        raise SceneError(f"--no-sync computes no Synchronization Index: {', '.join(given)} would not act; drop {them}")
    if args.snr is not None and (args.rule or "relative") == "relative":
        raise SceneError("--snr is the factor of the snr rule: add --rule snr (the relative rule takes --eta)")
    if args.eta is not None and args.rule == "snr":
        raise SceneError("--eta is the fraction of the relative rule: the snr rule takes --snr")


def _analyze(args: argparse.Namespace, run: str, band: tuple[float | None, float | None] | None) -> int:
    """``aca-warp analyze`` of the run file ``run`` (RUN.h5, or the pad file of a shard's pad)."""
    from aca_warp.common.files import reading

    check_writable_file(run)  # first: a refusal imports no analysis code (SciPy)
    from aca_warp.analysis.report import analyze_run

    with reading(run, "run file"), storage_errors(f"/analysis into {run}", "the file keeps its samples"):
        groups = analyze_run(
            run,
            freq_range=band,
            sync=not args.no_sync,
            **{k: getattr(args, k) for k in SYNC_OPTIONS if getattr(args, k) is not None},  # else analyze_run's
            stft_window_s=args.stft_window,
        )
    parts = [f"{run}: /analysis written ({', '.join(groups)})"]
    if run != args.run:
        parts[0] = f"{run} (pad {args.pad} of {args.run}): /analysis written ({', '.join(groups)})"
    early = record_ends_early(run)
    if early:
        parts.append(early)
    above = above_nyquist(run, args.freq_max, patches="patch_spectrum" in groups)
    if above:
        parts.append(above)
    for key in ("below_band", "few_periods"):
        if key in groups["cwt"].attrs:
            freq = groups["cwt"]["freq"]
            parts.append(f"CWT over {freq[0] / 1e3:.4g}-{freq[-1] / 1e3:.4g} kHz: {groups['cwt'].attrs[key]}")
    parts += peak_lines(groups, freq_min=args.freq_min)
    if "sync" in groups:
        from aca_warp.analysis.report import LEAKAGE_BINS, lowest_bin_remark, sync_excess

        ex = sync_excess(groups["sync"])
        if ex is None:
            parts.append("no frequency bin with Phi >= 2 above the leakage floor: no Synchronization Index to report")
        else:
            lo, hi = ex["band"]
            parts.append(
                f"Synchronization Index over {lo / 1e3:.4g}-{hi / 1e3:.4g} kHz (the analysis band without the bins "
                f"below max(10 Hz, {LEAKAGE_BINS} df) = {ex['floor'] / 1e3:.4g} kHz, the Hann leakage of the mean, as "
                f"in the figures): S > S_null in {ex['above']} of {ex['bins']} bins with Phi >= 2, largest excess "
                f"S - S_null = {ex['S'] - ex['S_null']:.3f} (S {ex['S']:.3f}, S_null {ex['S_null']:.3f}, "
                f"Phi {ex['Phi']}) at {ex['freq'] / 1e3:.4g} kHz" + lowest_bin_remark(ex)
            )
    elif args.no_sync:
        parts.append("per-patch velocities not read (--no-sync)")
    else:
        parts.append("no per-patch velocities: Synchronization Index skipped")
    if "saturation" in groups:
        from aca_warp.analysis.report import saturation_summary

        parts.append(saturation_summary(groups["saturation"]))
    print("\n  ".join(parts))  # the file and what was written, then one finding per line
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    """``aca-warp plot``: draw the figures and list the files written; 0 on success. The output folder is checked
    first (not a file, writable: exit 4 for a read-only or full file system); a folder this command created is
    removed again when no figure was written into it; every figure is written whole (``aca_warp.plots.figure``)."""
    from pathlib import Path

    from aca_warp.common.files import check_output_folder, reading

    out = check_output_folder(args.output_dir)  # first: a refusal imports no plotting code (Matplotlib)
    created = not out.exists()
    from aca_warp.plots import plot_run

    shown: dict[str, str] = {}  # a shard's pad in a file of its own -> the pad as the user named it

    def note(message: str) -> None:
        for path, name in shown.items():
            message = message.replace(path, name)
        print(f"aca-warp plot: {message}", file=sys.stderr)

    kept = plot_leftovers(args.output_dir, bool(args.only))
    files: list[Path] = []
    try:
        with (
            run_or_pad(args, "plot", keep=False) as run,
            reading(run, "run file"),
            storage_errors(f"figures into {out}", kept),
        ):
            if args.pad is not None:
                shown[run] = f"pad {args.pad} of {args.run}"
            check_times_in_record(run, args.times, args.run if args.pad is None else f"pad {args.pad} of {args.run}")
            files = plot_run(
                run,
                out,
                which=args.only,
                times=args.times,
                log=note,
                quantity=args.quantity,
                snapshots=args.snapshots,
            )
    finally:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
    for f in files:
        print(f)
    if not files:
        raise SceneError(f"no figure could be made from {args.run}")
    return 0


def plot_leftovers(output_dir: str, only: bool) -> str:
    """What a ``plot`` stopped by an error or an interrupt leaves in ``output_dir``: with ``--only`` (all or
    nothing) none of its figures, and an earlier plot's figures it had replaced put back; else those finished."""
    if only:
        return (
            f"none of its figures is left in {output_dir} (--only: all or nothing; an earlier plot's figures it had "
            "replaced are back)"
        )
    return f"the figures finished before it are in {output_dir}, each whole, its PNG and PDF together"


def check_times_in_record(run: str, times: list[float] | None, name: str) -> None:
    """Refuse ``plot --times`` instants [s] outside the per-patch record of the run file ``run`` (``name``: the run
    as the user gave it) before any figure is drawn; a run without a readable per-patch time axis is left to the
    figures, which say what they need."""
    import h5py

    from aca_warp.analysis.groups import open_h5_run
    from aca_warp.plots.hf import check_instants

    if not times:
        return
    with open_h5_run(run) as f:
        pt = f.get("patches/time")
        if not isinstance(pt, h5py.Dataset) or pt.ndim != 1 or pt.shape[0] == 0 or pt.dtype.kind not in "fiu":
            return
        lo, hi = float(pt[0]), float(pt[-1])  # two values: the axis is read no further
    check_instants(times, lo, hi, name, "--times: instant")


@contextmanager
def run_or_pad(args: argparse.Namespace, command: str, *, keep: bool) -> Iterator[str]:
    """The run file ``command`` works on: ``args.run``, or for a sweep shard its pad ``args.pad`` as a run file
    (:mod:`aca_warp.analysis.pads`): with ``keep`` written beside the shard (``SHARD_padK.h5``, analyze), else that
    file where an earlier ``analyze --pad`` wrote it, or a temporary one (plot). A shard without ``--pad``, or
    ``--pad`` with a file that is no shard: one line."""
    import tempfile
    from pathlib import Path

    from aca_warp.analysis.groups import missing_run_message
    from aca_warp.analysis.pads import extracted_from, pad_run_path, shard_pads, shard_refusal, write_pad_run

    said = missing_run_message(args.run) if args.pad is None else None
    if said is not None:  # before any output check names its folder
        raise SceneError(said)
    pads = shard_pads(args.run)
    if pads is None:
        if not Path(args.run).exists():  # before any output check names its folder
            raise SceneError(
                f"{args.run} not found (--pad picks a pad of a sweep shard)"
                if args.pad is not None
                else f"run file not found: {args.run}"
            )
        if args.pad is not None:
            raise SceneError(f"--pad picks a pad of a sweep shard; {args.run} is not one")
        yield args.run
        return
    if args.pad is None:
        raise shard_refusal(args.run, pads, command)
    dest = pad_run_path(args.run, args.pad)
    if keep:
        existed = dest.exists()
        written = write_pad_run(args.run, args.pad, dest)
        try:
            yield str(written)
        except BaseException:
            if not existed:  # bad input (a record too short, say) leaves nothing behind
                written.unlink(missing_ok=True)
            raise
    elif dest.exists() and extracted_from(dest, args.run):
        yield str(dest)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            temporary = write_pad_run(args.run, args.pad, Path(tmp) / dest.name)
            try:
                yield str(temporary)
            except SceneError as e:  # name the pad as given, not the temporary file no one saw
                raise SceneError(str(e).replace(str(temporary), f"pad {args.pad} of {args.run}")) from None


def peak_lines(groups: dict[str, Any], freq_min: float | None = None) -> list[str]:
    """The ``analyze`` summary's lines on the first velocity-spectrum peak and the largest μ peak, from the groups
    :func:`~aca_warp.analysis.report.analyze_run` returns: each peak with the bin width and period count of the
    spectrum it comes from (the per-patch spectrum's own, which ``--patch-window``/``--patch-decimation`` may make
    coarser than the global record's), a peak that is only a band edge said to be one, and an empty peak search's
    band said with the edge that empties it (``freq_min``: ``--freq-min`` [Hz], None when not given). The velocity
    peak names its spectrum; one from the mean per-patch spectrum has Σu̇'s beside it, the spectrum the paper's
    Fig. 8 is read to plot (the two readings the paper leaves open: docs/analysis.md)."""
    from aca_warp.analysis.report import bin_width

    peaks, spectra = groups["peaks"].attrs, groups["spectra"]
    df = bin_width(spectra["freq"], spectra.attrs)
    lines = []
    if "first_velocity_peak_frequency" in peaks:
        f = float(peaks["first_velocity_peak_frequency"])
        patch = groups.get("patch_spectrum")
        from_patch = "patch_spectrum" in str(peaks.get("first_velocity_peak_source", ""))  # the peak's own record
        dfv = bin_width(patch["freq"], patch.attrs) if from_patch and patch is not None else df
        edge = _edge_clause(peaks.get("first_velocity_peak_at_band_edge"))
        line = f"first velocity-spectrum peak {f / 1e3:.4g} kHz{edge}{_few_periods(f, dfv)}"
        if not from_patch:
            line += ", of the Σu̇ spectrum (the paper's Fig. 8)"
        elif "sum_velocity_peak_frequency" in peaks:
            fs = float(peaks["sum_velocity_peak_frequency"])
            sum_edge = _edge_clause(peaks.get("sum_velocity_peak_at_band_edge"))
            other = f"{fs / 1e3:.4g} kHz{sum_edge}{_few_periods(fs, df)}"
            line += f", of the mean per-patch velocity spectrum; the Σu̇ spectrum's (the paper's Fig. 8): {other}"
        else:
            line += ", of the mean per-patch velocity spectrum"
        lines.append(line)
    else:
        lines.append(_no_peak_line(peaks["band"], df, freq_min))
    if "mu_peak_frequency" in peaks:
        f = float(peaks["mu_peak_frequency"])
        edge = _edge_clause(peaks.get("mu_peak_at_band_edge"))
        lines.append(f"largest mu peak {f / 1e3:.4g} kHz{edge}{_few_periods(f, df)}")
    return lines


def _no_peak_line(band: Any, df: float, freq_min: float | None) -> str:
    """The summary's line when the peak search's ``band`` [Hz] (its ``peaks`` attribute) held no velocity-spectrum
    peak; ``df``: the global spectra's bin width [Hz]; ``freq_min``: ``--freq-min`` [Hz] or None. An empty band is
    said with the edge that empties it: a ``--freq-min`` at or above the spectra's end, or the search's own start."""
    lo, hi = (float(v) for v in band)
    if lo < hi:
        return f"no velocity-spectrum peak in the peak search's band {lo / 1e3:.4g}-{hi / 1e3:.4g} kHz"
    if freq_min is not None and freq_min >= lo:
        return (
            f"no velocity-spectrum peak: --freq-min {freq_min:g} Hz lies at or above the global spectra's last bin, "
            f"{hi / 1e3:.4g} kHz, so the peak search's band is empty: lower --freq-min"
        )
    return (
        f"no velocity-spectrum peak: the peak search's band {lo / 1e3:.4g}-{hi / 1e3:.4g} kHz is empty (it starts "
        f"at max(1 kHz, 3 bins = {3 * df / 1e3:.4g} kHz), above the Hann leakage of the mean, and within "
        "--freq-min/--freq-max)"
    )


def _edge_clause(edge: object) -> str:
    """For a peak's ``<name>_peak_at_band_edge`` attribute (``"lower"``, ``"upper"`` or ``"no"``;
    :func:`aca_warp.analysis.report.band_edge`), the clause that says the band holds no peak; else ""."""
    if edge in ("lower", "upper"):
        return f" (at the band's {edge} edge: no peak inside the band)"
    return ""


def _few_periods(freq: float, df: float) -> str:
    """For a peak at ``freq`` [Hz] of which the record holds at most ``FEW_PERIODS`` periods (``freq / df``, ``df``
    [Hz] the spectra's bin width, 1 / record length: what the frequency is known to), the clause that says so;
    else ""."""
    from aca_warp.analysis.patch_report import FEW_PERIODS

    if not df > 0 or not 0 < freq / df <= FEW_PERIODS:
        return ""
    return f" (bins {df / 1e3:.3g} kHz wide: {freq / df:.3g} periods in the record)"


def above_nyquist(path: str, freq_max: float | None, *, patches: bool) -> str | None:
    """A line when ``--freq-max`` [Hz] lies above a Nyquist frequency (half the sampling rate) of the run's records,
    saying where each spectrum then ends: the global spectra at the global record's, and (``patches``: the analysis
    read the per-patch velocities) S(f) and the mean per-patch spectrum at the per-patch record's, which
    ``--patch-decimation`` makes lower; else None."""
    if freq_max is None:
        return None
    from aca_warp.analysis.groups import sample_interval
    from aca_warp.analysis.report import open_run_file

    with open_run_file(path) as f:
        top = 0.5 / sample_interval(f["global/time"][()])
        patch_top = 0.5 / sample_interval(f["patches/time"][()], "/patches/time") if patches else None
    said = f"--freq-max {freq_max:g} Hz lies above the Nyquist frequency (half the sampling rate)"
    samples, per_patch = f"of the global record, {top / 1e3:.4g} kHz", "S(f) and the per-patch spectrum"
    if patch_top is None or math.isclose(patch_top, top, rel_tol=1e-9):
        spectra = f"the global spectra, {per_patch}" if patches else "the global spectra"
        return f"{said} {samples}: {spectra} end there" if freq_max > top else None
    if freq_max <= patch_top:
        return None
    record = f"of the per-patch record, {patch_top / 1e3:.4g} kHz"
    if freq_max <= top:
        return f"{said} {record}: {per_patch} end there (the global spectra at {top / 1e3:.4g} kHz)"
    return f"{said} {samples}, and {record}: the global spectra end at the first, {per_patch} at the second"


def record_ends_early(path: str) -> str | None:
    """For a run that did not complete (interrupted, stopped on a fault, killed), where its record ends against the
    duration asked, in words; None for a complete run. A killed run (its file still marked running, no process
    writing it) is called so, with the command that continues it (which drops the analysis written here)."""
    import json

    import h5py

    from aca_warp.common.files import recovery

    with h5py.File(path, "r") as f:
        if bool(f.attrs.get("complete", True)):
            return None
        t = f["global/time"]
        end = float(t[-1]) if t.shape[0] else 0.0
        try:
            asked = json.loads(f.attrs["run_options"])["duration"]
        except (KeyError, TypeError, ValueError):
            asked = None
        status = str(f.attrs.get("status", "incomplete"))
    of = "" if asked is None else f" of the {float(asked):.4g} s asked"
    said = f"its record ends early, at t = {end:.4g} s{of}, and so does the analysis"
    if status.startswith("running"):  # no live process writes it (analyze_run holds its lock): the run was killed
        again = f"{recovery(path)} (the resume drops this analysis)"
        return f"the run is incomplete (killed: no process writes it): {said}; {again}"
    return f"the run is incomplete ({status}): {said}"


def check_writable_file(path: str) -> None:
    """``analyze`` writes into the run file: refuse one that cannot be opened for writing (read-only file system,
    no permission) before anything is computed, with exit 4. A missing file is left to the analysis' own message."""
    import os

    from aca_warp.common.errors import StorageError
    from aca_warp.common.files import UNWRITABLE

    if not os.path.isfile(path):
        return
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CLOEXEC)  # opens for writing, changes nothing
    except OSError as e:
        why = UNWRITABLE.get(e.errno or 0, e.strerror)
        raise StorageError(
            f"cannot write into {path} ({why}); analyze stores /analysis in the run file: copy it to a writable folder"
        ) from None
    os.close(fd)


@contextmanager
def storage_errors(what: str, kept: str) -> Iterator[None]:
    """Turn a full device, a file-size limit or a quota met while writing ``what`` into one StorageError line
    (exit 4) that says what is kept (``kept``)."""
    from aca_warp.common.errors import AcaError, StorageError
    from aca_warp.common.storage import STORAGE_ERRNOS, storage_errno

    try:
        yield
    except AcaError:
        raise
    except (OSError, RuntimeError) as e:
        code = storage_errno(e)
        if code is None:
            raise
        raise StorageError(f"{STORAGE_ERRNOS[code]} while writing {what}; {kept}") from None
