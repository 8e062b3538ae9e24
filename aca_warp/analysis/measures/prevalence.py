"""The Synchronization Index compared at equal prevalence Φ (paper Fig. 9; S of a few patches is high by chance), and
its rank agreement with a friction spectrum (§3.1, §3.3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from .peaks import _band_bins


@dataclass(frozen=True)
class PrevalenceTable:
    """S(f) averaged within classes of Φ (equal-prevalence comparison); every array has shape (C,).

    Attributes:
        lower: Smallest Φ of each class (inclusive).
        upper: Largest Φ of each class (exclusive).
        bins: Frequency bins in each class.
        mean_S: Mean S over the class's bins (NaN if empty).
        mean_S_null: Mean null level S_null (NaN if empty).
        mean_excess: Mean of S − S_null (NaN if empty).
    """

    lower: np.ndarray
    upper: np.ndarray
    bins: np.ndarray
    mean_S: np.ndarray
    mean_S_null: np.ndarray
    mean_excess: np.ndarray

    def value(self, name: str) -> np.ndarray:
        """``"S"``, ``"S_null"`` or ``"excess"`` per class."""
        return {"S": self.mean_S, "S_null": self.mean_S_null, "excess": self.mean_excess}[name]


def prevalence_classes(phi_max: int) -> np.ndarray:
    """Octave class edges 2, 4, 8, …, the first power of two above ``phi_max`` (Φ < 2 leaves S undefined)."""
    top = max(2, int(np.ceil(np.log2(max(phi_max, 2) + 1))))
    return 2 ** np.arange(1, top + 1)


def sync_by_prevalence(
    S: np.ndarray, S_null: np.ndarray, Phi: np.ndarray, *, edges: np.ndarray | None = None
) -> PrevalenceTable:
    """Mean S, S_null and S − S_null over the frequency bins of each class of Φ.

    S of a few patches is high by chance (its null level falls as Φ grows), so S of two records is comparable
    only at equal Φ. Bins with Φ < 2 or a non-finite S or S_null are left out.

    Args:
        S: Synchronization Index per bin, shape (F,).
        S_null: Its random-phase null level per bin, shape (F,).
        Phi: Oscillating patches per bin, shape (F,).
        edges: Increasing class edges (class k: edges[k] <= Φ < edges[k+1]); default
            :func:`prevalence_classes` of the largest Φ.

    Returns:
        A :class:`PrevalenceTable` with len(edges) − 1 classes.
    """
    S, null = np.asarray(S, dtype=np.float64), np.asarray(S_null, dtype=np.float64)
    phi = np.asarray(Phi, dtype=np.int64)
    if not S.shape == null.shape == phi.shape or S.ndim != 1:
        raise ValueError(f"S, S_null and Phi must be 1-D of equal length, got {S.shape}, {null.shape}, {phi.shape}")
    edges = prevalence_classes(int(phi.max()) if phi.size else 2) if edges is None else np.asarray(edges)
    ok = (phi >= 2) & np.isfinite(S) & np.isfinite(null)
    cls = np.searchsorted(edges, phi[ok], side="right") - 1
    inside = (cls >= 0) & (cls < edges.size - 1)
    cls, s, sn = cls[inside], S[ok][inside], null[ok][inside]
    c = edges.size - 1
    count = np.bincount(cls, minlength=c)

    def mean(v: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(count > 0, np.bincount(cls, v, minlength=c) / count, np.nan)

    return PrevalenceTable(edges[:-1].copy(), edges[1:].copy(), count, mean(s), mean(sn), mean(s - sn))


@dataclass(frozen=True)
class EqualPrevalence:
    """Differences of S between paired records at equal Φ.

    Attributes:
        difference: Per pair, the mean over the common classes of (value of a − value of b), shape (n,); NaN
            when no class is common.
        classes: Boolean mask of the classes used (populated by ``min_bins`` bins in every record), shape (C,).
        lower: Smallest Φ of each class, shape (C,).
        upper: Largest Φ (exclusive), shape (C,).
        value: Which per-class value was compared ("S", "S_null" or "excess").
        reference: Per pair, the mean over the common classes of b's value, the level the difference is taken from
            (b's value + difference is a's), shape (n,); NaN when no class is common.
    """

    difference: np.ndarray
    classes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    value: str
    reference: np.ndarray


def equal_prevalence_difference(
    a: list[PrevalenceTable], b: list[PrevalenceTable], *, value: str = "excess", min_bins: int = 10
) -> EqualPrevalence:
    """Paired differences a_k − b_k of S at equal Φ, over the Φ classes every record populates.

    A class counts when each of the records a_1…a_n, b_1…b_n has at least ``min_bins`` bins in it, so every
    pair is compared over the same classes; each class weighs the same (an average over Φ, not over bins).

    Args:
        a: Tables of the first ensemble (one per seed), all with the same class edges.
        b: Tables of the second ensemble, paired with ``a`` by position.
        value: "excess" (S − S_null, default), "S" or "S_null".
        min_bins: Fewest bins a class needs in every record.

    Returns:
        An :class:`EqualPrevalence`.
    """
    if len(a) != len(b) or not a:
        raise ValueError(f"need two non-empty ensembles of equal size, got {len(a)} and {len(b)}")
    edges = a[0].lower
    if any(t.lower.shape != edges.shape or np.any(t.lower != edges) for t in (*a, *b)):
        raise ValueError("every table must have the same class edges")
    mask = np.logical_and.reduce([t.bins >= min_bins for t in (*a, *b)])
    pairs = zip(a, b, strict=True)
    diff = np.array([np.mean(x.value(value)[mask] - y.value(value)[mask]) if mask.any() else np.nan for x, y in pairs])
    ref = np.array([np.mean(y.value(value)[mask]) if mask.any() else np.nan for y in b])
    return EqualPrevalence(diff, mask, edges.copy(), a[0].upper.copy(), value, ref)


def spectral_agreement(
    freq: np.ndarray, S: np.ndarray, Phi: np.ndarray, amp: np.ndarray, *, band: tuple[float, float] = (20e3, 80e3)
) -> float:
    """Spearman rank correlation of S(f)·Φ(f) with an amplitude spectrum over ``band`` (paper §3.1, §4).

    High where the bins with synchronised, prevalent patch motion are the bins where the friction spectrum is
    high. Bins where S is undefined count as S·Φ = 0 (no synchronised patches). The paper's 20–80 kHz is
    where it finds its friction and synchronisation behaviour to agree with measurements (§4).

    Args:
        freq: Frequencies [Hz], shape (F,).
        S: Synchronization Index, shape (F,) (NaN where undefined).
        Phi: Oscillating patches per bin, shape (F,).
        amp: Amplitude spectrum on the same bins (e.g. |μ(f)|/μ̄), shape (F,).
        band: (fmin, fmax) [Hz].

    Returns:
        ρ in [−1, 1] (NaN when either series is constant over the band).
    """
    freq = np.asarray(freq, dtype=np.float64)
    S, phi, amp = (np.asarray(v, dtype=np.float64) for v in (S, Phi, amp))
    if not freq.shape == S.shape == phi.shape == amp.shape or freq.ndim != 1:
        raise ValueError("freq, S, Phi and amp must be 1-D of equal length")
    idx = _band_bins(freq, band[0], band[1], "agreement")
    weight = np.where(np.isfinite(S[idx]), S[idx], 0.0) * phi[idx]
    if np.ptp(weight) == 0 or np.ptp(amp[idx]) == 0:
        return float("nan")
    return float(scipy.stats.spearmanr(weight, amp[idx]).statistic)
