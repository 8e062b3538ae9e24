"""The measures, statistics and rule of the statistical work-precision study
(:mod:`aca_warp.studies.work_precision_stats`); NumPy only, so that a result file is judged without a simulation.

**Measures** (:data:`MEASURES`): what the validation's ensembles rest on, read from the validation's own per-pad
analysis (``pad_measures`` over the per-patch window of a saturated run, ``growth_measures`` of a growing run and
the saturation figures of every pad). A measure's per-pad value is a number, or a vector (the spectra: log10 of
the mean amplitude in :data:`BAND_WIDTH` bands over :data:`SPECTRUM_BAND`).

**Statistics** (:func:`compare`): for one measure, the reference ensemble x_ref (one value per seed) and the
ensemble of a setting x (the same seeds, the same pads), with d = x − x_ref per seed:

* error = |mean(d)| = |mean(x) − mean(x_ref)|, the error of the setting's ensemble mean (the paired estimate of
  its bias);
* σ = the standard deviation of x_ref between seeds (ddof 1), and the 95 % half-width of its mean
  t(0.975, n − 1) σ / √n (as ``aca_warp.analysis.measures.ensemble_interval`` gives it);
* the standard error of the error, sd(d) / √n: a chaotic run parts from the reference's soon after it saturates,
  so part of any error is the sampling noise of two different trajectories over a finite window, not a bias of
  the integrator; ``bound`` = error + t(0.975, n − 1) sd(d)/√n is the upper end of the 95 % interval of the bias
  (``bound90`` with t(0.95, n − 1): the 90 % interval of a two one-sided test);
* for a vector measure every figure is the root mean square over the components (bands), the bound over the
  components' bounds.

A regime whose pads have members (the LF states) is compared member by member; the regime's figure is the member
with the largest bound/σ, its verdict the worst of the members'.

**Resolution floor**: runs of two equally exact settings that have parted give d of standard deviation up to √2 σ
(no pairing left, equal spread), so the 95 % interval of an exact setting's bias has the half-width
t(0.975, n − 1) √2 σ/√n (:func:`resolution_floor`): 0.51 σ with 32 seeds. No setting can be shown within ¼ σ
below it; :func:`seeds_needed` gives the seeds at which a measure's observed sd(d) would allow it.

**Rule** (:func:`settings_for`): a setting **keeps** a measure when the 95 % interval of its bias lies within
± ``rule`` · σ, **moves** it when the interval lies wholly beyond (error − t sd(d)/√n > ``rule`` · σ). Between the
two, the ``criterion`` (:data:`CRITERIA`) decides: ``resolution`` (the default) calls the measure **kept within
resolution** when the estimate of the bias is within ± ``rule`` · σ and the interval is no wider than the floor's
(sd(d)² ≤ 2 σ² F(0.95; n − 1, n − 1): d's variance not significantly larger than two independent draws of the
reference ensemble give), **undecided** otherwise; ``twin`` takes the floor from the measured sd(d) of the
reference's twin (:func:`twin_of`); ``strict`` keeps only what the 95 % interval proves; ``tost`` what the 90 %
interval proves. The rule picks the setting of least stepping wall time that keeps every measure asked for; the
reference always does (and is the pick when no other setting does).
"""

from __future__ import annotations

import functools
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
CRITERIA = {
    "resolution": "95 % interval within ± rule·σ, or else the bias estimate within ± rule·σ and sd(d) no larger "
    "than the floor √2 σ allows",
    "twin": "95 % interval within ± rule·σ, or else the bias estimate within ± rule·σ and sd(d) no larger than the "
    "twin's allows",
    "strict": "95 % interval within ± rule·σ",
    "tost": "90 % interval within ± rule·σ (two one-sided tests at 5 %)",
}
"""What each criterion of the rule counts as keeping a measure (module docstring)."""
DEFAULT_CRITERION = "resolution"
FLOOR_LEVEL = 0.95  # level of the variance-ratio test of sd(d) against the floor
ORDER = ("moves", "undecided", "within resolution", "keeps")  # verdicts, worst first


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
    "f1": Measure("f1", "Hz", SAT, _measure("f1_patch.0p1"),
                  "first peak of the mean per-patch velocity spectrum (0.1 × max)"),
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
        paired_se: Standard error of the mean paired difference, sd(x − x_ref)/√n (rms over components).
        bound: Upper end of the 95 % interval of |bias|: error + t sd/√n (rms over components).
        low: Lower end, max(0, error − t sd/√n) (rms over components).
        bound90: Upper end of the 90 % interval of |bias| (rms over components).
        member: The member (LF state) it belongs to, or None.
    """

    n: int
    reference_mean: float
    error: float
    sigma: float
    half_width: float
    paired_se: float
    bound: float
    low: float
    bound90: float
    member: str | None = None

    @property
    def ratio(self) -> float:
        """error / σ (NaN when σ is not positive or not known)."""
        return self.error / self.sigma if self.sigma > 0 else math.nan

    @property
    def bound_ratio(self) -> float:
        """bound / σ: the largest bias in units of σ that the 95 % interval allows."""
        return self.bound / self.sigma if self.sigma > 0 else math.nan

    @property
    def sd_ratio(self) -> float:
        """sd(d) / σ: how far the setting's seeds scatter about the reference's (√2 once the runs have parted)."""
        return self.paired_se * math.sqrt(self.n) / self.sigma if self.sigma > 0 else math.nan

    def verdict(self, rule: float, criterion: str = "resolution", twin: Comparison | None = None) -> str:
        """ "keeps", "within resolution", "undecided" or "moves" under ``criterion`` (:data:`CRITERIA`; module
        docstring); ``twin``: the reference's twin on the same seeds (criterion "twin"; None: no floor, as
        "strict"). NaN figures: undecided."""
        if criterion not in CRITERIA:
            raise KeyError(f"no criterion {criterion!r} (choose from {', '.join(CRITERIA)})")
        bound = self.bound90 if criterion == "tost" else self.bound
        if self.sigma > 0 and bound <= rule * self.sigma:
            return "keeps"
        if not self.sigma > 0:
            return "undecided"
        if self.low > rule * self.sigma:
            return "moves"
        floor = {"resolution": math.sqrt(2.0), "twin": twin.sd_ratio if twin is not None else math.nan}
        if self.ratio <= rule and self.sd_ratio <= floor.get(criterion, math.nan) * floor_factor(self.n):
            return "within resolution"
        return "undecided"


def floor_factor(n: int) -> float:
    """How much larger than the floor's a sample sd(d) of ``n`` seeds may be: √F(:data:`FLOOR_LEVEL`; n − 1, n − 1)
    (the one-sided variance-ratio test of two ensembles of n seeds; 1.35 at n = 32)."""
    import scipy.stats

    return math.sqrt(float(scipy.stats.f.ppf(FLOOR_LEVEL, n - 1, n - 1))) if n >= 2 else math.nan


@functools.lru_cache(maxsize=4096)
def _t(n: int, level: float = 0.95) -> float:
    """The two-sided ``level`` quantile of Student's t with n − 1 degrees of freedom (the half-width of a mean's
    interval over n seeds in units of sd/√n)."""
    from aca_warp.analysis.measures.ensemble import t_quantile

    return t_quantile(0.5 + level / 2.0, n - 1)


def resolution_floor(n: int) -> float:
    """The 95 % half-width of an exact setting's bias in units of σ once its runs have parted from the
    reference's (sd(d) = √2 σ): t(0.975, n − 1) √2 / √n."""
    return _t(n) * math.sqrt(2.0 / n) if n >= 2 else math.nan


def seeds_needed(sd_ratio: float, rule: float = DEFAULT_RULE, limit: int = 100_000) -> int | None:
    """The least number of seeds at which the 95 % half-width t(0.975, n − 1) · sd(d)/√n of an unbiased setting
    whose sd(d) is ``sd_ratio`` σ falls to ``rule`` σ: the seeds the strict rule needs to keep the measure at all
    (None past ``limit`` or for a ratio that is not finite)."""
    if not math.isfinite(sd_ratio) or sd_ratio < 0:
        return None
    n = max(2, math.ceil((1.959963984540054 * sd_ratio / rule) ** 2))  # the normal quantile: t is larger
    while _t(n) * sd_ratio / math.sqrt(n) > rule:
        n += 1
        if n > limit:
            return None
    return n


def keep_chance(n: int, bias: float, rule: float = DEFAULT_RULE) -> float:
    """Probability that an estimate of the bias lies within ± ``rule`` σ for a setting of true bias ``bias`` σ whose
    runs have parted from the reference's (sd(d) = √2 σ), over ``n`` seeds (normal approximation): how often the
    "resolution" criterion keeps such a measure."""
    from scipy.stats import norm

    se = math.sqrt(2.0 / n)
    return float(norm.cdf((rule - bias) / se) - norm.cdf((-rule - bias) / se))


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def compare(reference: Any, values: Any, member: str | None = None) -> Comparison:
    """:class:`Comparison` of per-seed ``values`` against ``reference`` (each shape (seeds,) or (seeds, components),
    NaN where missing; the same seed in the same row). A seed counts when both have every component that at least
    half of the seeds have; fewer than two seeds give NaN figures."""
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
        return Comparison(n, *([math.nan] * 8), member=member)
    r, v = ref2[rows][:, cols], val2[rows][:, cols]
    sigma, d = r.std(axis=0, ddof=1), v - r
    err, se = np.abs(d.mean(axis=0)), d.std(axis=0, ddof=1) / math.sqrt(n)  # the error and its standard error
    half = _t(n) * se
    return Comparison(
        n=n,
        reference_mean=float(np.mean(r)),
        error=_rms(err),
        sigma=_rms(sigma),
        half_width=_rms(_t(n) * sigma / math.sqrt(n)),
        paired_se=_rms(se),
        bound=_rms(err + half),
        low=_rms(np.maximum(err - half, 0.0)),
        bound90=_rms(err + _t(n, 0.90) * se),
        member=member,
    )


def _members(regime: dict[str, Any]) -> dict[str | None, list[int]]:
    """Member -> indices of its pads (one member None without members)."""
    out: dict[str | None, list[int]] = {}
    for i, p in enumerate(regime["pads"]):
        out.setdefault(p.get("member"), []).append(i)
    return out


def member_comparisons(
    regime: dict[str, Any], setting: dict[str, Any], measure: str, ref: dict[str, Any] | None = None
) -> list[Comparison]:
    """``setting`` against ``ref`` (default the regime's reference) for ``measure``, one :class:`Comparison` per
    member (one for a regime without members)."""
    ref = reference_of(regime) if ref is None else ref
    out = []
    for member, idx in _members(regime).items():
        a = [ref["values"][measure][i] for i in idx]
        b = [setting["values"][measure][i] for i in idx] if setting.get("values") else [math.nan] * len(idx)
        out.append(compare(_matrix(a), _matrix(b), member))
    return out


def compare_setting(
    regime: dict[str, Any], setting: dict[str, Any], measure: str, ref: dict[str, Any] | None = None
) -> Comparison:
    """``setting`` against ``ref`` (default the regime's reference) for ``measure``: the member with the largest
    bound/σ (a member whose figure is not defined counts as the worst)."""
    worst: Comparison | None = None
    for c in member_comparisons(regime, setting, measure, ref):
        if worst is None or not (c.bound_ratio <= worst.bound_ratio):  # NaN beats every number
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


def measures_asked(name: str, regime: dict[str, Any], measures: Sequence[str] | None) -> list[str]:
    """The measures ``measures`` of the regime ``name`` (None: every one it has), in that order; ValueError naming
    those it lacks."""
    names = list(measures or regime["measures"])
    unknown = [m for m in names if m not in regime["measures"]]
    if unknown:
        raise ValueError(f"{name} has no measure {', '.join(unknown)} (it has {', '.join(regime['measures'])})")
    return names


def usable(setting: dict[str, Any]) -> bool:
    """A setting whose run completed and was analysed."""
    return bool(setting.get("complete")) and bool(setting.get("values"))


VARIANT = {"integrator": None, "dt": None, "tolerance": None, "fast_math": False, "growth_dt": None,
           "crossing": "point", "solve_tol": None}  # fmt: skip
"""A setting's fields besides its precision (the study's ``Setting``), with the value a result file's row that lacks
one holds (files written before the field existed)."""


def variant(setting: dict[str, Any]) -> tuple[Any, ...]:
    """Everything of a setting (a result file's row) but its precision, old rows' missing fields at their defaults:
    two settings of one variant differ in precision alone."""
    return tuple(setting.get(k, default) for k, default in VARIANT.items())


def twin_of(regime: dict[str, Any]) -> dict[str, Any] | None:
    """The reference's twin: the completed grid setting of the reference's :func:`variant` (integrator, step,
    tolerances, growth events, crossing treatment; the reference runs without fast math) in the other precision (as
    exact as the reference; its runs part from the reference's by rounding alone), or None."""
    ref = reference_of(regime)
    twins = [s for s in regime["settings"] if s["role"] == "grid" and usable(s) and variant(s) == variant(ref)
             and s.get("precision") != ref.get("precision")]  # fmt: skip
    return twins[0] if twins else None


def verdict(
    regime: dict[str, Any], setting: dict[str, Any], measure: str, rule: float, criterion: str = DEFAULT_CRITERION
) -> str:
    """ "keeps", "within resolution", "undecided" or "moves" (:meth:`Comparison.verdict`; of a regime with members
    the worst member's); the reference keeps, a run that did not complete keeps nothing ("no run")."""
    if setting["role"] == "reference":
        return "keeps"
    if not usable(setting):
        return "no run"
    twin = twin_of(regime) if criterion == "twin" else None
    twins = member_comparisons(regime, twin, measure) if twin is not None else None
    own = member_comparisons(regime, setting, measure)
    verdicts = [c.verdict(rule, criterion, twins[k] if twins else None) for k, c in enumerate(own)]
    return min(verdicts, key=ORDER.index)


def kept(v: str) -> bool:
    """A verdict that counts as keeping the measure."""
    return v in ("keeps", "within resolution")


# ------------------------------------------------------------------------------------------------ the rule


@dataclass(frozen=True)
class Choice:
    """What the rule picks in one regime (:func:`settings_for`).

    Attributes:
        regime: The regime.
        setting: Label of the chosen setting.
        wall_s: Its stepping wall time [s].
        reference_wall_s: The reference's [s].
        measures: The measures it keeps.
        passing: Labels of every setting that keeps them all, cheapest first.
        cheapest: Per measure, the cheapest setting that keeps it (the dearest of these sets the choice).
        rule: The fraction of σ.
        criterion: What counts as keeping (:data:`CRITERIA`).
        verdicts: Per measure, the chosen setting's verdict.
        fails: Per completed setting cheaper than the chosen one, cheapest first, the measures it does not keep.
    """

    regime: str
    setting: str
    wall_s: float
    reference_wall_s: float
    measures: list[str]
    passing: list[str] = field(default_factory=list)
    cheapest: dict[str, str] = field(default_factory=dict)
    rule: float = DEFAULT_RULE
    criterion: str = DEFAULT_CRITERION
    verdicts: dict[str, str] = field(default_factory=dict)
    fails: dict[str, list[str]] = field(default_factory=dict)

    @property
    def binding(self) -> list[str]:
        """The measures that bind the choice: each the only one a cheaper setting does not keep."""
        return [m for m in self.measures if [m] in self.fails.values()]

    @property
    def speedup(self) -> float:
        """Reference wall time over the chosen setting's."""
        return self.reference_wall_s / self.wall_s if self.wall_s > 0 else math.nan


def load_results(source: dict[str, Any] | str | Path) -> dict[str, Any]:
    """A result document (the study's JSON) from a dict or a path; ValueError for a file that is not one (no
    object with a ``regimes`` object of regimes that each hold ``pads`` and ``settings`` lists)."""
    if isinstance(source, dict):
        return source
    import json

    try:
        doc = json.loads(Path(source).read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{source}: not JSON ({e})") from None
    regimes = doc.get("regimes") if isinstance(doc, dict) else None
    if not isinstance(regimes, dict) or not all(
        isinstance(r, dict) and isinstance(r.get("pads"), list) and isinstance(r.get("settings"), list)
        for r in regimes.values()
    ):
        raise ValueError(f"{source}: not a result file of the statistical work-precision study")
    return doc


def settings_for(
    results: dict[str, Any] | str | Path,
    regime: str,
    measures: Sequence[str] | None = None,
    rule: float = DEFAULT_RULE,
    criterion: str = DEFAULT_CRITERION,
) -> Choice:
    """The cheapest setting of ``regime`` in a result file that keeps every one of ``measures`` (None: every measure
    of the regime) within ``rule`` × the standard deviation between seeds, as ``criterion`` counts keeping (module
    docstring). Raises KeyError for a regime, measure or criterion the file or rule does not hold."""
    doc = load_results(results)
    if criterion not in CRITERIA:
        raise KeyError(f"no criterion {criterion!r} (choose from {', '.join(CRITERIA)})")
    if regime not in doc["regimes"]:
        raise KeyError(f"no regime {regime!r} in the results (has {', '.join(doc['regimes'])})")
    reg = doc["regimes"][regime]
    names = list(reg["measures"] if measures is None else measures)
    unknown = [m for m in names if m not in reg["measures"]]
    if unknown:
        raise KeyError(f"regime {regime!r} has no measure {', '.join(unknown)} (has {', '.join(reg['measures'])})")
    ref = reference_of(reg)
    if not usable(ref) or ref.get("wall_s") is None:
        raise ValueError(f"the reference of regime {regime!r} did not complete: {ref.get('fault')}")
    cands = sorted((s for s in reg["settings"] if s.get("wall_s") is not None), key=lambda s: s["wall_s"])
    verdicts = {s["label"]: {m: verdict(reg, s, m, rule, criterion) for m in names} for s in cands}
    passing = [s for s in cands if all(kept(v) for v in verdicts[s["label"]].values())]
    cheapest = {m: next(s["label"] for s in cands if kept(verdicts[s["label"]][m])) for m in names}
    best = passing[0]
    cheaper = [s["label"] for s in cands[: cands.index(best)] if usable(s)]
    fails = {s: [m for m, v in verdicts[s].items() if not kept(v)] for s in cheaper}
    return Choice(regime, best["label"], best["wall_s"], ref["wall_s"], names, [s["label"] for s in passing],
                  cheapest, rule, criterion, verdicts[best["label"]], fails)  # fmt: skip
