"""The verdicts of the validation at a glance, from a validation results file: per section of the paper, how many
rows carry each verdict, from the primary start (every row) and from rest at the paper's length (the rows measured
there, :func:`~aca_warp.studies.validation.causes.beside_rest`), with the primary's verdicts on those same rows
beside them; the rows reproduced by construction or as checks of the code hatched. The counts are the page's
(``verdict_counts``, ``rest_counts``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aca_warp.studies.validation.base import Config, evaluate_rows
from aca_warp.studies.validation.causes import beside_rest
from aca_warp.studies.validation.verdicts import FAILED, NOT_MEASURED, REPRODUCED, VERDICTS

COLOURS = {
    "reproduced": "#2e8b57",
    "partly": "#e0b030",
    "not reproduced": "#c0392b",
    "significant but negligible": "#7fb3d5",
    "undetermined": "#9b59b6",
    "not comparable": "#aaaaaa",
    NOT_MEASURED: "#ffffff",
    FAILED: "#000000",
}
"""The colour of each verdict."""
BARS = ("primary, every row", "primary, the rows measured from rest", "from rest, paper length")


def section(row: dict[str, Any]) -> str:
    """A row's section of the paper: its section's first part ("§3.1, Fig. 8" → "§3.1")."""
    return row["section"].split(",")[0]


def tallies(results: dict[str, dict], cfg: Config) -> tuple[list[str], dict[tuple[str, str], dict[str, list[bool]]]]:
    """The sections in the paper's order and, per (section, bar of :data:`BARS`), verdict → one flag per row (True
    for a row reproduced by construction)."""
    rows = evaluate_rows(results, cfg)
    rest = beside_rest(results, cfg)
    order = sorted({section(r) for r in rows}, key=lambda s: (not s.startswith("§"), s))
    out: dict[tuple[str, str], dict[str, list[bool]]] = {}
    for r, b in zip(rows, rest, strict=True):
        built = r["verdict"] == REPRODUCED and bool(r.get("construction"))
        out.setdefault((section(r), BARS[0]), {}).setdefault(r["verdict"], []).append(built)
        if b is not None and b["verdict"] in VERDICTS:
            out.setdefault((section(r), BARS[1]), {}).setdefault(r["verdict"], []).append(built)
            held = b["verdict"] == REPRODUCED and bool(r.get("construction"))
            out.setdefault((section(r), BARS[2]), {}).setdefault(b["verdict"], []).append(held)
    return order, out


def verdicts_figure(results: dict[str, dict], cfg: Config, path: Path, title: str = "") -> Path:
    """Write the figure (PNG) of the verdicts per section to ``path``; its parent is created."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    order, counts = tallies(results, cfg)
    fig, ax = plt.subplots(figsize=(11.0, 0.3 * len(counts) + 0.2 * len(order) + 1.6))
    labels, y = [], 0
    for sec in order:
        for bar in BARS:
            c = counts.get((sec, bar))
            if c is None:
                continue
            left = 0
            for verdict in (*VERDICTS, NOT_MEASURED, FAILED):
                flags = c.get(verdict, [])
                for built, n in ((True, sum(flags)), (False, len(flags) - sum(flags))):
                    if n:
                        ax.barh(y, n, left=left, color=COLOURS[verdict], edgecolor="0.3", lw=0.5,
                                hatch="///" if built else None)  # fmt: skip
                        left += n
                if flags:
                    ax.text(left - len(flags) / 2, y, str(len(flags)), ha="center", va="center", fontsize=7)
            labels.append((y, f"{sec}: {bar}"))
            y += 1
        y += 0.6
    ax.set_yticks([t for t, _ in labels], [s for _, s in labels], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("rows")
    legend = [Patch(facecolor=COLOURS[v], edgecolor="0.3", label=v) for v in (*VERDICTS, NOT_MEASURED)]
    legend.append(Patch(facecolor="white", edgecolor="0.3", hatch="///", label="reproduced by construction"))
    ax.legend(handles=legend, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title(title or f"verdicts per section of the paper ({cfg.seeds} seeds per experiment)", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
