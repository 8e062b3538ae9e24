"""Synchronization Index S(f) of many oscillating patches (paper §2.2, Eqs. 5-9, Appendix; docs/model.md §3.3).

Per frequency bin f of the per-patch spectra X_i(f):

1. Φ(f) patches are counted as oscillating at f by a selectable rule (docs/model.md §3.3, step 1).
2. Their phases arg X_i(f) are binned into ``n_bins`` equal bins on [-π, π) (+π falls into
   the first bin); G = counts per bin, Φ = ΣG. S is undefined (NaN) for Φ < 2.
3. Optionally, G is smoothed by a circular 3-bin moving average with Gaussian weights
   (σ = one bin): e^(-1/2) : 1 : e^(-1/2), normalised to sum 1.
4. The (smoothed) bins are sorted descending, G_1 ≥ G_2 ≥ ...; n_AB is the smallest fractional
   n whose cumulative sum reaches τ_AB·Φ, with element precision n = k + (τΦ - C_k)/G_(k+1)
   (C_k the sum of the k largest); n_BC likewise with τ_BC.
5. n_max = τ·n_bins (uniform phases); n_min = the count for all Φ phases in one bin, after
   the filter when it is used (τ without it). S_AB = (n_AB,max - n_AB)/(n_AB,max - n_AB,min),
   S_BC likewise, S = w·S_AB + (1 - w)·S_BC.

Also reported: a Monte-Carlo null level (mean S of Φ uniformly random phases) and the
amplitude-weighted order parameter R_w(f) = |Σ_i X_i| / Σ_i |X_i| over all patches.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

import numpy as np
import scipy.fft

from .spectra import complex_spectrum

_EDGE = np.exp(-0.5)
SMOOTHING_WEIGHTS = np.array([_EDGE, 1.0, _EDGE]) / (1.0 + 2.0 * _EDGE)
"""Weights of the circular 3-bin Gaussian moving average (σ = one bin), previous:own:next."""

SNR_REFERENCE = "median of |X_i| over all analysed frequency bins of patch i"
"""Noise floor of patch i used by the ``"snr"`` rule (one value per patch, not a local band)."""


class SyncBins(NamedTuple):
    """ABC analysis of phase-bin counts (shapes: the leading shape of G, scalars for 1-D G).

    Attributes:
        S: Synchronization Index, Eq. 9 (NaN where Φ < 2).
        S_AB: A/B contribution, Eq. 6.
        S_BC: B/C contribution, Eq. 8.
        n_AB: Fractional bin count reaching τ_AB·Φ, Eq. 5 [bins].
        n_BC: Fractional bin count reaching τ_BC·Φ, Eq. 7 [bins].
        n_AB_max: Bound for uniform phases, τ_AB·n_bins [bins] (float).
        n_AB_min: Bound for all phases in one bin [bins] (float).
        n_BC_max: As n_AB_max with τ_BC [bins] (float).
        n_BC_min: As n_AB_min with τ_BC [bins] (float).
    """

    S: np.ndarray
    S_AB: np.ndarray
    S_BC: np.ndarray
    n_AB: np.ndarray
    n_BC: np.ndarray
    n_AB_max: float
    n_AB_min: float
    n_BC_max: float
    n_BC_min: float


@dataclass(frozen=True)
class SyncResult:
    """Synchronization analysis of per-patch spectra; every array has shape (F,).

    Attributes:
        freq: Frequencies of the analysed bins [Hz], or None if they were not given.
        S: Synchronization Index (NaN where Φ < 2).
        S_AB: A/B contribution to S.
        S_BC: B/C contribution to S.
        Phi: Number of patches counted as oscillating (Φ), int.
        S_null: Mean S of Φ uniformly random phases (Monte-Carlo; NaN where Φ < 2 or disabled).
        R_w: Amplitude-weighted order parameter |Σ X_i| / Σ |X_i| over all patches (NaN if all zero).
        rule: Name of the rule that defines Φ ("relative" or "snr").
        params: Rule and analysis parameters, JSON/HDF5-attribute friendly.
    """

    freq: np.ndarray | None
    S: np.ndarray
    S_AB: np.ndarray
    S_BC: np.ndarray
    Phi: np.ndarray
    S_null: np.ndarray
    R_w: np.ndarray
    rule: str
    params: dict[str, Any]


def _smooth(G: np.ndarray) -> np.ndarray:
    """Circular 3-bin weighted moving average along the last axis."""
    edge, centre, _ = SMOOTHING_WEIGHTS
    return centre * G + edge * (np.roll(G, 1, axis=-1) + np.roll(G, -1, axis=-1))


def _abc_count(G_sorted: np.ndarray, threshold: np.ndarray) -> np.ndarray:
    """Smallest fractional n with element precision such that Σ_{i≤n} G_i ≥ threshold."""
    cum = np.cumsum(G_sorted, axis=-1)
    k = np.minimum(np.count_nonzero(cum < threshold[..., None], axis=-1), G_sorted.shape[-1] - 1)
    c_k = np.where(k > 0, np.take_along_axis(cum, np.maximum(k - 1, 0)[..., None], axis=-1)[..., 0], 0.0)
    g_next = np.take_along_axis(G_sorted, k[..., None], axis=-1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        return k + (threshold - c_k) / g_next


def sync_index_from_bins(
    G: np.ndarray, *, tau_ab: float = 0.5, tau_bc: float = 0.55, w: float = 0.9, smooth: bool = True
) -> SyncBins:
    """Synchronization Index from phase-bin counts (paper Eqs. 5-9).

    Args:
        G: Raw counts per phase bin, shape (n_bins,) or (..., n_bins) to vectorise (e.g. over
            frequencies). Φ = ΣG over the last axis.
        tau_ab: Threshold τ_AB of the A/B split.
        tau_bc: Threshold τ_BC of the B/C split.
        w: Weight of S_AB in S.
        smooth: Apply the circular 3-bin Gaussian moving average before sorting (the paper's
            Appendix examples use ``smooth=False``).

    Returns:
        A ``SyncBins``; S, S_AB, S_BC, n_AB, n_BC are NaN where Φ < 2.
    """
    for name, tau in (("tau_ab", tau_ab), ("tau_bc", tau_bc)):
        if not 0.0 < tau < 1.0:
            raise ValueError(f"{name} must lie in (0, 1), got {tau}")
    G = np.asarray(G, dtype=np.float64)
    n_bins = G.shape[-1]
    phi = G.sum(axis=-1)
    if smooth:
        G = _smooth(G)
    G_sorted = -np.sort(-G, axis=-1)
    one_bin = np.zeros(n_bins)
    one_bin[0] = 1.0
    one_bin = -np.sort(-(_smooth(one_bin) if smooth else one_bin))
    n_ab_min, n_bc_min = (float(_abc_count(one_bin, np.asarray(t))) for t in (tau_ab, tau_bc))
    n_ab_max, n_bc_max = tau_ab * n_bins, tau_bc * n_bins
    invalid = phi < 2
    n_ab = np.where(invalid, np.nan, _abc_count(G_sorted, tau_ab * phi))
    n_bc = np.where(invalid, np.nan, _abc_count(G_sorted, tau_bc * phi))
    s_ab = (n_ab_max - n_ab) / (n_ab_max - n_ab_min)
    s_bc = (n_bc_max - n_bc) / (n_bc_max - n_bc_min)
    return SyncBins(
        S=(w * s_ab + (1.0 - w) * s_bc)[()],
        S_AB=s_ab[()],
        S_BC=s_bc[()],
        n_AB=n_ab[()],
        n_BC=n_bc[()],
        n_AB_max=n_ab_max,
        n_AB_min=n_ab_min,
        n_BC_max=n_bc_max,
        n_BC_min=n_bc_min,
    )


def sync_null_level(
    phi: np.ndarray,
    *,
    n_bins: int = 180,
    trials: int = 100,
    seed: int = 0,
    tau_ab: float = 0.5,
    tau_bc: float = 0.55,
    w: float = 0.9,
    smooth: bool = True,
) -> np.ndarray:
    """Mean Synchronization Index of Φ uniformly random phases (Monte-Carlo null level).

    For each distinct Φ, ``trials`` sets of Φ phases uniform on [-π, π) are binned (a uniform
    phase falls into each bin with probability 1/n_bins, so bin indices are drawn directly)
    and analysed like data. The random stream of a given Φ is seeded by ``(seed, Φ)``, so
    the level of a Φ does not depend on which other Φ occur.

    Args:
        phi: Patch counts Φ, any shape.
        n_bins: Number of phase bins.
        trials: Monte-Carlo repetitions per Φ.
        seed: Base seed.
        tau_ab: As in ``sync_index_from_bins``.
        tau_bc: As in ``sync_index_from_bins``.
        w: As in ``sync_index_from_bins``.
        smooth: As in ``sync_index_from_bins``.

    Returns:
        Mean S per entry of ``phi`` (same shape); NaN where Φ < 2.
    """
    phi = np.asarray(phi, dtype=np.int64)
    values, inverse = np.unique(phi, return_inverse=True)
    level = np.full(values.shape, np.nan)
    offsets = (np.arange(trials) * n_bins)[:, None]
    for i, p in enumerate(values):
        if p < 2:
            continue
        idx = np.random.default_rng([seed, int(p)]).integers(0, n_bins, size=(trials, int(p))) + offsets
        G = np.bincount(idx.ravel(), minlength=trials * n_bins).reshape(trials, n_bins)
        level[i] = sync_index_from_bins(G, tau_ab=tau_ab, tau_bc=tau_bc, w=w, smooth=smooth).S.mean()
    return level[inverse.reshape(phi.shape)]


def _row_blocks(X: np.ndarray | Iterable[np.ndarray], rows: int) -> Iterator[np.ndarray]:
    """Split an array or a stream of frequency chunks (F_k, n_patches) into blocks of ≤ rows."""
    for chunk in [X] if isinstance(X, np.ndarray) else X:
        chunk = np.asarray(chunk)
        if chunk.ndim != 2:
            raise ValueError(f"spectra must be 2-D (frequencies x patches), got shape {chunk.shape}")
        for i in range(0, chunk.shape[0], rows):
            yield chunk[i : i + rows].copy()
        del chunk  # no view of it is left: a streamed chunk is freed before the next one is made


def sync_index(
    X: np.ndarray | Iterable[np.ndarray],
    *,
    freq: np.ndarray | None = None,
    rule: Literal["relative", "snr"] = "relative",
    eta: float = 0.1,
    snr: float = 5.0,
    noise_floor: np.ndarray | None = None,
    n_bins: int = 180,
    tau_ab: float = 0.5,
    tau_bc: float = 0.55,
    w: float = 0.9,
    smooth: bool = True,
    null_trials: int = 100,
    seed: int = 0,
    rows_per_block: int = 1024,
) -> SyncResult:
    """Synchronization Index S(f) of per-patch complex spectra.

    Args:
        X: Complex spectra of shape (F, n_patches) (e.g. from ``complex_spectrum``), or an
            iterable of such arrays covering consecutive frequency rows (F_k, n_patches).
        freq: Frequencies of the F rows [Hz], stored in the result.
        rule: How Φ(f) is counted. ``"relative"``: |X_i(f)| ≥ η·max_j |X_j(f)|.
            ``"snr"``: |X_i(f)| ≥ κ·floor_i with floor_i = ``noise_floor[i]``, by default the
            median of |X_i| over all F rows (``SNR_REFERENCE``). Zero amplitudes never count.
        eta: η of the relative rule.
        snr: κ of the SNR rule.
        noise_floor: Per-patch floor of shape (n_patches,) for the SNR rule (units of X);
            required when X is an iterable and ``rule="snr"``.
        n_bins: Number of phase bins on [-π, π).
        tau_ab: Threshold τ_AB.
        tau_bc: Threshold τ_BC.
        w: Weight of S_AB in S.
        smooth: Apply the circular 3-bin Gaussian filter to the phase bins.
        null_trials: Monte-Carlo trials per Φ for ``S_null`` (0 disables it: NaN).
        seed: Base seed of the null level (see ``sync_null_level``).
        rows_per_block: Frequencies processed at once (bounds the temporaries).

    Returns:
        A ``SyncResult`` with per-frequency S, S_AB, S_BC, Φ, S_null and R_w.
    """
    rule_params, noise_floor = _rule_params(X, rule, eta, snr, noise_floor)
    options = {"tau_ab": tau_ab, "tau_bc": tau_bc, "w": w, "smooth": smooth}
    parts: dict[str, list[np.ndarray]] = {key: [] for key in ("S", "S_AB", "S_BC", "Phi", "R_w")}
    for block in _row_blocks(X, rows_per_block):
        amp = np.abs(block)
        threshold = eta * amp.max(axis=1, keepdims=True) if rule == "relative" else snr * noise_floor[None, :]
        for key, value in _block_index(block, amp, threshold, n_bins, options).items():
            parts[key].append(value)
    out = {key: np.concatenate(value) if value else np.empty(0) for key, value in parts.items()}
    if freq is not None and np.shape(freq) != out["S"].shape:
        raise ValueError(f"freq has shape {np.shape(freq)} but the spectra have {out['S'].size} rows")
    if null_trials > 0:
        s_null = sync_null_level(out["Phi"], n_bins=n_bins, trials=null_trials, seed=seed, **options)
    else:
        s_null = np.full(out["S"].shape, np.nan)
    params = {"rule": rule, **rule_params, "n_bins": n_bins, **options, "null_trials": null_trials, "seed": seed}
    params["smoothing_weights"] = SMOOTHING_WEIGHTS.tolist() if smooth else [1.0]
    return SyncResult(freq=freq, S_null=s_null, rule=rule, params=params, **out)


def _rule_params(
    X: np.ndarray | Iterable[np.ndarray], rule: str, eta: float, snr: float, noise_floor: np.ndarray | None
) -> tuple[dict[str, Any], np.ndarray | None]:
    """The parameters of the Φ ``rule`` as stored in the result, and the SNR rule's per-patch floor (the median of
    |X_i| over all rows unless given; ``noise_floor`` unchanged for the relative rule). ValueError for an unknown
    rule or streamed spectra without a floor."""
    if rule == "relative":
        return {"eta": eta}, noise_floor
    if rule != "snr":
        raise ValueError(f"rule must be 'relative' or 'snr', got {rule!r}")
    if noise_floor is None:
        if not isinstance(X, np.ndarray):
            raise ValueError('rule="snr" with streamed spectra needs an explicit noise_floor')
        noise_floor = np.median(np.abs(X), axis=0)
    return {"snr": snr, "snr_reference": SNR_REFERENCE}, np.asarray(noise_floor)


def _block_index(
    block: np.ndarray, amp: np.ndarray, threshold: np.ndarray, n_bins: int, options: dict[str, Any]
) -> dict[str, np.ndarray]:
    """S, S_AB, S_BC, Φ and R_w of the rows of ``block`` (rows, patches) with amplitudes ``amp``: the patches with
    |X_i| ≥ ``threshold`` (and > 0) counted into ``n_bins`` phase bins, then :func:`sync_index_from_bins`."""
    counted = (amp >= threshold) & (amp > 0)
    bins = np.floor((np.angle(block) + np.pi) * (n_bins / (2.0 * np.pi))).astype(np.intp) % n_bins
    bins += (np.arange(block.shape[0]) * n_bins)[:, None]
    G = np.bincount(bins[counted], minlength=block.shape[0] * n_bins).reshape(-1, n_bins)
    res = sync_index_from_bins(G, **options)
    total = amp.sum(axis=1, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        r_w = np.abs(block.sum(axis=1, dtype=np.complex128)) / total
    out = {key: np.atleast_1d(value) for key, value in (("S", res.S), ("S_AB", res.S_AB), ("S_BC", res.S_BC))}
    out["Phi"] = counted.sum(axis=1)
    out["R_w"] = np.where(total > 0, r_w, np.nan)
    return out


_FFT_COLUMNS = 32
"""Patch columns per FFT call: bounds the FFT temporaries to about 16·N·32 bytes."""

_READ_BYTES = 64 << 20
"""Size of one row-block read from a file-backed array [bytes]."""


def _patch_groups(v: Any, group: int) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(first column, block of shape (N, <= group))`` covering every patch column of ``v``.

    NumPy arrays are sliced directly. Other array-likes (h5py Datasets) are read in row blocks
    of whole HDF5 chunks into one reused float32 buffer, so a file chunked along time (all
    patches per chunk) is read once per group rather than once per column.
    """
    n_samples, n_patches = v.shape
    if isinstance(v, np.ndarray):
        for g0 in range(0, n_patches, group):
            yield g0, v[:, g0 : g0 + group]
        return
    buf = np.empty((n_samples, min(group, n_patches)), dtype=np.float32)
    rows = max(1, _READ_BYTES // (4 * buf.shape[1]))
    hdf5_chunks = getattr(v, "chunks", None)
    if hdf5_chunks:
        rows = max(1, rows // hdf5_chunks[0]) * hdf5_chunks[0]
    for g0 in range(0, n_patches, group):
        g1 = min(g0 + group, n_patches)
        for r0 in range(0, n_samples, rows):
            buf[r0 : r0 + rows, : g1 - g0] = v[r0 : r0 + rows, g0:g1]
        yield g0, buf[:, : g1 - g0]


def _band_spectra(
    v: Any,
    dt: float,
    band: tuple[float, float],
    rows: slice,
    group: int,
    workers: int | None,
    floor: np.ndarray | None = None,
) -> np.ndarray:
    """Rows ``rows`` of the in-band complex64 spectra of all patches, shape (rows, n_patches).

    If ``floor`` is given, it receives each patch's median |X| over the whole band.
    """
    out = np.empty((rows.stop - rows.start, v.shape[1]), dtype=np.complex64)
    for g0, block in _patch_groups(v, group):
        for c0 in range(0, block.shape[1], _FFT_COLUMNS):
            x = np.asarray(block[:, c0 : c0 + _FFT_COLUMNS], dtype=np.float32)
            _, spec = complex_spectrum(x, dt, axis=0, freq_range=band, workers=workers)
            cols = slice(g0 + c0, g0 + c0 + spec.shape[1])
            out[:, cols] = spec[rows]
            if floor is not None:
                floor[cols] = np.median(np.abs(spec), axis=0)
    return out


def sync_index_from_signals(
    v: Any,
    dt: float,
    *,
    freq_range: tuple[float, float] | None = None,
    chunk_patches: int | None = None,
    max_bytes: int = 1 << 30,
    workers: int | None = -1,
    rule: Literal["relative", "snr"] = "relative",
    **options: Any,
) -> SyncResult:
    """Synchronization Index straight from per-patch time histories.

    Patch columns are read in groups; their Hann-windowed spectra (``complex_spectrum``
    scaling, float32 in, complex64 out) are computed 32 columns at a time, keeping only the
    bins inside ``freq_range``. The band array then goes to ``sync_index``; if it would exceed
    ``max_bytes`` the band is split into sub-bands, one pass over the data each. Peak memory
    is about 2·max_bytes plus the FFT temporaries (≈ 16·N·32 bytes) and the sync temporaries.

    Args:
        v: Velocities [m/s] of shape (N samples, n_patches): a NumPy array or an h5py Dataset.
            A Dataset is read in row blocks of whole chunks, one patch group at a time.
        dt: Sampling interval [s].
        freq_range: Inclusive band ``(fmin, fmax)`` [Hz]; None = every bin above 0 Hz.
        chunk_patches: Patch columns per read group; default: as many as fit a float32
            buffer of ``max_bytes`` (rounded to the HDF5 chunk width when that is narrower).
        max_bytes: Budget for the read buffer and for the band array, each [bytes].
        workers: Threads for ``scipy.fft`` (-1: all CPUs).
        rule: Φ rule, see ``sync_index``.
        **options: Further keyword arguments of ``sync_index`` (eta, snr, noise_floor, n_bins,
            tau_ab, tau_bc, w, smooth, null_trials, seed, rows_per_block).

    Returns:
        The ``SyncResult`` of ``sync_index``, with ``freq`` set.
    """
    n_samples, n_patches = v.shape
    freq_all = scipy.fft.rfftfreq(n_samples, dt)
    band = freq_range if freq_range is not None else (freq_all[1], freq_all[-1])
    keep = np.flatnonzero((freq_all >= band[0]) & (freq_all <= band[1]))
    if keep.size == 0:
        raise ValueError(f"no frequency bin inside freq_range={freq_range} Hz")
    freq = freq_all[keep[0] : keep[-1] + 1]
    group = chunk_patches or max(1, max_bytes // (4 * n_samples))
    hdf5_chunks = getattr(v, "chunks", None)
    if hdf5_chunks and hdf5_chunks[1] < n_patches:
        group = max(1, group // hdf5_chunks[1]) * hdf5_chunks[1]
    step = max(1, max_bytes // (8 * n_patches))
    passes = [slice(i, min(i + step, freq.size)) for i in range(0, freq.size, step)]
    args = (v, dt, band)
    if len(passes) == 1:
        return sync_index(_band_spectra(*args, passes[0], group, workers), freq=freq, rule=rule, **options)
    if rule == "snr" and options.get("noise_floor") is None:
        options["noise_floor"] = np.empty(n_patches)
        _band_spectra(*args, slice(0, 0), group, workers, options["noise_floor"])
    spectra = (_band_spectra(*args, rows, group, workers) for rows in passes)
    return sync_index(spectra, freq=freq, rule=rule, **options)
