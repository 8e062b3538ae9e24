"""§3.1 rows on the patterns of motion of Figs. 4–7: the loads and the surface pressures they give, the loads keeping
every patch in contact, co-moving neighbour
groups in HF1 and HF2, their periodicity following μ, radially imbalanced synchronisation in the friction radius and
torque, and the larger patches' "larger and better-defined synchronization patterns".

The pattern of Figs. 4/6 is the direction of motion of every patch at an instant (red: with the disc, blue: against
it). Its measures (``correlation_measures``): C of coupled neighbours — ⟨s_i s_j⟩ of the directions s = sign(u̇) over
the pairs within the 5 mm coupling radius, at 64 instants — and the size of the co-moving groups, the distance where
C(d) falls to 0, against the patches' spacing (the median distance to the nearest neighbour): a group smaller than
the spacing is no group. "Macroscopic groups ... move together" needs both C > 0 and a size beyond the spacing.
"""

from __future__ import annotations

import numpy as np

from aca_warp.studies.validation.base import (
    Config,
    Row,
    RowValue,
    _get,
    by_seed,
    each,
    interval,
    paired,
    register_row,
    seed_map,
    values,
)
from aca_warp.studies.validation.hf_experiments import PRESETS
from aca_warp.studies.validation.verdicts import (
    NOT_REPRODUCED,
    all_of,
    direction_verdict,
    effect,
    effect_text,
    threshold_verdict,
    value_verdict,
)

C_MARGIN = 0.1  # a correlation of the directions of coupled neighbours of at least 0.1
COHERENCE_LIMIT = 0.5  # Σu̇ and μ coherent at the first peak: γ² ≥ 0.5
RHO_MARGIN = 0.1
MATRIX_LIMIT = 0.01  # "the contact between the pad matrix and the disc minimized": below 1 % of the load
PAPER_PRESSURE_PA = {"hf1": 44e3, "hf2": 1108e3, "hf3": 44e3, "hf4": 1108e3}  # "a surface pressure of about ..."
PRESSURE_TOLERANCE = 0.05  # relative: "about 44 kPa", "about 1108 kPa"


def pressure_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """The surface pressure F_N / A_pad of every preset's pads against §3.1's (A_pad: the preset's pad sector, or the
    narrower sector of the same patch density that ``cfg.patches`` runs, whose load is reduced alike)."""
    from aca_warp.scene import preset
    from aca_warp.studies.validation.plan import reduced_pad

    def pad_area(name: str) -> float:
        base = preset(name)
        nominal = int(base.origin["patches"]["count"])
        same = cfg.patches is None or cfg.patches == nominal
        return float((base.pad if same else reduced_pad(base.pad, cfg.patches / nominal)).area)

    area = {n: pad_area(n) for n in PRESETS}
    p = {n: np.array(list(by_seed(results.get(n), lambda q: q["normal_force_N"]).values())) / area[n] for n in PRESETS}
    verdicts = [value_verdict(p[n], PAPER_PRESSURE_PA[n], PRESSURE_TOLERANCE * PAPER_PRESSURE_PA[n]) for n in PRESETS]
    return RowValue(
        "F_N / A_pad: " + "; ".join(f"{n} {interval(p[n], '.4g', 1e-3, 'kPa')}" for n in PRESETS),
        all_of(verdicts),
        "pad area "
        + ", ".join(f"{a:.6f}" for a in sorted(set(area.values())))
        + " m² (the presets' sector); the normal force as each pad recorded it",
    )


def contact_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """Every patch in contact and the matrix load share near 0 under the presets' loads."""
    share = {n: by_seed(results.get(n), lambda p: p["in_contact"] / p["patches"]) for n in PRESETS}
    matrix = {n: by_seed(results.get(n), lambda p: p["matrix_share"]) for n in PRESETS}
    verdicts = [threshold_verdict(np.array(list(share[n].values())), 1.0, False) for n in PRESETS]
    verdicts += [threshold_verdict(np.array(list(matrix[n].values())), MATRIX_LIMIT, True) for n in PRESETS]
    return RowValue(
        "patches in contact: " + "; ".join(f"{n} {interval(np.array(list(v.values())))}" for n, v in share.items()),
        all_of(verdicts),
        "share of the load on the matrix " + "; ".join(f"{n} {interval(np.array(list(v.values())))}"
                                                       for n, v in matrix.items()),
    )  # fmt: skip


def groups(results: dict[str, dict], name: str) -> tuple[np.ndarray, np.ndarray]:
    """C of coupled neighbours, and the group size minus the patch spacing [m], per seed."""
    c = values(results.get(name), "corr_near")
    size = np.array(list(by_seed(results.get(name), lambda p: _get(p, "corr_zero") - _get(p, "patch_spacing"))
                         .values()))  # fmt: skip
    return c, size


def comoving_row(name: str):  # noqa: ANN201
    def measure(results: dict[str, dict], cfg: Config) -> RowValue:
        c, size = groups(results, name)
        res = results.get(name)
        return RowValue(
            f"C of the directions of coupled neighbours: {interval(c)}; group size − spacing: "
            f"{interval(size, '.3g', 1e3, 'mm')}",
            direction_verdict([effect(c, C_MARGIN), effect(size, 0.0)]),
            f"group size {interval(values(res, 'corr_zero'), '.3g', 1e3, 'mm')}, spacing "
            f"{interval(values(res, 'patch_spacing'), '.3g', 1e3, 'mm')}; {effect_text(c, C_MARGIN)}; the spectral "
            f"phases at f1 (amplitude-weighted): C {interval(values(res, 'corr_f1_near'))}",
        )

    return measure


def periodic_row(results: dict[str, dict], cfg: Config) -> RowValue:
    texts = each(results, ("hf1", "hf2"), "coherence_f1")
    verdicts = [
        threshold_verdict(values(results.get(n), "coherence_f1"), COHERENCE_LIMIT, False) for n in ("hf1", "hf2")
    ]
    return RowValue(
        f"coherence γ² of Σu̇ with μ at f1: {texts}",
        all_of(verdicts),
        "Welch, segments of an eighth of the saturated span; mean over 20–80 kHz "
        + each(results, ("hf1", "hf2"), "coherence_band"),
    )


def radial_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """ρ of the radial imbalance B(t) of the motion with the friction radius, and with the torque beyond with μ."""
    rad = {n: values(results.get(n), "radial_rho_radius") for n in PRESETS}
    beyond = {
        n: paired(seed_map(results.get(n), "radial_rho_torque"), seed_map(results.get(n), "radial_rho_mu"))
        for n in PRESETS
    }
    parts = [effect(v, RHO_MARGIN) for v in rad.values()] + [effect(v, 0.0) for v in beyond.values()]
    return RowValue(
        "ρ(B, friction radius) " + "; ".join(f"{n}: {interval(v)}" for n, v in rad.items()),
        direction_verdict(parts),
        "B(t) = Σ u̇_i (r_i − r̄) / Σ |u̇_i|; ρ(B, torque) − ρ(B, μ) "
        + "; ".join(f"{n}: {interval(v)}" for n, v in beyond.items()),
    )


def patterns_row(results: dict[str, dict], cfg: Config) -> RowValue:
    """HF2 vs HF1: co-moving groups must exist in HF2 to be larger and better defined; then Δ C and Δ size."""
    c2, size2 = groups(results, "hf2")
    d_c = paired(seed_map(results.get("hf2"), "corr_near"), seed_map(results.get("hf1"), "corr_near"))
    d_size = paired(seed_map(results.get("hf2"), "corr_zero"), seed_map(results.get("hf1"), "corr_zero"))
    exist = direction_verdict([effect(c2, C_MARGIN), effect(size2, 0.0)])
    verdict = direction_verdict([effect(d_c, C_MARGIN), effect(d_size, 0.0)])
    if exist == NOT_REPRODUCED:
        verdict = NOT_REPRODUCED
    return RowValue(
        f"Δ C of coupled neighbours hf2 − hf1: {interval(d_c)}; Δ group size: {interval(d_size, '.3g', 1e3, 'mm')}",
        verdict,
        f"co-moving groups in hf2 (C > 0 and a size beyond the spacing): {exist}; C "
        + each(results, ("hf1", "hf2"), "corr_near") + "; size " + each(results, ("hf1", "hf2"), "corr_zero", ".3g",
                                                                          1e3, "mm")
        + "; spacing " + each(results, ("hf1", "hf2"), "patch_spacing", ".3g", 1e3, "mm"),
    )  # fmt: skip


COMOVING = f"C > 0 (margin {C_MARGIN:g}) and size > spacing"
PATTERN_ROWS = (
    Row("§3.1", "the loads give a surface pressure of about 44 kPa (HF1, HF3) and 1108 kPa (HF2, HF4)",
        "44 kPa, 1108 kPa", "value", PRESETS, pressure_row, f"± {PRESSURE_TOLERANCE * 100:g} % each",
        construction="the pad's sector was sized so that its area is the one the paper's loads and pressures imply, "
        "0.011095 m² against 0.01107 and 0.01116 m² (docs/model.md §1)"),
    Row("§3.1", "the loads keep every patch in contact with the disc, the matrix contact minimised", "all in contact",
        "threshold", PRESETS, contact_row, f"every patch in contact, matrix share ≤ {MATRIX_LIMIT:g}",
        construction="the presets' heights are drawn so that the paper's loads sit 10 % above the load that brings "
        "every patch into contact, the matrix free (docs/presets.md)"),
    Row("§3.1, Fig. 4", "HF1: macroscopic groups of patches move together in the same direction as their neighbours",
        "co-moving groups", "direction", ("hf1",), comoving_row("hf1"), COMOVING),
    Row("§3.1, Fig. 6", "HF2: macroscopic groups of patches move together in the same direction as their neighbours",
        "co-moving groups", "direction", ("hf2",), comoving_row("hf2"), COMOVING),
    Row("§3.1, Figs. 4–7", "the synchronised islands behave periodically, corresponding well to the global friction "
        "dynamics", "periodic, with μ", "threshold", ("hf1", "hf2"), periodic_row, f"γ²(f1) ≥ {COHERENCE_LIMIT:g}"),
    Row("§3.1, Figs. 5/7", "radially imbalanced synchronisation shows in the friction torque and the friction radius",
        "yes", "direction", PRESETS, radial_row, f"ρ(B, radius) > 0 (margin {RHO_MARGIN:g}), ρ(B, T) > ρ(B, μ)"),
    Row("§3.1, Figs. 4/6", "larger patches: larger, better-defined synchronisation patterns (HF2 vs HF1)", "yes",
        "direction", ("hf1", "hf2"), patterns_row, f"groups in HF2; Δ C > 0 (margin {C_MARGIN:g}) and Δ size > 0"),
)  # fmt: skip


def register() -> None:
    """Register the §3.1 rows on the patterns of motion (Figs. 4–7)."""
    for row in PATTERN_ROWS:
        register_row(row)
