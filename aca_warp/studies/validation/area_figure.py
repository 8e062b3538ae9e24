"""The CWT of μ of the growth runs (Fig. 11) as a figure, from a validation results file: the ensemble mean of the
stored CWT (``cwt_measures``) of ``va_full`` and ``va_full_rest``, amplitude-true and energy-normalised, each window
scaled to its largest value, with the median first line of Σu̇'s STFT and the median CWT ridge within §4's band."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aca_warp.studies.validation.area import cwt_lines, l2_weight
from aca_warp.studies.validation.base import CHARACTERISTIC_BAND

EXPERIMENTS = ("va_full", "va_full_rest")


def mean_cwt(res: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Window centres [s] (T,), frequencies [Hz] (F,) and the mean amplitude-true CWT (F, T) over the pads with one,
    cut to the shortest pad's windows; and the number of pads."""
    cwts = [p["measures"]["cwt"] for p in res.get("pads", []) if "cwt" in (p.get("measures") or {})]
    if not cwts:
        raise ValueError("no pad of this experiment has a stored CWT (a results file made before it was measured)")
    n = min(len(c["times"]) for c in cwts)
    amp = np.mean([np.asarray(c["amplitude"], dtype=np.float64)[:, :n] for c in cwts], axis=0)
    return np.asarray(cwts[0]["times"][:n]), np.asarray(cwts[0]["freqs_hz"]), amp, len(cwts)


def _median_track(tracks: list[Any]) -> np.ndarray:
    n = min(len(x) for x in tracks)
    return np.median([np.asarray(x[:n], dtype=np.float64) for x in tracks], axis=0)


def cwt_figure(results: dict[str, dict], path: Path, title: str = "") -> Path:
    """Write the figure (PNG) of the growth runs' CWT to ``path``; its parent is created."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in EXPERIMENTS if n in results]
    if not names:
        raise ValueError(f"the results hold none of {', '.join(EXPERIMENTS)}")
    fig, axes = plt.subplots(2, len(names), figsize=(6.0 * len(names), 7.0), sharex=True, squeeze=False)
    for j, name in enumerate(names):
        res = results[name]
        t, f, amp, pads = mean_cwt(res)
        cwt_pads = [p for p in res["pads"] if "cwt" in (p.get("measures") or {})]
        first = _median_track([p["measures"]["line"]["first_hz"] for p in cwt_pads])
        first_t = np.asarray(cwt_pads[0]["measures"]["line"]["times"][: first.size])
        ridge = _median_track([cwt_lines(p["measures"]["cwt"])["band"]["hz"] for p in cwt_pads])
        views = (("amplitude-true", amp), ("energy-normalised (÷ √f)", amp * l2_weight(f)[:, None]))
        for i, (label, w) in enumerate(views):
            ax = axes[i, j]
            mesh = ax.pcolormesh(1e3 * t, 1e-3 * f, w / w.max(axis=0, keepdims=True), shading="nearest", vmin=0, vmax=1)
            ax.plot(1e3 * first_t, 1e-3 * first, "w--", lw=1.2, label="first line of Σu̇'s STFT (median)")
            ax.plot(1e3 * t[: ridge.size], 1e-3 * ridge, "r-", lw=1.2, label="CWT ridge within 20–80 kHz (median)")
            for edge in CHARACTERISTIC_BAND:
                ax.axhline(1e-3 * edge, color="0.8", lw=0.6, ls=":")
            ax.set_yscale("log")
            ax.set_title(f"{name} ({pads} pads): {label}", fontsize=10)
            ax.set_ylabel("frequency [kHz]")
            if i == 1:
                ax.set_xlabel("time [ms]")
            if i == 0 and j == 0:
                ax.legend(loc="lower left", fontsize=8)
            fig.colorbar(mesh, ax=ax, label="mean |W| ÷ the window's largest")
    fig.suptitle(title or "CWT of μ over the growth (complex Morlet cmor1.5-1.0, ensemble mean, each window scaled)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
