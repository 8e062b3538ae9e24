"""§5 and the Appendix: the Synchronization Index does not see the spatial arrangement of the patches (a permutation
test on the §3.1 pads), Table A.2, the index of the four theoretical cases of Table A.1, computed with this
project's implementation (``sync_index_from_bins``: 10 phase bins, Φ = 100, τ_AB = 0.5, τ_BC = 0.55, w = 0.9, the
filter left out as the Appendix does), and §2.2's best and worst case with the filter and the 180 bins of the
simulations (n_AB,min and n_BC,min "taking into account the effects of the weighted moving average filter").
"""

from __future__ import annotations

import numpy as np

from aca_warp.studies.validation.base import Config, Row, RowValue, interval, register_row, values
from aca_warp.studies.validation.hf_experiments import PRESETS
from aca_warp.studies.validation.verdicts import (
    NOT_REPRODUCED,
    REPRODUCED,
    direction_verdict,
    effect,
)

TABLE_A1 = {  # bin values of the four cases (Table A.1)
    1: (100, 0, 0, 0, 0, 0, 0, 0, 0, 0),
    2: (75, 3, 3, 3, 3, 3, 3, 3, 2, 2),
    3: (27, 25, 23, 4, 4, 4, 4, 3, 3, 3),
    4: (10,) * 10,
}
TABLE_A2 = {  # n_AB, n_AB,max, n_AB,min, n_BC, n_BC,max, n_BC,min, S_AB, S_BC, S (Table A.2)
    1: (0.500, 5.000, 0.500, 0.550, 5.500, 0.550, 1.000, 1.000, 1.000),
    2: (0.667, 5.000, 0.500, 0.733, 5.500, 0.550, 0.963, 0.963, 0.963),
    3: (1.920, 5.000, 0.500, 2.130, 5.500, 0.550, 0.684, 0.681, 0.684),
    4: (5.000, 5.000, 0.500, 5.500, 5.500, 0.550, 0.000, 0.000, 0.000),
}
CASES = {1: "complete synchronisation", 2: "one group of 75 patches", 3: "three islands of 75 patches",
         4: "perfectly asynchronous"}  # fmt: skip
COLUMNS = ("n_AB", "n_AB,max", "n_AB,min", "n_BC", "n_BC,max", "n_BC,min", "S_AB", "S_BC", "S")
DECIMALS = 0.0005 + 1e-9  # the table's three decimals
PERMUTED_LIMIT = 1e-9  # S of the permuted patches equal to S up to rounding
COHERENCE_MARGIN = 0.02


def table_row(case: int):  # noqa: ANN201
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        from aca_warp.analysis.sync import sync_index_from_bins

        r = sync_index_from_bins(np.array(TABLE_A1[case]), smooth=False)
        ours = (r.n_AB, r.n_AB_max, r.n_AB_min, r.n_BC, r.n_BC_max, r.n_BC_min, r.S_AB, r.S_BC, r.S)
        ours = tuple(round(float(v), 12) + 0.0 for v in ours)  # no "-0.000" for a rounding residue
        worst = max(abs(a - b) for a, b in zip(ours, TABLE_A2[case], strict=True))
        return RowValue(
            ", ".join(f"{k} {v:.3f}" for k, v in zip(COLUMNS, ours, strict=True)),
            REPRODUCED if worst <= DECIMALS else NOT_REPRODUCED,
            f"bins {TABLE_A1[case]}; largest difference from the table {worst:.2g}",
        )

    return measure


FILTER_BINS = 180  # §2.2: the phase bins of the simulations' analyses


def one_bin(phi: float) -> np.ndarray:
    """Bin values of complete synchronisation over ``FILTER_BINS`` bins: all Φ patches in the first, shape (180,)."""
    g = np.zeros(FILTER_BINS)
    g[0] = phi
    return g


def filtered_extremes_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """S with the filter over 180 bins: every patch in one bin (at each of the 180 positions: the filter is
    circular) gives the best case, S = 1, because n_AB,min and n_BC,min are those of one filtered bin; patches spread
    evenly over the bins give the worst case, S = 0."""
    from aca_warp.analysis.sync import sync_index_from_bins

    phi = 100.0
    one = [sync_index_from_bins(np.roll(one_bin(phi), k), smooth=True) for k in range(FILTER_BINS)]
    even = sync_index_from_bins(np.full(FILTER_BINS, phi / FILTER_BINS), smooth=True).S
    best = np.array([r.S for r in one])
    raw = sync_index_from_bins(one_bin(phi), smooth=False).n_AB_min
    worst = max(float(np.max(np.abs(best - 1.0))), abs(float(even)))
    return RowValue(
        f"one bin: S {best.min():.3f}–{best.max():.3f} over the 180 positions; an even spread: S {abs(even):.3f}",
        REPRODUCED if worst <= DECIMALS else NOT_REPRODUCED,
        f"Φ = {phi:g}, τ_AB = 0.5, τ_BC = 0.55, w = 0.9; n_AB,min = {one[0].n_AB_min:.3f} with the filter "
        f"({raw:.3f} without it); largest difference from 1 and 0: {worst:.2g}",
    )


def permutation_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """S of the patches with their arrangement permuted equals S; the neighbours' coherence changes."""
    ds = np.concatenate([values(results.get(n), "perm_max_dS") for n in PRESETS])
    dc = np.concatenate(
        [values(results.get(n), "perm_coherence") - values(results.get(n), "perm_coherence_permuted") for n in PRESETS]
    )
    same = ds.size > 0 and float(np.max(ds)) <= PERMUTED_LIMIT
    verdict = direction_verdict([effect(np.abs(dc), COHERENCE_MARGIN)]) if same else NOT_REPRODUCED
    return RowValue(
        f"largest |ΔS| over the bins, permuted − original: {float(np.max(ds)) if ds.size else float('nan'):.2g} "
        f"(over {ds.size} pads)",
        verdict,
        "the same spectra with the patches' positions permuted at random; the spatial measure that does see it, the "
        f"neighbours' coherence C over 20–80 kHz, changes by {interval(dc)}",
    )


def register_method() -> None:
    """Register §2.2's row (the filtered extremes of Eq. 6), first in the paper's order."""
    register_row(
        Row("§2.2, Eq. 6", "n_AB,min and n_BC,min take the filter into account: complete synchronisation gives S = 1, "
            "an even spread S = 0 (180 bins, filtered)", "1, 0", "value", (), filtered_extremes_row,
            "to three decimals", construction="the index of synthetic phase sets: a check of the code")
    )  # fmt: skip


def register() -> None:
    """Register the §5 permutation row and the Table A.2 rows."""
    register_row(
        Row("§5", "the Synchronization Index is not sensitive to the spatial distribution of the patches",
            "insensitive", "direction", PRESETS, permutation_row, f"ΔS ≤ {PERMUTED_LIMIT:g} while |ΔC| > 0 (margin "
            f"{COHERENCE_MARGIN:g})", min_experiments=1,
            construction="S is a function of the patches' phases alone, so permuting their positions cannot change it: "
            "a check of the code")
    )  # fmt: skip
    for case in sorted(TABLE_A1):
        register_row(Row("Appendix, Table A.2", f"case {case} ({CASES[case]}): n_AB … S", "Table A.2", "value", (),
                         table_row(case), "every entry to the table's three decimals",
                         construction="the index of synthetic phase sets: a check of the code"))  # fmt: skip
