"""The verdicts of the validation rows, fixed before any result (:data:`CRITERIA`).

Every row compares an ensemble measure (one value per seed; intervals are Student-t 95 % intervals of the mean,
``ensemble_interval``) with a statement of the paper, by one of these kinds:

* **value** — a number of the paper within a tolerance;
* **equivalence** — "not significantly different": the interval of the paired difference inside ± a margin;
* **direction** — "A greater than B": the paired difference significantly on the paper's side *and* at least the
  row's margin (the smallest effect the statement implies); significant but below the margin is a verdict of its
  own (*significant but negligible*);
* **threshold** — a measure on the paper's side of a limit;
* **not comparable** — the paper does not determine the number (an unstated window, scaling, threshold or rule):
  the candidate conventions are computed and their spread shown, no verdict on the model is drawn.

A measure computed under the two Φ rules of S (relative and snr) that is significant in opposite directions under
them is **undetermined**: the paper's own threshold would decide it.
"""

from __future__ import annotations

import contextlib
import contextvars
import math
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

REPRODUCED = "reproduced"
PARTLY = "partly"
NOT_REPRODUCED = "not reproduced"
NEGLIGIBLE = "significant but negligible"
UNDETERMINED = "undetermined"
NOT_COMPARABLE = "not comparable"
NOT_MEASURED = "not measured"
FAILED = "failed"

VERDICTS = (REPRODUCED, PARTLY, NOT_REPRODUCED, NEGLIGIBLE, UNDETERMINED, NOT_COMPARABLE)
"""The verdicts a measured row can carry (``not measured`` and ``failed`` say why a row has none)."""

CRITERIA = {
    "value": "reproduced when the whole 95 % interval of the mean lies within the paper's value ± the tolerance; "
    "partly when the mean does; not reproduced otherwise",
    "equivalence": "reproduced when the whole 95 % interval of the paired difference lies within ± the margin; not "
    "reproduced when it lies wholly beyond the margin; partly when it straddles the margin",
    "direction": "reproduced when the 95 % interval of the paired difference excludes 0 on the paper's side and the "
    "mean effect reaches the margin, for every part of the statement; significant but negligible when every part is "
    "significant on the paper's side but below its margin; partly when some parts are significant on the paper's "
    "side; not reproduced otherwise (an interval containing 0 is no evidence either way); undetermined when the two "
    "Φ rules of S give significant effects of opposite sign",
    "threshold": "reproduced when the whole 95 % interval lies on the paper's side of the threshold; partly when the "
    "mean does; not reproduced otherwise; a statement of several parts (presets, states, measures) is reproduced when "
    "every part is, not reproduced when every part is not, partly otherwise",
    "not comparable": "the paper does not give what decides the number (named in the row); the candidate "
    "conventions are computed and their spread is shown, without a verdict on the model",
}

# the outcome of one part of a direction statement
AGREES = "agrees"  # significant on the paper's side, mean effect ≥ margin
SMALL = "small"  # significant on the paper's side, mean effect < margin
NONE = "none"  # the interval contains 0
OPPOSITE = "opposite"  # significant against the paper


def ci(v: np.ndarray) -> tuple[float, float, float]:
    """(mean, low, high) of the 95 % t-interval of the mean over the finite values; NaN interval for one value."""
    from aca_warp.analysis.measures import ensemble_interval

    v = np.asarray(v, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return (float("nan"),) * 3
    e = ensemble_interval(v)
    return float(e.mean), float(e.mean_low), float(e.mean_high)


def side(v: np.ndarray, sign: float = 1.0) -> int:
    """+1 when the 95 % interval of the mean of ``sign``·v lies above 0, −1 when below, 0 otherwise."""
    m, lo, hi = ci(sign * np.asarray(v, dtype=np.float64))
    if not math.isfinite(lo):
        return 0
    return 1 if lo > 0 else (-1 if hi < 0 else 0)


@contextmanager
def raised(flag: contextvars.ContextVar[bool]) -> Iterator[None]:
    """``flag`` set inside the block, as it was after it: the switch of another reading of the rows, evaluated a
    second time under it for the page's line on what that reading would move."""
    token = flag.set(True)
    try:
        yield
    finally:
        flag.reset(token)


_STRICT = contextvars.ContextVar("strict_direction", default=False)


def strict_direction() -> contextlib.AbstractContextManager[None]:
    """Inside it a direction part agrees only when the whole 95 % interval of ``sign``·v, not its mean alone, reaches
    the margin (:func:`effect`): the stricter reading of the criterion, for the page's line on what it would move."""
    return raised(_STRICT)


def effect(v: np.ndarray, margin: float, sign: float = 1.0) -> str:
    """The outcome of one part of a direction statement: ``sign``·v significantly positive with a mean of at least
    ``margin`` (:data:`AGREES`; inside :func:`strict_direction` the interval's lower end), significantly positive
    below it (:data:`SMALL`), not significant (:data:`NONE`) or significantly negative (:data:`OPPOSITE`)."""
    s = side(v, sign)
    if s < 0:
        return OPPOSITE
    if s == 0:
        return NONE
    if _STRICT.get():
        return AGREES if ci(sign * np.asarray(v, dtype=np.float64))[1] >= margin else SMALL
    return AGREES if sign * ci(v)[0] >= margin else SMALL


def effect_text(v: np.ndarray, margin: float, sign: float = 1.0) -> str:
    """How the mean effect compares with the margin, in words ("mean 0.021 against the margin 0.05")."""
    m = ci(v)[0]
    if not math.isfinite(m):
        return "no effect measured"
    return f"mean {sign * m:.3g} against the margin {margin:.3g} ({effect(v, margin, sign)})"


def direction_verdict(parts: list[str], secondary: list[str] | None = None) -> str:
    """Verdict of a directional statement from the :func:`effect` of each part (:data:`CRITERIA`).

    ``secondary``: effects of further measures of a one-part statement; one significantly opposite makes an agreeing
    primary only "partly", one agreeing lifts a non-significant primary to "partly".
    """
    sec = secondary or []
    if parts and all(p == AGREES for p in parts):
        return PARTLY if OPPOSITE in sec else REPRODUCED
    if parts and all(p in (AGREES, SMALL) for p in parts):
        return NEGLIGIBLE if all(p == SMALL for p in parts) else PARTLY
    if any(p in (AGREES, SMALL) for p in parts) or (parts == [NONE] and AGREES in sec):
        return PARTLY
    return NOT_REPRODUCED


def rules_verdict(verdict: str, relative: np.ndarray, snr: np.ndarray, sign: float = 1.0) -> str:
    """``verdict`` (from the relative rule), or :data:`UNDETERMINED` when the relative and the snr rule of Φ give
    significant effects of opposite sign (the paper does not state its threshold, so it would decide)."""
    a, b = side(relative, sign), side(snr, sign)
    return UNDETERMINED if a * b < 0 else verdict


def value_verdict(v: np.ndarray, paper: float, tol: float) -> str:
    """Verdict of a value within ``paper`` ± ``tol`` (:data:`CRITERIA`)."""
    m, lo, hi = ci(v)
    if not math.isfinite(m):
        return NOT_MEASURED
    if math.isfinite(lo) and paper - tol <= lo and hi <= paper + tol:
        return REPRODUCED
    return PARTLY if abs(m - paper) <= tol else NOT_REPRODUCED


def threshold_verdict(v: np.ndarray, limit: float, below: bool) -> str:
    """Verdict of a value on the paper's side of ``limit`` (below it when ``below``) (:data:`CRITERIA`)."""
    m, lo, hi = ci(v)
    if not math.isfinite(m):
        return NOT_MEASURED
    whole = (hi <= limit) if below else (lo >= limit)
    if math.isfinite(lo) and whole:
        return REPRODUCED
    return PARTLY if (m <= limit if below else m >= limit) else NOT_REPRODUCED


def equivalence_verdict(d: np.ndarray, margin: float) -> str:
    """Verdict of "not significantly different" with an equivalence ``margin`` (:data:`CRITERIA`): the two one-sided
    tests of equivalence on the 95 % interval."""
    m, lo, hi = ci(d)
    if not math.isfinite(lo):
        return NOT_MEASURED
    if -margin <= lo and hi <= margin:
        return REPRODUCED
    if lo > margin or hi < -margin:
        return NOT_REPRODUCED
    return PARTLY


def all_of(verdicts: list[str]) -> str:
    """The verdict of a statement of several parts: reproduced when every part is, not reproduced when every part
    measured is not, partly otherwise (a part not measured keeps a statement from reproduced, and counts for
    nothing else); not measured when no part is."""
    measured = [v for v in verdicts if v != NOT_MEASURED]
    if not measured:
        return NOT_MEASURED
    if len(measured) == len(verdicts) and all(v == REPRODUCED for v in measured):
        return REPRODUCED
    return NOT_REPRODUCED if all(v == NOT_REPRODUCED for v in measured) else PARTLY


def spread_text(values: dict[str, float], spec: str = ".3g") -> str:
    """The spread of candidate values (name → value): "min … max (×ratio) over N candidates: a: …; b: …"."""
    v = {k: x for k, x in values.items() if x is not None and math.isfinite(x)}
    if not v:
        return "no candidate measured"
    lo, hi = min(v.values()), max(v.values())
    ratio = f", ×{hi / lo:.3g}" if lo > 0 else ""
    each = "; ".join(f"{k}: {format(x, spec)}" for k, x in v.items())
    return f"{format(lo, spec)} … {format(hi, spec)}{ratio} over {len(v)} candidates ({each})"
