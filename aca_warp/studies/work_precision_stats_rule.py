"""The measures, statistics and rule of the statistical work-precision study
(:mod:`aca_warp.studies.work_precision_stats`); NumPy only, so that a result file is judged without a simulation.

**Measures** (:data:`MEASURES`): what the validation's ensembles rest on, read from the validation's own per-pad
analysis (``pad_measures`` over the per-patch window of a saturated run, ``growth_measures`` of a growing run and
the saturation figures of every pad). A measure's per-pad value is a number, or a vector (the spectra: log10 of
the mean amplitude in :data:`BAND_WIDTH` bands over :data:`SPECTRUM_BAND`).

**Statistics** (:func:`compare`): for one measure, the reference ensemble x_ref (one value per seed) and the
ensemble of a setting x (the same seeds, the same pads):

* error = |mean(x) − mean(x_ref)|, the error of the setting's ensemble mean;
* σ = the standard deviation of x_ref between seeds (ddof 1), and the 95 % half-width of its mean
  t(0.975, n − 1) σ / √n (``ensemble_interval``);
* the paired standard error sd(x − x_ref) / √n: how much of the error chaos alone makes (the runs part after
  saturation, so their values differ seed by seed even for an exact integrator);
* for a vector measure every figure is the root mean square over the components (bands).

A regime whose pads have members (the LF states) is compared member by member; the regime's figure is the
member with the largest error/σ.

**Rule** (:func:`settings_for`): a setting meets the rule for a measure when error ≤ ``rule`` · σ. The **floor**
(the reference settings from initial velocities perturbed by 1e-9 m/s: an equally exact ensemble) shows what
chaos alone gives; a measure whose floor already exceeds ``rule`` · σ cannot tell settings apart with this many
seeds and is *undecided* (listed, not used). The chosen setting is the one with the least stepping wall time that
meets the rule for every decided measure; the reference itself always does, and is the choice when no measure is
decided (nothing shows that a coarser setting keeps the statistics).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

SPECTRUM_BAND = (5.0e3, 150.0e3)  # Hz: the spectra measures' band (the validation's S band reaches 150 kHz)
BAND_WIDTH = 5.0e3  # Hz
PEAK_FMIN = 5.0e3  # Hz: lowest frequency of the velocity-sum peak (as the μ peak of ``mu_measures``)
STFT_SAMPLES = 2**12  # the STFT window of the varying-area rows
DEFAULT_RULE = 0.25  # error ≤ ¼ of the standard deviation between seeds
ROLES = ("reference", "floor", "grid")


# ------------------------------------------------------------------------------------------------ measures


def band_log10(freq: np.ndarray, amp: np.ndarray) -> np.ndarray:
    """log10 of the mean amplitude in :data:`BAND_WIDTH` bands over :data:`SPECTRUM_BAND` (NaN for a band with no
    bin, e.g. above the Nyquist frequency); shape (bands,)."""
    edges = np.arange(SPECTRUM_BAND[0], SPECTRUM_BAND[1] + 0.5 * BAND_WIDTH, BAND_WIDTH)
    out = np.full(edges.size - 1, np.nan)
    for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        sel = (freq >= lo) & (freq < hi)
        if sel.any() and np.all(amp[sel] >= 0) and amp[sel].mean() > 0:
            out[k] = math.log10(float(amp[sel].mean()))
    return out


def _dig(d: Any, key: str) -> float:
    """A number by dotted key from nested dicts; NaN when missing or not a finite number."""
    for part in key.split("."):
        d = d.get(part) if isinstance(d, dict) else None
    return float(d) if isinstance(d, (int, float)) and not isinstance(d, bool) and math.isfinite(d) else math.nan


def _measure(key: str) -> Callable[[dict[str, Any], dict[str, np.ndarray] | None], float]:
    return lambda pad, spectra: _dig(pad.get("measures", {}), key)


def _pad(key: str) -> Callable[[dict[str, Any], dict[str, np.ndarray] | None], float]:
    return lambda pad, spectra: _dig(pad, key)


def _vsum_peak(pad: dict[str, Any], spectra: dict[str, np.ndarray] | None) -> float:
    from aca_warp.analysis.spectra import peak

    if spectra is None:
        return math.nan
    return peak(spectra["freq"], spectra["velocity"], fmin=PEAK_FMIN)[0]


def _spectrum(name: str) -> Callable[[dict[str, Any], dict[str, np.ndarray] | None], np.ndarray | float]:
    return lambda pad, spectra: math.nan if spectra is None else band_log10(spectra["freq"], spectra[name])


def _stft(what: str) -> Callable[[dict[str, Any], dict[str, np.ndarray] | None], float]:
    def get(pad: dict[str, Any], spectra: dict[str, np.ndarray] | None) -> float:
        hits = [e for e in pad.get("measures", {}).get("stft", []) if e.get("samples") == STFT_SAMPLES]
        return _dig(hits[0], what) if hits else math.nan

    return get


def _tonality_change(pad: dict[str, Any], spectra: dict[str, np.ndarray] | None) -> float:
    t = pad.get("measures", {}).get("tonality", {}).get("peak_to_median", [])
    return math.log(t[-1] / t[0]) if len(t) == 3 and t[0] and t[-1] and t[0] > 0 and t[-1] > 0 else math.nan


@dataclass(frozen=True)
class Measure:
    """One measure of the study.

    Attributes:
        label: Short name for tables and legends.
        unit: Unit of its values ("1" for none; "log10" for the band spectra).
        kinds: Experiment kinds it applies to: "saturated" (the per-patch window of a run into saturation) and/or
            "growth" (a growing run).
        get: ``(pad, spectra) -> value``: the pad's dict of the validation's analysis (saturation figures and
            ``measures``), and its global spectra {"freq", "mu", "velocity"} (saturated kind) or None.
        what: One line for the docs.
    """

    label: str
    unit: str
    kinds: tuple[str, ...]
    get: Callable[[dict[str, Any], dict[str, np.ndarray] | None], Any]
    what: str


SAT, GROW = ("saturated",), ("growth",)
MEASURES: dict[str, Measure] = {
    "mu_mean": Measure("μ mean", "1", SAT + GROW, _measure("mu_mean"), "mean of μ over the window"),
    "mu_std": Measure("μ std", "1", SAT, _measure("mu_std"), "standard deviation of μ over the window"),
    "vsum_peak": Measure("Σu̇ peak", "Hz", SAT, _vsum_peak,
                         f"largest peak ≥ {PEAK_FMIN / 1e3:g} kHz of the velocity-sum spectrum (Fig. 8)"),
    "f1": Measure("f1", "Hz", SAT, _measure("f1"), "first peak of the mean per-patch velocity spectrum (0.1 × max)"),
    "mu_spectrum": Measure("μ spectrum", "log10", SAT, _spectrum("mu"),
                           f"μ/μ̄ amplitude spectrum, log10 of {BAND_WIDTH / 1e3:g} kHz band means"),
    "vsum_spectrum": Measure("Σu̇ spectrum", "log10", SAT, _spectrum("velocity"),
                             "velocity-sum amplitude spectrum (Fig. 8), log10 of band means"),
    "sync_excess": Measure("S − S_null", "1", SAT, _measure("sync_relative.median_excess_phi10"),
                           "median S − S_null over the bins with Φ ≥ 10 (relative rule)"),
    "phi": Measure("Φ", "patches", SAT, _measure("sync_relative.prevalence"),
                   "mean Φ over [f1/8, 2 f1] (relative rule)"),
    "top_excess": Measure("top S − S_null", "1", SAT, _measure("sync_relative.top_excess"),
                          "mean of the top 1 % of S − S_null (§3.3's individual high S)"),
    "corr_near": Measure("C(≤ 5 mm)", "1", SAT, _measure("corr_near"),
                         "correlation of the directions of motion of patch pairs within 5 mm (Figs. 4/6)"),
    "growth_rate": Measure("growth rate", "1/s", SAT + GROW, _pad("growth_rate"),
                           "linear growth rate of Σ|u̇| before saturation (saturation detector)"),
    "mu_rise": Measure("μ rise", "1", GROW, _measure("mu_rise"), "Δμ over the growth (least-squares slope × length)"),
    "line_first": Measure("first line Δln f", "1", GROW, _measure("line.first_dlnf"),
                          "trend of the first line of Σu̇'s STFT over the record (the falling frequency)"),
    "stft_amplitude": Measure("STFT max", "1", GROW, _stft("amplitude"),
                              f"largest STFT amplitude of μ/μ̄ (window {STFT_SAMPLES} samples, Fig. 10)"),
    "stft_frequency": Measure("STFT max f", "Hz", GROW, _stft("frequency"), "its frequency"),
    "tonality": Measure("Δ tonality", "1", GROW, _tonality_change,
                        "ln of μ's peak/median spectrum, last third over first (stochastic → periodic)"),
}  # fmt: skip


def measures_of(kind: str) -> list[str]:
    """The names of :data:`MEASURES` that apply to experiments of ``kind``."""
    return [k for k, m in MEASURES.items() if kind in m.kinds]


def pad_values(
    pads: Sequence[dict[str, Any]], spectra: Sequence[dict[str, np.ndarray] | None], names: Sequence[str]
) -> dict[str, list[Any]]:
    """Per measure of ``names``, its value for every pad (NaN where the pad was not analysed or the measure is not
    defined there; a vector as a list)."""
    out: dict[str, list[Any]] = {}
    for name in names:
        vals: list[Any] = []
        for pad, spec in zip(pads, spectra, strict=True):
            try:
                v = MEASURES[name].get(pad, spec) if "measures" in pad else math.nan
            except (ValueError, ZeroDivisionError, IndexError, KeyError, TypeError):  # not defined on this pad
                v = math.nan
            vals.append(np.asarray(v, dtype=np.float64).tolist())
        out[name] = vals
    return out


# ------------------------------------------------------------------------------------------------ statistics


@dataclass(frozen=True)
class Comparison:
    """A setting's ensemble against the reference ensemble for one measure (module docstring).

    Attributes:
        n: Seeds both have a value for.
        reference_mean: Mean of the reference ensemble (of a vector measure: the mean of its components).
        error: |mean − mean_ref| (rms over components).
        sigma: Standard deviation between the reference's seeds (rms over components).
        half_width: 95 % half-width of the reference ensemble's mean (rms over components).
        paired_se: Standard error of the mean paired difference (rms over components).
        member: The member (LF state) it belongs to, or None.
    """

    n: int
    reference_mean: float
    error: float
    sigma: float
    half_width: float
    paired_se: float
    member: str | None = None

    @property
    def ratio(self) -> float:
        """error / σ (NaN when σ is not positive or not known)."""
        return self.error / self.sigma if self.sigma > 0 else math.nan


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def compare(reference: Any, values: Any, member: str | None = None) -> Comparison:
    """:class:`Comparison` of per-seed ``values`` against ``reference`` (each shape (seeds,) or (seeds, components),
    NaN where missing; the same seed in the same row). A seed counts when both have every component that at least
    half of the seeds have; fewer than two seeds give NaN figures."""
    from aca_warp.analysis.measures import ensemble_interval

    ref = np.asarray(reference, dtype=np.float64)
    val = np.asarray(values, dtype=np.float64)
    if ref.shape != val.shape:
        raise ValueError(f"reference and values differ in shape: {ref.shape} and {val.shape}")
    ref2, val2 = ref.reshape(ref.shape[0], -1), val.reshape(val.shape[0], -1)
    both = np.isfinite(ref2) & np.isfinite(val2)
    cols = both.mean(axis=0) >= 0.5 if ref2.shape[0] else np.zeros(ref2.shape[1], bool)
    rows = both[:, cols].all(axis=1) if cols.any() else np.zeros(ref2.shape[0], bool)
    n = int(rows.sum())
    if n < 2:
        return Comparison(n, math.nan, math.nan, math.nan, math.nan, math.nan, member)
    r, v = ref2[rows][:, cols], val2[rows][:, cols]
    e = ensemble_interval(r)
    d = v - r
    return Comparison(
        n=n,
        reference_mean=float(np.mean(e.mean)),
        error=_rms(v.mean(axis=0) - r.mean(axis=0)),
        sigma=_rms(e.std),
        half_width=_rms(e.mean_high - e.mean),
        paired_se=_rms(d.std(axis=0, ddof=1) / math.sqrt(n)),
        member=member,
    )


def _members(regime: dict[str, Any]) -> dict[str | None, list[int]]:
    """Member -> indices of its pads (one member None without members)."""
    out: dict[str | None, list[int]] = {}
    for i, p in enumerate(regime["pads"]):
        out.setdefault(p.get("member"), []).append(i)
    return out


def compare_setting(regime: dict[str, Any], setting: dict[str, Any], measure: str) -> Comparison:
    """``setting`` against the regime's reference for ``measure``: the member with the largest error/σ (a member
    whose ratio is not defined counts as the worst)."""
    ref = reference_of(regime)
    worst: Comparison | None = None
    for member, idx in _members(regime).items():
        a = [ref["values"][measure][i] for i in idx]
        b = [setting["values"][measure][i] for i in idx] if setting.get("values") else [math.nan] * len(idx)
        c = compare(_matrix(a), _matrix(b), member)
        if worst is None or not (c.ratio <= worst.ratio):  # NaN beats every number
            worst = c
    assert worst is not None
    return worst


def _matrix(vals: list[Any]) -> np.ndarray:
    """Per-pad values (numbers, None or lists) as a (pads,) or (pads, components) float array."""
    width = max((len(v) for v in vals if isinstance(v, list)), default=0)
    if width == 0:
        return np.array([math.nan if v is None else v for v in vals], dtype=np.float64)
    rows = [[math.nan if x is None else x for x in v] if isinstance(v, list) else [math.nan] * width for v in vals]
    return np.array(rows, dtype=np.float64)


def reference_of(regime: dict[str, Any]) -> dict[str, Any]:
    """The regime's reference setting."""
    refs = [s for s in regime["settings"] if s["role"] == "reference"]
    if not refs:
        raise ValueError(f"regime {regime.get('name', '?')} has no reference setting")
    return refs[0]


def usable(setting: dict[str, Any]) -> bool:
    """A setting whose run completed and was analysed."""
    return bool(setting.get("complete")) and bool(setting.get("values"))


# ------------------------------------------------------------------------------------------------ the rule


@dataclass(frozen=True)
class Choice:
    """What the rule picks in one regime (:func:`settings_for`).

    Attributes:
        regime: The regime.
        setting: Label of the chosen setting.
        wall_s: Its stepping wall time [s].
        reference_wall_s: The reference's [s].
        ratios: error/σ of the chosen setting per decided measure.
        decided: Measures the choice rests on.
        undecided: Measures whose floor exceeds the rule (chaos alone; too few seeds to judge).
        passing: Labels of every setting that meets the rule, cheapest first.
        rule: The fraction of σ.
    """

    regime: str
    setting: str
    wall_s: float
    reference_wall_s: float
    ratios: dict[str, float]
    decided: list[str]
    undecided: list[str]
    passing: list[str] = field(default_factory=list)
    rule: float = DEFAULT_RULE

    @property
    def speedup(self) -> float:
        """Reference wall time over the chosen setting's."""
        return self.reference_wall_s / self.wall_s if self.wall_s > 0 else math.nan


def floor_ratios(regime: dict[str, Any], measures: Sequence[str]) -> dict[str, float]:
    """error/σ of the floor run per measure (empty without one)."""
    floors = [s for s in regime["settings"] if s["role"] == "floor" and usable(s)]
    return {m: compare_setting(regime, floors[0], m).ratio for m in measures} if floors else {}


def meets(regime: dict[str, Any], setting: dict[str, Any], measures: Sequence[str], rule: float) -> bool:
    """True when ``setting`` completed and its error is within ``rule`` · σ for every one of ``measures``."""
    if setting["role"] == "reference":
        return True
    return usable(setting) and all(compare_setting(regime, setting, m).ratio <= rule for m in measures)


def load_results(source: dict[str, Any] | str | Path) -> dict[str, Any]:
    """A result document (the study's JSON) from a dict or a path."""
    if isinstance(source, dict):
        return source
    import json

    return json.loads(Path(source).read_text())


def settings_for(
    results: dict[str, Any] | str | Path,
    regime: str,
    measures: Sequence[str] | None = None,
    rule: float = DEFAULT_RULE,
) -> Choice:
    """The cheapest setting of ``regime`` in a result file whose ensemble-mean error is within ``rule`` × the
    standard deviation between seeds for every one of ``measures`` (None: every measure of the regime) that its
    floor can decide (module docstring). Raises KeyError for a regime or measure the file does not hold."""
    doc = load_results(results)
    if regime not in doc["regimes"]:
        raise KeyError(f"no regime {regime!r} in the results (has {', '.join(doc['regimes'])})")
    reg = doc["regimes"][regime]
    names = list(reg["measures"] if measures is None else measures)
    unknown = [m for m in names if m not in reg["measures"]]
    if unknown:
        raise KeyError(f"regime {regime!r} has no measure {', '.join(unknown)} (has {', '.join(reg['measures'])})")
    floor = floor_ratios(reg, names)
    undecided = [m for m in names if m in floor and not floor[m] <= rule]
    decided = [m for m in names if m not in undecided]
    cands = [s for s in reg["settings"] if s["role"] in ("reference", "grid") and s.get("wall_s") is not None]
    ref = reference_of(reg)
    passing = (
        sorted((s for s in cands if meets(reg, s, decided, rule)), key=lambda s: s["wall_s"]) if decided else [ref]
    )
    best = passing[0]
    ratios = {m: compare_setting(reg, best, m).ratio if best is not ref else 0.0 for m in decided}
    return Choice(
        regime, best["label"], best["wall_s"], ref["wall_s"], ratios, decided, undecided,
        [s["label"] for s in passing], rule,
    )  # fmt: skip
