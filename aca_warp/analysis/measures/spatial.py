"""Spatial measures of the patches' motion (paper Figs. 4/6, §3.3): the decay of the phase correlation with patch
distance and the phase coherence of neighbouring patches per frequency bin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class CorrelationLength:
    """Spatial phase correlation C(d) = ⟨cos(φ_i − φ_j)⟩ over patch pairs binned by distance.

    Attributes:
        length: ℓ of the least-squares fit C(d) = exp(−d/ℓ) over the bins (pair-count weights) [m]; 0 for
            uncorrelated phases, inf for phases correlated over the whole range.
        length_e: Distance where the binned C first falls below 1/e (linear interpolation) [m]; 0 if the
            first bin is already below, inf if no bin is.
        distance: Mean pair distance per bin [m], shape (B,).
        correlation: C per bin, shape (B,) (NaN for an empty bin).
        pairs: Pairs per bin, shape (B,).
        fit_rms: RMS residual of the fit over the non-empty bins.
    """

    length: float
    length_e: float
    distance: np.ndarray
    correlation: np.ndarray
    pairs: np.ndarray
    fit_rms: float


def _fit_exponential(d: np.ndarray, c: np.ndarray, w: np.ndarray, d_max: float) -> tuple[float, float]:
    """ℓ of the weighted least-squares fit of exp(−d/ℓ) to c, with ℓ in [d_max/1e4, 1e4·d_max] (0/inf at the ends)."""

    def cost(log_l: float) -> float:
        return float(np.sum(w * (c - np.exp(-d / np.exp(log_l))) ** 2))

    lo, hi = np.log(d_max * 1e-4), np.log(d_max * 1e4)
    grid = np.linspace(lo, hi, 161)
    best = int(np.argmin([cost(g) for g in grid]))
    a, b = grid[max(best - 1, 0)], grid[min(best + 1, grid.size - 1)]
    res = scipy.optimize.minimize_scalar(cost, bounds=(a, b), method="bounded", options={"xatol": 1e-6})
    ell = float(np.exp(res.x))
    rms = float(np.sqrt(cost(res.x) / w.sum()))
    if res.x <= lo + 1e-3:
        ell = 0.0
    elif res.x >= hi - 1e-3:
        ell = float("inf")
    return ell, rms


def phase_correlation_length(
    x: np.ndarray,
    y: np.ndarray,
    phase: np.ndarray,
    amplitude: np.ndarray | None = None,
    *,
    max_distance: float | None = None,
    bins: int = 20,
) -> CorrelationLength:
    """Correlation length of the phase pattern of the patches (synchronised islands, paper Figs. 4/6).

    For every pair of patches i < j closer than ``max_distance``, cos(φ_i − φ_j) (1: in phase, −1: in
    antiphase) is averaged within equal-width distance bins, over all snapshots, with weights a_i·a_j when
    amplitudes are given (so that patches barely moving count little). C(d) = exp(−d/ℓ) is then fitted with
    C(0) = 1 fixed (neighbours at zero distance move together), weighted by the pairs per bin. For a 1-D
    phase random walk C(d) is exactly exp(−d/ℓ); for other patterns ℓ is the best exponential scale and
    ``length_e``, the 1/e distance of the binned curve, is model-free.

    Args:
        x: Patch centres x [m], shape (n,).
        y: Patch centres y [m], shape (n,).
        phase: Phases [rad], shape (n,) or (m, n) for m snapshots (e.g. arg X_i(f) at a frequency bin, or
            instantaneous phases at several times).
        amplitude: Weights per patch (e.g. |X_i(f)|), shape of ``phase`` or (n,); None: equal weights.
        max_distance: Largest pair distance [m]; default half the diagonal of the patches' bounding box.
        bins: Number of distance bins on (0, max_distance].

    Returns:
        A :class:`CorrelationLength`.
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    phase = np.atleast_2d(np.asarray(phase, dtype=np.float64))
    if x.shape != y.shape or x.ndim != 1 or phase.shape[1] != x.size:
        raise ValueError(f"x, y must be (n,) and phase (n,) or (m, n); got {x.shape}, {y.shape}, {phase.shape}")
    if amplitude is None:
        amp = np.ones_like(phase)
    else:
        amp = np.broadcast_to(np.asarray(amplitude, dtype=np.float64), phase.shape)
    if not (np.all(np.isfinite(phase)) and np.all(np.isfinite(amp))):
        raise ValueError("phase and amplitude must be finite")
    if max_distance is None:
        max_distance = 0.5 * float(np.hypot(np.ptp(x), np.ptp(y)))
    pairs = cKDTree(np.column_stack([x, y])).query_pairs(max_distance, output_type="ndarray")
    if len(pairs) == 0:
        raise ValueError(f"no pair of patches closer than {max_distance:g} m")
    i, j = pairs[:, 0], pairs[:, 1]
    d = np.hypot(x[i] - x[j], y[i] - y[j])
    b = np.minimum((d / max_distance * bins).astype(np.intp), bins - 1)
    w = amp[:, i] * amp[:, j]
    wc = np.sum(w * np.cos(phase[:, i] - phase[:, j]), axis=0)
    num = np.bincount(b, wc, minlength=bins)
    den = np.bincount(b, w.sum(axis=0), minlength=bins)
    count = np.bincount(b, minlength=bins)
    dist = np.bincount(b, d, minlength=bins) / np.maximum(count, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.where(den > 0, num / den, np.nan)
    ok = np.isfinite(corr) & (count > 0)
    ell, rms = _fit_exponential(dist[ok], corr[ok], count[ok].astype(np.float64), max_distance)
    below = np.flatnonzero(corr[ok] < np.exp(-1.0))
    if below.size == 0:
        ell_e = float("inf")
    elif below[0] == 0:
        ell_e = 0.0
    else:
        d_ok, c_ok, k = dist[ok], corr[ok], below[0]
        ell_e = float(d_ok[k - 1] + (c_ok[k - 1] - np.exp(-1.0)) / (c_ok[k - 1] - c_ok[k]) * (d_ok[k] - d_ok[k - 1]))
    return CorrelationLength(ell, ell_e, np.where(count > 0, dist, np.nan), corr, count, rms)


def neighbour_coherence(x: np.ndarray, y: np.ndarray, spectra: np.ndarray, radius: float) -> np.ndarray:
    """Phase coherence of neighbouring patches per frequency bin (local clustering of synchronised motion).

    C(f) = Σ_pairs Re(X_i X_j*) / Σ_pairs |X_i||X_j| over the pairs of patches closer than ``radius``: the
    amplitude-weighted mean cos(φ_i − φ_j) of neighbours at f, as :func:`phase_correlation_length` over the
    first distance bin but for every bin at once. 1: neighbours oscillate in phase at f (a synchronised island),
    0: unrelated phases, negative: neighbours in antiphase.

    Args:
        x: Patch centres x [m], shape (n,).
        y: Patch centres y [m], shape (n,).
        spectra: Complex per-patch spectra X_i(f), shape (F, n).
        radius: Largest pair distance [m] (e.g. the coupling radius).

    Returns:
        C per bin, shape (F,); NaN where no pair has amplitude.
    """
    import scipy.sparse as sp

    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    X = np.asarray(spectra)
    if x.shape != y.shape or x.ndim != 1 or X.ndim != 2 or X.shape[1] != x.size:
        raise ValueError(f"x, y must be (n,) and spectra (F, n); got {x.shape}, {y.shape}, {X.shape}")
    pairs = cKDTree(np.column_stack([x, y])).query_pairs(radius, output_type="ndarray")
    if len(pairs) == 0:
        raise ValueError(f"no pair of patches closer than {radius:g} m")
    n = x.size
    adj = sp.csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    num = np.real(np.sum(np.conj(X) * (adj @ X.T).T, axis=1))
    a = np.abs(X)
    den = np.sum(a * (adj @ a.T).T, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)
