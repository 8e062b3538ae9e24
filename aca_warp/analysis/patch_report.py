"""The per-patch velocity groups of ``/analysis``: the mean per-patch velocity spectrum and the Synchronization Index
(paper §2.2, Fig. 9), and the leakage floor below which the figures and the ``analyze`` summary show no bin.

:func:`compute_patch_velocity` makes both groups in one pass over ``/patches/velocity``
(:func:`aca_warp.analysis.report.analyze_run` writes them as ``/analysis/patch_spectrum`` and ``/analysis/sync``);
:func:`sync_excess` is the summary's reading of S(f).
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np
import scipy.fft

from aca_warp.common.errors import SceneError, option

from .groups import DEFAULT_BAND_TOP, Group, has_patch_velocity, sample_interval
from .spectra import DEFAULT_FLOOR_HZ, complex_spectrum
from .sync import SyncResult, _patch_groups, sync_index, sync_index_from_signals

LEAKAGE_BINS = 2
"""Figures and the ``analyze`` summary leave out the lowest bins f < LEAKAGE_BINS·Δf (see :func:`leakage_floor`)."""
FEW_PERIODS = 20
"""At most this many periods of a frequency in the record (f / Δf): the ``analyze`` summary says that a start-up
transient or a drift shared by the patches can read as synchronised there, where the largest excess S sits at the
lowest bin counted."""


def bin_width(freq: np.ndarray, attrs: Any = None) -> float:
    """Δf [Hz] of a spectrum's bins ``freq``: 1 / (``samples`` × ``sample_interval``) where ``attrs`` (a group's
    attributes) hold both, as a band of a spectrum does (it may hold one bin only), else freq[1] − freq[0] (0 for a
    single bin)."""
    if attrs is not None and "samples" in attrs and "sample_interval" in attrs:
        n, dt = float(attrs["samples"]), float(attrs["sample_interval"])
        if n > 0 and dt > 0:
            return 1.0 / (n * dt)
    freq = np.asarray(freq, dtype=np.float64)
    return float(freq[1] - freq[0]) if freq.size > 1 else 0.0


def leakage_floor(freq: np.ndarray, attrs: Any = None) -> float:
    """Lowest frequency [Hz] the figures show and the ``analyze`` summary names: max(10 Hz, 2 Δf).

    ``freq``: a uniform frequency grid (Hz, any start); Δf from :func:`bin_width` (``attrs``: the attributes of the
    group ``freq`` belongs to). A periodic Hann window over the whole record puts the record's mean into bins 0 and
    1 (bin 1 at half its height); on a short record bin 1 lies inside the band, and there every patch's velocity
    spectrum holds its mean with one common phase, which makes S(f) ≈ 1 without any oscillation. 10 Hz is the
    paper's floor (Fig. 10).
    """
    return max(DEFAULT_FLOOR_HZ, LEAKAGE_BINS * bin_width(freq, attrs))


def shown_bins(freq: np.ndarray, attrs: Any = None) -> np.ndarray:
    """Boolean mask of the bins of ``freq`` at or above :func:`leakage_floor` (bin 2 itself is kept whatever the
    rounding of freq[1] − freq[0])."""
    freq = np.asarray(freq, dtype=np.float64)
    return freq >= leakage_floor(freq, attrs) * (1.0 - 1e-9)


def sync_excess(sync: Group) -> dict[str, Any] | None:
    """Where S(f) exceeds its null level most, over the bins the figures show (f ≥ :func:`leakage_floor`).

    Returns None when no such bin has Φ ≥ 2, else a dict: ``freq`` [Hz], ``S``, ``S_null``, ``Phi`` of the bin
    with the largest S − S_null; ``above`` (bins with S > S_null) and ``bins`` (bins with Φ ≥ 2), both counted
    over the shown bins; ``band`` [Hz] (the stored band, its lower edge raised to the floor), ``floor`` [Hz],
    ``periods`` (of that bin's frequency in the record: f / Δf) and ``lowest`` (whether it is the lowest bin counted).
    """
    freq, S, s0 = (np.asarray(sync[k], dtype=np.float64) for k in ("freq", "S", "S_null"))
    floor = leakage_floor(freq, sync.attrs)
    band = np.asarray(sync.attrs.get("band", [freq[0], freq[-1]]), dtype=np.float64)
    shown = shown_bins(freq, sync.attrs) & (freq >= float(band[0]))
    valid = shown & np.isfinite(S)
    if not valid.any():
        return None
    k = int(np.argmax(np.where(valid, S - s0, -np.inf)))
    return {
        "periods": float(freq[k] / bin_width(freq, sync.attrs)),
        "lowest": k == int(np.flatnonzero(valid)[0]),
        "freq": float(freq[k]),
        "S": float(S[k]),
        "S_null": float(s0[k]),
        "Phi": int(sync["Phi"][k]),
        "above": int(np.count_nonzero(S[valid] > s0[valid])),
        "bins": int(np.count_nonzero(valid)),
        "band": (max(floor, float(band[0])), float(band[1])),
        "floor": floor,
    }


def lowest_bin_remark(excess: dict[str, Any]) -> str:
    """The ``analyze`` summary's remark on the largest excess S (:func:`sync_excess`) where it sits at the lowest
    bin counted and the record holds at most :data:`FEW_PERIODS` periods of it; else ""."""
    if not (excess["lowest"] and excess["periods"] <= FEW_PERIODS):
        return ""
    return (
        f" (the lowest bin counted, {excess['periods']:.3g} periods in the record: there a start-up transient or a "
        "drift shared by the patches reads as synchronised as a vibration does; a longer record, or a higher "
        "--freq-min, tells them apart)"
    )


def _band(freq_range: tuple[float, float] | None, nyquist: float, top: float = DEFAULT_BAND_TOP) -> tuple[float, float]:
    """The per-patch analysis band [Hz]: ``freq_range`` (a None edge: 10 Hz, or min(``top``, ``nyquist``)) clipped
    to the per-patch record's Nyquist frequency ``nyquist`` [Hz]; one line when nothing of it is left."""
    lo, hi = (DEFAULT_FLOOR_HZ, min(top, nyquist)) if freq_range is None else freq_range
    lo = DEFAULT_FLOOR_HZ if lo is None else float(lo)
    hi = min(top, nyquist) if hi is None else min(float(hi), nyquist)
    if not hi > lo:
        skip = option("sync=False", "--no-sync")
        raise SceneError(
            f"empty frequency band {lo:g}-{hi:g} Hz for the per-patch velocities (the Nyquist frequency of their "
            f"record is {nyquist:g} Hz): lower the band's start, or leave them out ({skip})"
        )
    return lo, hi


def _band_rows(freq: np.ndarray, band: tuple[float, float]) -> slice:
    keep = np.flatnonzero((freq >= band[0]) & (freq <= band[1]))
    if keep.size == 0:
        raise SceneError(f"no frequency bin inside {band[0]:g}-{band[1]:g} Hz")
    return slice(int(keep[0]), int(keep[-1]) + 1)


def compute_patch_velocity(
    f: h5py.File,
    *,
    sync: bool = True,
    freq_range: tuple[float, float] | None = None,
    rule: str = "relative",
    eta: float = 0.1,
    snr: float = 5.0,
    n_bins: int = 180,
    null_trials: int = 100,
    max_bytes: int = 1 << 30,
    workers: int | None = -1,
) -> tuple[Group | None, Group | None]:
    """Per-patch velocity analysis: the mean amplitude spectrum and (``sync``) the Synchronization Index.

    One pass over ``/patches/velocity`` in patch-column groups of whole HDF5 chunks computes each patch's
    Hann complex spectrum (float32 in, complex64 out, 32 columns per FFT, the scaling of
    ``complex_spectrum``), adds |X_i(f)| to the mean amplitude spectrum and keeps the bins of the
    Synchronization Index band. When that band array would exceed ``max_bytes``, the Synchronization Index
    is computed by ``sync_index_from_signals`` instead (further passes, same results). The band defaults
    to 10 Hz – min(200 kHz, Nyquist).

    Returns:
        ``(patch_spectrum, sync)``, each None when the run holds no per-patch velocities (``sync`` also
        when not asked for).
    """
    if not has_patch_velocity(f):
        return None, None
    v = f["patches/velocity"]
    dt = sample_interval(f["patches/time"][()], "/patches/time")
    n, n_patches = v.shape
    freq_all = scipy.fft.rfftfreq(n, dt)
    band = _band(freq_range, 0.5 / dt)
    rows = _band_rows(freq_all, band)
    keep_band = sync and (rows.stop - rows.start) * n_patches * 8 <= max_bytes
    total, X = _patch_spectra(v, dt, rows if keep_band else None, max_bytes, workers)
    patch = Group(
        attrs={
            "quantity": "mean over all patches of the one-sided Hann amplitude spectra |X_i(f)| of the per-patch "
            "velocities (not normalised)",
            "window": f"periodic Hann window over the per-patch record ({n} samples, {n * dt:.6g} s)",
            "patches": n_patches,
            "sample_interval": dt,
        }
    )
    patch.add("freq", freq_all, "Hz")
    patch.add("mean_amplitude", total / n_patches, "m s-1", signal="/patches/velocity", normalisation="none")
    if not sync:
        return patch, None
    options = {"rule": rule, "eta": eta, "snr": snr, "n_bins": n_bins, "null_trials": null_trials}
    try:
        if X is not None:
            res = sync_index(X, freq=freq_all[rows], **options)
        else:
            res = sync_index_from_signals(v, dt, freq_range=band, max_bytes=max_bytes, workers=workers, **options)
    except ValueError as e:
        raise SceneError(f"Synchronization Index: {e}") from None
    del X
    return patch, _sync_group(res, band, dt, v.shape)


def _patch_spectra(
    v: h5py.Dataset, dt: float, band_rows: slice | None, max_bytes: int, workers: int | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """One pass over the per-patch velocities ``v`` (samples, patches) [m/s] sampled every ``dt`` [s].

    Reads patch-column groups of whole HDF5 chunks (at most ``max_bytes`` of float32 each) and computes each
    patch's Hann complex spectrum, 32 columns per FFT (``complex_spectrum``'s scaling).

    Returns:
        ``(total, X)``: total, shape (samples // 2 + 1,), the sum over patches of |X_i(f)| [m/s]; X, shape
        (rows of ``band_rows``, patches), complex64, the spectra's bins ``band_rows``, or None without them.
    """
    n, n_patches = v.shape
    X = None if band_rows is None else np.empty((band_rows.stop - band_rows.start, n_patches), dtype=np.complex64)
    group = max(1, max_bytes // (4 * n))
    if v.chunks and v.chunks[1] < n_patches:
        group = max(1, group // v.chunks[1]) * v.chunks[1]
    total = np.zeros(n // 2 + 1)  # one entry per bin of the one-sided spectrum
    for g0, block in _patch_groups(v, group):
        for c0 in range(0, block.shape[1], 32):
            x = np.asarray(block[:, c0 : c0 + 32], dtype=np.float32)
            _, spec = complex_spectrum(x, dt, axis=0, workers=workers)
            total += np.abs(spec).sum(axis=1, dtype=np.float64)
            if X is not None:
                X[:, g0 + c0 : g0 + c0 + spec.shape[1]] = spec[band_rows]
            del spec
    return total, X


def _sync_group(res: SyncResult, band: tuple[float, float], dt: float, shape: tuple[int, int]) -> Group:
    """``/analysis/sync`` from the Synchronization Index ``res`` of per-patch velocities of ``shape`` (samples,
    patches), sampled every ``dt`` [s], over ``band`` [Hz]."""
    n, n_patches = shape
    attrs: dict[str, Any] = dict(res.params)
    attrs.update(
        signal="/patches/velocity",
        band=[band[0], band[1]],
        band_unit="Hz",
        sample_interval=dt,
        samples=n,
        patches=n_patches,
        spectra="Hann-windowed one-sided complex spectra per patch (float32 in, complex64 out); phase arg X_i(f) "
        "referenced to the first per-patch sample",
        definition="paper §2.2 Eqs. 5-9 and Appendix; docs/analysis.md",
    )
    g = Group(attrs=attrs)
    g.add("freq", res.freq, "Hz")
    g.add("S", res.S, "1", meaning="Synchronization Index, Eq. 9 (NaN where Phi < 2)")
    g.add("S_AB", res.S_AB, "1", meaning="A/B contribution, Eq. 6")
    g.add("S_BC", res.S_BC, "1", meaning="B/C contribution, Eq. 8")
    g.add("Phi", res.Phi.astype(np.int64), "1", meaning=f"patches counted as oscillating ({res.rule} rule)")
    g.add("S_null", res.S_null, "1", meaning="mean S of Phi uniformly random phases (Monte-Carlo)")
    g.add("R_w", res.R_w, "1", meaning="|sum_i X_i| / sum_i |X_i| over all patches")
    return g


def compute_patch_spectrum(f: h5py.File, *, max_bytes: int = 1 << 30, workers: int | None = -1) -> Group | None:
    """Mean over patches of the per-patch velocity amplitude spectra (None without per-patch velocities)."""
    return compute_patch_velocity(f, sync=False, max_bytes=max_bytes, workers=workers)[0]


def compute_sync(f: h5py.File, **options: Any) -> Group | None:
    """Synchronization Index of the per-patch velocities (keywords of :func:`compute_patch_velocity`)."""
    return compute_patch_velocity(f, sync=True, **options)[1]
