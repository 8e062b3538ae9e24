"""What every part of the validation study shares: settings, the registries of experiments and rows, and the
helpers that turn saved per-pad results into intervals over seeds.

:mod:`~aca_warp.studies.validation.hf_experiments` (§3.1), :mod:`~aca_warp.studies.validation.area` (§3.2) and
:mod:`~aca_warp.studies.validation.multiscale` (§3.3, §4) register their experiments here, the row modules
(``hf_patterns``, ``hf_peaks``, ``hf_sync``, ``area_rows``, ``multiscale_rows``, ``appendix``) their rows;
:mod:`~aca_warp.studies.validation.experiments` runs them and :mod:`~aca_warp.studies.validation.cli` writes the
results and the table; the verdicts are in :mod:`~aca_warp.studies.validation.verdicts`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aca_warp.studies.report import clean
from aca_warp.studies.validation.verdicts import (
    FAILED,
    NOT_MEASURED,
    direction_verdict,
    effect,
    effect_text,
    rules_verdict,
)

MM2 = 1.0e-6  # m² per mm²
CHARACTERISTIC_BAND = (20.0e3, 80.0e3)
"""Hz: §4, "the characteristic friction and synchronization behavior ... 20–80 kHz"."""
SYNC_EXCESS = 0.05
"""S − S_null above which a frequency bin counts as synchronised."""
CHANCE_MARGIN = 0.05
"""μ's peaks "do not correspond" to S, read against chance: the share of them without a synchronised bin nearby at
most 0.05 below the share of all bins without one (peaks at S at most that much more often than at random)."""

# ------------------------------------------------------------------------------------------------ settings


@dataclass(frozen=True)
class Config:
    """Settings of a validation run (one for every experiment).

    Attributes:
        device: Warp device ("cpu", "cuda:0").
        engine: "auto", "general" or "onchip".
        seeds: Pads per experiment (seeds first_seed … first_seed + seeds − 1).
        first_seed: Seed of pad 0 (1: the presets' own layout).
        patches: Patches per pad; None: the preset's count (1758). Fewer sit on a sector of the pad.
        dt: Time step [s] for every experiment instead of :data:`~aca_warp.studies.validation.settings.STEPPING`'s.
        precision: "fp32" or "fp64" for every experiment instead of the stepping table's.
        growth_dt: Spacing of the growth events [s] of the growing experiments instead of the stepping table's;
            "scene": the scenes' own interval (the paper's clock).
        sample_dt: Sampling interval of the global outputs [s].
        decimation: Per-patch velocities every ``decimation`` global samples (Nyquist 1/(2·dt_p)).
        window: Measurement window at the end of a run [s] (per-patch record; spectra resolve 1/window).
        perturbation: Standard deviation of the initial patch velocities about equilibrium [m/s].
        settle_safety: Factor on the predicted time to saturation.
        sync_band: (fmin, fmax) of S(f) [Hz]; fmax is lowered to 0.9 Nyquist of the per-patch record.
        quick: The reduced CPU variant (named in the table).
        growth_speedup: Compression of the varying-area growth of the ``va`` variants (§3.2): the increment of
            Eq. 10 × this, the run ÷ this, so the areas follow the same path in a shorter time (``va_full`` runs
            the paper's 0.36 s).
        paper_length: Length of the from-rest runs at the paper's length [s] (0.36 s: the varying-area run,
            "about as long as HF1").
        track_windows: Per-patch windows of those runs over time (f1, neighbour correlation, S per window).
        track_window: Length of each such window [s].
        state_patches: Patches per LF state of the multi-timescale experiments (a sector of the state, §3.3);
            None: ``patches`` (None: the whole state).
        lf_dir: Folder of the LF runs of the multi-timescale experiments (§3.3); not part of the run key.
        workers: Processes that analyse the pads of an experiment in parallel; not part of the run key.
    """

    device: str = "cpu"
    engine: str = "auto"
    seeds: int = 8
    first_seed: int = 1
    patches: int | None = None
    dt: float | None = None
    precision: str | None = None
    growth_dt: float | str | None = None
    sample_dt: float = 1.0e-6
    decimation: int = 3
    window: float = 20.0e-3
    perturbation: float = 1.0e-2
    settle_safety: float = 1.5
    sync_band: tuple[float, float] = (1.0e3, 150.0e3)
    quick: bool = False
    growth_speedup: float = 10.0
    paper_length: float = 0.36
    track_windows: int = 8
    track_window: float = 5.0e-3
    state_patches: int | None = None
    lf_dir: str | None = None
    workers: int = 1

    def run_key(self) -> dict[str, Any]:
        """The settings that decide a run's result (device, engine, LF folder and workers left out), with the
        stepping of each kind of experiment as it describes itself, so that results made under another stepping
        or friction scheme are not taken for this run's (:func:`same_settings`)."""
        from aca_warp.studies.validation.settings import STEPPING

        d = dataclasses.asdict(self)
        for k in ("device", "engine", "lf_dir", "workers"):
            d.pop(k)
        d["stepping"] = {kind: self.stepping(kind).describe() for kind in STEPPING}
        return clean(d)

    def stepping(self, kind: str) -> Any:
        """The :class:`~aca_warp.studies.validation.settings.Stepping` of experiments of ``kind``."""
        from aca_warp.studies.validation.settings import stepping

        return stepping(kind, self.quick, self.dt, self.precision, self.growth_dt)


STEPPING_OVERRIDES = ("dt", "precision", "growth_dt")
"""Settings that only replace values of the stepping table: a run key's stepping describes what each kind ran with."""


def without_stepping(key: Any) -> Any:
    """A run key (:meth:`Config.run_key`) less the stepping table and its overrides (:data:`STEPPING_OVERRIDES`):
    the settings every kind of experiment shares. The work-precision study compares its result files so (its grid
    and reference set the steps), so that a change of the table, or an override added to the run key, does not make
    a file another run (continued or merged); anything but a dict is returned as it is."""
    if not isinstance(key, dict):
        return key
    return {k: v for k, v in key.items() if k != "stepping" and k not in STEPPING_OVERRIDES}


def same_settings(key: dict[str, Any], other: dict[str, Any], kind: str | None) -> bool:
    """Whether two run keys (:meth:`Config.run_key`) agree on everything an experiment of stepping ``kind`` depends
    on: every setting, and the stepping of that kind as described (the other kinds' may differ: a result of the hf
    kind made before the growth stepping changed is still this run's; the overrides :data:`STEPPING_OVERRIDES` count
    through the description); ``kind`` None: every setting but the stepping."""

    def mine(k: dict[str, Any]) -> dict[str, Any]:
        return {**without_stepping(k), "stepping": (k.get("stepping") or {}).get(kind) if kind else None}

    return mine(key) == mine(other)


FULL = Config()
QUICK = Config(
    seeds=3,
    patches=150,
    window=8.0e-3,
    quick=True,
    growth_speedup=20.0,
    paper_length=0.03,
    track_windows=4,
    track_window=2.0e-3,
    state_patches=60,
)


# ------------------------------------------------------------------------------------------------ processes


_POOL: dict[int, Any] = {}


def map_pads(fn: Callable[[Any], Any], jobs: list[Any], workers: int) -> list[Any]:
    """``[fn(j) for j in jobs]``, in ``workers`` processes (spawned, kept for the next call) when more than one."""
    if workers <= 1 or len(jobs) <= 1:
        return [fn(j) for j in jobs]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if workers not in _POOL:
        _POOL[workers] = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
    return list(_POOL[workers].map(fn, jobs))


def close_pools() -> None:
    """Shut the analysis processes down."""
    for pool in _POOL.values():
        pool.shutdown()
    _POOL.clear()


# ------------------------------------------------------------------------------------------------ registries


@dataclass(frozen=True)
class Experiment:
    """One ensemble: a preset with changes, one pad per seed.

    Attributes:
        name: Key (folder name under ``--out``).
        section: The paper's section it serves.
        description: One line for the tables.
        preset: Base preset.
        M: Friction factor of Eq. 4 instead of the preset's (None: keep).
        mean_area_mm2: Mean patch area [mm²] instead of the preset's: areas uniform in AREA_SPREAD × mean, load
            HF1_PRESSURE × patches × mean, height spread derived so the load is HEIGHT_MARGIN above the
            all-in-contact load (None: keep the preset's patches).
        initial: "equilibrium" (+ the configured velocity perturbation) or "rest".
        duration: Fixed run length [s]; None: from the predicted growth rate (:func:`plan_run`), or for a
            growing scene its own duration (compressed by the growth speedup).
        builder: ``(experiment, pad index, config) -> Scene`` instead of :func:`experiment_scene` (for studies
            whose scenes are not a changed preset, e.g. LF snapshots); the pad index k stands for member
            ``members[k // seeds]`` of seed ``first_seed + k % seeds`` (:func:`pad_member`).
        kind: How the run is planned and analysed: ``"saturated"`` (run to saturation, analyse the saturated
            part), ``"window"`` (a fixed run, every pad analysed over the per-patch window from ``window_start``
            whether saturated or not: the linear phase of the single-run studies) or ``"growth"`` (a growing
            scene, μ and the global sums analysed over the whole run after the first saturation).
        members: Scenes per seed (e.g. LF states); the experiment has seeds × len(members) pads (one per seed
            when empty).
        window_scale: Measurement window of a ``"saturated"`` run as a multiple of the configured window.
        window_start: Start of the per-patch record of a ``"window"`` run [s].
        growth_speedup: Growth compression of a growing scene; None: the configured one (``va`` and its variants;
            1: the paper's growth rate).
        schedule_bar: Application pressures [bar] of the LF schedule in order (None: the preset's).
        tracks: Run for the paper's length (``Config.paper_length``) and analyse, besides the final window, the
            per-patch windows of ``Config.track_windows`` over the run (f1, neighbour correlation and S over time).
        batch: Experiments with the same batch name run as one batch of pads (one run, one kernel; the run as long
            as its longest member's plan, the step the smallest of their bounds), each analysed on its own.
        stepping: Key of :data:`~aca_warp.studies.validation.settings.STEPPING` (integrator, step, precision).
        quick: Run in the quick CPU variant too (False: only in the full variant or when named with --only).
        opt_in: Run only when named with --only.
    """

    name: str
    section: str
    description: str
    preset: str
    M: float | None = None
    mean_area_mm2: float | None = None
    initial: str = "equilibrium"
    duration: float | None = None
    builder: Callable[[Experiment, int, Config], Any] | None = None
    kind: str = "saturated"
    members: tuple[str, ...] = ()
    window_scale: float = 1.0
    window_start: float | None = None
    growth_speedup: float | None = None
    schedule_bar: tuple[float, ...] | None = None
    tracks: bool = False
    batch: str | None = None
    stepping: str = "hf"
    quick: bool = True
    opt_in: bool = False

    def key(self) -> dict[str, Any]:
        """The definition as it decides the result (for checkpoint reuse; fields at their defaults beyond the
        original eight are left out, so that results saved before they existed still match)."""
        skip = ("builder", "quick", "opt_in", "batch")
        d = {k: v for k, v in dataclasses.asdict(self).items() if k not in skip}
        defaults = {f.name: f.default for f in dataclasses.fields(self) if f.name not in _ORIGINAL_KEYS}
        return {k: v for k, v in d.items() if k in _ORIGINAL_KEYS or v != defaults.get(k)}

    @property
    def pads_per_seed(self) -> int:
        """Pads per seed: the number of members (1 without)."""
        return max(1, len(self.members))


_ORIGINAL_KEYS = ("name", "section", "description", "preset", "M", "mean_area_mm2", "initial", "duration")


def pad_member(exp: Experiment, k: int, cfg: Config) -> tuple[str | None, int]:
    """(member, seed) of pad ``k`` of ``exp``: member ``members[k // seeds]``, seed ``first_seed + k % seeds``."""
    member = exp.members[k // cfg.seeds] if exp.members else None
    return member, cfg.first_seed + k % cfg.seeds


@dataclass(frozen=True)
class RowValue:
    """What a row function returns: the value text, the verdict, and notes (secondary measures)."""

    value: str
    verdict: str
    notes: str = ""

    @classmethod
    def direction(
        cls,
        what: str,
        d: np.ndarray,
        margin: float,
        before: str = "",
        after: str = "",
        *,
        sign: float = 1.0,
        snr: np.ndarray | None = None,
    ) -> RowValue:
        """The row of one directional effect ``d`` (one value per seed): the value "``what``: interval of d"; the
        verdict of ``sign``·d against ``margin`` (:func:`~aca_warp.studies.validation.verdicts.direction_verdict`),
        with ``snr`` (the same measure under the snr rule of Φ) undetermined where the two rules disagree
        (``rules_verdict``); the notes ``before``, how the mean effect compares with the margin, ``after`` (joined by
        "; ", the empty ones left out)."""
        verdict = direction_verdict([effect(d, margin, sign)])
        if snr is not None:
            verdict = rules_verdict(verdict, d, snr, sign)
        notes = "; ".join(t for t in (before, effect_text(d, margin, sign), after) if t)
        return cls(f"{what}: {interval(d)}", verdict, notes)


@dataclass(frozen=True)
class Row:
    """One statement of the paper and the ensemble measure that tests it.

    Attributes:
        section: Where the paper says it (section/figure).
        statement: The statement, quoted briefly.
        paper: The paper's value or claim.
        kind: Key of :data:`~aca_warp.studies.validation.verdicts.CRITERIA` (how the verdict is decided).
        experiments: Experiments the row needs.
        measure: ``(results, config) -> RowValue``; results maps experiment name -> saved result (JSON dict).
        criterion: The row's own tolerance or threshold, in words.
        min_experiments: How many of ``experiments`` need two usable pads (None: all of them).
        uses: What the measure depends on beyond the runs, for the analysis variants of
            :mod:`~aca_warp.studies.validation.causes`: "sync" (S and Φ), "stft" (the STFT window).
        construction: Why the statement holds by construction (the model's parameters were chosen so that it does,
            or it is a property of the index's definition) or checks the code rather than the model; empty for a
            finding of the model. The page marks such rows and counts them apart.
    """

    section: str
    statement: str
    paper: str
    kind: str
    experiments: tuple[str, ...]
    measure: Callable[[dict[str, dict], Config], RowValue]
    criterion: str = ""
    min_experiments: int | None = None
    uses: tuple[str, ...] = ()
    construction: str = ""


EXPERIMENTS: dict[str, Experiment] = {}
ROWS: list[Row] = []


def register_experiment(exp: Experiment) -> Experiment:
    """Add ``exp`` to :data:`EXPERIMENTS` (a name already there is replaced)."""
    EXPERIMENTS[exp.name] = exp
    return exp


def register_row(row: Row) -> Row:
    """Append ``row`` to :data:`ROWS`."""
    ROWS.append(row)
    return row


# ------------------------------------------------------------------------------------------------ row helpers


USABLE = ("saturated", "linear phase", "LF state")
"""Pad statuses that enter rows: saturated, analysed over a fixed window of a ``"window"`` experiment, or an LF
state's facts (``multiscale.lf_facts``)."""


def usable(res: dict[str, Any] | None, member: str | None = None) -> list[dict[str, Any]]:
    """The analysed pads of an experiment's result (saturated or a linear-phase window, with measures); with
    ``member``, only that member's pads (e.g. one LF state)."""
    if not res:
        return []
    pads = [p for p in res.get("pads", []) if p.get("status") in USABLE and "measures" in p]
    return pads if member is None else [p for p in pads if p.get("member") == member]


def _get(pad: dict[str, Any], key: str) -> float:
    """A measure of a pad by dotted key ("sync_relative.spread"), NaN when missing or not finite."""
    v: Any = pad["measures"]
    for part in key.split("."):
        v = v.get(part) if isinstance(v, dict) else None
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else float("nan")


def member_result(results: dict[str, dict], names: tuple[str, ...], member: str) -> dict[str, Any]:
    """The pads of ``member`` (e.g. the LF state "app3_start") over the results of the experiments ``names``,
    as one result {"pads": [...]} that the other helpers take (an experiment named twice counts once)."""
    seen: set[int] = set()
    pads: list[dict[str, Any]] = []
    for n in names:
        res = results.get(n)
        if res is None or id(res) in seen:
            continue
        seen.add(id(res))
        pads += [p for p in res.get("pads", []) if p.get("member") == member]
    return {"pads": pads}


def by_seed(res: dict[str, Any] | None, value: Callable[[dict[str, Any]], float]) -> dict[int, float]:
    """Seed -> value(pad) over the usable pads, finite values only."""
    out = {}
    for p in usable(res):
        try:
            v = float(value(p))
        except (ValueError, ZeroDivisionError, KeyError, TypeError):  # a measure missing or out of its domain
            continue
        if math.isfinite(v):
            out[int(p["seed"])] = v
    return out


def values(res: dict[str, Any] | None, key: str) -> np.ndarray:
    """A measure over the usable pads (finite values)."""
    return np.array(list(by_seed(res, lambda p: _get(p, key)).values()))


def paired(a: dict[int, float], b: dict[int, float]) -> np.ndarray:
    """a − b over the seeds both have."""
    return np.array([a[s] - b[s] for s in sorted(a) if s in b])


def interval(v: np.ndarray, spec: str = ".3g", scale: float = 1.0, unit: str = "") -> str:
    """ "mean [low, high] unit (n)" of the Student-t 95 % interval of the mean over seeds (``ensemble_interval``)."""
    from aca_warp.analysis.measures import ensemble_interval

    v = np.asarray(v, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return "–"
    e = ensemble_interval(v * scale)
    u = f" {unit}" if unit else ""
    if v.size == 1:
        return f"{format(e.mean, spec)}{u} (n = 1, no interval)"
    return f"{format(e.mean, spec)} [{format(e.mean_low, spec)}, {format(e.mean_high, spec)}]{u} (n = {v.size})"


def tables(res: dict[str, Any] | None, rule: str, which: str = "table") -> dict[int, Any]:
    """Seed -> ``PrevalenceTable`` of S at equal Φ of the usable pads."""
    from aca_warp.analysis.measures import PrevalenceTable

    out = {}
    for p in usable(res):
        t = p["measures"][f"sync_{rule}"][which]
        arr = {k: np.array([np.nan if x is None else x for x in t[k]], dtype=np.float64) for k in t}
        out[int(p["seed"])] = PrevalenceTable(
            arr["lower"].astype(int), arr["upper"].astype(int), arr["bins"].astype(int), arr["mean_S"],
            arr["mean_S_null"], arr["mean_excess"],
        )  # fmt: skip
    return out


def equal_phi(
    results: dict[str, dict], a: str, b: str, rule: str = "relative", value: str = "excess", which: str = "table"
) -> tuple[np.ndarray, str]:
    """Paired differences a − b of S (``value``: "excess" = S − S_null, or "S") at equal Φ, and the classes used."""
    seeds, d = _equal_prevalence(results, a, b, rule, which, value)
    if d is None:
        return np.array([]), "no common seed"
    used = [f"{lo}–{hi - 1}" for lo, hi, u in zip(d.lower, d.upper, d.classes, strict=True) if u]
    return d.difference, "Φ classes " + (", ".join(used) if used else "none in common")


def equal_phi_ratio(
    results: dict[str, dict],
    a: str,
    b: str,
    rule: str = "relative",
    which: str = "table",
    only: set[int] | None = None,
) -> dict[int, float]:
    """Seed -> ln(a / b) of S − S_null at equal Φ: each one's mean over the classes both populate (the classes and
    pairs of :func:`equal_phi`; ``only``: over these seeds alone, so that two ratios share their pads), NaN where
    either mean is not positive. The relative reading of a difference of S − S_null, whose margin is a ratio where
    :func:`equal_phi`'s is absolute."""
    seeds, d = _equal_prevalence(results, a, b, rule, which, "excess", only)
    if d is None:
        return {}
    top, ref = d.reference + d.difference, d.reference
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where((top > 0) & (ref > 0), np.log(top / ref), np.nan)
    return dict(zip(seeds, ratio.tolist(), strict=True))


def _equal_prevalence(
    results: dict[str, dict], a: str, b: str, rule: str, which: str, value: str, only: set[int] | None = None
) -> tuple[list[int], Any]:
    """(common seeds (within ``only``), ``EqualPrevalence`` of a − b over them), or ([], None) without one."""
    from aca_warp.analysis.measures import equal_prevalence_difference

    ta, tb = tables(results.get(a), rule, which), tables(results.get(b), rule, which)
    seeds = [s for s in sorted(ta) if s in tb and (only is None or s in only)]
    if not seeds:
        return [], None
    return seeds, equal_prevalence_difference([ta[s] for s in seeds], [tb[s] for s in seeds], value=value)


def _need(results: dict[str, dict], names: tuple[str, ...], n: int = 2) -> str | None:
    """Why a row cannot be measured (an experiment missing or with fewer than ``n`` usable pads), or None."""
    short = [f"{k} ({len(usable(results.get(k)))} usable pads)" for k in names if len(usable(results.get(k))) < n]
    return ("needs " + ", ".join(short)) if short else None


# ------------------------------------------------------------------------------------------------ the table


def evaluate_rows(results: dict[str, dict], cfg: Config, rows: list[Row] | None = None) -> list[dict[str, Any]]:
    """Every row's value and verdict; a row whose experiments are missing says so, a row that fails is marked."""
    out = []
    for row in ROWS if rows is None else rows:
        entry = {
            "section": row.section,
            "statement": row.statement,
            "paper": row.paper,
            "kind": row.kind,
            "criterion": row.criterion,
            "experiments": list(row.experiments),
            "construction": row.construction,
        }
        need = row.min_experiments or len(row.experiments)
        have = [k for k in row.experiments if len(usable(results.get(k))) >= 2]
        if len(have) < need:
            missing = _need(results, row.experiments) or ""
            entry.update(value="–", verdict=NOT_MEASURED, notes=missing)
        else:
            try:
                v = row.measure(results, cfg)
                entry.update(value=v.value, verdict=v.verdict, notes=v.notes)
            except Exception as e:  # noqa: BLE001 (one failing row must not take the table with it)
                entry.update(value="–", verdict=FAILED, notes=f"{type(e).__name__}: {e}")
        out.append(entry)
    return out


def seed_map(res: dict[str, Any] | None, key: str) -> dict[int, float]:
    """Seed -> a measure (dotted key) over the usable pads of ``res``."""
    return by_seed(res, lambda p: _get(p, key))


def ratio_interval(d: np.ndarray) -> str:
    """exp of the interval of a mean log ratio: "×1.23 [1.1, 1.4]"."""
    from aca_warp.studies.validation.verdicts import ci

    m, lo, hi = ci(d)
    if not math.isfinite(m):
        return "–"
    return (
        f"×{math.exp(m):.3g} [{math.exp(lo):.3g}, {math.exp(hi):.3g}]" if math.isfinite(lo) else f"×{math.exp(m):.3g}"
    )


def each(results: dict[str, dict], names: tuple[str, ...], key: str, spec: str = ".3g", scale: float = 1.0,
         unit: str = "") -> str:  # fmt: skip
    """ "name: interval; …" of a measure over the experiments ``names``."""
    return "; ".join(f"{n}: {interval(values(results.get(n), key), spec, scale, unit)}" for n in names)
